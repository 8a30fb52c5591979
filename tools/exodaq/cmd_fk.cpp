// exodaq fk: forward kinematics of a model file at one joint vector.
//   exodaq fk [--model FILE] (--joints-deg a,b,... | --joints-rad a,b,...) [--json]
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"
#include "exodaq/settings/model_file.hpp"
#include "json_out.hpp"

namespace exodaq::tools {
namespace {

struct FkOptions {
  std::string model;
  std::vector<double> deg;
  std::vector<double> rad;
  bool json = false;
};

// The joint values given on the command line, in radians; nullopt (after an
// error message) when their number or a value is wrong.
std::optional<kinematics::JointVector> given_joints(const FkOptions& o,
                                                    const settings::KinematicModel& model) {
  const bool in_deg = !o.deg.empty();
  const std::vector<double>& given = in_deg ? o.deg : o.rad;
  const int n = model.chain.joint_count();
  if (static_cast<int>(given.size()) != n) {
    print_error("model '" + model.name + "' has " + std::to_string(n) + " joints, " +
                std::to_string(given.size()) + " joint values given");
    return std::nullopt;
  }
  kinematics::JointVector q(n);
  for (int i = 0; i < n; ++i) {
    const double v = given[static_cast<std::size_t>(i)];
    if (!std::isfinite(v)) {
      print_error("joint " + std::to_string(i + 1) + " value is not a finite number");
      return std::nullopt;
    }
    q[i] = in_deg ? v * exodaq::kDegToRad : v;
  }
  return q;
}

// What `fk` computed, for either output form.
struct FkResult {
  const settings::KinematicModel& model;
  std::string path;
  kinematics::JointVector q;
  kinematics::RigPose pose;
  std::vector<std::string> outside;  // joints outside their limits (computed anyway)
};

void print_json(const FkResult& r) {
  std::vector<std::string> names;
  for (const auto& j : r.model.chain.joints()) names.push_back(j.name);
  const auto& pose = r.pose;
  const auto& R = pose.palm_rotation;
  const std::string rotation = "[" + json_array(Eigen::Vector3d(R.row(0).transpose())) + ", " +
                               json_array(Eigen::Vector3d(R.row(1).transpose())) + ", " +
                               json_array(Eigen::Vector3d(R.row(2).transpose())) + "]";
  JsonObject j;
  j.add("model", json_string(r.model.name))
      .add("model_file", json_string(r.path))
      .add("joint_names", json_strings(names))
      .add("joints_rad", json_array(r.q))
      .add("palm_position_m", json_array(pose.palm_position))
      .add("palm_rotation", rotation)
      .add("palm_quaternion_wxyz", json_array(pose.palm_quaternion_wxyz))
      .add("elbow_frame", std::to_string(r.model.rig.elbow_frame))
      .add("elbow_position_m", json_array(pose.elbow_position))
      .add("shoulder_manipulability", json_measure(pose.shoulder_manipulability))
      .add("shoulder_manipulability_normalised",
           json_measure(pose.shoulder_manipulability_normalised))
      .add("near_singular", json_bool(pose.near_singular))
      .add("joints_outside_limits", json_strings(r.outside));
  std::printf("%s\n", j.text().c_str());
}

void print_text(const FkResult& r) {
  // Print -0.000000 as 0.000000.
  auto z = [](double v) { return std::abs(v) < 5e-13 ? 0.0 : v; };
  const auto& pose = r.pose;
  std::printf("model: %s (%s)\n", r.model.name.c_str(), r.path.c_str());
  std::printf("joints (deg):");
  for (int i = 0; i < r.q.size(); ++i) std::printf(" %.4f", z(r.q[i] / exodaq::kDegToRad));
  std::printf("\n");
  const auto& p = pose.palm_position;
  std::printf("palm position (m):            %10.6f %10.6f %10.6f\n", z(p.x()), z(p.y()), z(p.z()));
  std::printf("palm rotation:");
  for (int row = 0; row < 3; ++row) {
    std::printf("%s%10.6f %10.6f %10.6f\n",
                row ? "                              " : "                ",
                z(pose.palm_rotation(row, 0)), z(pose.palm_rotation(row, 1)),
                z(pose.palm_rotation(row, 2)));
  }
  const auto& qw = pose.palm_quaternion_wxyz;
  std::printf("palm quaternion (w, x, y, z): %10.6f %10.6f %10.6f %10.6f\n", z(qw[0]), z(qw[1]),
              z(qw[2]), z(qw[3]));
  const auto& e = pose.elbow_position;
  std::printf("elbow position (m):           %10.6f %10.6f %10.6f   (frame %d)\n", z(e.x()),
              z(e.y()), z(e.z()), r.model.rig.elbow_frame);
  std::printf("shoulder manipulability:      %10.6f (normalised %.6f%s)\n",
              z(pose.shoulder_manipulability), z(pose.shoulder_manipulability_normalised),
              pose.near_singular ? ", NEAR SINGULAR" : "");
  if (!r.outside.empty()) {
    std::printf("warning: outside joint limits:");
    for (const auto& s : r.outside) std::printf(" %s", s.c_str());
    std::printf("\n");
  }
}

int run_fk(const FkOptions& o) {
  if (o.deg.empty() == o.rad.empty()) {
    print_error("give the joints with --joints-deg or --joints-rad");
    return kExitUsage;
  }
  const std::string path = o.model.empty() ? settings::default_model_path() : o.model;
  const settings::KinematicModel model = settings::load_model_file(path);
  const std::optional<kinematics::JointVector> q = given_joints(o, model);
  if (!q) return kExitUsage;
  FkResult r{model, path, *q, {}, {}};
  kinematics::evaluate_rig(model.chain, model.rig, r.q, r.pose);
  for (int i = 0; i < r.q.size(); ++i) {
    const auto& j = model.chain.joints()[static_cast<std::size_t>(i)];
    if (r.q[i] < j.limits.lower || r.q[i] > j.limits.upper) r.outside.push_back(j.name);
  }
  if (o.json) {
    print_json(r);
  } else {
    print_text(r);
  }
  return kExitOk;
}

std::function<int()> setup_fk(CLI::App& sub) {
  auto o = std::make_shared<FkOptions>();
  sub.add_option("--model", o->model,
                 "kinematic model file (default: " + settings::default_model_path() + ")");
  auto* deg = sub.add_option("--joints-deg", o->deg, "joint angles in degrees, a,b,c,...")
                  ->delimiter(',')
                  ->expected(1, -1);
  auto* rad = sub.add_option("--joints-rad", o->rad, "joint angles in radians, a,b,c,...")
                  ->delimiter(',')
                  ->expected(1, -1);
  deg->excludes(rad);
  rad->excludes(deg);
  sub.add_flag("--json", o->json, "print one JSON object");
  return [o] { return run_fk(*o); };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(fk, "fk",
                        "forward kinematics of a model at one joint vector: palm pose, elbow, "
                        "shoulder manipulability",
                        exodaq::tools::setup_fk);
