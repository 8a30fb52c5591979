#include "exodaq/settings/model_file.hpp"

#include <sys/stat.h>
#include <cmath>
#include <cstdio>
#include <exception>
#include <set>
#include <sstream>

#include "exodaq/common/yaml_reader.hpp"

namespace exodaq::settings {

namespace {

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

struct Units {
  double angle = 1.0;   // file unit -> rad
  double length = 1.0;  // file unit -> m
  std::string angle_name;
};

// A pose block: {translation: [x, y, z], rpy: [roll, pitch, yaw]} or
// {translation, rotation: [[r00, r01, r02], [r10, ...], [r20, ...]]}; every key optional.
kinematics::Pose read_pose(MapReader& parent, const std::string& key, const Units& u) {
  MapReader m = parent.map(key);
  kinematics::Pose pose = kinematics::Pose::Identity();
  if (m.has("translation")) {
    const auto t = m.numbers_fixed<3>("translation");
    pose.translation() = Eigen::Vector3d(t[0], t[1], t[2]) * u.length;
  }
  if (m.has("rpy") && m.has("rotation")) {
    m.fail_key("rotation", "give either 'rpy' or 'rotation' in " + m.context() + ", not both");
  }
  if (m.has("rpy")) {
    const auto r = m.numbers_fixed<3>("rpy");
    // Fixed axes x, y, z (roll, pitch, yaw): R = Rz(yaw) Ry(pitch) Rx(roll).
    pose.linear() = (Eigen::AngleAxisd(r[2] * u.angle, Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(r[1] * u.angle, Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(r[0] * u.angle, Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
  } else if (m.has("rotation")) {
    const YAML::Node rows = m.child("rotation");
    if (!rows.IsSequence() || rows.size() != 3) {
      m.fail(rows, "'rotation' must be a list of 3 rows of 3 numbers");
    }
    Eigen::Matrix3d R;
    for (std::size_t i = 0; i < 3; ++i) {
      const auto row = m.to_numbers(rows[i], "rotation[" + std::to_string(i) + "]");
      if (row.size() != 3) {
        m.fail(rows[i], "'rotation[" + std::to_string(i) + "]' must have 3 numbers, has " +
                            std::to_string(row.size()));
      }
      for (std::size_t j = 0; j < 3; ++j)
        R(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = row[j];
    }
    const double orth = (R * R.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (orth > 1e-6 || std::abs(R.determinant() - 1.0) > 1e-6) {
      m.fail(rows, "'rotation' in " + m.context() +
                       " is not a rotation matrix (R R^T must be I and det R = 1 to 1e-6)");
    }
    // Re-orthonormalise the printed digits.
    pose.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  }
  m.finish();
  return pose;
}

kinematics::Convention read_convention(MapReader& top, std::string& name) {
  name = top.choice("convention", {"standard_dh", "modified_dh", "poe"});
  return name == "standard_dh"   ? kinematics::Convention::kStandardDh
         : name == "modified_dh" ? kinematics::Convention::kModifiedDh
                                 : kinematics::Convention::kProductOfExponentials;
}

Units read_units(MapReader& top) {
  Units u;
  u.angle_name = top.choice("angle_unit", {"deg", "rad"});
  u.angle = u.angle_name == "deg" ? kDegToRad : 1.0;
  u.length = top.choice_or("length_unit", {"m", "mm"}, "m") == "mm" ? 1e-3 : 1.0;
  return u;
}

void read_screw(MapReader& j, const Units& u, kinematics::JointDescription& d) {
  MapReader s = j.map("screw");
  const auto w = s.numbers_fixed<3>("omega");
  const auto q = s.numbers_fixed<3>("q");
  const Eigen::Vector3d omega(w[0], w[1], w[2]);
  if (!(omega.norm() > 1e-9)) {
    s.fail_key("omega", "joint '" + d.name + "': screw axis 'omega' has zero length");
  }
  d.screw.omega = omega.normalized();
  d.screw.q = Eigen::Vector3d(q[0], q[1], q[2]) * u.length;
  s.finish();
  d.dh.theta_offset = j.number_or("offset", 0.0) * u.angle;
}

void read_dh(MapReader& j, const Units& u, kinematics::JointDescription& d) {
  MapReader h = j.map("dh");
  d.dh.a = h.number("a") * u.length;
  d.dh.alpha = h.number("alpha") * u.angle;
  d.dh.d = h.number("d") * u.length;
  d.dh.theta_offset = h.number_or("theta_offset", 0.0) * u.angle;
  h.finish();
}

kinematics::JointDescription read_joint(MapReader& j, const Units& u, bool poe,
                                        std::set<std::string>& names) {
  kinematics::JointDescription d;
  d.name = j.string("name");
  if (d.name.empty()) j.fail_key("name", "joint name in " + j.context() + " is empty");
  if (!names.insert(d.name).second) j.fail_key("name", "duplicate joint name '" + d.name + "'");
  const auto lim = j.numbers_fixed<2>("limits");
  if (!(lim[0] < lim[1])) {
    j.fail_key("limits", "joint '" + d.name + "' limits reversed: lower " + fmt(lim[0]) +
                             " must be below upper " + fmt(lim[1]));
  }
  d.limits.lower = lim[0] * u.angle;
  d.limits.upper = lim[1] * u.angle;
  if (poe) {
    read_screw(j, u, d);
  } else {
    read_dh(j, u, d);
  }
  j.finish();
  return d;
}

struct Joints {
  std::vector<kinematics::JointDescription> list;
  std::vector<int> lines;  // where each joint is written
  YAML::Node node;
};

Joints read_joints(MapReader& top, const Units& u, bool poe) {
  Joints out;
  out.node = top.child("joints");
  const YAML::Node& jnode = out.node;
  if (!jnode.IsSequence()) top.fail(jnode, "'joints' must be a list of joints");
  if (jnode.size() == 0) top.fail(jnode, "'joints' is empty: a model needs at least one joint");
  if (jnode.size() > static_cast<std::size_t>(kinematics::kMaxJoints)) {
    top.fail(jnode, "'joints' has " + std::to_string(jnode.size()) + " joints, at most " +
                        std::to_string(kinematics::kMaxJoints) + " are supported");
  }
  std::set<std::string> names;
  for (std::size_t i = 0; i < jnode.size(); ++i) {
    MapReader j(top.file(), jnode[i], "joints[" + std::to_string(i) + "]");
    out.list.push_back(read_joint(j, u, poe, names));
    out.lines.push_back(line_of(jnode[i]));
  }
  return out;
}

// Standard and modified DH take a 'tool' (frame n to palm); PoE takes the
// palm pose at q = 0 as 'home_pose'.
kinematics::Pose read_tool(MapReader& top, const Units& u, bool poe,
                           const std::string& convention) {
  if (poe) {
    if (top.has("tool")) {
      top.fail_key("tool",
                   "'tool' is not used with convention poe: give the palm pose at q = 0 "
                   "as 'home_pose'");
    }
    return read_pose(top, "home_pose", u);
  }
  if (top.has("home_pose")) {
    top.fail_key("home_pose",
                 "'home_pose' is only used with convention poe: give 'tool' "
                 "(frame n to palm) for " +
                     convention);
  }
  return top.has("tool") ? read_pose(top, "tool", u) : kinematics::Pose::Identity();
}

kinematics::JointVector read_home_posture(MapReader& top, const Units& u, const Joints& joints) {
  const int n = static_cast<int>(joints.list.size());
  kinematics::JointVector home = kinematics::JointVector::Zero(n);
  if (top.has("home_posture")) {
    const YAML::Node hp = top.child("home_posture");
    const auto v = top.to_numbers(hp, "home_posture");
    if (static_cast<int>(v.size()) != n) {
      top.fail(hp, "'home_posture' must have " + std::to_string(n) +
                       " numbers (one per joint), has " + std::to_string(v.size()));
    }
    for (int i = 0; i < n; ++i) home[i] = v[static_cast<std::size_t>(i)] * u.angle;
  }
  for (int i = 0; i < n; ++i) {
    const auto idx = static_cast<std::size_t>(i);
    const auto& lim = joints.list[idx].limits;
    if (home[i] >= lim.lower && home[i] <= lim.upper) continue;
    const double k = 1.0 / u.angle;
    const std::string what = "home posture of joint '" + joints.list[idx].name + "' (" +
                             fmt(home[i] * k) + " " + u.angle_name + ") is outside its limits [" +
                             fmt(lim.lower * k) + ", " + fmt(lim.upper * k) + "]";
    if (top.has("home_posture")) top.fail(top.node()["home_posture"][i], what);
    throw ConfigError(top.file(), joints.lines[idx], what);
  }
  return home;
}

kinematics::RigKinematicsConfig read_rig(MapReader& top, int n) {
  kinematics::RigKinematicsConfig rig;
  rig.elbow_frame = static_cast<int>(top.integer_or("elbow_frame", n < 4 ? n : 4));
  if (rig.elbow_frame < 0 || rig.elbow_frame > n + 1) {
    top.fail_key("elbow_frame", "'elbow_frame' must be a frame 0.." + std::to_string(n + 1) +
                                    " (0 = base, " + std::to_string(n + 1) + " = palm), found " +
                                    std::to_string(rig.elbow_frame));
  }
  rig.shoulder_joints = static_cast<int>(top.integer_or("shoulder_joints", n < 4 ? n : 4));
  if (rig.shoulder_joints < 1 || rig.shoulder_joints > n) {
    top.fail_key("shoulder_joints", "'shoulder_joints' must be 1.." + std::to_string(n) +
                                        ", found " + std::to_string(rig.shoulder_joints));
  }
  const double k = rig.shoulder_joints;
  rig.shoulder_manipulability_max =
      top.number_or("shoulder_manipulability_max", k >= 3.0 ? std::pow(k / 3.0, 1.5) : 1.0);
  if (!(rig.shoulder_manipulability_max > 0.0)) {
    top.fail_key("shoulder_manipulability_max", "'shoulder_manipulability_max' must be positive");
  }
  rig.singularity_threshold = top.number_or("singularity_threshold", rig.singularity_threshold);
  if (rig.singularity_threshold < 0.0 || rig.singularity_threshold > 1.0) {
    top.fail_key("singularity_threshold",
                 "'singularity_threshold' must be in [0, 1] (it applies to the normalised value)");
  }
  return rig;
}

KinematicModel read_model(const YAML::Node& root, const std::string& file) {
  MapReader top(file, root, "model");
  KinematicModel model;
  model.file = file;
  model.name = top.string("name");
  model.description = top.string_or("description", "");
  std::string conv;
  const kinematics::Convention convention = read_convention(top, conv);
  const bool poe = convention == kinematics::Convention::kProductOfExponentials;
  const Units u = read_units(top);
  Joints joints = read_joints(top, u, poe);

  top.allow("base");
  top.allow(poe ? "home_pose" : "tool");
  const kinematics::Pose base =
      top.has("base") ? read_pose(top, "base", u) : kinematics::Pose::Identity();
  const kinematics::Pose tool = read_tool(top, u, poe, conv);
  model.home_posture = read_home_posture(top, u, joints);
  model.rig = read_rig(top, static_cast<int>(joints.list.size()));
  top.finish();

  try {
    model.chain = kinematics::Chain(convention, std::move(joints.list), base, tool);
  } catch (const std::exception& e) {
    throw ConfigError(file, line_of(joints.node), e.what());
  }
  return model;
}

// yaml-cpp may throw from any accessor on malformed input; nothing escapes but
// ConfigError.
template <typename F>
KinematicModel guarded(const std::string& file, F&& f) {
  try {
    return f();
  } catch (const ConfigError&) {
    throw;
  } catch (const YAML::Exception& e) {
    throw ConfigError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0, "YAML: " + e.msg);
  } catch (const std::exception& e) {
    throw ConfigError(file, 0, e.what());
  }
}

}  // namespace

KinematicModel load_model_file(const std::string& path) {
  return guarded(path, [&] { return read_model(load_yaml_file(path), path); });
}

KinematicModel load_model_text(const std::string& text, const std::string& name) {
  return guarded(name, [&] { return read_model(load_yaml_text(text, name), name); });
}

std::string default_model_path() {
  std::string installed = "/etc/exodaq/models/macaque_exo.yaml";
#ifdef EXODAQ_SOURCE_DIR
  std::string source = std::string(EXODAQ_SOURCE_DIR) + "/config/models/macaque_exo.yaml";
  struct stat st {};
  if (::stat(source.c_str(), &st) == 0) return source;
#endif
  return installed;
}

}  // namespace exodaq::settings
