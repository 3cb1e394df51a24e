// LZF decoder, written from the format description: a stream of tokens, each starting with a
// control byte c. c < 32: a literal run of c + 1 bytes follows. Otherwise a back reference:
// length L = c >> 5 (7 means "add the next byte"), offset = ((c & 31) << 8) + next byte + 1,
// copy L + 2 bytes from `offset` bytes back (the source may overlap the destination).
#include <cstdint>
#include <cstring>

#include "pcdp/io/pcd.hpp"

namespace pcdp::io {

bool lzf_decompress(const std::uint8_t* in, std::size_t in_size, std::uint8_t* out, std::size_t out_size) {
  std::size_t ip = 0, op = 0;
  while (ip < in_size) {
    const unsigned c = in[ip++];
    if (c < 32) {
      const std::size_t len = c + 1;
      if (ip + len > in_size || op + len > out_size) return false;
      std::memcpy(out + op, in + ip, len);
      ip += len;
      op += len;
    } else {
      std::size_t len = c >> 5;
      if (len == 7) {
        if (ip >= in_size) return false;
        len += in[ip++];
      }
      if (ip >= in_size) return false;
      const std::size_t back = ((static_cast<std::size_t>(c & 31) << 8) | in[ip++]) + 1;
      len += 2;
      if (back > op || op + len > out_size) return false;
      std::size_t ref = op - back;
      for (std::size_t k = 0; k < len; ++k) out[op++] = out[ref++];  // may overlap
    }
  }
  return op == out_size;
}

}  // namespace pcdp::io
