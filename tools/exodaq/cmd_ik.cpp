// exodaq ik: inverse kinematics of a model file at one palm pose.
//   exodaq ik [--model FILE] --palm-position x,y,z
//             (--palm-rotation r11,...,r33 | --palm-quaternion w,x,y,z)
//             [--free-joint-deg A | --free-joint-rad A]
//             [--position-tolerance M] [--orientation-tolerance RAD] [--json]
#include <Eigen/SVD>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/kinematics/ik.hpp"
#include "exodaq/settings/model_file.hpp"
#include "json_out.hpp"

namespace exodaq::tools {
namespace {

struct IkCliOptions {
  std::string model;
  std::vector<double> position;
  std::vector<double> rotation;
  std::vector<double> quaternion;
  std::vector<double> free_deg;
  std::vector<double> free_rad;
  double position_tolerance = 1e-6;
  double orientation_tolerance = 1e-6;
  bool json = false;
};

int usage_error(const std::string& what) {
  print_error(what);
  return kExitUsage;
}

bool all_finite(const std::vector<double>& v) {
  for (const double x : v) {
    if (!std::isfinite(x)) return false;
  }
  return true;
}

// The target pose from the options, or an error message.
std::string read_target(const IkCliOptions& o, kinematics::Pose& target) {
  if (o.position.size() != 3 || !all_finite(o.position)) {
    return "--palm-position needs three finite numbers x,y,z (metres)";
  }
  if (o.rotation.empty() == o.quaternion.empty()) {
    return "give the palm orientation with --palm-rotation or --palm-quaternion";
  }
  target = kinematics::Pose::Identity();
  target.translation() = Eigen::Vector3d(o.position[0], o.position[1], o.position[2]);
  if (!o.quaternion.empty()) {
    if (o.quaternion.size() != 4 || !all_finite(o.quaternion)) {
      return "--palm-quaternion needs four finite numbers w,x,y,z";
    }
    Eigen::Quaterniond q(o.quaternion[0], o.quaternion[1], o.quaternion[2], o.quaternion[3]);
    if (!(q.norm() > 1e-9)) return "--palm-quaternion has zero length";
    target.linear() = q.normalized().toRotationMatrix();
    return "";
  }
  if (o.rotation.size() != 9 || !all_finite(o.rotation)) {
    return "--palm-rotation needs nine finite numbers r11,r12,...,r33 (row by row)";
  }
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R(r, c) = o.rotation[static_cast<std::size_t>(3 * r + c)];
  }
  const double off = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (off > 1e-6 || R.determinant() < 0.0) {
    return "--palm-rotation is not a rotation (R^T R differs from I by " + std::to_string(off) +
           ", det " + std::to_string(R.determinant()) + "; 1e-6 allowed)";
  }
  // The nearest rotation, so a matrix printed to six digits is taken as meant.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  target.linear() = svd.matrixU() * svd.matrixV().transpose();
  return "";
}

std::string outside_list(const kinematics::Chain& chain, const kinematics::JointVector& q) {
  std::string out;
  for (int i = 0; i < chain.joint_count(); ++i) {
    const auto& j = chain.joints()[static_cast<std::size_t>(i)];
    if (q[i] < j.limits.lower - 1e-12 || q[i] > j.limits.upper + 1e-12) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "%s%s (%.4f deg, limits [%.4f, %.4f])",
                    out.empty() ? "" : ", ", j.name.c_str(), q[i] / exodaq::kDegToRad,
                    j.limits.lower / exodaq::kDegToRad, j.limits.upper / exodaq::kDegToRad);
      out += buf;
    }
  }
  return out;
}

struct IkRun {
  const settings::KinematicModel* model = nullptr;
  std::string path;
  kinematics::Pose target;
  const kinematics::IkSolver* solver = nullptr;
  const kinematics::IkResult* result = nullptr;
  double free_value = std::numeric_limits<double>::quiet_NaN();
  const IkCliOptions* options = nullptr;
};

std::string free_joint_name(const IkRun& r) {
  const int f = r.solver->free_joint();
  return f < 0 ? "" : r.model->chain.joints()[static_cast<std::size_t>(f)].name;
}

JsonObject solution_json(const IkRun& r, const kinematics::IkSolution& s) {
  std::vector<std::string> outside;
  for (int i = 0; i < r.model->chain.joint_count(); ++i) {
    const auto& j = r.model->chain.joints()[static_cast<std::size_t>(i)];
    if (s.q[i] < j.limits.lower - 1e-12 || s.q[i] > j.limits.upper + 1e-12) {
      outside.push_back(j.name);
    }
  }
  const kinematics::JointVector deg = s.q / exodaq::kDegToRad;
  const std::string interval =
      std::isfinite(s.free_lower)
          ? "[" + json_measure(s.free_lower) + ", " + json_measure(s.free_upper) + "]"
          : "null";
  JsonObject j;
  j.add("joints_rad", json_array(s.q))
      .add("joints_deg", json_array(deg))
      .add("within_limits", json_bool(s.within_limits))
      .add("joints_outside_limits", json_strings(outside))
      .add("position_residual_m", json_number(s.position_residual))
      .add("orientation_residual_rad", json_number(s.orientation_residual))
      .add("shoulder_manipulability", json_measure(s.shoulder_manipulability))
      .add("shoulder_manipulability_normalised", json_measure(s.shoulder_manipulability_normalised))
      .add("free_joint_interval_rad", interval);
  return j;
}

void print_json(const IkRun& r) {
  const auto& chain = r.model->chain;
  std::vector<std::string> names;
  for (const auto& j : chain.joints()) names.push_back(j.name);
  const Eigen::Matrix3d& R = r.target.linear();
  const std::string free = free_joint_name(r);
  const std::string rotation = "[" + json_array(Eigen::Vector3d(R.row(0).transpose())) + ", " +
                               json_array(Eigen::Vector3d(R.row(1).transpose())) + ", " +
                               json_array(Eigen::Vector3d(R.row(2).transpose())) + "]";
  std::vector<JsonObject> solutions;
  for (const auto& s : r.result->solutions) solutions.push_back(solution_json(r, s));
  JsonObject j;
  j.add("model", json_string(r.model->name))
      .add("model_file", json_string(r.path))
      .add("joint_names", json_strings(names))
      .add("palm_position_m", json_array(Eigen::Vector3d(r.target.translation())))
      .add("palm_rotation", rotation)
      .add("palm_quaternion_wxyz", json_array(kinematics::quaternion_wxyz(R)))
      .add("solver", json_string(r.solver->analytical() ? "closed_form" : "numerical"))
      .add("redundancy", std::to_string(r.solver->redundancy()))
      .add("free_joint", free.empty() ? "null" : json_string(free))
      .add("free_joint_value_rad", json_number(r.free_value))
      .add("position_tolerance_m", json_number(r.options->position_tolerance))
      .add("orientation_tolerance_rad", json_number(r.options->orientation_tolerance))
      .add("status", json_string(kinematics::to_string(r.result->status)))
      .add("truncated", json_bool(r.result->truncated))
      .add("best_position_residual_m", json_number(r.result->best_position_residual))
      .add("best_orientation_residual_rad", json_number(r.result->best_orientation_residual))
      .add("elbow_sphere_miss_m", json_number(r.result->elbow_sphere_miss))
      .add("solutions", json_objects(solutions, 2));
  std::printf("%s\n", j.text().c_str());
}

// Print -0.000000 as 0.000000.
double z(double v) {
  return std::abs(v) < 5e-13 ? 0.0 : v;
}
// Degrees as printed with four decimals, -0.0000 as 0.0000.
double deg4(double rad) {
  const double d = rad / exodaq::kDegToRad;
  return std::abs(d) < 5e-5 ? 0.0 : d;
}

void print_header(const IkRun& r) {
  const auto& p = r.target.translation();
  const Eigen::Matrix3d& R = r.target.linear();
  std::printf("model: %s (%s)\n", r.model->name.c_str(), r.path.c_str());
  std::printf("palm position (m):  %10.6f %10.6f %10.6f\n", z(p.x()), z(p.y()), z(p.z()));
  for (int i = 0; i < 3; ++i) {
    std::printf("%s%10.6f %10.6f %10.6f\n",
                i ? "                    " : "palm rotation:      ", z(R(i, 0)), z(R(i, 1)),
                z(R(i, 2)));
  }
  const std::string free = free_joint_name(r);
  std::printf("solver: %s", r.solver->analytical()
                                ? "closed form (spherical shoulder, elbow, forearm), polished"
                                : "numerical (Levenberg-Marquardt from many starts)");
  if (free.empty()) {
    std::printf("; finitely many solutions\n");
  } else if (std::isfinite(r.free_value)) {
    std::printf("; joint %d (%s) redundant, fixed at %.4f deg\n", r.solver->free_joint() + 1,
                free.c_str(), r.free_value / exodaq::kDegToRad);
  } else {
    std::printf(
        "; joint %d (%s) redundant: one solution per branch (an interval of it), the posture of "
        "largest shoulder manipulability on the branch\n",
        r.solver->free_joint() + 1, free.c_str());
  }
}

void print_solutions(const IkRun& r) {
  const auto& sols = r.result->solutions;
  for (std::size_t i = 0; i < sols.size(); ++i) {
    const kinematics::IkSolution& s = sols[i];
    std::printf("#%zu joints (deg):", i + 1);
    for (int j = 0; j < s.q.size(); ++j) std::printf(" %.4f", deg4(s.q[j]));
    std::printf("\n");
    if (std::isfinite(s.free_lower)) {
      std::printf("   branch: %s in [%.4f, %.4f] deg\n", free_joint_name(r).c_str(),
                  deg4(s.free_lower), deg4(s.free_upper));
    }
    std::printf("   residual: position %.1e m, orientation %.1e rad\n", s.position_residual,
                s.orientation_residual);
    std::printf("   shoulder manipulability: %.6f (normalised %.6f)\n", s.shoulder_manipulability,
                s.shoulder_manipulability_normalised);
    if (!s.within_limits) {
      std::printf("   outside limits: %s\n", outside_list(r.model->chain, s.q).c_str());
    }
  }
}

void print_status(const IkRun& r) {
  const kinematics::IkResult& res = *r.result;
  switch (res.status) {
    case kinematics::IkStatus::kSolved:
      std::printf("status: solved, %zu solution%s within the joint limits%s\n",
                  res.solutions.size(), res.solutions.size() == 1 ? "" : "s",
                  res.truncated ? " (more exist: list truncated)" : "");
      break;
    case kinematics::IkStatus::kOutsideLimits:
      std::printf("status: outside_limits: the pose is reached only outside the joint limits\n");
      break;
    case kinematics::IkStatus::kUnreachable:
      std::printf(
          "status: unreachable: no joint vector reaches this palm pose within %.1e m and %.1e "
          "rad; the nearest misses by %.3e m and %.3e rad\n",
          r.options->position_tolerance, r.options->orientation_tolerance,
          res.best_position_residual, res.best_orientation_residual);
      if (std::isfinite(res.elbow_sphere_miss)) {
        std::printf(
            "   the elbow (fixed in the palm frame) lies %.6f m %s the sphere the upper arm "
            "reaches\n",
            std::abs(res.elbow_sphere_miss), res.elbow_sphere_miss > 0 ? "outside" : "inside");
      }
      break;
  }
}

int run_ik(const IkCliOptions& o) {
  kinematics::Pose target;
  if (const std::string e = read_target(o, target); !e.empty()) return usage_error(e);
  if (!(o.position_tolerance > 0.0) || !(o.orientation_tolerance > 0.0)) {
    return usage_error("tolerances must be > 0");
  }
  const std::string path = o.model.empty() ? settings::default_model_path() : o.model;
  settings::KinematicModel model;
  try {
    model = settings::load_model_file(path);
  } catch (const exodaq::ConfigError& e) {
    return usage_error(e.what());
  }
  kinematics::IkOptions options;
  options.position_tolerance = o.position_tolerance;
  options.orientation_tolerance = o.orientation_tolerance;
  std::unique_ptr<kinematics::IkSolver> solver;
  try {
    solver = std::make_unique<kinematics::IkSolver>(model.chain, model.rig, options);
  } catch (const std::invalid_argument& e) {
    return usage_error(std::string(path) + ": " + e.what());
  }
  IkRun run{&model, path, target, solver.get(), nullptr, std::numeric_limits<double>::quiet_NaN(),
            &o};
  const std::vector<double>& free = o.free_deg.empty() ? o.free_rad : o.free_deg;
  if (!free.empty()) {
    if (solver->redundancy() == 0) {
      return usage_error("model '" + model.name + "' is not redundant: it has no free joint");
    }
    if (free.size() != 1 || !std::isfinite(free[0])) {
      return usage_error("the free joint's value must be one finite number");
    }
    run.free_value = o.free_deg.empty() ? free[0] : free[0] * exodaq::kDegToRad;
    run.result = &solver->solve_fixed(target, run.free_value);
  } else {
    run.result = &solver->solve(target);
  }
  if (o.json) {
    print_json(run);
  } else {
    print_header(run);
    print_status(run);
    print_solutions(run);
  }
  return run.result->status == kinematics::IkStatus::kSolved ? kExitOk : kExitFailure;
}

std::function<int()> setup_ik(CLI::App& sub) {
  auto o = std::make_shared<IkCliOptions>();
  sub.add_option("--model", o->model,
                 "kinematic model file (default: " + settings::default_model_path() + ")");
  sub.add_option("--palm-position", o->position, "palm position x,y,z in metres (world frame)")
      ->delimiter(',')
      ->expected(1, -1);
  auto* rot = sub.add_option("--palm-rotation", o->rotation,
                             "palm rotation matrix r11,r12,...,r33, row by row")
                  ->delimiter(',')
                  ->expected(1, -1);
  auto* quat = sub.add_option("--palm-quaternion", o->quaternion, "palm orientation w,x,y,z")
                   ->delimiter(',')
                   ->expected(1, -1);
  rot->excludes(quat);
  quat->excludes(rot);
  auto* fd = sub.add_option("--free-joint-deg", o->free_deg,
                            "redundant models: fix the free joint at this angle (degrees)");
  auto* fr = sub.add_option("--free-joint-rad", o->free_rad,
                            "redundant models: fix the free joint at this angle (radians)");
  fd->excludes(fr);
  fr->excludes(fd);
  sub.add_option("--position-tolerance", o->position_tolerance,
                 "metres a solution's palm may miss the target by (default 1e-6)");
  sub.add_option("--orientation-tolerance", o->orientation_tolerance,
                 "radians a solution's palm may turn from the target by (default 1e-6)");
  sub.add_flag("--json", o->json, "print one JSON object");
  return [o] { return run_ik(*o); };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(ik, "ik",
                        "inverse kinematics of a model at one palm pose: every solution within the "
                        "joint limits, with residual and shoulder manipulability",
                        exodaq::tools::setup_ik);
