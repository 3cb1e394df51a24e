// Outputs are written under temporary names in the output folder and renamed to their final
// names only when the whole run has succeeded (DESIGN.md "Conventions"). A run that fails or is
// killed leaves no file that looks complete; earlier outputs are not clobbered by a failed run.
#pragma once

#include <string>
#include <vector>

#include "pcdp/stage.hpp"

namespace pcdp::io {

class StagedOutputs final : public OutputSink {
 public:
  /// Creates `dir` if needed. Throws ConfigError if it exists and is not a folder.
  explicit StagedOutputs(std::string dir);
  ~StagedOutputs() override;  // removes whatever was not committed
  StagedOutputs(const StagedOutputs&) = delete;
  StagedOutputs& operator=(const StagedOutputs&) = delete;

  std::string staged_path(const std::string& filename) override;
  std::string final_path(const std::string& filename) const;
  /// The final paths of everything staged so far.
  std::vector<std::string> final_paths() const;
  /// Renames every staged file to its final name.
  void commit();
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
  std::vector<std::pair<std::string, std::string>> staged_;  // temp, final
  bool committed_ = false;
};

/// Writes `content` to `path` atomically (temporary file in the same folder, then rename).
void write_file_atomic(const std::string& path, const std::string& content);

}  // namespace pcdp::io
