// One named, typed column of a point record, as a PCD header declares it (FIELDS, TYPE, SIZE,
// COUNT). The core's own description of a field: a pass carries the input's extra fields with it
// (Pass::extra) and the PCD reader and writer (pcdp/io/pcd.hpp) use the same type.
#pragma once

#include <cstddef>
#include <string>

namespace pcdp {

struct Field {
  std::string name;
  char type = 'F';  ///< 'F' float, 'U' unsigned, 'I' signed
  int size = 4;     ///< bytes: 1, 2, 4, 8
  int count = 1;
  std::size_t bytes() const { return static_cast<std::size_t>(size) * static_cast<std::size_t>(count); }
};

}  // namespace pcdp
