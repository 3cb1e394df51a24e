#include <string>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/pipeline.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  pcdp::LoadOptions o;
  o.check_inputs = false;
  try {
    pcdp::Pipeline::prepare(pcdp::load_pipeline_from_string(text, "fuzz.yaml", "/nonexistent", o));
  } catch (const pcdp::ConfigError&) {
  } catch (const pcdp::InputError&) {
  }
  return 0;
}
