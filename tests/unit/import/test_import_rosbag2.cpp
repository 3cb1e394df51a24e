// import_rosbag2 on small bags written here with the sqlite3 C API (the schema rosbag2's sqlite3
// storage writes): a JointState tilt (one joint of two, radians), Odometry poses, several .db3 files
// named by metadata.yaml, topic choice and its errors.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/import/rosbag2.hpp"
#include "rosbag2_test_bag.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;
using namespace pcdp::io;

namespace {
using test::rosbag2::kT0;
using test::rosbag2::kMs;
using test::rosbag2::Msg;
using test::rosbag2::W;
using test::rosbag2::write_db3;
constexpr double kPi = 3.14159265358979323846;

/// The tilt joint's position (rad) at bag time t: a triangle wave +-0.3 rad, period 2 s.
double tilt_at(long long t) {
  const double s = std::fmod(static_cast<double>(t - kT0) * 1e-9, 2.0);
  return s < 1.0 ? -0.3 + 0.6 * s : 0.3 - 0.6 * (s - 1.0);
}

/// A bag of 4 s in two .db3 files: /scan (10 Hz, 100 beams), /joint_states (25 Hz, joints "wheel"
/// and "tilt"), /odom (20 Hz, x = t m, yaw = 0.1 t rad), /battery (Float32, a second number topic).
/// `increment` is the scans' angle_increment; `intensity`, when not NaN, every beam's intensity.
std::string make_bag(const std::string& dir, float increment = 0.03f, float intensity = NAN) {
  const std::vector<std::pair<std::string, std::string>> topics = {{"/scan", "sensor_msgs/msg/LaserScan"},
                                                                   {"/joint_states", "sensor_msgs/msg/JointState"},
                                                                   {"/odom", "nav_msgs/msg/Odometry"},
                                                                   {"/battery", "std_msgs/msg/Float32"}};
  std::vector<Msg> a, b;
  for (long long t = kT0; t <= kT0 + 4000 * kMs; t += 40 * kMs) {
    W w;
    w.header();
    w.put(2, 4);
    w.str("wheel");
    w.str("tilt");
    w.put(2, 4);
    w.f64(7.0);
    w.f64(tilt_at(t));
    w.put(0, 4);
    w.put(0, 4);
    (t < kT0 + 2000 * kMs ? a : b).push_back({2, t, w.b});
    W v;
    v.f32(12.5f);
    (t < kT0 + 2000 * kMs ? a : b).push_back({4, t, v.b});
  }
  for (long long t = kT0; t <= kT0 + 4000 * kMs; t += 50 * kMs) {
    const double s = static_cast<double>(t - kT0) * 1e-9;
    W w;
    w.header();
    w.str("base_link");
    for (double x : {s, 0.0, 0.0, 0.0, 0.0, std::sin(0.05 * s), std::cos(0.05 * s)}) w.f64(x);
    for (int k = 0; k < 78; ++k) w.f64(0);
    (t < kT0 + 2000 * kMs ? a : b).push_back({3, t, w.b});
  }
  for (long long t = kT0 + 200 * kMs; t < kT0 + 3900 * kMs; t += 100 * kMs) {
    W w;
    w.header();
    for (float f : {-1.5f, 1.5f, increment, 0.001f, 0.1f, 0.1f, 20.0f}) w.f32(f);
    w.put(100, 4);
    for (int k = 0; k < 100; ++k) w.f32(k == 5 ? INFINITY : 2.0f + 0.01f * static_cast<float>(k));
    if (std::isnan(intensity)) {
      w.put(0, 4);  // no intensities
    } else {
      w.put(100, 4);
      for (int k = 0; k < 100; ++k) w.f32(intensity);
    }
    (t < kT0 + 2000 * kMs ? a : b).push_back({1, t, w.b});
  }
  const std::string bag = dir + "/bag";
  fs::create_directories(bag);
  write_db3(bag + "/bag_0.db3", topics, a);
  write_db3(bag + "/bag_1.db3", topics, b);
  test::write_text(bag + "/metadata.yaml",
                   "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n"
                   "  compression_format: \"\"\n  relative_file_paths:\n    - bag_0.db3\n    - bag_1.db3\n");
  return bag;
}
}  // namespace

TEST(ImportRosbag2, JointStateTiltOdometryPosesAndSplitFiles) {
  const std::string bag = make_bag(test::fresh_dir());
  Rosbag2ImportParams p;
  p.tilt_topic = "/joint_states:tilt";
  p.passes.geometry.zero = 0;  // the joint is level at 0; radians are converted to degrees
  const ImportedRosbag2 r = import_rosbag2(bag, p);
  EXPECT_EQ(r.scan_topic, "/scan");
  EXPECT_EQ(r.tilt_topic, "/joint_states:tilt");
  EXPECT_EQ(r.odom_topic, "/odom");
  EXPECT_EQ(r.passes.scans, 37u);
  EXPECT_EQ(r.passes.dropped_scans, 0u);
  EXPECT_EQ(r.passes.beams, 3700u);
  // The tilt reverses at 1, 2 and 3 s: four passes.
  ASSERT_EQ(r.passes.passes.size(), 4u);
  std::size_t lines = 0;
  for (const Pass& pass : r.passes.passes) {
    for (std::size_t l = 0; l < pass.line_count(); ++l, ++lines) {
      const std::size_t last = pass.line_begin[l + 1] - 1;
      // nod = -pitch = -(-1) * (deg - 0): the joint position at the line's last beam, in rad.
      const long long t = r.passes.t0_ns + std::llround(pass.stamp[last] * 1e9);
      EXPECT_NEAR(pass.nod[last], tilt_at(t), 1e-6) << "line " << pass.line[last];
      EXPECT_EQ(pass.range[pass.line_begin[l] + 5], 0.0f);  // inf: no return
      EXPECT_FLOAT_EQ(pass.range[pass.line_begin[l] + 6], 2.06f);
      EXPECT_EQ(pass.amplitude[pass.line_begin[l] + 6], 0.0f);  // no intensities
      EXPECT_NEAR(pass.bearing[pass.line_begin[l] + 60], -1.5 + 60 * static_cast<double>(0.03f), 1e-6);
    }
  }
  EXPECT_EQ(lines, 37u);
  // Odometry: 81 poses on the passes' time axis (t0 = 10 s before the first scan).
  ASSERT_EQ(r.poses.size(), 81u);
  EXPECT_NEAR(r.poses.front().stamp, 10.0 - 0.2, 1e-9);
  EXPECT_NEAR(r.poses[40].position.x(), 2.0, 1e-12);
  EXPECT_NEAR(r.poses[40].orientation.z(), std::sin(0.1), 1e-12);
}

TEST(ImportRosbag2, ScansThatNoPassFileCanHoldAreRefusedNamingTheMessage) {
  Rosbag2ImportParams p;
  p.tilt_topic = "/joint_states:tilt";
  p.passes.geometry.zero = 0;
  const auto error_of = [&](const std::string& bag) {
    try {
      import_rosbag2(bag, p);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  // Every beam at one bearing: a collapsed cloud.
  const std::string zero = error_of(make_bag(test::fresh_dir(), 0.0f));
  EXPECT_NE(zero.find("angle_increment is 0 for 100 ranges"), std::string::npos) << zero;
  EXPECT_NE(zero.find("/scan"), std::string::npos) << zero;
  // A negative intensity: run would refuse the pass file's amplitude, far from the bag.
  const std::string neg = error_of(make_bag(test::fresh_dir(), 0.03f, -5.0f));
  EXPECT_NE(neg.find("intensities[0] = -5"), std::string::npos) << neg;
  EXPECT_NE(neg.find("/scan"), std::string::npos) << neg;
  // The same bag with intensities 7 imports, every amplitude 7 or 0 (no return).
  const ImportedRosbag2 r = import_rosbag2(make_bag(test::fresh_dir(), 0.03f, 7.0f), p);
  ASSERT_FALSE(r.passes.passes.empty());
  for (float a : r.passes.passes[0].amplitude) EXPECT_TRUE(a == 7.0f || a == 0.0f) << a;
}

TEST(ImportRosbag2, TopicChoiceIsExplicitWhenTheBagIsAmbiguous) {
  const std::string bag = make_bag(test::fresh_dir());
  const auto err = [&](Rosbag2ImportParams p) -> std::string {
    try {
      import_rosbag2(bag, p);
    } catch (const ConfigError& e) {
      return std::string("config: ") + e.what();
    } catch (const InputError& e) {
      return std::string("input: ") + e.what();
    }
    return "(no error)";
  };
  Rosbag2ImportParams p;
  // Two tilt candidates: /battery (Float32) and /joint_states.
  EXPECT_NE(err(p).find("config: import rosbag2: " + bag + " has 2 topics of type a std_msgs number or sensor_msgs/msg/JointState (/battery, /joint_states): choose one with --tilt-topic"),
            std::string::npos)
      << err(p);
  // A JointState of two joints needs the joint.
  p.tilt_topic = "/joint_states";
  EXPECT_NE(err(p).find("carries 2 joints: name the tilt joint with --tilt-topic /joint_states:JOINT"), std::string::npos)
      << err(p);
  p.tilt_topic = "/joint_states:nope";
  EXPECT_NE(err(p).find("input: " + bag + ": topic /joint_states:nope has 0 usable message(s)"), std::string::npos) << err(p);
  // The wheel at 7 rad = 401 deg is no tilt.
  p.tilt_topic = "/joint_states:wheel";
  p.passes.geometry.zero = 0;
  EXPECT_NE(err(p).find("gives a nod of 401.07"), std::string::npos) << err(p);
  p.tilt_topic = "/battery:x";
  EXPECT_NE(err(p).find("config: import rosbag2: --tilt-topic /battery:x: a joint name is for sensor_msgs/msg/JointState"),
            std::string::npos)
      << err(p);
  // A .db3 given directly reads that file alone (the second half of the bag).
  Rosbag2ImportParams q;
  q.tilt_topic = "/joint_states:tilt";
  q.passes.geometry.zero = 0;
  q.odom_topic = "/odom";
  const ImportedRosbag2 r = import_rosbag2(bag + "/bag_1.db3", q);
  EXPECT_EQ(r.passes.scans, 19u);
}

namespace {
/// |angle| between two rotations.
double rotation_error(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) { return a.angularDistance(b); }

std::string import_error(const std::string& bag, const Rosbag2ImportParams& p) {
  try {
    import_rosbag2(bag, p);
  } catch (const ConfigError& e) {
    return std::string("config: ") + e.what();
  } catch (const InputError& e) {
    return std::string("input: ") + e.what();
  }
  return "(no error)";
}
}  // namespace

// Poses from tf: the only /tf pair chosen by itself; a chain map -> odom -> base_link (and on to
// the laser through /tf_static) composed at the links' times.
TEST(ImportRosbag2, TfPosesDirectAndComposedAlongTheTree) {
  using namespace test::rosbag2;
  TfBagOptions one;
  one.map_odom = false;
  const std::string bag1 = tf_bag(test::fresh_dir("one"), one);
  const ImportedRosbag2 a = import_rosbag2(bag1, {});
  EXPECT_EQ(a.odom_topic, "");
  EXPECT_EQ(a.tf_frames, "odom:base_link");
  EXPECT_EQ(a.tf_chain, "odom:base_link (/tf)");
  EXPECT_EQ(a.passes.scans, 37u);
  ASSERT_EQ(a.poses.size(), 81u);
  for (std::size_t k = 0; k < a.poses.size(); ++k) {
    const long long t = kT0 + static_cast<long long>(k) * 50 * kMs;
    const double s = static_cast<double>(k) * 0.05;
    const Eigen::Isometry3d T = odom_base(s);
    EXPECT_NEAR(a.poses[k].stamp, static_cast<double>(t - a.passes.t0_ns) * 1e-9, 1e-9);
    EXPECT_NEAR((a.poses[k].position - T.translation()).norm(), 0.0, 1e-12) << k;
    EXPECT_LT(rotation_error(a.poses[k].orientation, Eigen::Quaterniond(T.rotation())), 1e-12) << k;
  }

  const std::string bag2 = tf_bag(test::fresh_dir("chain"));
  Rosbag2ImportParams p;
  p.tf_frames = "map:base_link";
  const ImportedRosbag2 b = import_rosbag2(bag2, p);
  EXPECT_EQ(b.tf_frames, "map:base_link");
  EXPECT_EQ(b.tf_chain, "map:odom (/tf), odom:base_link (/tf)");
  ASSERT_EQ(b.poses.size(), 81u);
  for (std::size_t k = 0; k < b.poses.size(); k += 7) {
    const double s = static_cast<double>(k) * 0.05;
    const Eigen::Isometry3d T = map_odom(s) * odom_base(s);
    EXPECT_NEAR((b.poses[k].position - T.translation()).norm(), 0.0, 1e-9) << k;
    EXPECT_LT(rotation_error(b.poses[k].orientation, Eigen::Quaterniond(T.rotation())), 1e-9) << k;
  }
  // Down to the laser: the static link is applied on the right; a leading '/' is dropped.
  p.tf_frames = "/map:laser";
  const ImportedRosbag2 c = import_rosbag2(bag2, p);
  EXPECT_EQ(c.tf_chain, "map:odom (/tf), odom:base_link (/tf), base_link:laser (/tf_static)");
  ASSERT_EQ(c.poses.size(), 81u);
  const Eigen::Isometry3d T = map_odom(2.0) * odom_base(2.0) * base_laser();
  EXPECT_NEAR((c.poses[40].position - T.translation()).norm(), 0.0, 1e-9);
  EXPECT_LT(rotation_error(c.poses[40].orientation, Eigen::Quaterniond(T.rotation())), 1e-9);
  // A chain of static links only: its constant pose over the passes' span.
  p.tf_frames = "base_link:laser";
  const ImportedRosbag2 d = import_rosbag2(bag2, p);
  ASSERT_EQ(d.poses.size(), 2u);
  EXPECT_NEAR((d.poses[1].position - base_laser().translation()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(d.poses[0].stamp, 10.0, 0.1);  // the first scan (t0 is 10 s before it)
}

TEST(ImportRosbag2, TfFrameChoiceIsExplicitWhenAmbiguous) {
  using namespace test::rosbag2;
  const std::string bag = tf_bag(test::fresh_dir("two"));
  Rosbag2ImportParams p;
  EXPECT_EQ(import_error(bag, p),
            "config: import rosbag2: " + bag + " has 2 transforms on /tf (map:odom, odom:base_link): choose the one "
            "that becomes T_M_V with --tf-frames PARENT:CHILD (a chain such as map:base_link through odom is composed)");
  p.tf_frames = "odom:base_lnk";
  EXPECT_EQ(import_error(bag, p),
            "config: import rosbag2: --tf-frames odom:base_lnk: no chain of transforms from odom down to base_lnk in " +
                bag + " (followed base_lnk, and base_lnk has no parent); tf pairs: map:odom (/tf), "
                "odom:base_link (/tf), base_link:laser (/tf_static)");
  p.tf_frames = "base_link:map";  // upward: not composed (no inverses)
  EXPECT_NE(import_error(bag, p).find("no chain of transforms from base_link down to map"), std::string::npos);
  for (const char* bad : {"odom", "odom:", ":base_link", "a:b:c", "odom:odom"}) {
    p.tf_frames = bad;
    EXPECT_NE(import_error(bag, p).find(std::string("config: import rosbag2: --tf-frames ") + bad + ": expected"),
              std::string::npos)
        << bad << ": " << import_error(bag, p);
  }
  p.tf_frames = "odom:base_link";
  p.odom_topic = "/odom";
  EXPECT_EQ(import_error(bag, p),
            "config: import rosbag2: --odom-topic /odom and --tf-frames odom:base_link: the poses come from one of them");

  // Odometry and tf both present: the option decides.
  TfBagOptions o;
  o.map_odom = false;
  o.odometry = true;
  const std::string both = tf_bag(test::fresh_dir("both"), o);
  EXPECT_EQ(import_error(both, {}),
            "config: import rosbag2: " + both + " has poses from Odometry (/odom) and from tf (/tf: odom:base_link): "
            "choose with --odom-topic /odom or --tf-frames PARENT:CHILD");
  Rosbag2ImportParams q;
  q.odom_topic = "/odom";
  const ImportedRosbag2 r = import_rosbag2(both, q);
  EXPECT_EQ(r.odom_topic, "/odom");
  EXPECT_EQ(r.tf_frames, "");
  EXPECT_EQ(r.poses[40].orientation.w(), 1.0);  // the Odometry's identity, not tf's yaw
  q = {};
  q.tf_frames = "odom:base_link";
  const ImportedRosbag2 s = import_rosbag2(both, q);
  EXPECT_EQ(s.odom_topic, "");
  EXPECT_NEAR(s.poses[40].position.y(), 1.0, 1e-12);  // tf's y = 0.5 s, odometry's 0

  // A bag without tf.
  q.tf_frames = "odom:base_link";
  q.tilt_topic = "/joint_states:tilt";
  const std::string plain = make_bag(test::fresh_dir("plain"));
  EXPECT_EQ(import_error(plain, q), "config: import rosbag2: --tf-frames odom:base_link: " + plain +
                                        " has no topic /tf or /tf_static of type tf2_msgs/msg/TFMessage");
}

TEST(ImportRosbag2, ATruncatedTfMessageNamesTheTopicAndTheByte) {
  using namespace test::rosbag2;
  TfBagOptions o;
  o.truncate = true;
  const std::string bag = tf_bag(test::fresh_dir(), o);
  const std::string e = import_error(bag, {});
  EXPECT_NE(e.find("input: " + bag + "/tfbag_0.db3: topic /tf, message 10 ("), std::string::npos) << e;
  EXPECT_NE(e.find("byte 180: truncated: transforms.transform.rotation.w needs 8 byte(s), 3 left"), std::string::npos) << e;
}
