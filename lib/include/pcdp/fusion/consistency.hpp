// The evidence of stage `check_consistency` (pcdp/stages/check_consistency.hpp): with several
// passes, the kept returns that other passes
// contradict: rays of other passes went through the return's voxel (they saw free
// space there, from another viewpoint), and no other pass returned from within hit_radius
// voxels of it. A second line of defence against mixed pixels and false ranges that single-scan
// filters miss.
//
// How the evidence is gathered (the definition above is unchanged; only where it is looked for):
//  1. prepass, one pass at a time: the voxels the pass's kept returns end in (its hits), and its
//     rays, kept compactly (32 bytes a ray) until every pass has been seen;
//  2. finalize, once: a return with another pass's hit within hit_radius voxels is consistent
//     whatever crossed it, so free-space evidence is needed only at the voxels of the other,
//     "lonely" returns (a few per cent of them). The rays of each scan line are then taken
//     together as a fan (nearly one origin, nearly one plane; bounds measured on the rays):
//     only the lonely voxels near the fan's plane, and for each only the rays whose bearing
//     points at it, get the exact test (ray against box). Lines whose rays make no fan are
//     walked over a coarse grid of the lonely voxels' cells;
//  3. label: straight to the lonely returns step 2 found.
// Walking every ray voxel by voxel cost about 3 ns a step, 300 ns a ray; see docs/performance.md.
#pragma once

#include <cstdint>
#include <map>
#include <vector>

#include "pcdp/fusion/detail/flat_map.hpp"
#include "pcdp/fusion/detail/voxel_blocks.hpp"

namespace pcdp {

struct Pass;

struct ConsistencyParams {
  double resolution = 0.1;  ///< m, voxel size
  double margin = 0.5;      ///< m, rays stop this short of their end
  int min_passes = 1;       ///< other passes that must have seen free space through the return
  double max_range = 30.0;  ///< m, longer rays are not walked
  int hit_radius = 2;       ///< voxels: a return from another pass this close makes a surface
};

/// Hit evidence per voxel and the rays of every pass; after finalize(), the free-space evidence
/// at the voxels where it decides a label.
class ConsistencyEvidence {
 public:
  /// Voxel keys hold 21 bits an axis: indices within this many voxels of the map origin.
  static constexpr std::int64_t kKeyHalfRange = std::int64_t{1} << 20;
  explicit ConsistencyEvidence(const ConsistencyParams& p) : p_(p) {}

  /// One kept return: its end voxel (packed coordinates) and its ray, relative to the pass's
  /// anchor (single precision: a few micrometres within a kilometre of it).
  struct Ray {
    float o[3], e[3];
    std::uint64_t voxel;
  };
  /// What one pass contributes: the voxels it returned from and its rays.
  struct PassRays {
    std::size_t index = 0;  ///< the pass's index
    std::uint64_t bit = 0;  ///< 1 << (pass index mod 64)
    VoxelSet hit{0x27d4eb2fu};
    double anchor[3] = {0.0, 0.0, 0.0};
    std::vector<Ray> rays;
    /// Rays of the pass's scan line k are [lines[k], lines[k+1]).
    std::vector<std::uint32_t> lines;
  };
  /// The evidence of one pass (const: any thread, several passes at once).
  PassRays collect(const Pass& pass) const;
  /// Adds one pass's evidence (the bits of different passes commute: any order gives one result).
  /// Throws std::logic_error after finalize().
  void merge(PassRays&& v);
  /// collect + merge.
  void add_pass(const Pass& pass);
  /// After the last pass: finds the lonely returns and the passes whose rays crossed their voxels,
  /// on up to `threads` threads (the result does not depend on it), then frees the rays.
  void finalize(unsigned threads = 1);
  /// Labels the contradicted kept returns of `pass`; returns how many. Needs finalize(). Meant
  /// for the passes as they were collected: it goes straight to the lonely returns finalize()
  /// found. A pass with another count of kept returns, or whose listed returns lie in other
  /// voxels, is judged return by return instead.
  std::size_t label(Pass& pass) const;

  /// What finalize() found, for the stage's report.
  struct Stats {
    std::uint64_t returns = 0;        ///< kept returns of every pass
    std::uint64_t lonely_returns = 0; ///< with no other pass's hit within hit_radius
    std::uint64_t lonely_voxels = 0;
    std::uint64_t rays_walked = 0;    ///< rays that give free-space evidence (margin < length <= max_range)
    std::uint64_t crossings = 0;      ///< (ray, lonely voxel) pairs found crossed
    std::uint64_t rays_in_fans = 0;   ///< of rays_walked, those tested through their scan line's fan (the rest walk a grid)
  };
  const Stats& stats() const { return stats_; }

 private:
  /// Which passes returned from each voxel of a block, as much as other_hit_near needs: whether
  /// any did, which one if only one did (its index mod 64), whether several did. 640 bytes a block
  /// (a 64-bit set per voxel took 4 KB: 6x the memory to clear and to miss in the cache).
  struct HitBlock {
    std::uint64_t any[8] = {}, several[8] = {};
    std::uint8_t owner[512] = {};
    /// Whether a pass other than `pass` (index mod 64) returned from the cell.
    bool other(unsigned cell, unsigned pass) const {
      const std::uint64_t m = 1ull << (cell & 63);
      return (several[cell >> 6] & m) != 0 || ((any[cell >> 6] & m) != 0 && owner[cell] != pass);
    }
  };
  struct Lonely {
    std::uint64_t key;            ///< packed voxel coordinates (21 bits each: they wrap)
    std::int64_t v[3];            ///< the voxel's signed indices (they do not)
    std::uint64_t passes = 0;     ///< passes with a lonely return in this voxel
    std::uint64_t free = 0;       ///< passes whose rays crossed it
  };
  struct Chunk {
    std::size_t pass, begin, end;  ///< rays (chunks()) or lines (line_chunks()) [begin, end) of passes_[pass]
  };
  std::vector<Chunk> chunks() const;
  std::vector<Chunk> line_chunks() const;
  bool other_hit_near(std::uint64_t voxel, std::uint64_t bit) const;
  void find_lonely(unsigned threads);
  void walk_rays(unsigned threads);

  /// A pass's lonely returns as finalize() found them, so that label() looks up only those:
  /// (position among the pass's rays, position in lonely_), in ray order.
  struct PassLonely {
    std::uint32_t rays = 0;  ///< the pass's ray count, to check label() is given the same pass
    bool unique = true;      ///< false when two passes had this index (label() then looks up every return)
    bool seen = false;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> lonely;
  };
  std::size_t label_by_lookup(Pass& pass) const;

  ConsistencyParams p_;
  std::map<std::size_t, PassLonely> pass_lonely_;  ///< by pass index
  BlockGrid<HitBlock> hits_{0x61c88647u};
  std::vector<PassRays> passes_;  ///< until finalize()
  bool finalized_ = false;
  std::vector<Lonely> lonely_;
  FlatMap<std::uint32_t> lonely_index_{0x3c6ef372u};  ///< key -> position in lonely_
  Stats stats_;
};

}  // namespace pcdp
