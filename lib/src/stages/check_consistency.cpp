#include "pcdp/stages/check_consistency.hpp"


#include <algorithm>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "pipeline/ordered_parallel.hpp"
#include "pcdp/pipeline/work_share.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/core/pass.hpp"

namespace pcdp {

const Options<ConsistencyParams>& check_consistency_options() {
  using P = ConsistencyParams;
  static const auto o = Options<P>()
      .add("resolution", &P::resolution, bounds(0.01, 10), "m", "voxel size of the free-space evidence")
      .add("margin", &P::margin, bounds(0, 10), "m", "rays mark free space up to this short of their end")
      .add("min_passes", &P::min_passes, bounds(1, 64), "passes", "other passes that must have seen free space through a return")
      .add("max_range", &P::max_range, bounds(0.1, 1e4), "m", "longer rays give no free-space evidence")
      .add("hit_radius", &P::hit_radius, bounds(0, 5), "voxels", "a return from another pass within this many voxels makes a surface, not free space");
  return o;
}

const OptionSchema& check_consistency_schema() { return check_consistency_options().schema(); }

// A pass's evidence to a stream and back (InOrderPartial::save / load): the hit voxels in the
// order VoxelSet lists them (blocks as first touched), inserted again in that order, so the
// blocks keep their order and a merge sees what it sees in one process.
void save_item(std::ostream& o, const ConsistencyEvidence::PassRays& r) {
  partial_io::put_str(o, "check_consistency.pass_rays");
  partial_io::put<std::uint64_t>(o, r.index);
  partial_io::put(o, r.bit);
  partial_io::put(o, r.anchor);
  partial_io::put_vec(o, r.rays);
  partial_io::put_vec(o, r.lines);
  std::vector<std::uint32_t> hit;
  r.hit.for_each([&](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    hit.push_back(x);
    hit.push_back(y);
    hit.push_back(z);
  });
  partial_io::put_vec(o, hit);
}
void load_item(std::istream& i, ConsistencyEvidence::PassRays& r) {
  partial_io::expect(i, "check_consistency.pass_rays");
  r.index = partial_io::get<std::uint64_t>(i);
  partial_io::get(i, r.bit);
  partial_io::get(i, r.anchor);
  partial_io::get_vec(i, r.rays);
  partial_io::get_vec(i, r.lines);
  std::vector<std::uint32_t> hit;
  partial_io::get_vec(i, hit);
  if (hit.size() % 3) throw InputError("the partial is corrupt (hit voxels)");
  r.hit = VoxelSet(0x27d4eb2fu);
  for (std::size_t k = 0; k < hit.size(); k += 3) r.hit.insert(hit[k], hit[k + 1], hit[k + 2]);
}

namespace {
class CheckConsistencyStage final : public Stage {
 public:
  CheckConsistencyStage(ConsistencyParams p, std::string name, Eigen::Vector3d origin)
      : p_(p), name_(std::move(name)), origin_(origin), collector_(p) {}
  // Evidence from every pass first (collect, merge, finish), then label() reads it.
  StageKind kind() const override { return StageKind::kTwoPhase; }
  std::unique_ptr<Partial> collect(const Pass& pass, StageReport&, WorkShare&) const override {
    check_key_range(pass);
    return Evidence::of(collector_.collect(pass), pass.index == 0, [this] { return fresh(); }, &fold);
  }
  // The passes' hit bits commute; the rays are kept in pass order (InOrderPartial) so that
  // finish() sees them as a pass-by-pass fold would.
  void merge(Partial& into, Partial&& later) const override {
    static_cast<Evidence&>(into).absorb(std::move(static_cast<Evidence&>(later)), &fold);
  }
  std::vector<ProductWriter> finish(std::unique_ptr<Partial> all, StageReport& report, unsigned threads) override {
    evidence_ = Evidence::fold_all(all.get(), [this] { return fresh(); }, &fold);
    evidence_->finalize(*WorkShare::threads(threads));
    // What decided the labels: how many returns needed free-space evidence at all.
    const ConsistencyEvidence::Stats& s = evidence_->stats();
    report.metrics["lonely_returns"] = static_cast<double>(s.lonely_returns);
    report.metrics["lonely_voxels"] = static_cast<double>(s.lonely_voxels);
    report.metrics["rays_walked"] = static_cast<double>(s.rays_walked);
    report.metrics["ray_crossings"] = static_cast<double>(s.crossings);
    report.metrics["rays_in_fans"] = static_cast<double>(s.rays_in_fans);
    return {};
  }
  void label(Pass& pass, StageReport&) const override {
    if (!evidence_) throw std::logic_error("check_consistency: label() before finish()");
    evidence_->label(pass);
  }

 private:
  using Evidence = InOrderPartial<ConsistencyEvidence, ConsistencyEvidence::PassRays>;
  static void fold(ConsistencyEvidence& e, ConsistencyEvidence::PassRays&& r) { e.merge(std::move(r)); }
  std::unique_ptr<ConsistencyEvidence> fresh() const { return std::make_unique<ConsistencyEvidence>(p_); }

  // The voxel keys hold 21 bits per axis and wrap beyond: two voxels 2^21 apart would share
  // evidence. Every voxel the run touches lies within 2^20 voxels of the map origin (less the
  // neighbourhood a hit covers, and a voxel for rounding) or the run is refused: an InputError,
  // never a wrap.
  void check_key_range(const Pass& pass) const {
    const double lim = (static_cast<double>(ConsistencyEvidence::kKeyHalfRange) - 2.0 - p_.hit_radius) * p_.resolution;
    const auto in = [lim](double x, double y, double z) { return std::fabs(x) < lim && std::fabs(y) < lim && std::fabs(z) < lim; };
    for (std::size_t i = 0; i < pass.size(); ++i) {
      if (!pass.is_kept(i) || !std::isfinite(pass.x[i])) continue;
      const bool e_in = in(pass.x[i], pass.y[i], pass.z[i]);
      const bool o_in = !std::isfinite(pass.ox[i]) || in(pass.ox[i], pass.oy[i], pass.oz[i]);
      if (e_in && o_in) continue;
      const double x = !e_in ? pass.x[i] : pass.ox[i], y = !e_in ? pass.y[i] : pass.oy[i], z = !e_in ? pass.z[i] : pass.oz[i];
      throw InputError(pass.source + ": line " + std::to_string(pass.line[i]) + " beam " + std::to_string(pass.beam[i]) +
                       ": stage '" + name_ + "' (check_consistency): the " + (!e_in ? "point " : "sensor origin ") +
                       format_point(x + origin_.x(), y + origin_.y(), z + origin_.z()) +
                       " (map metres) lies beyond the stage's voxel keys, " + format_value(lim) +
                       " m on each axis around the map origin " + format_point(origin_.x(), origin_.y(), origin_.z()) +
                       " (2^20 voxels of " + format_value(p_.resolution) +
                       " m); check the pose file's coordinates, use a coarser 'resolution' or split the run");
    }
  }

  ConsistencyParams p_;
  std::string name_;
  Eigen::Vector3d origin_;
  ConsistencyEvidence collector_;  ///< empty: collect() only reads its parameters
  std::unique_ptr<ConsistencyEvidence> evidence_;  ///< after finish()
};
}  // namespace

StageInfo check_consistency_stage_info() {
  return {"check_consistency",
          "label inconsistent the returns other passes saw free space through (needs several passes)",
          check_consistency_schema(), [](const StageConfig& sc, const RunContext& ctx) -> std::unique_ptr<Stage> {
            const ConsistencyParams p = check_consistency_options().bind(sc.options);
            return std::make_unique<CheckConsistencyStage>(p, sc.name, ctx.map_origin);
          }};
}

}  // namespace pcdp
