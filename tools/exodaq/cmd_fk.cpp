// exodaq fk: forward kinematics of a model file at one joint vector.
//   exodaq fk [--model FILE] (--joints-deg a,b,... | --joints-rad a,b,...) [--json]
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/config/model_file.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"
#include "json_out.hpp"

namespace exodaq::tools {
namespace {

struct FkOptions {
  std::string model;
  std::vector<double> deg;
  std::vector<double> rad;
  bool json = false;
};

int run_fk(const FkOptions& o) {
  if (o.deg.empty() == o.rad.empty()) {
    print_error("give the joints with --joints-deg or --joints-rad");
    return kExitUsage;
  }
  const std::string path = o.model.empty() ? config::default_model_path() : o.model;
  const config::KinematicModel model = config::load_model_file(path);
  const bool in_deg = !o.deg.empty();
  const std::vector<double>& given = in_deg ? o.deg : o.rad;
  const int n = model.chain.joint_count();
  if (static_cast<int>(given.size()) != n) {
    print_error("model '" + model.name + "' has " + std::to_string(n) + " joints, " +
                std::to_string(given.size()) + " joint values given");
    return kExitUsage;
  }
  kin::JointVector q(n);
  for (int i = 0; i < n; ++i) {
    const double v = given[static_cast<std::size_t>(i)];
    if (!std::isfinite(v)) {
      print_error("joint " + std::to_string(i + 1) + " value is not a finite number");
      return kExitUsage;
    }
    q[i] = in_deg ? v * config::kDegToRad : v;
  }
  kin::RigPose pose;
  kin::evaluate_rig(model.chain, model.rig, q, pose);

  // Joints outside their limits are computed anyway, and reported.
  std::vector<std::string> outside;
  for (int i = 0; i < n; ++i) {
    const auto& j = model.chain.joints()[static_cast<std::size_t>(i)];
    if (q[i] < j.limits.lower || q[i] > j.limits.upper) outside.push_back(j.name);
  }

  if (o.json) {
    std::vector<std::string> names;
    for (const auto& j : model.chain.joints()) names.push_back(j.name);
    const auto& R = pose.palm_rotation;
    const std::string rotation = "[" + json_array(Eigen::Vector3d(R.row(0).transpose())) + ", " +
                                 json_array(Eigen::Vector3d(R.row(1).transpose())) + ", " +
                                 json_array(Eigen::Vector3d(R.row(2).transpose())) + "]";
    JsonObject j;
    j.add("model", json_string(model.name))
        .add("model_file", json_string(path))
        .add("joint_names", json_strings(names))
        .add("joints_rad", json_array(q))
        .add("palm_position_m", json_array(pose.palm_position))
        .add("palm_rotation", rotation)
        .add("palm_quaternion_wxyz", json_array(pose.palm_quaternion_wxyz))
        .add("elbow_frame", std::to_string(model.rig.elbow_frame))
        .add("elbow_position_m", json_array(pose.elbow_position))
        .add("shoulder_manipulability", json_measure(pose.shoulder_manipulability))
        .add("shoulder_manipulability_normalised",
             json_measure(pose.shoulder_manipulability_normalised))
        .add("near_singular", json_bool(pose.near_singular))
        .add("joints_outside_limits", json_strings(outside));
    std::printf("%s\n", j.text().c_str());
    return kExitOk;
  }

  // Print -0.000000 as 0.000000.
  auto z = [](double v) { return std::abs(v) < 5e-13 ? 0.0 : v; };
  std::printf("model: %s (%s)\n", model.name.c_str(), path.c_str());
  std::printf("joints (deg):");
  for (int i = 0; i < n; ++i) std::printf(" %.4f", z(q[i] / config::kDegToRad));
  std::printf("\n");
  const auto& p = pose.palm_position;
  std::printf("palm position (m):            %10.6f %10.6f %10.6f\n", z(p.x()), z(p.y()), z(p.z()));
  std::printf("palm rotation:");
  for (int r = 0; r < 3; ++r) {
    std::printf(
        "%s%10.6f %10.6f %10.6f\n", r ? "                              " : "                ",
        z(pose.palm_rotation(r, 0)), z(pose.palm_rotation(r, 1)), z(pose.palm_rotation(r, 2)));
  }
  const auto& qw = pose.palm_quaternion_wxyz;
  std::printf("palm quaternion (w, x, y, z): %10.6f %10.6f %10.6f %10.6f\n", z(qw[0]), z(qw[1]),
              z(qw[2]), z(qw[3]));
  const auto& e = pose.elbow_position;
  std::printf("elbow position (m):           %10.6f %10.6f %10.6f   (frame %d)\n", z(e.x()),
              z(e.y()), z(e.z()), model.rig.elbow_frame);
  std::printf("shoulder manipulability:      %10.6f (normalised %.6f%s)\n",
              z(pose.shoulder_manipulability), z(pose.shoulder_manipulability_normalised),
              pose.near_singular ? ", NEAR SINGULAR" : "");
  if (!outside.empty()) {
    std::printf("warning: outside joint limits:");
    for (const auto& s : outside) std::printf(" %s", s.c_str());
    std::printf("\n");
  }
  return kExitOk;
}

std::function<int()> setup_fk(CLI::App& sub) {
  auto o = std::make_shared<FkOptions>();
  sub.add_option("--model", o->model,
                 "kinematic model file (default: " + config::default_model_path() + ")");
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
