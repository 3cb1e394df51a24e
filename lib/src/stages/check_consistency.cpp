#include "pcdp/stages/check_consistency.hpp"


#include <cmath>

#include "pcdp/pass.hpp"

namespace pcdp {

const OptionSchema& check_consistency_schema() {
  static const OptionSchema s = {
      opt_double("resolution", 0.1, 0.01, 10.0, "m", "voxel size of the free-space evidence"),
      opt_double("margin", 0.5, 0.0, 10.0, "m", "rays mark free space up to this short of their end"),
      opt_int("min_passes", 1, 1.0, 64.0, "passes", "other passes that must have seen free space through a return"),
      opt_double("max_range", 30.0, 0.1, 1e4, "m", "longer rays give no free-space evidence"),
      opt_int("hit_radius", 2, 0.0, 5.0, "voxels", "a return from another pass within this many voxels makes a surface, not free space"),
  };
  return s;
}

namespace {
// A voxel index made non-negative and kept to 21 bits (+-2^20 voxels: +-10 km at 1 cm).
std::uint32_t coord(std::int64_t v) { return static_cast<std::uint32_t>(v + (1 << 20)) & kVoxelCoordMask; }
std::uint32_t voxel_coord(double c, double res) { return coord(static_cast<std::int64_t>(std::floor(c / res))); }

// 3-D DDA (Amanatides & Woo): f(x, y, z) for every voxel of edge `res` that the ray o + t d
// (d a unit vector) enters for 0 <= t < tend, in order. The state is kept in scalars: kept in
// arrays indexed by the stepping axis, every step waited on a store (measured 1.4x slower).
// Ties go y over x, z over either.
template <class F>
void walk_voxels(const double o[3], const double d[3], double tend, double res, F&& f) {
  std::int64_t v[3], step[3];
  double tmax[3], tdelta[3];
  for (int a = 0; a < 3; ++a) {
    v[a] = static_cast<std::int64_t>(std::floor(o[a] / res));
    step[a] = d[a] > 0 ? 1 : -1;
    const double boundary = (static_cast<double>(v[a]) + (d[a] > 0 ? 1.0 : 0.0)) * res;
    tmax[a] = std::fabs(d[a]) > 1e-12 ? (boundary - o[a]) / d[a] : INFINITY;
    tdelta[a] = std::fabs(d[a]) > 1e-12 ? res / std::fabs(d[a]) : INFINITY;
  }
  std::int64_t x = v[0], y = v[1], z = v[2];
  double tx = tmax[0], ty = tmax[1], tz = tmax[2];
  const double dx = tdelta[0], dy = tdelta[1], dz = tdelta[2];
  const std::int64_t sx = step[0], sy = step[1], sz = step[2];
  double t = 0.0;
  while (t < tend) {
    f(x, y, z);
    if (tx < ty) {
      if (tx < tz) {
        t = tx;
        tx += dx;
        x += sx;
        continue;
      }
    } else if (ty < tz) {
      t = ty;
      ty += dy;
      y += sy;
      continue;
    }
    t = tz;
    tz += dz;
    z += sz;
  }
}
}  // namespace

ConsistencyEvidence::PassVoxels ConsistencyEvidence::collect(const Pass& pass) const {
  PassVoxels out;
  out.bit = 1ull << (pass.index % 64);
  const double res = p_.resolution;
  // The voxels the pass can touch, for the sets' dense block directories: every walked ray lies
  // between its origin and its end point (a voxel of slack for the walk's rounding).
  VoxelBounds bounds;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i]) || !std::isfinite(pass.ox[i])) continue;
    for (const double s : {-1.0, 1.0}) {
      bounds.add(voxel_coord(pass.x[i] + s * res, res), voxel_coord(pass.y[i] + s * res, res), voxel_coord(pass.z[i] + s * res, res));
      bounds.add(voxel_coord(pass.ox[i] + s * res, res), voxel_coord(pass.oy[i] + s * res, res), voxel_coord(pass.oz[i] + s * res, res));
    }
  }
  out.hit = VoxelSet(bounds, 0x27d4eb2fu);
  out.free = VoxelSet(bounds, 0x5bd1e995u);
  VoxelSet::Cursor hit(out.hit), free(out.free);
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i]) || !std::isfinite(pass.ox[i])) continue;
    const double o[3] = {pass.ox[i], pass.oy[i], pass.oz[i]}, e[3] = {pass.x[i], pass.y[i], pass.z[i]};
    double d[3] = {e[0] - o[0], e[1] - o[1], e[2] - o[2]};
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    hit.insert(voxel_coord(e[0], res), voxel_coord(e[1], res), voxel_coord(e[2], res));
    if (len <= p_.margin || len > p_.max_range) continue;
    for (double& c : d) c /= len;
    walk_voxels(o, d, len - p_.margin, res, [&](std::int64_t x, std::int64_t y, std::int64_t z) {
      free.insert(coord(x), coord(y), coord(z));
    });
  }
  return out;
}

void ConsistencyEvidence::merge(const PassVoxels& v) {
  // Block by block: one lookup per block, then the pass's bit into each voxel it set.
  const auto add = [&](const VoxelSet& set, std::uint64_t Voxel::*field) {
    const BlockGrid<BitBlock>& g = set.blocks();
    for (std::size_t b = 0; b < g.size(); ++b) {
      Block& dst = voxels_.block(g.key(b));
      for_each_bit(g[b].w, [&](unsigned c) { dst.v[c].*field |= v.bit; });
    }
  };
  add(v.hit, &Voxel::hit);
  add(v.free, &Voxel::free);
}

void ConsistencyEvidence::add_pass(const Pass& pass) { merge(collect(pass)); }

const ConsistencyEvidence::Voxel* ConsistencyEvidence::find(std::uint32_t x, std::uint32_t y, std::uint32_t z) const {
  const BlockPos p = block_pos(x & kVoxelCoordMask, y & kVoxelCoordMask, z & kVoxelCoordMask);
  const Block* b = voxels_.find(p.block);
  return b ? &b->v[p.cell] : nullptr;
}

std::size_t ConsistencyEvidence::label(Pass& pass) const {
  const std::uint64_t bit = 1ull << (pass.index % 64);
  const double res = p_.resolution;
  std::size_t n = 0;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i])) continue;
    const std::uint32_t x = voxel_coord(pass.x[i], res), y = voxel_coord(pass.y[i], res), z = voxel_coord(pass.z[i], res);
    const Voxel* it = find(x, y, z);
    if (!it) continue;
    const std::uint64_t free_other = it->free & ~bit;
    if (__builtin_popcountll(free_other) < p_.min_passes) continue;
    bool hit_other = false;  // another pass returned from here or next door: a real surface
    const int h = p_.hit_radius;
    // Unsigned offsets wrap modulo 2^21 in find(), as the coordinates do.
    for (int dx = -h; dx <= h && !hit_other; ++dx)
      for (int dy = -h; dy <= h && !hit_other; ++dy)
        for (int dz = -h; dz <= h && !hit_other; ++dz) {
          const Voxel* hv = find(x + static_cast<std::uint32_t>(dx), y + static_cast<std::uint32_t>(dy), z + static_cast<std::uint32_t>(dz));
          hit_other = hv && (hv->hit & ~bit) != 0;
        }
    if (hit_other) continue;
    pass.label[i] = Label::kInconsistent;
    ++n;
  }
  return n;
}

namespace {
class CheckConsistencyStage final : public Stage {
 public:
  explicit CheckConsistencyStage(ConsistencyParams p) : evidence_(p) {}
  bool wants_prepass() const override { return true; }
  bool concurrent() const override { return true; }  // label() reads the evidence, complete after the prepass
  void prepass(const Pass& pass) override { evidence_.add_pass(pass); }
  bool prepass_split() const override { return true; }
  std::unique_ptr<StageWork> prepass_compute(const Pass& pass) const override {
    auto w = std::make_unique<Work>();
    w->voxels = evidence_.collect(pass);
    return w;
  }
  void prepass_apply(std::unique_ptr<StageWork> w) override { evidence_.merge(static_cast<Work&>(*w).voxels); }
  void process(Pass& pass, StageReport&) override { evidence_.label(pass); }

 private:
  ConsistencyEvidence evidence_;
  struct Work final : StageWork {
    ConsistencyEvidence::PassVoxels voxels;
  };
};
}  // namespace

StageInfo check_consistency_stage_info() {
  return {"check_consistency",
          "label inconsistent the returns other passes saw free space through (needs several passes)",
          check_consistency_schema(), [](const StageConfig& sc, const RunContext&) -> std::unique_ptr<Stage> {
            const OptionValues& o = sc.options;
            ConsistencyParams p;
            p.resolution = o.get_double("resolution");
            p.margin = o.get_double("margin");
            p.min_passes = static_cast<int>(o.get_int("min_passes"));
            p.max_range = o.get_double("max_range");
            p.hit_radius = static_cast<int>(o.get_int("hit_radius"));
            return std::make_unique<CheckConsistencyStage>(p);
          }};
}

}  // namespace pcdp
