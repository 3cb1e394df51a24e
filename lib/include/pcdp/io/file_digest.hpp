// Size and SHA-256 of a file, for report.json's lists of inputs and outputs (OpenSSL's libcrypto).
#pragma once

#include <cstdint>
#include <string>

namespace pcdp::io {

struct FileDigest {
  std::uint64_t bytes = 0;
  std::string sha256;  ///< 64 lowercase hex digits
};

/// Reads `path` to its end and returns its size and SHA-256. Returns 0, or the errno of the
/// failing open or read (the caller names the file and the error class: input or output).
int digest_file(const std::string& path, FileDigest& out);

/// SHA-256 of a byte string, as 64 lowercase hex digits.
std::string sha256_hex(const void* data, std::size_t size);

}  // namespace pcdp::io
