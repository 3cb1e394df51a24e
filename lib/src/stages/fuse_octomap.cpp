#include "pcdp/stages/fuse_octomap.hpp"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/fusion/octomap_fusion.hpp"
#include "pcdp/core/pass.hpp"

namespace pcdp {

/// The options of `fuse_octomap`: the OctoMap's sensor model and whether map.ot is written.
struct FuseOctoMapParams : OctoMapParams {
  bool write_ot = false;
};

namespace {
const Options<FuseOctoMapParams>& fuse_octomap_options() {
  using P = FuseOctoMapParams;
  static const auto o = Options<P>()
      .add("resolution", &P::resolution, bounds(0.001, 100), "m", "leaf size of the OctoMap")
      .add("max_range", &P::max_range, bounds(-1, 1e4), "m", "rays are cut here and mark only free space (-1: unlimited)")
      .add("prob_hit", &P::prob_hit, bounds(0.5, 1), "", "sensor model: occupancy probability of a hit (OctoMap default)")
      .add("prob_miss", &P::prob_miss, bounds(0, 0.5), "", "sensor model: occupancy probability of a miss (OctoMap default)")
      .add("clamping_min", &P::clamping_min, bounds(0, 1), "", "lower clamping threshold (OctoMap default)")
      .add("clamping_max", &P::clamping_max, bounds(0, 1), "", "upper clamping threshold (OctoMap default)")
      .add("occupancy_threshold", &P::occupancy_threshold, bounds(0, 1), "", "a node is occupied above this probability (OctoMap default)")
      .add("write_ot", &P::write_ot, "also write map.ot (full probabilities)")
      .rule("clamping_min < clamping_max", [](const P& p) { return p.clamping_min < p.clamping_max; },
            "the clamping thresholds bound the occupancy from below and above",
            "option 'clamping_min' = {clamping_min} must be less than 'clamping_max' = {clamping_max}")
      .rule("max_range == -1 or max_range > 0", [](const P& p) { return p.max_range == -1 || p.max_range > 0; },
            "-1 means unlimited; a positive range cuts the rays there",
            "option 'max_range' = {max_range} must be -1 (unlimited) or a positive range");
  return o;
}
}  // namespace

const OptionSchema& fuse_octomap_schema() { return fuse_octomap_options().schema(); }

// A pass's cells to a stream and back (InOrderPartial::save / load).
namespace {
struct Key3 {
  std::uint16_t k[3];
};
void put_keys(std::ostream& o, const std::vector<octomap::OcTreeKey>& keys) {
  std::vector<Key3> v(keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) v[i] = {{keys[i].k[0], keys[i].k[1], keys[i].k[2]}};
  partial_io::put_vec(o, v);
}
void get_keys(std::istream& in, std::vector<octomap::OcTreeKey>& keys) {
  std::vector<Key3> v;
  partial_io::get_vec(in, v);
  keys.resize(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) keys[i] = octomap::OcTreeKey(v[i].k[0], v[i].k[1], v[i].k[2]);
}
}  // namespace

void save_item(std::ostream& out, const PassRays& r) {
  partial_io::put_str(out, "fuse_octomap.pass_rays");
  partial_io::put(out, r.rays);
  put_keys(out, r.free_list);
  put_keys(out, r.occupied_list);
}
void load_item(std::istream& in, PassRays& r) {
  partial_io::expect(in, "fuse_octomap.pass_rays");
  partial_io::get(in, r.rays);
  get_keys(in, r.free_list);
  get_keys(in, r.occupied_list);
}

namespace {
class FuseOctoMapStage final : public Stage {
 public:
  FuseOctoMapStage(OctoMapParams p, bool write_ot, std::string name, Eigen::Vector3d origin)
      : Stage(write_ot ? std::vector<std::string>{"map.bt", "map.ot"} : std::vector<std::string>{"map.bt"}),
        params_(p), write_ot_(write_ot), name_(std::move(name)), origin_(origin), caster_(make_octree(p)) {}
  StageKind kind() const override { return StageKind::kAccumulator; }
  // The costly part: each pass's rays cast to the cells they update (any thread).
  std::unique_ptr<Partial> collect(const Pass& pass, StageReport& report, WorkShare& share) const override {
    check_key_range(pass);
    PassRays rays = cast_pass(caster_, pass, params_, share);
    report.metrics["rays"] += static_cast<double>(rays.rays);
    return Cells::of(std::move(rays), pass.index == 0, [this] { return fresh(); }, &fold);
  }
  // Each pass's cells into the log-odds accumulator, in pass order: OctoMap's clamped update does
  // not commute, so the partial folds in pass order (InOrderPartial), the leaves of updating a
  // tree pass by pass.
  void merge(Partial& into, Partial&& later) const override {
    static_cast<Cells&>(into).absorb(std::move(static_cast<Cells&>(later)), &fold);
  }
  // One writer: map.bt straight from the accumulated leaves (the same bytes as building OctoMap's
  // tree and writing it, at a fraction of the time and memory); the tree is built only for map.ot.
  std::vector<ProductWriter> finish(std::unique_ptr<Partial> all, StageReport&, unsigned) override {
    std::shared_ptr<const OccupancyAccumulator> cells = Cells::fold_all(all.get(), [this] { return fresh(); }, &fold);
    return {{products(), [this, cells](const std::vector<std::string>& to, StageReport& report, WorkShare&) {
               const OccupancyAccumulator::BinaryMap map = cells->encode_binary();
               const auto t0 = std::chrono::steady_clock::now();
               {
                 std::ofstream out(to[0], std::ios::binary);
                 if (!out || !out.write(map.bytes.data(), static_cast<std::streamsize>(map.bytes.size())) || !out.flush())
                   throw OutputError(to[0] + ": cannot write the map (" + std::string(std::strerror(errno)) + ")");
               }
               if (write_ot_) {
                 octomap::OcTree tree = make_octree(params_);
                 cells->build(tree);
                 std::ofstream out(to[1], std::ios::binary);
                 if (!out || !tree.write(out) || !out.flush())
                   throw OutputError(to[1] + ": cannot write the map (" + std::string(std::strerror(errno)) + ")");
               }
               report.metrics["write_seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
               report.metrics["occupied_leaves"] = static_cast<double>(map.occupied_leaves);
               report.metrics["nodes"] = static_cast<double>(map.nodes);
             }}};
  }

 private:
  using Cells = InOrderPartial<OccupancyAccumulator, PassRays>;
  static void fold(OccupancyAccumulator& acc, PassRays&& rays) { acc.add(rays); }
  std::unique_ptr<OccupancyAccumulator> fresh() const { return std::make_unique<OccupancyAccumulator>(params_); }

  // OctoMap's keys hold +-32768 leaves around 0 of the map (the run's map origin): a ray with an
  // end beyond would be dropped without a word (an empty map.bt for UTM poses before the map
  // origin). Every ray the stage casts must have both ends within 32767 leaves of the origin (one
  // leaf short of the keys' limit, so that no rounding at the edge decides): otherwise an InputError.
  void check_key_range(const Pass& pass) const {
    const double lim = 32767.0 * params_.resolution;
    const auto in = [lim](double x, double y, double z) { return std::fabs(x) < lim && std::fabs(y) < lim && std::fabs(z) < lim; };
    for (std::size_t i = 0; i < pass.size(); ++i) {
      if (!pass.is_kept(i) || !std::isfinite(pass.x[i]) || !std::isfinite(pass.ox[i])) continue;
      const bool o_in = in(pass.ox[i], pass.oy[i], pass.oz[i]), e_in = in(pass.x[i], pass.y[i], pass.z[i]);
      if (o_in && e_in) continue;
      const bool end = o_in;  // the end is out (or both)
      const double x = end ? pass.x[i] : pass.ox[i], y = end ? pass.y[i] : pass.oy[i], z = end ? pass.z[i] : pass.oz[i];
      throw InputError(pass.source + ": line " + std::to_string(pass.line[i]) + " beam " + std::to_string(pass.beam[i]) +
                       ": stage '" + name_ + "' (fuse_octomap): the ray's " + (end ? "end point " : "sensor origin ") +
                       format_point(x + origin_.x(), y + origin_.y(), z + origin_.z()) +
                       " (map metres) lies outside the OctoMap's key range, 32767 leaves of " +
                       format_value(params_.resolution) + " m (" + format_value(lim) +
                       " m) on each axis around the map origin " + format_point(origin_.x(), origin_.y(), origin_.z()) +
                       "; check the pose file's coordinates, use a coarser 'resolution' or split the run");
    }
  }

  OctoMapParams params_;
  bool write_ot_;
  std::string name_;
  Eigen::Vector3d origin_;
  // An empty tree of the same resolution: only its key geometry is used, by cast_pass on any
  // thread, while the accumulator is updated in pass order.
  octomap::OcTree caster_;
};
}  // namespace

StageInfo fuse_octomap_stage_info() {
  return {"fuse_octomap", "every pass into one OctoMap, a sensor origin per return, batched per pass (map.bt)",
          fuse_octomap_schema(), [](const StageConfig& sc, const RunContext& ctx) -> std::unique_ptr<Stage> {
            const FuseOctoMapParams p = fuse_octomap_options().bind(sc.options);
            return std::make_unique<FuseOctoMapStage>(p, p.write_ot, sc.name, ctx.map_origin);
          }};
}

}  // namespace pcdp
