// The range-calibration samples file (pcd_pipeline calibrate-range): a CSV of true distances
// and measured ranges, for pcdp::fit_range_calibration (pcdp/models/calibration.hpp).
#pragma once

#include <string>
#include <vector>

namespace pcdp::io {

/// Reads a CSV whose header names the columns `true` and `measured` (m; others are ignored).
/// Throws InputError naming the file, the line and the column.
void read_range_samples_csv(const std::string& path, std::vector<double>& true_distance, std::vector<double>& measured);

}  // namespace pcdp::io
