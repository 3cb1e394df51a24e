// The accounting invariant over random stage combinations and random inputs: returns.pcd holds
// every input return exactly once, the report's label histogram sums to the input count, and
// every stage's in/out counts chain.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "sim/bench_scenes.hpp"
#include "test_support.hpp"

using namespace pcdp;

TEST(NothingLost, RandomStageCombinationsAndInputsAccountForEveryReturn) {
  std::mt19937 rng(2026);
  const std::vector<std::string> optional = {"reject_occlusion", "reject_mixed_pixels", "check_consistency", "fuse_elevation",
                                             "fuse_octomap"};
  for (int trial = 0; trial < 6; ++trial) {
    bench::Setting st = bench::make_setting(trial % 2 ? 'B' : 'A', static_cast<std::uint64_t>(trial + 10));
    st.sim.passes = 1 + static_cast<int>(rng() % 3);
    st.sim.lines_per_pass = 10 + static_cast<int>(rng() % 30);
    st.sim.scanner.beams = 20 + static_cast<int>(rng() % 100);
    st.sim.scanner.subrays = 3;
    const std::string dir = test::fresh_dir(std::to_string(trial));
    const auto r = sim::simulate(st.sim);
    sim::write_run(r, st.sim, dir);
    // Some poses missing at the end (no_pose), and a random subset of stages in a random order
    // after register.
    std::vector<std::string> stages;
    for (const auto& s : optional)
      if (rng() % 2) stages.push_back(s);
    std::shuffle(stages.begin(), stages.end(), rng);
    std::ostringstream y;
    y << "input: {scans: " << dir << "/pass_*.pcd, poses: " << dir << "/poses.csv}\noutput_dir: " << dir << "/out\n"
      << "sensor: {transceiver_separation: " << st.sensor.transceiver_separation << ", beam_divergence: "
      << st.sensor.beam_divergence << ", range_max: " << (10 + rng() % 25) << "}\nstages:\n  - type: register\n    max_pose_gap: 0.05\n";
    for (const auto& s : stages) y << "  - type: " << s << "\n";
    test::write_text(dir + "/p.yaml", y.str());
    // Odd trials on 2 threads: the passes a prepass keeps for the main loop differ with the count.
    const RunSummary sum = Pipeline::prepare(load_pipeline(dir + "/p.yaml")).run({}, 1 + trial % 2);

    std::size_t input = 0;
    for (const auto& sp : r.passes) input += sp.pass.size();
    const io::PcdTable t = io::read_pcd(dir + "/out/returns.pcd");
    ASSERT_EQ(t.header.points, input) << y.str();
    std::set<std::pair<double, double>> keys;
    const auto line = test::column(t, "line"), beam = test::column(t, "beam");
    for (std::size_t i = 0; i < line.size(); ++i) keys.insert({line[i], beam[i]});
    EXPECT_EQ(keys.size(), input);
    const auto rep = nlohmann::json::parse(test::read_text(dir + "/out/report.json"));
    std::uint64_t hist = 0;
    for (const auto& [k, v] : rep["labels"].items()) hist += v.get<std::uint64_t>();
    EXPECT_EQ(hist, input);
    EXPECT_EQ(sum.input_returns, input);
    // Stage counts chain: each stage's in is the previous stage's out, and register saw every
    // return once (a pass kept from a prepass is counted once, not twice or never).
    EXPECT_EQ(sum.stages.front().in, input);
    for (std::size_t s = 1; s < sum.stages.size(); ++s) EXPECT_EQ(sum.stages[s].in, sum.stages[s - 1].out);
    EXPECT_EQ(sum.stages.back().out, sum.labels[0]);
  }
}
