#include "pcdp/import/rosbag2.hpp"

#include <sqlite3.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>

#include "import/rosbag2_db.hpp"
#include "io/cdr.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp::io {

namespace {
namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;
const char* const kLaserScan = "sensor_msgs/msg/LaserScan";
const char* const kJointState = "sensor_msgs/msg/JointState";
const char* const kOdometry = "nav_msgs/msg/Odometry";
const char* const kTFMessage = "tf2_msgs/msg/TFMessage";
const char* const kTf = "/tf";
const char* const kTfStatic = "/tf_static";

using namespace bag;

/// A pose a bag may hold: finite, with a quaternion of unit length (to 1e-3).
bool valid_pose(const Eigen::Vector3d& pos, const Eigen::Quaterniond& q) {
  return pos.allFinite() && q.coeffs().allFinite() && std::fabs(q.norm() - 1.0) <= 1e-3;
}

/// A tf frame name without a leading '/' (tf2 of ROS 2 refuses it; older bags have it).
std::string frame_name(const std::string& f) { return !f.empty() && f[0] == '/' ? f.substr(1) : f; }

/// One tf link: the transform of `child` in `parent` as published on `topic` (/tf or /tf_static).
struct TfLink {
  std::string parent, child, topic;
  std::size_t transforms = 0;         ///< how many the bag holds
  std::vector<PoseSample> samples;    ///< /tf: when collected, strictly increasing stamps; /tf_static: the last one
  std::string name() const { return parent + ":" + child; }
  std::string label() const { return name() + " (" + topic + ")"; }
};
using TfLinks = std::map<std::string, TfLink>;  ///< by topic + " " + PARENT:CHILD

std::string tf_list(const TfLinks& links) {
  std::string s;
  for (const auto& [key, l] : links) s += (s.empty() ? "" : ", ") + l.label();
  return s.empty() ? "none" : s;
}

/// Reads every TFMessage of `topic` (each strictly decoded and every transform checked) into
/// `links`; the samples of the links in `wanted` are kept, on the time axis of `t0_ns` (/tf_static:
/// every link's last transform).
void read_tf(std::vector<std::unique_ptr<Db>>& dbs, const std::vector<std::map<long long, Topic>>& topics,
             const std::string& topic, long long t0_ns, const std::set<std::string>& wanted, TfLinks& links) {
  const bool is_static = topic == kTfStatic;
  std::size_t index = 0;
  for (std::size_t f = 0; f < dbs.size(); ++f)
    for_each_message(*dbs[f], topics[f], topic, index, [&](const MsgRef& ref, const std::uint8_t* d, std::size_t n) {
      const cdr::TFMessage m = cdr::decode_tf_message(d, n);
      for (std::size_t k = 0; k < m.transforms.size(); ++k) {
        const cdr::TransformStamped& t = m.transforms[k];
        const std::string parent = frame_name(t.header.frame_id), child = frame_name(t.child_frame_id);
        const std::string at = ref.where() + ": transforms[" + std::to_string(k) + "]";
        if (parent.empty() || child.empty() || parent == child)
          throw InputError(at + ": frame_id '" + t.header.frame_id + "' and child_frame_id '" + t.child_frame_id +
                           "' must be two non-empty frame names");
        const Eigen::Vector3d pos(t.tx, t.ty, t.tz);
        const Eigen::Quaterniond q(t.qw, t.qx, t.qy, t.qz);
        if (!valid_pose(pos, q))
          throw InputError(at + " (" + parent + ":" + child +
                           "): the translation is not finite or the rotation is not a unit quaternion");
        TfLink& l = links[topic + " " + parent + ":" + child];
        l.parent = parent, l.child = child, l.topic = topic;
        ++l.transforms;
        if (!is_static && !wanted.count(l.name())) continue;
        PoseSample s;
        s.stamp = is_static ? 0.0 : static_cast<double>(ref.t_ns - t0_ns) * 1e-9;
        s.position = pos;
        s.orientation = q.normalized();
        if (is_static) {
          l.samples.assign(1, s);
        } else if (l.samples.empty() || s.stamp > l.samples.back().stamp) {  // same bag time: keep the first
          l.samples.push_back(s);
        }
      }
    });
}

/// The links from `parent` down to `child` along the tf tree (parent first).
std::vector<const TfLink*> tf_chain(const TfLinks& links, const std::string& frames, const std::string& parent,
                                    const std::string& child, const std::string& bag) {
  std::map<std::string, std::vector<const TfLink*>> up;  // child frame -> its links
  for (const auto& [key, l] : links) up[l.child].push_back(&l);
  std::vector<const TfLink*> chain;
  std::string cur = child, path = child;
  const std::string pre = "import rosbag2: --tf-frames " + frames + ": ";
  while (cur != parent) {
    const auto it = up.find(cur);
    if (it == up.end())
      throw ConfigError(pre + "no chain of transforms from " + parent + " down to " + child + " in " + bag +
                        " (followed " + path + ", and " + cur + " has no parent); tf pairs: " + tf_list(links));
    if (it->second.size() > 1) {
      std::string ps;
      for (const TfLink* l : it->second) ps += (ps.empty() ? "" : ", ") + l->label();
      throw ConfigError(pre + "frame " + cur + " has " + std::to_string(it->second.size()) + " transforms to it (" + ps +
                        "): not a tree, the chain is ambiguous");
    }
    chain.push_back(it->second[0]);
    cur = it->second[0]->parent;
    path += " <- " + cur;
    if (chain.size() > links.size()) throw ConfigError(pre + "the tf frames form a cycle (" + path + ")");
  }
  std::reverse(chain.begin(), chain.end());
  return chain;
}

Eigen::Isometry3d isometry(const PoseSample& s) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = s.orientation.toRotationMatrix();
  T.translation() = s.position;
  return T;
}

/// T_PARENT_CHILD along `chain`: at the union of the /tf links' times where they all overlap,
/// each /tf link interpolated (PoseTrack), /tf_static links constant; a chain of static links
/// alone gives its constant pose at `first` and `last`.
std::vector<PoseSample> compose_tf(const std::vector<const TfLink*>& chain, double first, double last,
                                   const std::string& bag) {
  std::vector<const TfLink*> dyn;
  for (const TfLink* l : chain) {
    if (l->topic == kTf) dyn.push_back(l);
    if (l->topic == kTf && l->samples.size() < 2)
      throw InputError(bag + ": the tf link " + l->label() + " has " + std::to_string(l->samples.size()) +
                       " transform(s) at distinct bag times; a pose track needs at least two");
  }
  if (chain.size() == 1 && !dyn.empty()) return chain[0]->samples;
  std::vector<double> times;
  if (dyn.empty()) {
    times = {first, last > first ? last : first + 1.0};
  } else {
    double lo = dyn[0]->samples.front().stamp, hi = dyn[0]->samples.back().stamp;
    for (const TfLink* l : dyn) lo = std::max(lo, l->samples.front().stamp), hi = std::min(hi, l->samples.back().stamp);
    if (!(lo < hi)) {
      std::string ls;
      for (const TfLink* l : dyn) ls += (ls.empty() ? "" : ", ") + l->label();
      throw InputError(bag + ": the tf links " + ls + " do not overlap in time: nothing to compose");
    }
    for (const TfLink* l : dyn)
      for (const PoseSample& s : l->samples)
        if (s.stamp >= lo && s.stamp <= hi) times.push_back(s.stamp);
    std::sort(times.begin(), times.end());
    times.erase(std::unique(times.begin(), times.end()), times.end());
  }
  std::vector<PoseTrack> tracks;
  for (const TfLink* l : chain) tracks.emplace_back(l->topic == kTf ? l->samples : std::vector<PoseSample>{});
  std::vector<std::size_t> hints(chain.size(), 0);
  std::vector<PoseSample> out;
  out.reserve(times.size());
  for (const double t : times) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (std::size_t k = 0; k < chain.size(); ++k)
      T = T * (chain[k]->topic == kTf ? tracks[k].at(t, hints[k]) : isometry(chain[k]->samples.at(0)));
    PoseSample s;
    s.stamp = t;
    s.position = T.translation();
    s.orientation = Eigen::Quaterniond(T.rotation()).normalized();
    out.push_back(s);
  }
  return out;
}

/// `wanted` (or the only topic of a type that `ok` accepts when wanted is empty).
std::string pick_topic(const std::map<std::string, Topic>& all, const std::string& wanted, const char* option,
                       const std::string& kind, bool (*ok)(const std::string&), bool optional, const std::string& bag) {
  std::string list;
  for (const auto& [name, t] : all) list += (list.empty() ? "" : ", ") + name + " (" + t.type + ")";
  if (!wanted.empty()) {
    const auto it = all.find(wanted);
    if (it == all.end())
      throw ConfigError(std::string("import rosbag2: ") + option + " " + wanted + ": no such topic in " + bag +
                        "; topics: " + list);
    if (!ok(it->second.type))
      throw ConfigError(std::string("import rosbag2: ") + option + " " + wanted + " has type " + it->second.type +
                        ", expected " + kind);
    return wanted;
  }
  std::vector<std::string> cands;
  for (const auto& [name, t] : all)
    if (ok(t.type)) cands.push_back(name);
  if (cands.size() == 1) return cands[0];
  if (cands.empty() && optional) return {};
  std::string names;
  for (const auto& c : cands) names += (names.empty() ? "" : ", ") + c;
  if (cands.empty())
    throw InputError(bag + ": no topic of type " + kind + "; topics: " + list);
  throw ConfigError(std::string("import rosbag2: ") + bag + " has " + std::to_string(cands.size()) + " topics of type " +
                    kind + " (" + names + "): choose one with " + option);
}
}  // namespace

ImportedRosbag2 import_rosbag2(const std::string& path, const Rosbag2ImportParams& p) {
  p.passes.geometry.check("import rosbag2");
  const std::vector<std::string> files = bag_files(path);
  std::vector<std::unique_ptr<Db>> dbs;
  std::vector<std::map<long long, Topic>> topics;
  std::map<std::string, Topic> all;  // by name
  for (const auto& f : files) {
    dbs.push_back(std::make_unique<Db>(f));
    topics.push_back(read_topics(*dbs.back()));
    for (const auto& [id, t] : topics.back()) {
      const auto [it, added] = all.emplace(t.name, t);
      if (!added && it->second.type != t.type)
        throw InputError(f + ": topic " + t.name + " has type " + t.type + " here and " + it->second.type + " in another file");
    }
  }

  ImportedRosbag2 out;
  std::string tilt_topic = p.tilt_topic, joint;
  if (const auto colon = tilt_topic.find(':'); colon != std::string::npos) {
    joint = tilt_topic.substr(colon + 1);
    tilt_topic.resize(colon);
    if (joint.empty()) throw ConfigError("import rosbag2: --tilt-topic " + p.tilt_topic + ": empty joint name after ':'");
  }
  out.scan_topic = pick_topic(all, p.scan_topic, "--scan-topic", kLaserScan,
                              [](const std::string& t) { return t == kLaserScan; }, false, path);
  out.tilt_topic = pick_topic(all, tilt_topic, "--tilt-topic", std::string("a std_msgs number or ") + kJointState,
                              [](const std::string& t) { return cdr::is_number_type(t) || t == kJointState; }, false, path);
  // Poses: from odometry or from tf (the rule is in import_rosbag2.hpp).
  if (!p.tf_frames.empty() && !p.odom_topic.empty())
    throw ConfigError("import rosbag2: --odom-topic " + p.odom_topic + " and --tf-frames " + p.tf_frames +
                      ": the poses come from one of them");
  std::vector<std::string> tf_topics;
  for (const char* t : {kTf, kTfStatic})
    if (all.count(t) && all.at(t).type == kTFMessage) {
      if (all.at(t).format != "cdr")
        throw InputError(path + ": topic " + std::string(t) + " has serialization_format '" + all.at(t).format +
                         "', only cdr is read");
      tf_topics.push_back(t);
    }
  TfLinks links;
  for (const std::string& t : tf_topics) read_tf(dbs, topics, t, 0, {}, links);
  std::string tf_parent, tf_child;
  if (!p.tf_frames.empty()) {
    const auto colon = p.tf_frames.find(':');
    if (colon == std::string::npos || p.tf_frames.find(':', colon + 1) != std::string::npos)
      throw ConfigError("import rosbag2: --tf-frames " + p.tf_frames + ": expected PARENT:CHILD, e.g. odom:base_link");
    tf_parent = frame_name(p.tf_frames.substr(0, colon));
    tf_child = frame_name(p.tf_frames.substr(colon + 1));
    if (tf_parent.empty() || tf_child.empty() || tf_parent == tf_child)
      throw ConfigError("import rosbag2: --tf-frames " + p.tf_frames + ": expected two different frame names PARENT:CHILD");
    if (tf_topics.empty())
      throw ConfigError("import rosbag2: --tf-frames " + p.tf_frames + ": " + path + " has no topic " + kTf + " or " +
                        kTfStatic + " of type " + kTFMessage);
  } else {
    out.odom_topic = pick_topic(all, p.odom_topic, "--odom-topic", kOdometry,
                                [](const std::string& t) { return t == kOdometry; }, true, path);
    std::vector<const TfLink*> dyn;
    for (const auto& [key, l] : links)
      if (l.topic == kTf) dyn.push_back(&l);
    std::string dyn_list;
    for (const TfLink* l : dyn) dyn_list += (dyn_list.empty() ? "" : ", ") + l->name();
    if (!out.odom_topic.empty()) {
      if (p.odom_topic.empty() && !dyn.empty())
        throw ConfigError("import rosbag2: " + path + " has poses from Odometry (" + out.odom_topic + ") and from tf (" +
                          kTf + ": " + dyn_list + "): choose with --odom-topic " + out.odom_topic +
                          " or --tf-frames PARENT:CHILD");
    } else if (dyn.size() == 1) {
      tf_parent = dyn[0]->parent;
      tf_child = dyn[0]->child;
    } else if (dyn.size() > 1) {
      throw ConfigError("import rosbag2: " + path + " has " + std::to_string(dyn.size()) + " transforms on " + kTf +
                        " (" + dyn_list + "): choose the one that becomes T_M_V with --tf-frames PARENT:CHILD "
                        "(a chain such as map:base_link through odom is composed)");
    }
  }
  std::vector<const TfLink*> chain;
  if (!tf_parent.empty()) {
    out.tf_frames = tf_parent + ":" + tf_child;
    chain = tf_chain(links, p.tf_frames.empty() ? out.tf_frames : p.tf_frames, tf_parent, tf_child, path);
    for (const TfLink* l : chain) out.tf_chain += (out.tf_chain.empty() ? "" : ", ") + l->label();
  }
  out.tilt_type = all.at(out.tilt_topic).type;
  if (!joint.empty() && out.tilt_type != kJointState)
    throw ConfigError("import rosbag2: --tilt-topic " + p.tilt_topic + ": a joint name is for " + kJointState +
                      " topics; " + out.tilt_topic + " is " + out.tilt_type);
  for (const std::string* t : {&out.scan_topic, &out.tilt_topic, &out.odom_topic})
    if (!t->empty() && all.at(*t).format != "cdr")
      throw InputError(path + ": topic " + *t + " has serialization_format '" + all.at(*t).format + "', only cdr is read");

  // Scans.
  std::vector<TiltScan> scans;
  std::size_t index = 0;
  for (std::size_t f = 0; f < dbs.size(); ++f)
    for_each_message(*dbs[f], topics[f], out.scan_topic, index, [&](const MsgRef& ref, const std::uint8_t* d, std::size_t n) {
      const cdr::LaserScan m = cdr::decode_laser_scan(d, n);
      // (An empty scan may carry angle_increment inf: 2 pi / 0 beams.)
      if (!m.ranges.empty() && (!std::isfinite(m.angle_min) || !std::isfinite(m.angle_increment)))
        throw InputError(ref.where() + ": angle_min or angle_increment is not finite");
      if (m.ranges.size() > 1 && m.angle_increment == 0.0f)
        throw InputError(ref.where() + ": angle_increment is 0 for " + std::to_string(m.ranges.size()) +
                         " ranges: every beam would have one bearing");
      if (!m.intensities.empty() && m.intensities.size() != m.ranges.size())
        throw InputError(ref.where() + ": " + std::to_string(m.intensities.size()) + " intensities for " +
                         std::to_string(m.ranges.size()) + " ranges (must be 0 or as many)");
      TiltScan s;
      s.t_ns = ref.t_ns;
      s.line = static_cast<std::uint32_t>(ref.index);
      s.scan_time = m.scan_time;
      // Drivers that leave scan_time 0 but give time_increment: the sweep is n beams long.
      if (s.scan_time == 0.0 && m.time_increment > 0.0f)
        s.scan_time = static_cast<double>(m.time_increment) * static_cast<double>(m.ranges.size());
      if (!m.ranges.empty() && !(s.scan_time > 0.0 && s.scan_time < 10.0))
        throw InputError(ref.where() + ": scan_time " + std::to_string(m.scan_time) + " s (time_increment " +
                         std::to_string(m.time_increment) + " s) gives no sweep duration within (0, 10) s");
      s.range.reserve(m.ranges.size());
      for (std::size_t k = 0; k < m.ranges.size(); ++k) {
        const float r = m.ranges[k];
        if (r < 0.0f)
          throw InputError(ref.where() + ": ranges[" + std::to_string(k) + "] = " + std::to_string(r) + " is negative");
        s.range.push_back(std::isfinite(r) ? r : 0.0f);  // inf / NaN: no return
        s.angle.push_back(static_cast<double>(m.angle_min) +
                          static_cast<double>(k) * static_cast<double>(m.angle_increment));
        const float q = m.intensities.empty() ? 0.0f : m.intensities[k];
        if (std::isfinite(q) && q < 0.0f)  // non-finite intensities read as 0, as before
          throw InputError(ref.where() + ": intensities[" + std::to_string(k) + "] = " + std::to_string(q) +
                           " is negative (an intensity is a received power)");
        s.intensity.push_back(std::isfinite(q) ? q : 0.0f);
      }
      scans.push_back(std::move(s));
    });
  std::stable_sort(scans.begin(), scans.end(), [](const TiltScan& a, const TiltScan& b) { return a.t_ns < b.t_ns; });

  // Tilt readings.
  std::vector<TiltSample> tilt;
  index = 0;
  const bool joints = out.tilt_type == kJointState;
  for (std::size_t f = 0; f < dbs.size(); ++f)
    for_each_message(*dbs[f], topics[f], out.tilt_topic, index, [&](const MsgRef& ref, const std::uint8_t* d, std::size_t n) {
      double v = 0;
      if (joints) {
        const cdr::JointState m = cdr::decode_joint_state(d, n);
        if (joint.empty()) {
          if (m.name.size() != 1)
            throw ConfigError("import rosbag2: " + ref.where() + " carries " + std::to_string(m.name.size()) +
                              " joints: name the tilt joint with --tilt-topic " + out.tilt_topic + ":JOINT");
          joint = m.name[0];
        }
        const auto it = std::find(m.name.begin(), m.name.end(), joint);
        if (it == m.name.end()) return;  // another publisher's joints
        const std::size_t k = static_cast<std::size_t>(it - m.name.begin());
        if (m.position.size() != m.name.size())
          throw InputError(ref.where() + ": " + std::to_string(m.position.size()) + " positions for " +
                           std::to_string(m.name.size()) + " names");
        v = m.position[k] * 180.0 / kPi;  // REP 103: radians
      } else {
        v = cdr::decode_number(out.tilt_type, d, n);
      }
      const double nod = p.passes.geometry.nod_rad(v);
      if (!std::isfinite(nod) || std::fabs(nod) > kPi / 2)
        throw InputError(ref.where() + ": the tilt reading " + std::to_string(v) + " gives a nod of " +
                         std::to_string(nod * 180.0 / kPi) +
                         " deg, outside -90 .. 90 (check --tilt-zero, --tilt-scale and the topic)");
      tilt.push_back({ref.t_ns, v});
    });
  out.tilt_messages = tilt.size();
  if (joints) out.tilt_topic += ":" + joint;
  std::stable_sort(tilt.begin(), tilt.end(), [](const TiltSample& a, const TiltSample& b) { return a.t_ns < b.t_ns; });
  if (scans.empty()) throw InputError(path + ": topic " + out.scan_topic + " has no message");
  if (tilt.size() < 2)
    throw InputError(path + ": topic " + out.tilt_topic + " has " + std::to_string(tilt.size()) +
                     " usable message(s); at least two are needed to interpolate the tilt");

  out.passes = build_tilt_passes(scans, tilt, p.passes, path);

  // Poses from odometry, on the passes' time axis.
  if (!out.odom_topic.empty()) {
    index = 0;
    for (std::size_t f = 0; f < dbs.size(); ++f)
      for_each_message(*dbs[f], topics[f], out.odom_topic, index, [&](const MsgRef& ref, const std::uint8_t* d, std::size_t n) {
        const cdr::Odometry m = cdr::decode_odometry(d, n);
        const Eigen::Vector3d pos(m.px, m.py, m.pz);
        const Eigen::Quaterniond q(m.qw, m.qx, m.qy, m.qz);
        if (!valid_pose(pos, q))
          throw InputError(ref.where() + ": the pose is not finite or its quaternion is not of unit length");
        PoseSample s;
        s.stamp = static_cast<double>(ref.t_ns - out.passes.t0_ns) * 1e-9;
        s.position = pos;
        s.orientation = q.normalized();
        if (!out.poses.empty() && s.stamp <= out.poses.back().stamp) return;  // same bag time: keep the first
        out.poses.push_back(s);
      });
    if (out.poses.size() < 2)
      throw InputError(path + ": topic " + out.odom_topic + " has " + std::to_string(out.poses.size()) +
                       " message(s); a pose track needs at least two");
  }

  // Poses from tf: the chain's /tf links collected on the passes' time axis, then composed.
  if (!chain.empty()) {
    std::set<std::string> wanted;
    for (const TfLink* l : chain) wanted.insert(l->name());
    if (std::find(tf_topics.begin(), tf_topics.end(), kTf) != tf_topics.end())
      read_tf(dbs, topics, kTf, out.passes.t0_ns, wanted, links);
    double first = 0, last = 0;
    bool any = false;
    for (const Pass& pass : out.passes.passes)
      for (const double st : pass.stamp) {
        first = any ? std::min(first, st) : st;
        last = any ? std::max(last, st) : st;
        any = true;
      }
    out.poses = compose_tf(chain, first, last, path);
  }
  return out;
}

}  // namespace pcdp::io
