// Stage `check_consistency`: with several passes, label `inconsistent` the kept returns that
// other passes contradict: rays of other passes went through the return's voxel (they saw free
// space there, from another viewpoint), and no other pass returned from within hit_radius
// voxels of it. A second line of defence against mixed pixels and false ranges that single-scan
// filters miss. The evidence and how it is gathered: pcdp/fusion/consistency.hpp.
#pragma once

#include "pcdp/fusion/consistency.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp {

/// The options of `check_consistency`, bound to ConsistencyParams (pcdp/fusion/consistency.hpp).
const Options<ConsistencyParams>& check_consistency_options();
const OptionSchema& check_consistency_schema();
StageInfo check_consistency_stage_info();

}  // namespace pcdp
