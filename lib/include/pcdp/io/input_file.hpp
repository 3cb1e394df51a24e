// The check every reader of a user file makes before opening it: the path must name a regular
// file (after following symlinks). A FIFO, a device (/dev/zero, /dev/stdin on a terminal or a
// pipe), a socket or a directory is refused up front, so that reading can neither block forever
// nor run until memory is exhausted. Header-only so that every reader can call it in one line.
#pragma once

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "pcdp/core/errors.hpp"

namespace pcdp::io {

/// "" when `path` names a regular file; otherwise the reason it is not one, phrased to follow
/// "path: ", e.g. "is a FIFO (named pipe), not a regular file: a pose file must be a regular file".
/// `what` names the role of the file ("pose file", "PCD file", "pipeline file", ...).
inline std::string regular_file_problem(const std::string& path, const std::string& what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int e = errno;
    std::string msg = "cannot open the " + what + " (" + std::strerror(e) + ")";
    if (e == ELOOP) msg += "; a symlink loop?";
    return msg;
  }
  if (S_ISREG(st.st_mode)) return "";
  if (S_ISDIR(st.st_mode)) return "is a directory, not a " + what;
  const char* kind = S_ISFIFO(st.st_mode)  ? "a FIFO (named pipe or a pipe such as /dev/stdin)"
                     : S_ISCHR(st.st_mode) ? "a character device (such as /dev/zero or a terminal)"
                     : S_ISBLK(st.st_mode) ? "a block device"
                     : S_ISSOCK(st.st_mode) ? "a socket"
                                            : "not a file";
  return std::string("is ") + kind + ", not a regular file: a " + what +
         " must be a regular file (pipes and devices are refused: reading them may never end)";
}

/// Throws InputError("path: <problem>") unless `path` names a regular file.
inline void require_regular_file(const std::string& path, const std::string& what) {
  const std::string problem = regular_file_problem(path, what);
  if (!problem.empty()) throw InputError(path + ": " + problem);
}

}  // namespace pcdp::io
