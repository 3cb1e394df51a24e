// Quality benchmark of reject_occlusion against the baselines, on the same simulated data:
// (a) a plain amplitude threshold and (b) PCL's StatisticalOutlierRemoval, each at its best
// setting (swept, best F1). Two sensor settings, several seeds.
//
// Scoring: positives are the truth `occlusion` false ranges that reach the filter (kept by
// `register`). A method's false positives are truth-valid returns it rejects; rejecting other bad
// returns (low-amplitude false ranges, mixed pixels) counts neither way.
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/point_types.h>

#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "sim/bench_scenes.hpp"
#include "quality.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/stages/reject_occlusion.hpp"

using namespace pcdp;

namespace {
struct Record {
  Label truth;
  float amplitude;
  bool ours;
};
using bench::Score;
}  // namespace

int main(int argc, char** argv) {
  const int seeds = argc > 1 ? std::atoi(argv[1]) : 3;
  bool all_met = true;
  for (char which : {'A', 'B'}) {
    std::vector<Record> recs;
    std::vector<pcl::PointCloud<pcl::PointXYZ>::Ptr> clouds;  // one per pass, register-kept points
    std::vector<std::size_t> cloud_offset;
    std::uint64_t low_truth = 0, low_rejected = 0;
    bench::Setting st = bench::make_setting(which, 1);
    for (int seed = 1; seed <= seeds; ++seed) {
      st = bench::make_setting(which, static_cast<std::uint64_t>(seed));
      const sim::SimResult r = sim::simulate(st.sim);
      const PoseTrack poses(r.poses);
      const Eigen::Isometry3d T_V_N = make_transform(st.sim.mount_translation, st.sim.mount_rpy, st.sim.rpy_order);
      for (const auto& sp : r.passes) {
        Pass p = sp.pass;
        register_pass(p, RegisterParams{}, st.sensor, T_V_N, &poses);
        Pass q = p;
        reject_occlusion(q, OcclusionParams{}, st.sensor);
        auto cloud = pcl::PointCloud<pcl::PointXYZ>::Ptr(new pcl::PointCloud<pcl::PointXYZ>);
        cloud_offset.push_back(recs.size());
        for (std::size_t i = 0; i < p.size(); ++i) {
          if (!p.is_kept(i)) continue;
          recs.push_back({sp.truth[i], p.amplitude[i], !q.is_kept(i)});
          cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x[i]), static_cast<float>(p.y[i]), static_cast<float>(p.z[i])));
          if (sp.truth[i] == Label::kLowAmplitude) {
            ++low_truth;
            low_rejected += !q.is_kept(i);
          }
        }
        clouds.push_back(cloud);
      }
    }
    const std::size_t n = recs.size();
    std::printf("\nsetting %c (%s, s-q = %.0f mm, alpha = %.0f mrad), %d seeds, %zu returns reaching the filter\n", which,
                st.sim.scanner.mirror ? "mirror transceiver angle" : "fixed transceiver angle",
                st.sim.scanner.transceiver_separation * 1000, st.sim.scanner.beam_divergence * 1000, seeds, n);
    bench::print_header();

    std::vector<Label> truth(n);
    for (std::size_t i = 0; i < n; ++i) truth[i] = recs[i].truth;
    const auto score = [&](const std::vector<char>& rej, std::string m, std::string prm) {
      return bench::score(truth, rej, Label::kOcclusion, std::move(m), std::move(prm));
    };
    std::vector<char> rej(n);
    for (std::size_t i = 0; i < n; ++i) rej[i] = recs[i].ours;
    const Score ours = score(rej, "reject_occlusion (defaults)", "-");

    Score best_thr;
    for (int t = 1; t <= 80; ++t) {
      for (std::size_t i = 0; i < n; ++i) rej[i] = recs[i].amplitude < static_cast<float>(t);
      const Score s = score(rej, "amplitude threshold", "amplitude < " + std::to_string(t));
      if (s.f1 > best_thr.f1) best_thr = s;
    }
    Score best_sor;
    for (int k : {2, 4, 8, 16, 32, 50}) {
      for (double m : {0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 10.0}) {
        std::fill(rej.begin(), rej.end(), 0);
        for (std::size_t c = 0; c < clouds.size(); ++c) {
          pcl::StatisticalOutlierRemoval<pcl::PointXYZ> sor(true);
          sor.setInputCloud(clouds[c]);
          sor.setMeanK(k);
          sor.setStddevMulThresh(m);
          pcl::PointCloud<pcl::PointXYZ> kept;
          sor.filter(kept);
          for (int idx : *sor.getRemovedIndices()) rej[cloud_offset[c] + static_cast<std::size_t>(idx)] = 1;
        }
        char buf[64];
        std::snprintf(buf, sizeof buf, "k = %d, std = %.2f", k, m);
        const Score s = score(rej, "PCL StatisticalOutlierRemoval", buf);
        if (s.f1 > best_sor.f1) best_sor = s;
      }
    }
    bench::print(ours);
    bench::print(best_thr);
    bench::print(best_sor);
    const bool met = ours.recall >= 0.95 && ours.valid_rejected <= 0.005 && ours.f1 > best_thr.f1 && ours.f1 > best_sor.f1;
    all_met = all_met && met;
    std::printf("  low-amplitude false ranges rejected by reject_occlusion: %llu/%llu (%.3f)\n",
                static_cast<unsigned long long>(low_rejected), static_cast<unsigned long long>(low_truth),
                low_truth ? static_cast<double>(low_rejected) / static_cast<double>(low_truth) : 0.0);
    std::printf("  acceptance (recall >= 0.95, valid rejected <= 0.5 %%, best F1): %s\n", met ? "met" : "NOT met");
  }
  return all_met ? 0 : 1;
}
