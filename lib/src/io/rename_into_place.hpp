// Internal: moves a finished temporary file over its destination, or removes it and throws.
#pragma once

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

#include "pcdp/core/errors.hpp"

namespace pcdp::io::detail {

/// rename(tmp, path); on failure the temporary is removed and an OutputError names `path`.
inline void rename_into_place(const std::string& tmp, const std::string& path) {
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(tmp.c_str());
    throw OutputError(path + ": cannot rename into place (" + std::string(std::strerror(e)) + ")");
  }
}

}  // namespace pcdp::io::detail
