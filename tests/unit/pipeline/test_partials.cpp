// The accumulators' partials are associative (Stage::merge): on the sample scans, folding the
// passes' partials grouped any way, (a + b) + c or a + (b + c), gives byte-identical products
// (fuse_elevation, fuse_octomap) and identical labels (check_consistency's evidence). Exact by
// construction (InOrderPartial): the partial holding the first pass folds, the others keep their
// passes' items in pass order.
#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <sstream>

#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/pipeline/pipeline.hpp"
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

struct Sample {
  PipelineConfig cfg = load_pipeline(std::string(PCDP_SOURCE_DIR) + "/pipelines/nodding_terrain.yaml");
  RunContext ctx;
  std::vector<Pass> passes;  // registered, labelled by the reject stages
  Sample() {
    ctx.config = &cfg;
    ctx.poses = std::make_shared<const PoseTrack>(io::read_pose_csv(cfg.poses, cfg.rpy_order));
    std::vector<std::unique_ptr<Stage>> labellers;
    for (std::size_t s = 0; s < 3; ++s) labellers.push_back(find_stage(cfg.stages[s].type)->create(cfg.stages[s], ctx));
    for (std::size_t k = 0; k < cfg.scans.size(); ++k) {
      Pass p = read_pass(cfg.scans[k], k);
      StageReport r;
      for (auto& st : labellers) st->label(p, r);
      passes.push_back(std::move(p));
    }
  }
  std::unique_ptr<Stage> make(const std::string& type) const {
    for (const auto& sc : cfg.stages)
      if (sc.type == type) return find_stage(type)->create(sc, ctx);
    return nullptr;
  }
};

const Sample& sample() {
  static const Sample s;
  return s;
}

using Grouping = std::function<std::unique_ptr<Partial>(const Stage&, std::vector<std::unique_ptr<Partial>>&)>;

std::unique_ptr<Partial> fold(const Stage& st, std::unique_ptr<Partial> a, std::unique_ptr<Partial> b) {
  st.merge(*a, std::move(*b));
  return a;
}

// Three groupings of 4 passes: ((0 1) 2) 3, 0 ((1 2) 3), (0 1) (2 3).
const std::vector<std::pair<std::string, Grouping>>& groupings() {
  static const std::vector<std::pair<std::string, Grouping>> g = {
      {"left", [](const Stage& st, std::vector<std::unique_ptr<Partial>>& p) {
         auto a = std::move(p[0]);
         for (std::size_t k = 1; k < p.size(); ++k) a = fold(st, std::move(a), std::move(p[k]));
         return a;
       }},
      {"right", [](const Stage& st, std::vector<std::unique_ptr<Partial>>& p) {
         auto b = std::move(p.back());
         for (std::size_t k = p.size() - 1; k-- > 1;) b = fold(st, std::move(p[k]), std::move(b));
         return fold(st, std::move(p[0]), std::move(b));
       }},
      {"pairs", [](const Stage& st, std::vector<std::unique_ptr<Partial>>& p) {
         auto a = fold(st, std::move(p[0]), std::move(p[1]));
         auto b = fold(st, std::move(p[2]), std::move(p[3]));
         return fold(st, std::move(a), std::move(b));
       }},
  };
  return g;
}

// The products of an accumulator, per grouping: file name -> bytes.
std::map<std::string, std::string> products(const std::string& type, const Grouping& group, const std::string& dir) {
  const Sample& s = sample();
  auto st = s.make(type);
  EXPECT_EQ(st->kind(), StageKind::kAccumulator);
  StageReport rep;
  std::vector<std::unique_ptr<Partial>> parts;
  for (const Pass& p : s.passes) parts.push_back(st->collect(p, rep, WorkShare::serial()));
  auto all = group(*st, parts);
  std::map<std::string, std::string> out;
  for (auto& w : st->finish(std::move(all), rep, 1)) {
    std::vector<std::string> paths;
    for (const auto& f : w.files) paths.push_back(dir + "/" + f);
    w.write(paths, rep, WorkShare::serial());
    for (std::size_t i = 0; i < paths.size(); ++i) out[w.files[i]] = slurp(paths[i]);
  }
  return out;
}
}  // namespace

TEST(Partials, TheSampleHasFourPasses) { ASSERT_EQ(sample().passes.size(), 4u); }

TEST(Partials, AccumulatorsGiveTheSameProductsWhateverTheGrouping) {
  for (const std::string type : {"fuse_elevation", "fuse_octomap"}) {
    std::map<std::string, std::string> first;
    for (const auto& [name, group] : groupings()) {
      const auto got = products(type, group, test::fresh_dir(type + "_" + name));
      ASSERT_FALSE(got.empty()) << type;
      for (const auto& [f, bytes] : got) EXPECT_FALSE(bytes.empty()) << type << " " << f;
      if (first.empty())
        first = got;
      else
        EXPECT_TRUE(got == first) << type << ": grouping " << name << " differs from left to right";
    }
  }
}

TEST(Partials, ConsistencyEvidenceGivesTheSameLabelsWhateverTheGrouping) {
  const Sample& s = sample();
  std::vector<Label> first;
  for (const auto& [name, group] : groupings()) {
    auto st = s.make("check_consistency");
    ASSERT_EQ(st->kind(), StageKind::kTwoPhase);
    StageReport rep;
    std::vector<std::unique_ptr<Partial>> parts;
    for (const Pass& p : s.passes) parts.push_back(st->collect(p, rep, WorkShare::serial()));
    EXPECT_TRUE(st->finish(group(*st, parts), rep, 1).empty());
    std::vector<Label> labels;
    for (Pass p : s.passes) {
      st->label(p, rep);
      labels.insert(labels.end(), p.label.begin(), p.label.end());
    }
    EXPECT_GT(rep.metrics.at("lonely_returns"), 0.0);
    if (first.empty())
      first = labels;
    else
      EXPECT_TRUE(labels == first) << "grouping " << name;
  }
  EXPECT_GT(std::count(first.begin(), first.end(), Label::kInconsistent), 0);
}
