#include <stdexcept>

#include "fuzz_common.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz_file(data, size, ".pcd");
  try {
    pcdp::read_pass(path, 0);  // header, data (all three encodings) and the contract checks
  } catch (const pcdp::InputError&) {
  }
  return 0;
}
