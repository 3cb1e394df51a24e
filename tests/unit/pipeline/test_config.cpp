#include <gtest/gtest.h>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/pipeline.hpp"

using namespace pcdp;

namespace {
const char* kBase = R"(
rpy_order: xyz
input:
  scans: scans/*.pcd
  poses: poses.csv
output_dir: out
mount: {x: 0.5, z: 1.64, pitch: 0.19775}
sensor:
  range_max: 30
  range_calibration: {k: 1.0002, b: -0.0036}
stages:
  - type: register
    skew_correction: true
)";

LoadOptions no_inputs() {
  LoadOptions o;
  o.check_inputs = false;
  return o;
}

std::string error_of(const std::string& yaml, LoadOptions o = no_inputs()) {
  try {
    load_pipeline_from_string(yaml, "p.yaml", "/base", o);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string replace(std::string s, const std::string& a, const std::string& b) {
  const auto p = s.find(a);
  EXPECT_NE(p, std::string::npos) << a;
  return s.replace(p, a.size(), b);
}
}  // namespace

TEST(Config, LoadsTypedValuesAndResolvesPathsAgainstTheFile) {
  const PipelineConfig c = load_pipeline_from_string(kBase, "p.yaml", "/base", no_inputs());
  EXPECT_EQ(c.rpy_order, RpyOrder::kXyz);
  EXPECT_DOUBLE_EQ(c.mount.translation.z(), 1.64);
  EXPECT_DOUBLE_EQ(c.mount.rpy.pitch, 0.19775);
  EXPECT_DOUBLE_EQ(c.sensor.range_k, 1.0002);
  EXPECT_DOUBLE_EQ(c.sensor.range_b, -0.0036);
  EXPECT_DOUBLE_EQ(c.sensor.min_amplitude, 18.0);  // default
  EXPECT_EQ(c.scan_patterns.at(0), "/base/scans/*.pcd");
  EXPECT_EQ(c.poses, "/base/poses.csv");
  EXPECT_EQ(c.output_dir, "/base/out");
  ASSERT_EQ(c.stages.size(), 1u);
  EXPECT_EQ(c.stages[0].name, "register");
  EXPECT_TRUE(c.stages[0].options.get_bool("skew_correction"));
}

TEST(Config, OverridesWinAndResolveAgainstTheWorkingDirectory) {
  LoadOptions o = no_inputs();
  o.overrides = {parse_override("sensor.min_amplitude=20"), parse_override("input.poses=here.csv"),
                 parse_override("stages.register.skew_correction=false"),
                 parse_override("sensor.range_calibration.k=1.01")};
  const PipelineConfig c = load_pipeline_from_string(kBase, "p.yaml", "/base", o);
  EXPECT_DOUBLE_EQ(c.sensor.min_amplitude, 20.0);
  EXPECT_DOUBLE_EQ(c.sensor.range_k, 1.01);
  EXPECT_EQ(c.poses, "here.csv");
  EXPECT_FALSE(c.stages[0].options.get_bool("skew_correction"));
  o.output_dir = "elsewhere";
  EXPECT_EQ(load_pipeline_from_string(kBase, "p.yaml", "/base", o).output_dir, "elsewhere");
}

TEST(Config, ErrorsNameTheLineKeyValueAndRule) {
  // Unknown stage option, with a suggestion.
  std::string e = error_of(replace(kBase, "skew_correction: true", "skew_corection: true"));
  EXPECT_NE(e.find("p.yaml:13"), std::string::npos) << e;
  EXPECT_NE(e.find("stage 'register' (register)"), std::string::npos) << e;
  EXPECT_NE(e.find("unknown option 'skew_corection' (did you mean 'skew_correction'?)"), std::string::npos) << e;
  // Wrong type.
  e = error_of(replace(kBase, "skew_correction: true", "skew_correction: maybe"));
  EXPECT_NE(e.find("option 'skew_correction' = 'maybe' must be true or false"), std::string::npos) << e;
  // Out of range: never clamped.
  e = error_of(replace(kBase, "range_max: 30", "range_max: -5"));
  EXPECT_NE(e.find("p.yaml:9: sensor: option 'range_max' = '-5' must be greater than 0"), std::string::npos) << e;
  // Rule between keys.
  e = error_of(replace(kBase, "range_max: 30", "range_max: 0.05"));
  EXPECT_NE(e.find("range_min (0.1 m) must be less than range_max (0.05 m)"), std::string::npos) << e;
  // Unknown top-level key and unknown block key.
  e = error_of(replace(kBase, "output_dir: out", "outptu_dir: out"));
  EXPECT_NE(e.find("unknown key 'outptu_dir' (did you mean 'output_dir'?)"), std::string::npos) << e;
  e = error_of(replace(kBase, "range_max: 30", "range_mx: 30"));
  EXPECT_NE(e.find("sensor: unknown option 'range_mx' (did you mean 'range_max'?)"), std::string::npos) << e;
  // Unknown stage type.
  e = error_of(replace(kBase, "type: register", "type: regster"));
  EXPECT_NE(e.find("unknown stage type 'regster' (did you mean 'register'?)"), std::string::npos) << e;
  // Empty pipeline.
  e = error_of(replace(replace(kBase, "  - type: register\n", ""), "    skew_correction: true\n", "  []\n"));
  EXPECT_NE(e.find("the pipeline is empty"), std::string::npos) << e;
  // Bad rpy_order and structural errors.
  e = error_of(replace(kBase, "rpy_order: xyz", "rpy_order: yxz"));
  EXPECT_NE(e.find("rpy_order = 'yxz' must be one of xyz|zyx"), std::string::npos) << e;
  e = error_of(replace(kBase, "mount: {x: 0.5, z: 1.64, pitch: 0.19775}", "mount: [1, 2]"));
  EXPECT_NE(e.find("mount must be a mapping"), std::string::npos) << e;
  e = error_of("stages: [ {type: register} ]\nbad: [");
  EXPECT_NE(e.find("not valid YAML"), std::string::npos) << e;
  e = error_of("");
  EXPECT_NE(e.find("the pipeline file is empty"), std::string::npos) << e;
}

TEST(Config, OverrideErrorsNameTheOverride) {
  LoadOptions o = no_inputs();
  o.overrides = {parse_override("sensor.min_amplitude=-3")};
  std::string e = error_of(kBase, o);
  EXPECT_NE(e.find("--set sensor.min_amplitude=-3: sensor: option 'min_amplitude' = '-3' must be at least 0"),
            std::string::npos)
      << e;
  o.overrides = {parse_override("stages.regist.skew_correction=false")};
  e = error_of(kBase, o);
  EXPECT_NE(e.find("no stage instance named 'regist' (did you mean 'register'?)"), std::string::npos) << e;
  EXPECT_THROW(parse_override("no_equals_sign"), ConfigError);
}

TEST(Config, DuplicateInstanceNamesAndRegisterFirst) {
  std::string y = std::string(kBase) + "  - type: register\n";
  EXPECT_NE(error_of(y).find("two stage instances are named 'register'"), std::string::npos);
  y = std::string(kBase) + "  - type: register\n    name: again\n";
  const PipelineConfig c = load_pipeline_from_string(y, "p.yaml", "/base", no_inputs());
  try {
    Pipeline::prepare(c);
    FAIL() << "expected an error";
  } catch (const ConfigError& err) {
    EXPECT_NE(std::string(err.what()).find("'register' may appear only once"), std::string::npos) << err.what();
  }
}

TEST(Config, MissingInputsAreInputErrors) {
  LoadOptions o;
  try {
    load_pipeline_from_string(kBase, "p.yaml", "/nonexistent-base", o);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no file matches '/nonexistent-base/scans/*.pcd'"), std::string::npos) << e.what();
  }
}
