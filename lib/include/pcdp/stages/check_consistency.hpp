// Stage `check_consistency`: with several passes, label `inconsistent` the kept returns that
// other passes contradict: rays of other passes went through the return's voxel (they saw free
// space there, from another viewpoint), and no other pass returned from within hit_radius
// voxels of it. A second line of defence against mixed pixels and false ranges that single-scan
// filters miss.
//
// Evidence is collected in a prepass over every pass (the pipeline streams the passes twice):
// each kept return's ray is walked voxel by voxel (3-D DDA) from its own sensor origin up to
// `margin` short of its end, marking the voxels free for that pass; its end voxel is marked hit.
// Voxels are kept in 8 x 8 x 8 blocks (voxel_blocks.hpp): the walk's steps stay in cache.
#pragma once

#include <cstdint>

#include "pcdp/stage.hpp"
#include "pcdp/voxel_blocks.hpp"

namespace pcdp {

struct Pass;

struct ConsistencyParams {
  double resolution = 0.1;  ///< m, voxel size
  double margin = 0.5;      ///< m, rays stop this short of their end
  int min_passes = 1;       ///< other passes that must have seen free space through the return
  double max_range = 30.0;  ///< m, longer rays are not walked
  int hit_radius = 2;       ///< voxels: a return from another pass this close makes a surface
};

const OptionSchema& check_consistency_schema();

/// Free-space and hit evidence per voxel, with the passes (modulo 64) that gave it.
class ConsistencyEvidence {
 public:
  explicit ConsistencyEvidence(const ConsistencyParams& p) : p_(p) {}
  /// The voxels one pass saw: its end points (hit) and the voxels its rays crossed (free).
  struct PassVoxels {
    std::uint64_t bit = 0;
    VoxelSet hit{0x27d4eb2fu}, free{0x5bd1e995u};  // salts unlike the evidence's own
  };
  /// The evidence of one pass (const: any thread, several passes at once).
  PassVoxels collect(const Pass& pass) const;
  /// Adds one pass's evidence (the bits of different passes commute: any order gives one result).
  void merge(const PassVoxels& v);
  /// collect + merge.
  void add_pass(const Pass& pass);
  /// Labels the contradicted kept returns of `pass`; returns how many.
  std::size_t label(Pass& pass) const;

 private:
  struct Voxel {
    std::uint64_t free = 0, hit = 0;  ///< bit (pass mod 64)
  };
  struct Block {
    Voxel v[512];
  };
  const Voxel* find(std::uint32_t x, std::uint32_t y, std::uint32_t z) const;
  ConsistencyParams p_;
  BlockGrid<Block> voxels_;
};

StageInfo check_consistency_stage_info();

}  // namespace pcdp
