// docs/adding_a_stage.md, built: its code is example_stage.hpp (checked block by block), and the
// example stage runs through Pipeline::prepare with builtin_stages() plus itself on the sample
// scans: the labels and report it should give, threads or not, and the stage order checked from
// what it needs.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "example_stage.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "pcdp/pipeline/stream.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The ```cpp blocks of a Markdown file, a blank line between two (other languages, ```c++
// included, are not taken).
std::string cpp_blocks(const std::string& md) {
  std::istringstream in(md);
  std::string out, l;
  bool inside = false;
  while (std::getline(in, l)) {
    if (!inside && l == "```cpp") {
      if (!out.empty()) out += "\n";
      inside = true;
    } else if (inside && l == "```") {
      inside = false;
    } else if (inside) {
      out += l + "\n";
    }
  }
  return out;
}

// The sample pipeline cut to register, with the example stage after it (or before it).
PipelineConfig sample_config(const std::string& out_dir, bool dim_stage, bool dim_first = false) {
  PipelineConfig c = load_pipeline(std::string(PCDP_SOURCE_DIR) + "/pipelines/nodding_terrain.yaml");
  c.output_dir = out_dir;
  c.stages.resize(1);  // register
  if (dim_stage) {
    StageConfig d;
    d.type = d.name = "reject_dim_returns";
    d.where = "test";
    d.options.set("min_amplitude", 20.0);
    d.options.set("reference_range", 10.0);
    c.stages.insert(c.stages.begin() + (dim_first ? 0 : 1), d);
  }
  return c;
}

std::vector<StageInfo> with_example() {
  std::vector<StageInfo> s = builtin_stages();
  s.push_back(reject_dim_returns_stage_info());
  return s;
}
}  // namespace

TEST(AddingAStage, TheDocsCodeIsTheExampleStage) {
  const std::string md = slurp(std::string(PCDP_SOURCE_DIR) + "/docs/adding_a_stage.md");
  const std::string hpp = slurp(std::string(PCDP_SOURCE_DIR) + "/tests/unit/pipeline/example_stage.hpp");
  ASSERT_FALSE(hpp.empty());
  EXPECT_EQ(cpp_blocks(md), hpp) << "docs/adding_a_stage.md's ```cpp blocks must be tests/unit/pipeline/example_stage.hpp";
}

TEST(AddingAStage, TheExampleLabelsDimReturnsAndReportsThem) {
  const std::string dir = test::fresh_dir();
  // Without the stage, then with it on 1 and 2 threads.
  Pipeline::prepare(sample_config(dir + "/without", false)).run();
  const RunSummary one = Pipeline::prepare(sample_config(dir + "/with1", true), with_example()).run({}, 1);
  const RunSummary two = Pipeline::prepare(sample_config(dir + "/with2", true), with_example()).run({}, 2);
  EXPECT_EQ(slurp(dir + "/with1/returns.pcd"), slurp(dir + "/with2/returns.pcd"));

  const io::PcdTable a = io::read_pcd(dir + "/without/returns.pcd"), b = io::read_pcd(dir + "/with1/returns.pcd");
  const auto la = test::column(a, "label"), lb = test::column(b, "label"), amp = test::column(b, "amplitude");
  const auto range = test::column(b, "range");  // float32; the stage reads the calibrated range: 2 % slack
  ASSERT_EQ(la.size(), lb.size());
  const double kept = static_cast<double>(Label::kKept), low = static_cast<double>(Label::kLowAmplitude);
  std::size_t dim = 0, near_floor = 0;
  for (std::size_t i = 0; i < la.size(); ++i) {
    // Every new low_amplitude label is the stage's: it labels only what register kept.
    if (lb[i] == low && la[i] != low) {
      ++dim;
      const double r = range[i];
      EXPECT_LT(amp[i] * (r / 10.0) * (r / 10.0), 20.0 * 1.02) << "return " << i;
    } else if (lb[i] == kept) {
      const double r = range[i];
      if (std::isfinite(amp[i])) EXPECT_GE(amp[i] * (r / 10.0) * (r / 10.0), 20.0 * 0.98) << "return " << i;
      near_floor += amp[i] * (r / 10.0) * (r / 10.0) < 40.0;
    }
  }
  EXPECT_GT(dim, 100u) << "the floor must bite on the sample scans";
  EXPECT_GT(near_floor, 0u);
  const StageReport& rep = one.stages[1];
  EXPECT_EQ(rep.name, "reject_dim_returns");
  EXPECT_EQ(rep.rejected[static_cast<std::size_t>(Label::kLowAmplitude)], dim);
  EXPECT_EQ(rep.metrics.at("dim"), static_cast<double>(rep.rejected[static_cast<std::size_t>(Label::kLowAmplitude)]));
  EXPECT_EQ(rep.in - rep.out, rep.rejected[static_cast<std::size_t>(Label::kLowAmplitude)]);
  EXPECT_EQ(two.stages[1].metrics.at("dim"), rep.metrics.at("dim"));
  EXPECT_EQ(one.stages[0].out, rep.in);  // it sees what register kept
}

TEST(AddingAStage, ItStreamsAndItsOrderIsChecked) {
  // reach() = 0: the line streaming API takes it.
  LineStream s(sample_config(test::fresh_dir() + "/s", true), 1, with_example());
  EXPECT_GE(s.lines_ahead(), 1);
  // Before register it has no registered points: a ConfigError naming it and the fix.
  try {
    Pipeline::prepare(sample_config(test::fresh_dir() + "/x", true, true), with_example());
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("stage 'reject_dim_returns' (reject_dim_returns) needs registered points"), std::string::npos) << m;
    EXPECT_NE(m.find("put 'register' before it"), std::string::npos) << m;
  }
  // Without it in the list of stage types, its type is unknown.
  EXPECT_THROW(Pipeline::prepare(sample_config(test::fresh_dir() + "/y", true)), ConfigError);
}
