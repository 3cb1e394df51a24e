#include <gtest/gtest.h>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/sim/evaluate.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/core/errors.hpp"
#include "test_support.hpp"

using namespace pcdp;

TEST(Evaluate, ScoresARegisterOnlyRunAgainstTheTruth) {
  sim::SimConfig cfg = test::small_sim_config();
  cfg.scanner.range_sigma = 0.01;
  const std::string dir = test::fresh_dir();
  const auto run = sim::simulate(cfg);
  sim::write_run(run, cfg, dir);
  sim::write_truth(run, cfg, dir);
  test::write_text(dir + "/p.yaml", test::pipeline_yaml(cfg, dir, dir + "/out"));
  Pipeline::prepare(load_pipeline(dir + "/p.yaml")).run();

  NoiseModel noise;
  noise.range_sigma = 0.01;
  noise.known = true;
  const Evaluation e = evaluate_run(dir, dir + "/out", noise);
  std::size_t n = 0;
  for (const auto& p : run.passes) n += p.pass.size();
  EXPECT_EQ(e.returns, n);
  EXPECT_EQ(e.valid_wrongly_rejected, 0u);  // register rejects nothing valid
  EXPECT_GT(e.compared, n / 2);
  // Range noise alone: the median 3-D error is about 0.67 sigma (half-normal median).
  EXPECT_NEAR(e.error_median, 0.0067, 0.002);
  EXPECT_NEAR(e.implied_median, 0.01, 1e-9);
  EXPECT_NE(evaluation_table(e).find("registration error"), std::string::npos);
}

TEST(Evaluate, RejectsARunOfAnotherSimulation) {
  sim::SimConfig cfg = test::small_sim_config();
  const std::string dir = test::fresh_dir();
  const auto run = sim::simulate(cfg);
  sim::write_run(run, cfg, dir);
  sim::write_truth(run, cfg, dir);
  test::write_text(dir + "/p.yaml", test::pipeline_yaml(cfg, dir, dir + "/out"));
  Pipeline::prepare(load_pipeline(dir + "/p.yaml")).run();
  cfg.passes = 1;
  const std::string other = test::fresh_dir("other");
  sim::write_truth(sim::simulate(cfg), cfg, other);
  EXPECT_THROW(evaluate_run(other, dir + "/out", {}), InputError);
  EXPECT_THROW(evaluate_run(dir + "/nowhere", dir + "/out", {}), InputError);
}
