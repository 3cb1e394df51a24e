// Stage `fuse_octomap`: every pass into one OctoMap (octomap_fusion.hpp: batched per pass, a
// sensor origin per return, rejected returns not inserted); writes map.bt (and map.ot on request).
#pragma once

#include "pcdp/pipeline/stage.hpp"

namespace pcdp {

const OptionSchema& fuse_octomap_schema();
StageInfo fuse_octomap_stage_info();

}  // namespace pcdp
