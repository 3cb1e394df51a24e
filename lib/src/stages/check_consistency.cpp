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

std::uint64_t ConsistencyEvidence::key(std::int64_t x, std::int64_t y, std::int64_t z) const {
  const auto u = [](std::int64_t v) { return static_cast<std::uint64_t>(v + (1 << 20)) & 0x1fffff; };
  return (u(x) << 42) | (u(y) << 21) | u(z);
}

ConsistencyEvidence::PassVoxels ConsistencyEvidence::collect(const Pass& pass) const {
  PassVoxels out;
  out.bit = 1ull << (pass.index % 64);
  const double res = p_.resolution;
  // Neighbouring rays cross the same voxels: a small direct-mapped cache of recent keys drops most
  // repeats before the set does the rest.
  constexpr std::size_t kCache = 4096;
  std::vector<std::uint64_t> cache(kCache, ~0ull);
  FlatMap<char> free_set(0x5bd1e995u), hit_set(0x27d4eb2fu);  // used as sets; salts unlike voxels_'s
  const auto add_free = [&](std::uint64_t k) {
    std::uint64_t& c = cache[(k * 0x9E3779B97F4A7C15ull) >> 52];
    if (c == k) return;
    c = k;
    free_set[k] = 1;
  };
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i]) || !std::isfinite(pass.ox[i])) continue;
    const double o[3] = {pass.ox[i], pass.oy[i], pass.oz[i]}, e[3] = {pass.x[i], pass.y[i], pass.z[i]};
    double d[3] = {e[0] - o[0], e[1] - o[1], e[2] - o[2]};
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    hit_set[key(static_cast<std::int64_t>(std::floor(e[0] / res)), static_cast<std::int64_t>(std::floor(e[1] / res)),
                       static_cast<std::int64_t>(std::floor(e[2] / res)))] = 1;
    if (len <= p_.margin || len > p_.max_range) continue;
    for (double& c : d) c /= len;
    // 3-D DDA (Amanatides & Woo) from the origin to len - margin.
    std::int64_t v[3], step[3];
    double tmax[3], tdelta[3];
    for (int a = 0; a < 3; ++a) {
      v[a] = static_cast<std::int64_t>(std::floor(o[a] / res));
      step[a] = d[a] > 0 ? 1 : -1;
      const double boundary = (static_cast<double>(v[a]) + (d[a] > 0 ? 1.0 : 0.0)) * res;
      tmax[a] = std::fabs(d[a]) > 1e-12 ? (boundary - o[a]) / d[a] : INFINITY;
      tdelta[a] = std::fabs(d[a]) > 1e-12 ? res / std::fabs(d[a]) : INFINITY;
    }
    const double tend = len - p_.margin;
    double t = 0.0;
    while (t < tend) {
      add_free(key(v[0], v[1], v[2]));
      const int a = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
      t = tmax[a];
      tmax[a] += tdelta[a];
      v[a] += step[a];
    }
  }
  out.hit.reserve(hit_set.size());
  out.free.reserve(free_set.size());
  hit_set.for_each([&](std::uint64_t k, char) { out.hit.push_back(k); });
  free_set.for_each([&](std::uint64_t k, char) { out.free.push_back(k); });
  return out;
}

void ConsistencyEvidence::merge(const PassVoxels& v) {
  voxels_.reserve(voxels_.size() + v.free.size() / 2);
  for (const std::uint64_t k : v.hit) voxels_[k].hit |= v.bit;
  for (const std::uint64_t k : v.free) voxels_[k].free |= v.bit;
}

void ConsistencyEvidence::add_pass(const Pass& pass) { merge(collect(pass)); }

std::size_t ConsistencyEvidence::label(Pass& pass) const {
  const std::uint64_t bit = 1ull << (pass.index % 64);
  const double res = p_.resolution;
  std::size_t n = 0;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i])) continue;
    const std::int64_t x = static_cast<std::int64_t>(std::floor(pass.x[i] / res)),
                       y = static_cast<std::int64_t>(std::floor(pass.y[i] / res)),
                       z = static_cast<std::int64_t>(std::floor(pass.z[i] / res));
    const Voxel* it = voxels_.find(key(x, y, z));
    if (!it) continue;
    const std::uint64_t free_other = it->free & ~bit;
    if (__builtin_popcountll(free_other) < p_.min_passes) continue;
    bool hit_other = false;  // another pass returned from here or next door: a real surface
    const int h = p_.hit_radius;
    for (int dx = -h; dx <= h && !hit_other; ++dx)
      for (int dy = -h; dy <= h && !hit_other; ++dy)
        for (int dz = -h; dz <= h && !hit_other; ++dz) {
          const Voxel* hv = voxels_.find(key(x + dx, y + dy, z + dz));
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
