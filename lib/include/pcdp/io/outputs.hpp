// Writers of the per-return products: returns.pcd (every input return exactly once, with its
// label) and cloud.pcd (the kept points). Fields are those of docs/data_contract.md "Outputs".
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "pcdp/io/pcd.hpp"

namespace pcdp {
struct Pass;
}

namespace pcdp::io {

/// returns.pcd: x y z range amplitude intensity (the amplitude again, PCL's name) pass line beam label flags stamp, then the input's extra fields
/// (carried through). x y z are NaN where there is no point.
/// `map_origin`: the origin the passes' coordinates are relative to, written in the header as the
/// comment "# map_origin X Y Z" when not 0 (map coordinates = x y z + map_origin). Not VIEWPOINT:
/// PCL's normal estimation and `clean-cloud` take that for the sensor position in the cloud's frame.
class ReturnsWriter {
 public:
  explicit ReturnsWriter(const std::string& path, const Eigen::Vector3d& map_origin = Eigen::Vector3d::Zero());
  void append(const Pass& pass);
  void close();
  std::uint64_t points() const { return writer_ ? writer_->points() : 0; }

 private:
  std::string path_;
  std::unique_ptr<PcdWriter> writer_;
  std::vector<PcdField> extra_;  ///< fixed by the first pass
  std::string extra_source_;
  Eigen::Vector3d origin_;
};

/// cloud.pcd: the kept points, x y z range amplitude intensity (the amplitude again, PCL's name) pass line beam stamp, their covariance
/// cov_xx cov_xy cov_xz cov_yy cov_yz cov_zz (m^2; cov_zz is the vertical variance) and sigma_h
/// (m, 1-sigma major semi-axis of the horizontal covariance). NaN when not computed.
class CloudWriter {
 public:
  explicit CloudWriter(const std::string& path, const Eigen::Vector3d& map_origin = Eigen::Vector3d::Zero());
  void append(const Pass& pass);
  void close() { writer_.close(); }
  std::uint64_t points() const { return writer_.points(); }

 private:
  PcdWriter writer_;
};

/// The column of a PCD that holds the amplitude: `intensity` (PCL's name, which returns.pcd and
/// cloud.pcd write beside `amplitude`), else `amplitude` (their only name up to version 0.1.0);
/// -1 when neither is there.
int amplitude_field(const PcdHeader& h);

}  // namespace pcdp::io
