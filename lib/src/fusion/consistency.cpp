// The evidence of check_consistency (pcdp/fusion/consistency.hpp): collecting a pass's rays and
// hits, merging them, finding the lonely returns and labelling. The walk of every ray against the
// lonely voxels (ray fans, coarse cells) is in consistency_rays.cpp.
#include "pcdp/fusion/consistency.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "fusion/ifloor.hpp"
#include "pipeline/ordered_parallel.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/core/pass.hpp"

namespace pcdp {

namespace {
// A voxel index made non-negative and kept to 21 bits (+-2^20 voxels: +-10 km at 1 cm).
constexpr std::int64_t kCoordOffset = ConsistencyEvidence::kKeyHalfRange;
std::uint32_t coord(std::int64_t v) { return static_cast<std::uint32_t>(v + kCoordOffset) & kVoxelCoordMask; }
using detail::ifloor;
std::uint32_t voxel_coord(double c, double res) { return coord(ifloor(c / res)); }
std::uint64_t pack(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  return (static_cast<std::uint64_t>(x) << 42) | (static_cast<std::uint64_t>(y) << 21) | z;
}
void unpack(std::uint64_t k, std::uint32_t c[3]) {
  c[0] = static_cast<std::uint32_t>(k >> 42) & kVoxelCoordMask;
  c[1] = static_cast<std::uint32_t>(k >> 21) & kVoxelCoordMask;
  c[2] = static_cast<std::uint32_t>(k) & kVoxelCoordMask;
}

// The signed voxel index whose 21-bit coordinate is `wrapped`, nearest to `approx` (any estimate
// within 2^20 voxels): the keys wrap (UTM coordinates at 0.1 m already do), the geometry must not.
std::int64_t unwrap(std::uint32_t wrapped, double approx) {
  constexpr std::int64_t kPeriod = std::int64_t{1} << 21;
  const std::int64_t near = ifloor(approx);
  std::int64_t diff = (static_cast<std::int64_t>(wrapped) - kCoordOffset - near) % kPeriod;
  if (diff < -kCoordOffset) diff += kPeriod;
  if (diff >= kCoordOffset) diff -= kPeriod;
  return near + diff;
}

}  // namespace

ConsistencyEvidence::PassRays ConsistencyEvidence::collect(const Pass& pass) const {
  PassRays out;
  out.index = pass.index;
  out.bit = 1ull << (pass.index % 64);
  const double res = p_.resolution;
  // The hits' bounds, for the set's dense block directory: from the coordinates' extremes (the
  // voxel coordinates increase with them, except where they wrap; the directory then exceeds its
  // limit and the set hashes, as it would have with per-voxel bounds).
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  std::size_t n = 0;
  bool anchored = false;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i])) continue;
    ++n;
    if (!std::isfinite(pass.ox[i])) continue;
    lo[0] = std::min(lo[0], pass.x[i]);
    lo[1] = std::min(lo[1], pass.y[i]);
    lo[2] = std::min(lo[2], pass.z[i]);
    hi[0] = std::max(hi[0], pass.x[i]);
    hi[1] = std::max(hi[1], pass.y[i]);
    hi[2] = std::max(hi[2], pass.z[i]);
    if (!anchored) {
      out.anchor[0] = pass.ox[i];
      out.anchor[1] = pass.oy[i];
      out.anchor[2] = pass.oz[i];
      anchored = true;
    }
  }
  VoxelBounds bounds;
  if (anchored) {
    bounds.add(voxel_coord(lo[0], res), voxel_coord(lo[1], res), voxel_coord(lo[2], res));
    bounds.add(voxel_coord(hi[0], res), voxel_coord(hi[1], res), voxel_coord(hi[2], res));
  }
  out.hit = VoxelSet(bounds, 0x27d4eb2fu);
  out.rays.reserve(n);
  out.lines.reserve(pass.line_count() + 1);
  VoxelSet::Cursor hit(out.hit);
  const double* a = out.anchor;
  std::size_t line = 0;  // the next line to start
  for (std::size_t i = 0; i < pass.size(); ++i) {
    for (; line < pass.line_count() && pass.line_begin[line] <= i; ++line)
      out.lines.push_back(static_cast<std::uint32_t>(out.rays.size()));
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i])) continue;
    const std::uint32_t x = voxel_coord(pass.x[i], res), y = voxel_coord(pass.y[i], res), z = voxel_coord(pass.z[i], res);
    Ray r;
    r.voxel = pack(x, y, z);
    r.e[0] = static_cast<float>(pass.x[i] - a[0]);
    r.e[1] = static_cast<float>(pass.y[i] - a[1]);
    r.e[2] = static_cast<float>(pass.z[i] - a[2]);
    // A return without a sensor origin neither returns (hit) nor sees through (a NaN origin).
    const bool origin = std::isfinite(pass.ox[i]);
    r.o[0] = origin ? static_cast<float>(pass.ox[i] - a[0]) : NAN;
    r.o[1] = origin ? static_cast<float>(pass.oy[i] - a[1]) : NAN;
    r.o[2] = origin ? static_cast<float>(pass.oz[i] - a[2]) : NAN;
    if (origin) hit.insert(x, y, z);
    out.rays.push_back(r);
  }
  for (; line < pass.line_count(); ++line) out.lines.push_back(static_cast<std::uint32_t>(out.rays.size()));
  if (out.lines.empty()) out.lines.push_back(0);  // no lines: one of every ray
  out.lines.push_back(static_cast<std::uint32_t>(out.rays.size()));
  return out;
}

void ConsistencyEvidence::merge(PassRays&& v) {
  if (finalized_) throw std::logic_error("ConsistencyEvidence::merge after finalize");
  const BlockGrid<BitBlock>& g = v.hit.blocks();
  const auto pass = static_cast<std::uint8_t>(__builtin_ctzll(v.bit));
  for (std::size_t b = 0; b < g.size(); ++b) {
    HitBlock& dst = hits_.block(g.key(b));
    for (unsigned w = 0; w < 8; ++w) {
      const std::uint64_t bits = g[b].w[w], fresh = bits & ~dst.any[w];
      for (std::uint64_t o = bits & dst.any[w]; o != 0; o &= o - 1) {  // seen before: by another pass?
        const unsigned c = 64 * w + static_cast<unsigned>(__builtin_ctzll(o));
        if (dst.owner[c] != pass) dst.several[w] |= 1ull << (c & 63);
      }
      for (std::uint64_t f = fresh; f != 0; f &= f - 1) dst.owner[64 * w + static_cast<unsigned>(__builtin_ctzll(f))] = pass;
      dst.any[w] |= fresh;
    }
  }
  v.hit = VoxelSet{};
  stats_.returns += v.rays.size();
  passes_.push_back(std::move(v));
}

void ConsistencyEvidence::add_pass(const Pass& pass) { merge(collect(pass)); }

bool ConsistencyEvidence::other_hit_near(std::uint64_t voxel, std::uint64_t bit) const {
  const auto pass = static_cast<unsigned>(__builtin_ctzll(bit));
  std::uint32_t c[3];
  unpack(voxel, c);
  std::uint64_t last = ~0ull;
  const HitBlock* b = nullptr;
  // Unsigned offsets wrap modulo 2^21, as the coordinates do.
  const auto hit = [&](std::int64_t dx, std::int64_t dy, std::int64_t dz) {
    const BlockPos p = block_pos((c[0] + static_cast<std::uint32_t>(dx)) & kVoxelCoordMask,
                                 (c[1] + static_cast<std::uint32_t>(dy)) & kVoxelCoordMask,
                                 (c[2] + static_cast<std::uint32_t>(dz)) & kVoxelCoordMask);
    if (p.block != last) {
      b = hits_.find(p.block);
      last = p.block;
    }
    return b && b->other(p.cell, pass);
  };
  // The voxel and its six faces first (most returns find a surface there), then the whole cube
  // in raster order, which crosses block boundaries (one lookup each) least often.
  const int h = p_.hit_radius;
  if (hit(0, 0, 0)) return true;
  if (h >= 1)
    for (int a = 0; a < 3; ++a)
      for (const int d : {-1, 1})
        if (hit(a == 0 ? d : 0, a == 1 ? d : 0, a == 2 ? d : 0)) return true;
  for (int dz = -h; dz <= h; ++dz)
    for (int dy = -h; dy <= h; ++dy)
      for (int dx = -h; dx <= h; ++dx)
        if (hit(dx, dy, dz)) return true;
  return false;
}

std::vector<ConsistencyEvidence::Chunk> ConsistencyEvidence::chunks() const {
  // Pieces of a few thousand rays: passes differ in cost, and two threads given one pass each
  // wait on the slower.
  constexpr std::size_t kRays = 4096;
  std::vector<Chunk> out;
  for (std::size_t k = 0; k < passes_.size(); ++k)
    for (std::size_t b = 0; b < passes_[k].rays.size(); b += kRays)
      out.push_back({k, b, std::min(b + kRays, passes_[k].rays.size())});
  return out;
}

void ConsistencyEvidence::find_lonely(unsigned threads) {
  struct Found {
    std::vector<Lonely> voxels;       // one per lonely return
    std::vector<std::uint32_t> rays;  // its position among the pass's rays
  };
  for (const PassRays& pr : passes_) {
    PassLonely& pl = pass_lonely_[pr.index];
    if (pl.seen) pl.unique = false;
    pl.seen = true;
    pl.rays = static_cast<std::uint32_t>(pr.rays.size());
  }
  const std::vector<Chunk> work = chunks();
  // The pieces' results are small (the lonely returns only): all are kept, then merged in order.
  std::vector<Found> found(work.size());
  detail::parallel_for(work.size(), threads, [&](std::size_t w) {
    Found& f = found[w];
    const PassRays& pr = passes_[work[w].pass];
    std::uint64_t last = ~0ull;
    bool last_lonely = false;
    for (std::size_t i = work[w].begin; i < work[w].end; ++i) {
      const Ray& r = pr.rays[i];
      if (r.voxel != last) {  // neighbours along a line often share a voxel
        last = r.voxel;
        last_lonely = !other_hit_near(r.voxel, pr.bit);
      }
      if (last_lonely) {
        std::uint32_t c[3];
        unpack(r.voxel, c);
        Lonely l{r.voxel, {}, 0, 0};
        for (int a = 0; a < 3; ++a) l.v[a] = unwrap(c[a], (pr.anchor[a] + static_cast<double>(r.e[a])) / p_.resolution);
        f.voxels.push_back(l);
        f.rays.push_back(static_cast<std::uint32_t>(i));
      }
    }
  });
  for (std::size_t w = 0; w < work.size(); ++w) {
    const Found& f = found[w];
    const PassRays& pr = passes_[work[w].pass];
    stats_.lonely_returns += f.voxels.size();
    PassLonely& pl = pass_lonely_[pr.index];
    for (std::size_t k = 0; k < f.voxels.size(); ++k) {
      const Lonely& l = f.voxels[k];
      std::uint32_t& slot = lonely_index_[l.key];  // position + 1; 0: new
      if (slot == 0) {
        lonely_.push_back(l);
        slot = static_cast<std::uint32_t>(lonely_.size());
      }
      lonely_[slot - 1].passes |= pr.bit;
      pl.lonely.emplace_back(f.rays[k], slot - 1);
    }
  }
  stats_.lonely_voxels = lonely_.size();
}

void ConsistencyEvidence::finalize(unsigned threads) {
  if (finalized_) return;
  find_lonely(threads);
  walk_rays(threads);
  passes_.clear();
  passes_.shrink_to_fit();
  hits_ = BlockGrid<HitBlock>{0x61c88647u};  // label() needs only the lonely voxels
  finalized_ = true;
}

std::size_t ConsistencyEvidence::label(Pass& pass) const {
  if (!finalized_) throw std::logic_error("ConsistencyEvidence::label before finalize");
  if (lonely_.empty()) return 0;
  // The lonely returns finalize() found for this pass, if it is the pass that was collected: the
  // same count of kept returns with a point, and each listed one in the voxel recorded for it.
  // Otherwise (another pass, or two passes with one index) every return is looked up.
  const auto found = pass_lonely_.find(pass.index);
  if (found == pass_lonely_.end() || !found->second.unique) return label_by_lookup(pass);
  const PassLonely* pl = &found->second;
  const std::uint64_t bit = 1ull << (pass.index % 64);
  const double res = p_.resolution;
  std::vector<std::size_t> contradicted;
  std::uint32_t ray = 0;
  auto next = pl->lonely.begin();
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i])) continue;
    if (next != pl->lonely.end() && next->first == ray) {
      const Lonely& l = lonely_[next->second];
      if (l.key != pack(voxel_coord(pass.x[i], res), voxel_coord(pass.y[i], res), voxel_coord(pass.z[i], res)))
        return label_by_lookup(pass);
      if (__builtin_popcountll(l.free & ~bit) >= p_.min_passes) contradicted.push_back(i);
      ++next;
    }
    ++ray;
  }
  if (ray != pl->rays || next != pl->lonely.end()) return label_by_lookup(pass);
  for (const std::size_t i : contradicted) pass.label[i] = Label::kInconsistent;
  return contradicted.size();
}

std::size_t ConsistencyEvidence::label_by_lookup(Pass& pass) const {
  const std::uint64_t bit = 1ull << (pass.index % 64);
  const double res = p_.resolution;
  std::size_t n = 0;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i])) continue;
    const std::uint32_t* slot = lonely_index_.find(pack(voxel_coord(pass.x[i], res), voxel_coord(pass.y[i], res), voxel_coord(pass.z[i], res)));
    if (!slot) continue;  // another pass returned from near it: a real surface
    const Lonely& l = lonely_[*slot - 1];
    if (!(l.passes & bit)) continue;  // this pass's returns here have another pass's hit nearby
    if (__builtin_popcountll(l.free & ~bit) < p_.min_passes) continue;
    pass.label[i] = Label::kInconsistent;
    ++n;
  }
  return n;
}

}  // namespace pcdp
