// The readers take paths (they check sizes against the file before allocating): each input is
// written to a per-process temporary file first.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

inline std::string fuzz_file(const std::uint8_t* data, std::size_t size, const char* ext) {
  const std::string path = "/tmp/pcdp_fuzz_" + std::to_string(::getpid()) + ext;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f) {
    std::fwrite(data, 1, size, f);
    std::fclose(f);
  }
  return path;
}
