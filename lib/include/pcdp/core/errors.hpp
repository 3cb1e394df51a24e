// Error types thrown at the boundaries of the library. Each maps to one CLI exit code:
//   ConfigError -> 2 (invalid configuration), InputError -> 3 (input data error),
//   OutputError -> 4 (an output cannot be written), anything else -> 1 (internal error).
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace pcdp {

/// The pipeline description (YAML, --set overrides, CLI options) breaks a rule.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An input file (scan, pose file) is missing, malformed or breaks the data contract.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An output cannot be written: the folder or file is not writable, the path runs through a file,
/// the disk is full, another run holds the output folder, the commit failed.
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class ExitCode : int { kOk = 0, kInternal = 1, kConfig = 2, kInput = 3, kOutput = 4 };

/// Levenshtein distance, for "did you mean" suggestions.
std::size_t edit_distance(const std::string& a, const std::string& b);

/// The candidate nearest to `word`, or "" when none is close enough to be a plausible typo.
std::string nearest_name(const std::string& word, const std::vector<std::string>& candidates);

/// " (did you mean 'x'?)" or "" — appended to "unknown ..." messages.
std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates);

/// A number as error messages and `describe` print it: up to 10 significant digits, "inf", "-inf".
std::string format_number(double v);

}  // namespace pcdp
