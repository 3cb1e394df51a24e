#include "pcdp/io/outputs.hpp"

#include <cmath>
#include <cstring>
#include <limits>
#include <set>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/pass.hpp"

namespace pcdp::io {

namespace {
// The amplitude twice: as `amplitude` (the data contract's name) and as `intensity`, the name
// PCL's point types (pcl::PointXYZI) and most tools give it, so loadPCDFile<pcl::PointXYZI> fills
// it. Files of version 0.1.0 and earlier have `amplitude` only: our readers take `intensity`, else
// `amplitude` (io::amplitude_field).
std::vector<PcdField> base_fields(bool with_label) {
  std::vector<PcdField> f = {{"x", 'F', 4, 1},         {"y", 'F', 4, 1},         {"z", 'F', 4, 1},
                             {"range", 'F', 4, 1},     {"amplitude", 'F', 4, 1}, {"intensity", 'F', 4, 1},
                             {"pass", 'U', 4, 1},      {"line", 'U', 4, 1},      {"beam", 'U', 4, 1}};
  if (with_label) {
    f.push_back({"label", 'U', 1, 1});
    f.push_back({"flags", 'U', 1, 1});
  }
  f.push_back({"stamp", 'F', 8, 1});
  return f;
}

template <typename T>
std::uint8_t* put(std::uint8_t* dst, T v) {
  std::memcpy(dst, &v, sizeof(T));
  return dst + sizeof(T);
}

std::vector<PcdField> cloud_fields();

// An input extra field named like a field of returns.pcd or cloud.pcd would make a file with that
// name twice, which no PCD reader accepts: it is written as input_<name> (the prefix repeated until
// the name is free). Other extra fields keep their names.
std::vector<PcdField> output_extra_fields(const std::vector<PcdField>& extra) {
  std::set<std::string> reserved;
  for (const auto& f : base_fields(true)) reserved.insert(f.name);
  for (const auto& f : cloud_fields()) reserved.insert(f.name);
  std::set<std::string> taken = reserved;
  for (const auto& f : extra) taken.insert(f.name);
  std::vector<PcdField> out = extra;
  for (auto& f : out) {
    if (!reserved.count(f.name)) continue;
    do f.name = "input_" + f.name;
    while (!taken.insert(f.name).second);
  }
  return out;
}

// x y z: the pass's coordinates, already relative to the map origin (the pipeline registers
// relative to it, pcdp/core/georef.hpp), so float32 keeps 1 mm; the header states the origin.
std::uint8_t* put_common(std::uint8_t* d, const Pass& p, std::size_t i) {
  d = put(d, static_cast<float>(p.x[i]));
  d = put(d, static_cast<float>(p.y[i]));
  d = put(d, static_cast<float>(p.z[i]));
  d = put(d, p.range_cal.empty() ? p.range[i] : p.range_cal[i]);
  d = put(d, p.amplitude[i]);
  d = put(d, p.amplitude[i]);  // intensity
  d = put(d, static_cast<std::uint32_t>(p.index));
  d = put(d, p.line[i]);
  d = put(d, p.beam[i]);
  return d;
}
}  // namespace

ReturnsWriter::ReturnsWriter(const std::string& path, const Eigen::Vector3d& map_origin)
    : path_(path), origin_(map_origin) {}

void ReturnsWriter::append(const Pass& pass) {
  if (!writer_) {
    // The first pass fixes the extra fields; later passes must carry the same ones.
    for (const auto& e : pass.extra) extra_.push_back(e.field);
    extra_source_ = pass.source;
    auto fields = base_fields(true);
    const auto renamed = output_extra_fields(extra_);
    fields.insert(fields.end(), renamed.begin(), renamed.end());
    writer_ = std::make_unique<PcdWriter>(path_, fields);
    writer_->set_map_origin(origin_.x(), origin_.y(), origin_.z());
  } else {
    bool same = pass.extra.size() == extra_.size();
    for (std::size_t k = 0; same && k < extra_.size(); ++k)
      same = pass.extra[k].field.name == extra_[k].name && pass.extra[k].field.bytes() == extra_[k].bytes() &&
             pass.extra[k].field.type == extra_[k].type;
    if (!same)
      throw InputError(pass.source + ": its extra fields differ from those of " + extra_source_ +
                       " (all passes of a run must carry the same extra fields)");
  }
  const std::size_t n = pass.size();
  const std::size_t pb = writer_->point_bytes();
  std::vector<std::uint8_t> rows(n * pb);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* d = rows.data() + i * pb;
    d = put_common(d, pass, i);
    d = put(d, static_cast<std::uint8_t>(pass.label[i]));
    d = put(d, pass.flags.empty() ? std::uint8_t{0} : pass.flags[i]);
    d = put(d, pass.stamp[i]);
    for (const auto& e : pass.extra) {
      const std::size_t b = e.field.bytes();
      std::memcpy(d, e.data.data() + i * b, b);
      d += b;
    }
  }
  writer_->append(rows.data(), n);
}

void ReturnsWriter::close() {
  if (!writer_) {  // a run of empty passes
    writer_ = std::make_unique<PcdWriter>(path_, base_fields(true));
    writer_->set_map_origin(origin_.x(), origin_.y(), origin_.z());
  }
  writer_->close();
}

namespace {
std::vector<PcdField> cloud_fields() {
  auto f = base_fields(false);
  for (const char* n : {"cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz", "sigma_h"}) f.push_back({n, 'F', 4, 1});
  return f;
}
}  // namespace

CloudWriter::CloudWriter(const std::string& path, const Eigen::Vector3d& map_origin) : writer_(path, cloud_fields()) {
  writer_.set_map_origin(map_origin.x(), map_origin.y(), map_origin.z());
}

void CloudWriter::append(const Pass& pass) {
  const std::size_t pb = writer_.point_bytes();
  std::vector<std::uint8_t> rows;
  rows.reserve(pass.size() * pb);
  std::size_t n = 0;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i)) continue;
    rows.resize((n + 1) * pb);
    std::uint8_t* d = rows.data() + n * pb;
    d = put_common(d, pass, i);
    d = put(d, pass.stamp[i]);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float* c = pass.cov.empty() ? nullptr : &pass.cov[6 * i];
    for (int k = 0; k < 6; ++k) d = put(d, c ? c[k] : nan);
    // Horizontal extent: 1-sigma major semi-axis of the horizontal (x, y) covariance.
    float sh = nan;
    if (c) {
      const double a = c[0], b = c[1], e = c[3];
      sh = static_cast<float>(std::sqrt(0.5 * (a + e) + std::sqrt(0.25 * (a - e) * (a - e) + b * b)));
    }
    put(d, sh);
    ++n;
  }
  writer_.append(rows.data(), n);
}

int amplitude_field(const PcdHeader& h) {
  const int k = h.field_index("intensity");
  return k >= 0 ? k : h.field_index("amplitude");
}

}  // namespace pcdp::io
