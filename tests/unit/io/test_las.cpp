// The LAS reader (pcdp/io/las.hpp): synthetic files of every supported point format and version,
// written here byte by byte from the specification, the malformed headers it must refuse with
// their field named, the real Autzen files against their own headers, and the LAS/PLY writers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <tuple>

#include "pcdp/core/errors.hpp"
#include "pcdp/import/scans.hpp"
#include "pcdp/io/las.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;
namespace fs = std::filesystem;

namespace {

template <typename T>
void put_at(std::string& b, std::size_t at, T v) {
  if (b.size() < at + sizeof v) b.resize(at + sizeof v, '\0');
  std::memcpy(&b[at], &v, sizeof v);
}

struct SynthPoint {
  double x, y, z;
  std::uint16_t intensity;
  std::uint8_t cls;
};

struct SynthVlr {
  std::string user;
  std::uint16_t id;
  std::string data;
};

/// A LAS file of version 1.`minor`, point format `format`, `extra` extra bytes per point, the
/// given VLRs, scale 0.01 and offset (1000, 2000, 0).
std::string make_las(int minor, int format, const std::vector<SynthPoint>& pts, std::size_t extra = 0,
                     const std::vector<SynthVlr>& vlrs = {}) {
  const std::size_t hsize = minor == 2 ? 227 : minor == 3 ? 235 : 375;
  const std::size_t rec = io::las_point_size(format) + extra;
  std::string b(hsize, '\0');
  std::memcpy(&b[0], "LASF", 4);
  b[24] = 1;
  b[25] = static_cast<char>(minor);
  put_at(b, 94, static_cast<std::uint16_t>(hsize));
  std::size_t vlr_bytes = 0;
  for (const auto& v : vlrs) vlr_bytes += 54 + v.data.size();
  put_at(b, 96, static_cast<std::uint32_t>(hsize + vlr_bytes));
  put_at(b, 100, static_cast<std::uint32_t>(vlrs.size()));
  b[104] = static_cast<char>(format);
  put_at(b, 105, static_cast<std::uint16_t>(rec));
  put_at(b, 107, static_cast<std::uint32_t>(format >= 6 ? 0 : pts.size()));
  const double scale[3] = {0.01, 0.01, 0.01}, offset[3] = {1000, 2000, 0};
  for (int a = 0; a < 3; ++a) {
    put_at(b, 131 + 8 * a, scale[a]);
    put_at(b, 155 + 8 * a, offset[a]);
  }
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const auto& p : pts) {
    const double v[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], v[a]), hi[a] = std::max(hi[a], v[a]);
  }
  for (int a = 0; a < 3; ++a) {
    put_at(b, 179 + 16 * a, pts.empty() ? 0.0 : hi[a]);
    put_at(b, 187 + 16 * a, pts.empty() ? 0.0 : lo[a]);
  }
  if (minor == 4) put_at(b, 247, static_cast<std::uint64_t>(pts.size()));
  for (const auto& v : vlrs) {
    std::string h(54, '\0');
    std::memcpy(&h[2], v.user.data(), std::min<std::size_t>(16, v.user.size()));
    put_at(h, 18, v.id);
    put_at(h, 20, static_cast<std::uint16_t>(v.data.size()));
    b += h + v.data;
  }
  for (const auto& p : pts) {
    std::string r(rec, '\x5a');  // extra bytes and fields not set here hold 0x5a
    const double v[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) put_at(r, 4 * a, static_cast<std::int32_t>(std::lround((v[a] - offset[a]) / scale[a])));
    put_at(r, 12, p.intensity);
    if (format >= 6) r[16] = static_cast<char>(p.cls);
    else r[15] = static_cast<char>(p.cls | 0xA0);  // the synthetic and withheld flags set: the class is the low 5 bits
    b += r;
  }
  return b;
}

std::string geokeys(std::uint16_t linear_unit) {
  std::string d;
  for (std::uint16_t v : std::initializer_list<std::uint16_t>{1, 1, 0, 1, 3076, 0, 1, linear_unit}) d.append(reinterpret_cast<const char*>(&v), 2);
  return d;
}

const std::vector<SynthPoint> kPts = {{1001.25, 2002.5, 10.75, 100, 2}, {999.0, 1999.99, -3.5, 65535, 1}, {1010.01, 2020.02, 0.0, 0, 6}};

std::string write(const std::string& name, const std::string& bytes) {
  static const std::string dir = test::fresh_dir("las");
  const std::string p = dir + "/" + name;
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

std::string read_error(const std::string& bytes) {
  const std::string p = write("bad.las", bytes);
  try {
    io::read_las(p);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(Las, EveryPointFormatAndVersionReadsItsPoints) {
  struct Case {
    int minor, format;
    std::size_t extra;
  };
  for (const Case c : {Case{2, 0, 0}, Case{2, 1, 0}, Case{2, 2, 0}, Case{2, 3, 0}, Case{3, 1, 0}, Case{4, 0, 0}, Case{4, 3, 0},
                       Case{4, 6, 0}, Case{4, 7, 0}, Case{4, 8, 0}, Case{4, 6, 5}, Case{2, 1, 3}}) {
    SCOPED_TRACE("LAS 1." + std::to_string(c.minor) + " format " + std::to_string(c.format) + " extra " + std::to_string(c.extra));
    const std::string p = write("f.las", make_las(c.minor, c.format, kPts, c.extra));
    const io::LasCloud cl = io::read_las(p);
    EXPECT_EQ(cl.header.version_minor, c.minor);
    EXPECT_EQ(cl.header.point_format, c.format);
    EXPECT_EQ(cl.header.record_length, io::las_point_size(c.format) + c.extra);
    ASSERT_EQ(cl.xyz.size(), kPts.size());
    for (std::size_t i = 0; i < kPts.size(); ++i) {
      EXPECT_NEAR(cl.xyz[i].x(), kPts[i].x, 1e-9);
      EXPECT_NEAR(cl.xyz[i].y(), kPts[i].y, 1e-9);
      EXPECT_NEAR(cl.xyz[i].z(), kPts[i].z, 1e-9);
      EXPECT_EQ(cl.intensity[i], static_cast<float>(kPts[i].intensity));
      EXPECT_EQ(cl.classification[i], kPts[i].cls);
    }
    EXPECT_EQ(cl.header.unit_to_metre, 0.0);  // no CRS VLR: unknown
    EXPECT_TRUE(io::has_las_signature(p));
  }
}

TEST(Las, UnitsComeFromTheGeoKeysOrTheWkt) {
  const io::LasHeader ft = io::read_las_header(write("ft.las", make_las(2, 1, kPts, 0, {{"LASF_Projection", 34735, geokeys(9002)}})));
  EXPECT_EQ(ft.unit_name, "foot");
  EXPECT_DOUBLE_EQ(ft.unit_to_metre, 0.3048);
  EXPECT_NE(ft.unit_source.find("ProjLinearUnitsGeoKey = 9002"), std::string::npos);
  const io::LasHeader us = io::read_las_header(write("us.las", make_las(4, 6, kPts, 0, {{"LASF_Projection", 34735, geokeys(9003)}})));
  EXPECT_EQ(us.unit_name, "US survey foot");
  const std::string wkt =
      "PROJCS[\"x\",GEOGCS[\"NAD83\",UNIT[\"degree\",0.0174532925199433]],PROJECTION[\"Lambert_Conformal_Conic_2SP\"],"
      "UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]]]";
  const io::LasHeader m = io::read_las_header(write("wkt.las", make_las(4, 6, kPts, 0, {{"LASF_Projection", 2112, wkt + '\0'}})));
  EXPECT_EQ(m.unit_name, "metre");
  EXPECT_DOUBLE_EQ(m.unit_to_metre, 1.0);
  // import cloud scales to metres by the declared unit, or by --unit-scale.
  const std::string p = write("ft_import.las", make_las(2, 1, kPts, 0, {{"LASF_Projection", 34735, geokeys(9002)}}));
  const Eigen::Vector3d vp(305, 610, 30);  // metres: the points are feet
  const io::ImportedScans r = io::import_cloud({p}, &vp, {});
  ASSERT_EQ(r.notes.size(), 1u);
  EXPECT_NE(r.notes[0].find("units: foot"), std::string::npos) << r.notes[0];
  EXPECT_NE(r.notes[0].find("scaled to metres"), std::string::npos) << r.notes[0];
  ASSERT_EQ(r.passes.size(), 1u);
  EXPECT_EQ(r.passes[0].size(), kPts.size());
}

TEST(Las, MalformedHeadersAreRefusedNamingTheField) {
  const std::string good = make_las(4, 6, kPts);
  EXPECT_EQ(read_error(good), "(no error)");
  auto with = [&](std::size_t at, auto v, const std::string& base) {
    std::string b = base;
    put_at(b, at, v);
    return b;
  };
  EXPECT_NE(read_error("LASX" + good.substr(4)).find("does not start with the signature \"LASF\""), std::string::npos);
  EXPECT_NE(read_error(good.substr(0, 100)).find("ends inside the LAS header"), std::string::npos);
  EXPECT_NE(read_error(with(25, std::uint8_t{5}, good)).find("version (byte 24): LAS 1.5 is not supported"), std::string::npos);
  EXPECT_NE(read_error(with(104, std::uint8_t{0x86}, good)).find("compressed (LAZ)"), std::string::npos);
  EXPECT_NE(read_error(with(104, std::uint8_t{4}, good)).find("point data format (byte 104) is 4; supported"), std::string::npos);
  EXPECT_NE(read_error(with(104, std::uint8_t{6}, make_las(2, 1, kPts))).find("formats 6-10 need LAS 1.4"), std::string::npos);
  EXPECT_NE(read_error(with(105, std::uint16_t{29}, good)).find("record length (byte 105) is 29; point format 6 needs at least 30"),
            std::string::npos);
  EXPECT_NE(read_error(with(94, std::uint16_t{227}, good)).find("header size (byte 94) is 227; LAS 1.4 needs at least 375"),
            std::string::npos);
  EXPECT_NE(read_error(with(96, std::uint32_t{100}, good)).find("offset to point data (byte 96) is 100, inside the header"),
            std::string::npos);
  EXPECT_NE(read_error(with(96, std::uint32_t{1u << 30}, good)).find("past the end of the file"), std::string::npos);
  // Counts: more points than the file holds, a count whose product with the record length
  // overflows 64 bits, and a legacy count that disagrees with the 1.4 one.
  EXPECT_NE(read_error(with(247, std::uint64_t{4}, good)).find("number of point records (byte 247) is 4: 4 x 30 bytes do not fit"),
            std::string::npos);
  EXPECT_NE(read_error(with(247, ~std::uint64_t{0}, good)).find("do not fit"), std::string::npos);
  EXPECT_NE(read_error(with(107, std::uint32_t{7}, good)).find("legacy number of point records (byte 107) is 7"), std::string::npos);
  EXPECT_NE(read_error(with(107, std::uint32_t{4}, make_las(2, 3, kPts))).find("(byte 107) is 4: 4 x 34 bytes"), std::string::npos);
  EXPECT_NE(read_error(good.substr(0, good.size() - 1)).find("do not fit in the 89 bytes"), std::string::npos);
  EXPECT_NE(read_error(with(131, 0.0, good)).find("X scale factor (byte 131) is 0.000000; it must be finite and not 0"),
            std::string::npos);
  EXPECT_NE(read_error(with(163, std::nan(""), good)).find("Y offset (byte 163) is not finite"), std::string::npos);
  // VLRs: more than fit before the points, and one whose data runs past the offset.
  EXPECT_NE(read_error(with(100, std::uint32_t{1}, good)).find("VLR 0 of 1 (byte 375): its 54-byte header does not fit"),
            std::string::npos);
  std::string v = make_las(2, 1, kPts, 0, {{"LASF_Projection", 34735, geokeys(9002)}});
  put_at(v, 227 + 20, std::uint16_t{200});
  EXPECT_NE(read_error(v).find("VLR 0 of 1 (LASF_Projection 34735, byte 227): its 200 bytes of data run past"), std::string::npos);
  std::string g = make_las(2, 1, kPts, 0, {{"LASF_Projection", 34735, geokeys(9002)}});
  put_at(g, 227 + 54 + 6, std::uint16_t{40});
  EXPECT_NE(read_error(g).find("GeoKeyDirectory): 40 keys need 328 bytes"), std::string::npos);
  // The file's name leads every message.
  EXPECT_EQ(read_error("LASX").rfind(fs::path(write("bad.las", "")).string(), 0), 0u);
}

TEST(Las, ImportCloudRefusesLazNamingTheWayOut) {
  const std::string p = write("c.laz", make_las(2, 1, kPts));
  try {
    io::import_cloud({p}, nullptr, {});
    FAIL() << "LAZ accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("LAZ (compressed LAS) is not supported"), std::string::npos) << e.what();
  }
}

TEST(Las, AutzenFilesMatchTheirHeaders) {
  const std::string dir = std::string(PCDP_SHARED_DIR) + "/datasets/pdal_autzen/";
  for (const auto& [name, points, feet] : {std::tuple<const char*, std::size_t, bool>{"autzen_trim.las", 110000, true},
                                           std::tuple<const char*, std::size_t, bool>{"autzen-thin.las", 10653, false}}) {
    SCOPED_TRACE(name);
    const io::LasCloud c = io::read_las(dir + name);
    EXPECT_EQ(c.header.version_minor, 2);
    EXPECT_EQ(c.header.point_format, 3);
    ASSERT_EQ(c.xyz.size(), points);
    Eigen::Vector3d lo = c.xyz[0], hi = c.xyz[0];
    for (const auto& p : c.xyz) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(lo[a], c.header.min[a], c.header.scale[a] / 2) << "axis " << a;
      EXPECT_NEAR(hi[a], c.header.max[a], c.header.scale[a] / 2) << "axis " << a;
    }
    // SOURCE.md: x 636,001.8-637,179.2 ft for autzen_trim; 26,107 ground points (class 2).
    if (feet) {
      EXPECT_EQ(c.header.unit_name, "foot");
      EXPECT_DOUBLE_EQ(c.header.unit_to_metre, 0.3048);
      EXPECT_NEAR(lo.x(), 636001.8, 0.1);
      EXPECT_NEAR(hi.x(), 637179.2, 0.1);
      EXPECT_EQ(std::count(c.classification.begin(), c.classification.end(), 2), 26107);
    } else {
      EXPECT_EQ(c.header.unit_to_metre, 0.0);  // autzen-thin has no VLR
    }
    float imax = 0;
    for (float i : c.intensity) imax = std::max(imax, i);
    EXPECT_EQ(imax, 254.0f);
  }
}

TEST(Las, WritersRoundTrip) {
  io::CloudOut c;
  c.xyz = {{512700.125, 5403547.5, 295.25}, {512834.75, 5403850.0, 404.081}, {512767.0, 5403700.0, 300.0}};
  c.intensity = {0.0f, 70000.0f, 12.4f};
  c.label = {0, 3, 5};
  const std::string las = write("out.las", ""), ply = write("out.ply", "");
  io::write_las(las, c);
  const io::LasCloud r = io::read_las(las);
  EXPECT_EQ(r.header.version_minor, 2);
  EXPECT_EQ(r.header.point_format, 1);
  ASSERT_EQ(r.xyz.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_LT((r.xyz[i] - c.xyz[i]).cwiseAbs().maxCoeff(), 0.0005 + 1e-9);
  EXPECT_EQ(r.intensity[0], 0.0f);
  EXPECT_EQ(r.intensity[1], 65535.0f);  // clamped
  EXPECT_EQ(r.intensity[2], 12.0f);
  for (int a = 0; a < 3; ++a) EXPECT_DOUBLE_EQ(r.header.scale[a], 0.001);
  // The header's bounds are the stored points' (404.081 rounds to 404.081 as stored, not below it).
  for (const auto& p : r.xyz)
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(r.header.min[a], p[a]) << "axis " << a;
      EXPECT_GE(r.header.max[a], p[a]) << "axis " << a;
    }
  io::write_ply(ply, c);
  std::vector<Eigen::Vector3d> xyz;
  std::vector<float> amp;
  io::read_ply(ply, xyz, amp);
  ASSERT_EQ(xyz.size(), 3u);
  EXPECT_EQ(xyz[1], c.xyz[1]);  // doubles: exact
  EXPECT_EQ(amp[2], 12.4f);
  // A cloud wider than a LAS int32 of millimetres is refused, not wrapped.
  c.xyz[0].x() = -3e6;
  c.xyz[1].x() = 3e6;
  EXPECT_THROW(io::write_las(las, c), OutputError);
  // Extensions.
  EXPECT_EQ(io::cloud_format_of("a/b.PLY", "-o"), io::CloudFormat::kPly);
  EXPECT_EQ(io::cloud_format_of("b.las", "-o"), io::CloudFormat::kLas);
  EXPECT_EQ(io::cloud_format_of("b.pcd", "-o"), io::CloudFormat::kPcd);
  EXPECT_THROW(io::cloud_format_of("b.xyz", "-o"), ConfigError);
  EXPECT_THROW(io::cloud_format_of("dir.d/b", "-o"), ConfigError);
}

TEST(Las, FuzzCorpusSeedsReadOrFailCleanly) {
  std::size_t seeds = 0, read = 0;
  for (const auto& e : fs::directory_iterator(std::string(PCDP_SOURCE_DIR) + "/tests/fuzz/corpus/las")) {
    ++seeds;
    try {
      EXPECT_GE(io::read_las(e.path().string()).xyz.size(), 2u) << e.path();
      ++read;
    } catch (const InputError& x) {
      EXPECT_NE(e.path().filename().string().find("truncated"), std::string::npos) << e.path() << ": " << x.what();
    }
  }
  EXPECT_GE(seeds, 7u);
  EXPECT_EQ(read, seeds - 1);
}

TEST(Las, ImportCloudRefusesAViewpointFarFromMostPoints) {
  // The rule: at least half of the points within max_range of the viewpoint. Distances from
  // (1000, 2001, 3): 7.99 m, 6.65 m and 21.7 m.
  const std::string p = write("rule.las", make_las(2, 1, kPts));
  const Eigen::Vector3d vp(1000, 2001, 3);
  io::ImportOptions opt;
  opt.max_range = 12;  // one of three out of reach: accepted
  EXPECT_EQ(io::import_cloud({p}, &vp, opt).passes.at(0).size(), 3u);
  opt.max_range = 7;  // two of three: refused, naming the counts and the rule
  try {
    io::import_cloud({p}, &vp, opt);
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("(--viewpoint) is farther than the maximum range 7.000 m from 2 of the 3 points"), std::string::npos) << m;
    EXPECT_NE(m.find("at least half of the points within --max-range of the viewpoint"), std::string::npos) << m;
    EXPECT_NE(m.find("above the centre, 1004.505,2010.005,10.750), and --max-range of at least 19.000 m"), std::string::npos) << m;
  }
}
