// What tiff_writer.cpp and tiff_reader.cpp share: the TIFF field types they use, and the one
// host they serve. Both move float samples between memory and an "II" (little-endian) TIFF as
// they lie, without swapping bytes.
#pragma once

#include <cstdint>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the TIFF writer and reader copy float samples as they lie in memory: little-endian hosts only"
#endif

namespace pcdp::io::detail {
// TIFF 6.0 field types, and BigTIFF's 8-byte integer.
constexpr std::uint16_t kTiffAscii = 2, kTiffShort = 3, kTiffLong = 4, kTiffDouble = 12, kTiffLong8 = 16;

/// Bytes of one value of a field type (TIFF 6.0 section 2, BigTIFF's 16-18); 0 for a type
/// neither knows, whose values a reader skips.
constexpr int tiff_type_bytes(std::uint16_t type) {
  switch (type) {
    case 1: case 2: case 6: case 7: return 1;   // BYTE, ASCII, SBYTE, UNDEFINED
    case 3: case 8: return 2;                    // SHORT, SSHORT
    case 4: case 9: case 11: case 13: return 4;  // LONG, SLONG, FLOAT, IFD
    case 5: case 10: case 12: case 16: case 17: case 18: return 8;  // RATIONALs, DOUBLE, LONG8, SLONG8, IFD8
    default: return 0;
  }
}
}  // namespace pcdp::io::detail
