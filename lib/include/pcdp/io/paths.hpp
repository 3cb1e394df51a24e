// How a path is resolved wherever two paths are compared as files or folders: an output that
// would overwrite an input, an input inside an output folder, a scan listed twice. One resolution
// for all of them, so that `a/../b`, `./b`, a symlink to b and b itself compare equal everywhere.
// Header-only: the checks live in the library and in the CLI's commands.
#pragma once

#include <filesystem>
#include <string>
#include <system_error>

namespace pcdp::io {

/// `path` made absolute against the working directory, then resolved: the symlinks and `.` and
/// `..` of its existing part followed, the rest normalized (std::filesystem::weakly_canonical;
/// absolute first, since the canonical form of a relative path none of whose parts exists stays
/// relative). Where a component cannot be read, the absolute path in normal form (no symlink
/// followed); empty when the working directory cannot be read.
inline std::filesystem::path resolved_path(const std::string& path) {
  std::error_code ec;
  const std::filesystem::path a = std::filesystem::absolute(path, ec);
  if (ec) return {};
  std::filesystem::path r = std::filesystem::weakly_canonical(a, ec);
  if (ec) return a.lexically_normal();
  return r;
}

}  // namespace pcdp::io
