#include "pcdp/io/atomic_file.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "pcdp/errors.hpp"

namespace fs = std::filesystem;

namespace pcdp::io {

StagedOutputs::StagedOutputs(std::string dir) : dir_(std::move(dir)) {
  std::error_code ec;
  if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec))
    throw ConfigError("output_dir '" + dir_ + "' exists and is not a folder");
  fs::create_directories(dir_, ec);
  if (ec) throw ConfigError("output_dir '" + dir_ + "': cannot create the folder (" + ec.message() + ")");
}

StagedOutputs::~StagedOutputs() {
  if (committed_) return;
  for (const auto& [tmp, fin] : staged_) {
    std::remove(tmp.c_str());
    std::remove((tmp + ".body").c_str());
  }
}

std::string StagedOutputs::staged_path(const std::string& filename) {
  const std::string tmp = (fs::path(dir_) / ("." + filename + ".tmp-" + std::to_string(::getpid()))).string();
  staged_.emplace_back(tmp, final_path(filename));
  return tmp;
}

std::string StagedOutputs::final_path(const std::string& filename) const {
  return (fs::path(dir_) / filename).string();
}

std::vector<std::string> StagedOutputs::final_paths() const {
  std::vector<std::string> out;
  for (const auto& [tmp, fin] : staged_) out.push_back(fin);
  return out;
}

void StagedOutputs::commit() {
  for (const auto& [tmp, fin] : staged_) {
    if (std::rename(tmp.c_str(), fin.c_str()) != 0)
      throw std::runtime_error("cannot move " + tmp + " to " + fin + ": " + std::strerror(errno));
  }
  committed_ = true;
}

void write_file_atomic(const std::string& path, const std::string& content) {
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary);
    out << content;
    out.close();
    if (!out) {
      std::remove(tmp.c_str());
      throw std::runtime_error(path + ": cannot write (" + std::strerror(errno) + ")");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot rename into place (" + std::strerror(errno) + ")");
  }
}

}  // namespace pcdp::io
