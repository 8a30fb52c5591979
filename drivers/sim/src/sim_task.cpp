#include "exodaq/drivers/sim_task.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/kinematics/ik.hpp"

namespace exodaq::drivers::sim {
namespace {

using exodaq::ConfigError;
using exodaq::kDegToRad;
using exodaq::MapReader;

std::size_t u(int i) noexcept {
  return static_cast<std::size_t>(i);
}

// R = Rz(yaw) Ry(pitch) Rx(roll), angles in degrees.
Eigen::Matrix3d rpy_rotation(const std::array<double, 3>& rpy_deg) {
  return (Eigen::AngleAxisd(rpy_deg[2] * kDegToRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy_deg[1] * kDegToRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy_deg[0] * kDegToRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d millimetres(MapReader& m, const std::string& key) {
  const auto v = m.numbers_fixed<3>(key);
  return Eigen::Vector3d(v[0], v[1], v[2]) * 1e-3;
}

std::map<std::string, Eigen::Matrix3d> read_hands(MapReader& top) {
  std::map<std::string, Eigen::Matrix3d> hands;
  const auto node = top.optional_child("hands");
  if (!node) return hands;
  if (!node->IsMap()) top.fail(*node, "hands must be a mapping: name: [roll, pitch, yaw] (deg)");
  for (const auto& kv : *node) {
    const auto v = top.to_numbers(kv.second, "hands." + kv.first.Scalar());
    if (v.size() != 3) top.fail(kv.second, "a hand is [roll, pitch, yaw] in degrees");
    hands[kv.first.Scalar()] = rpy_rotation({v[0], v[1], v[2]});
  }
  return hands;
}

SimTaskStep read_step(MapReader& s, const std::map<std::string, Eigen::Matrix3d>& hands) {
  SimTaskStep step;
  step.line = exodaq::line_of(s.node());
  step.name = s.string("name");
  step.position_m = millimetres(s, "position_mm");
  if (s.has("hand") == s.has("rpy_deg")) {
    s.fail(s.node(), "a step gives its palm orientation as either hand or rpy_deg");
  }
  if (s.has("hand")) {
    const std::string hand = s.string("hand");
    const auto it = hands.find(hand);
    if (it == hands.end()) s.fail_key("hand", "no hand named '" + hand + "' under hands");
    step.rotation = it->second;
  } else {
    step.rotation = rpy_rotation(s.numbers_fixed<3>("rpy_deg"));
  }
  step.dwell_s = s.number_or("dwell_s", 0.0);
  if (step.dwell_s < 0.0 || step.dwell_s > 3600.0) s.fail_key("dwell_s", "dwell_s must be 0..3600");
  if (s.has("azimuth_deg")) step.azimuth_rad = s.number("azimuth_deg") * kDegToRad;
  s.finish();
  return step;
}

SimTaskRandom read_random(MapReader& r, const std::vector<SimTaskStep>& loop) {
  SimTaskRandom out;
  const YAML::Node steps = r.child("steps");
  if (!steps.IsSequence() || steps.size() == 0) r.fail(steps, "random.steps lists step names");
  for (const auto& n : steps) {
    const auto it = std::find_if(loop.begin(), loop.end(),
                                 [&](const SimTaskStep& s) { return s.name == n.Scalar(); });
    if (it == loop.end()) r.fail(n, "no step named '" + n.Scalar() + "' in loop");
    out.steps.push_back(static_cast<int>(it - loop.begin()));
  }
  MapReader box = r.map("box_mm");
  out.line = exodaq::line_of(box.node());
  out.box_min_m = millimetres(box, "min");
  out.box_max_m = millimetres(box, "max");
  box.finish();
  if ((out.box_max_m - out.box_min_m).minCoeff() < 0.0) {
    r.fail_key("box_mm", "box_mm.min must not exceed box_mm.max");
  }
  const std::int64_t trips = r.integer_or("trips", 1);
  if (trips < 1 || trips > 1000) r.fail_key("trips", "trips must be 1..1000");
  out.trips = static_cast<int>(trips);
  r.finish();
  return out;
}

}  // namespace

SimTaskFile load_sim_task(const std::string& path) {
  SimTaskFile f;
  f.file = path;
  MapReader top(path, exodaq::load_yaml_file(path), "task");
  top.choice("format", {"exodaq-sim-task-1"});
  f.speed_fraction = top.number_or("speed_fraction", f.speed_fraction);
  if (!(f.speed_fraction > 0.0 && f.speed_fraction <= 1.0)) {
    top.fail_key("speed_fraction", "speed_fraction must be in (0, 1]");
  }
  f.min_move_s = top.number_or("min_move_s", f.min_move_s);
  if (!(f.min_move_s >= 0.001 && f.min_move_s <= 60.0)) {
    top.fail_key("min_move_s", "min_move_s must be 0.001..60");
  }
  f.max_adjust_rad = top.number_or("max_adjust_deg", f.max_adjust_rad / kDegToRad) * kDegToRad;
  if (!(f.max_adjust_rad >= 0.0 && f.max_adjust_rad <= std::numbers::pi)) {
    top.fail_key("max_adjust_deg", "max_adjust_deg must be 0..180");
  }
  const auto hands = read_hands(top);
  const YAML::Node loop = top.child("loop");
  if (!loop.IsSequence() || loop.size() < 2) top.fail(loop, "loop lists at least two steps");
  for (std::size_t i = 0; i < loop.size(); ++i) {
    MapReader s(path, loop[i], "loop[" + std::to_string(i) + "]");
    f.loop.push_back(read_step(s, hands));
  }
  if (auto r = top.optional_map("random")) f.random = read_random(*r, f.loop);
  top.finish();
  return f;
}

// ---------------------------------------------------------------------------
// Planning
// ---------------------------------------------------------------------------

namespace {

kinematics::JointVector to_joints(const Vec6& v) {
  kinematics::JointVector q(kJoints);
  for (int j = 0; j < kJoints; ++j) q[j] = v[u(j)];
  return q;
}

Vec6 to_vec6(const kinematics::JointVector& q) {
  Vec6 v{};
  for (int j = 0; j < kJoints; ++j) v[u(j)] = q[j];
  return v;
}

// Seed 000's arm: the elbow is fixed in the palm frame (joints 5 and 6 meet
// there) and stays at the upper arm's length from the shoulder centre (the
// origin of the frame before the elbow's, where joints 1-4 meet). A palm pose
// is reachable only with the elbow on that sphere.
struct ArmGeometry {
  bool spherical = false;
  Eigen::Vector3d shoulder = Eigen::Vector3d::Zero();
  Eigen::Vector3d elbow_in_palm = Eigen::Vector3d::Zero();
  double upper_arm = 0.0;
};

ArmGeometry arm_geometry(const kinematics::Chain& chain, const kinematics::RigKinematicsConfig& rig,
                         const Vec6& home) {
  ArmGeometry g;
  if (chain.joint_count() != kJoints || rig.elbow_frame < 2) return g;
  auto measure = [&](const kinematics::JointVector& q, ArmGeometry& m) {
    m.shoulder = chain.frame(q, rig.elbow_frame - 1).translation();
    const Eigen::Vector3d elbow = chain.frame(q, rig.elbow_frame).translation();
    m.elbow_in_palm = chain.palm(q).inverse() * elbow;
    m.upper_arm = (elbow - m.shoulder).norm();
  };
  measure(to_joints(home), g);
  g.spherical = true;
  kinematics::JointVector q = to_joints(home);
  for (int j = 0; j < kJoints; ++j) q[j] += 0.1 * (j + 1);  // another posture: same geometry?
  ArmGeometry other;
  measure(q, other);
  g.spherical = (other.shoulder - g.shoulder).norm() < 1e-9 &&
                (other.elbow_in_palm - g.elbow_in_palm).norm() < 1e-9 &&
                std::abs(other.upper_arm - g.upper_arm) < 1e-9;
  return g;
}

// Turns the palm about its position as little as possible so that the elbow
// lies on the upper arm's sphere. Returns the angle turned, or a negative
// value when no orientation reaches the position.
double make_reachable(const ArmGeometry& g, kinematics::Pose& pose) {
  if (!g.spherical) return 0.0;
  const Eigen::Vector3d v = pose.linear() * g.elbow_in_palm;  // palm -> elbow
  const Eigen::Vector3d d = pose.translation() - g.shoulder;
  const double dn = d.norm();
  const double vn = v.norm();
  if (dn < 1e-9 || vn < 1e-9) return -1.0;
  const double cos_phi = (g.upper_arm * g.upper_arm - dn * dn - vn * vn) / (2.0 * dn * vn);
  if (cos_phi < -1.0 || cos_phi > 1.0) return -1.0;
  const Eigen::Vector3d dh = d / dn;
  Eigen::Vector3d perp = v - v.dot(dh) * dh;
  if (perp.norm() < 1e-12) perp = dh.unitOrthogonal();
  const Eigen::Vector3d w =
      vn * (cos_phi * dh + std::sqrt(1.0 - cos_phi * cos_phi) * perp.normalized());
  const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(v, w);
  pose.linear() = turn.toRotationMatrix() * pose.linear();
  return std::acos(std::clamp(v.dot(w) / (vn * vn), -1.0, 1.0));
}

double distance_sq(const kinematics::JointVector& a, const Vec6& b) {
  double s = 0.0;
  for (int j = 0; j < kJoints; ++j) s += (a[j] - b[u(j)]) * (a[j] - b[u(j)]);
  return s;
}

// The posture reaching `pose` for `step`: at its azimuth the solution within
// the limits nearest `seed`, else the IK's nearest solution. nullopt: none.
std::optional<Vec6> solve_step(kinematics::IkSolver& ik, const SimTaskStep& step,
                               const kinematics::Pose& pose, const Vec6& seed) {
  if (step.azimuth_rad) {
    const kinematics::IkResult& r = ik.solve_fixed(pose, *step.azimuth_rad);
    const kinematics::IkSolution* best = nullptr;
    for (const kinematics::IkSolution& s : r.solutions) {
      if (s.within_limits &&
          (best == nullptr || distance_sq(s.q, seed) < distance_sq(best->q, seed)))
        best = &s;
    }
    if (best == nullptr) return std::nullopt;
    return to_vec6(best->q);
  }
  kinematics::IkSolution s;
  if (!ik.solve_nearest(pose, to_joints(seed), s)) return std::nullopt;
  return to_vec6(s.q);
}

// Every trip's palm targets in loop order (random steps drawn in the box).
std::vector<kinematics::Pose> trip_targets(const SimTaskFile& f, std::uint64_t seed, int trip,
                                           int attempt) {
  std::vector<kinematics::Pose> poses;
  for (const SimTaskStep& s : f.loop) {
    kinematics::Pose p = kinematics::Pose::Identity();
    p.linear() = s.rotation;
    p.translation() = s.position_m;
    poses.push_back(p);
  }
  if (!f.random) return poses;
  const SimTaskRandom& r = *f.random;
  Eigen::Vector3d at;
  for (int a = 0; a < 3; ++a) {
    const auto k = static_cast<std::uint64_t>((trip * 1000 + attempt) * 3 + a);
    at[a] = r.box_min_m[a] + (r.box_max_m[a] - r.box_min_m[a]) * unit_random(seed, 7, k);
  }
  const Eigen::Vector3d first = f.loop[u(r.steps.front())].position_m;
  for (int i : r.steps) poses[u(i)].translation() = at + (f.loop[u(i)].position_m - first);
  return poses;
}

// One trip's stops. Returns the index of the step out of reach (the reason
// in `why`), or -1.
int plan_trip(const SimTask& task, const ArmGeometry& g, kinematics::IkSolver& ik,
              const std::vector<kinematics::Pose>& targets, Vec6 seed, int trip,
              std::vector<SimTaskPlan::Stop>& out, std::string& why) {
  const SimTaskFile& f = *task.file;
  for (std::size_t i = 0; i < f.loop.size(); ++i) {
    SimTaskPlan::Stop stop;
    stop.trip = trip;
    stop.step = static_cast<int>(i);
    stop.target = targets[i];
    stop.adjust_rad = make_reachable(g, stop.target);
    if (stop.adjust_rad < 0.0 || stop.adjust_rad > f.max_adjust_rad) {
      why = stop.adjust_rad < 0.0
                ? "no palm orientation reaches its position (too near or too far)"
                : "its orientation is " + std::to_string(stop.adjust_rad / kDegToRad) +
                      " deg from a reachable one (max_adjust_deg)";
      return static_cast<int>(i);
    }
    const auto posture = solve_step(ik, f.loop[i], stop.target, seed);
    if (!posture) {
      why = "no posture within the joint limits reaches it";
      return static_cast<int>(i);
    }
    stop.posture = *posture;
    seed = *posture;
    out.push_back(stop);
  }
  return -1;
}

bool is_random(const SimTaskFile& f, int step) {
  return f.random &&
         std::find(f.random->steps.begin(), f.random->steps.end(), step) != f.random->steps.end();
}

std::vector<SimTaskPlan::Stop> plan_stops(const SimTask& task, const SimMotionOptions& o,
                                          std::uint64_t seed) {
  const SimTaskFile& f = *task.file;
  const ArmGeometry g = arm_geometry(task.chain, task.rig, o.home_rad);
  kinematics::IkSolver ik(task.chain, task.rig);
  std::vector<SimTaskPlan::Stop> stops;
  const int trips = f.random ? f.random->trips : 1;
  for (int trip = 0; trip < trips; ++trip) {
    const Vec6 from = stops.empty() ? o.home_rad : stops.back().posture;
    // A drawn target out of reach is drawn again; a fixed one is an error.
    for (int attempt = 0;; ++attempt) {
      std::vector<SimTaskPlan::Stop> trip_stops;
      std::string why;
      const int bad =
          plan_trip(task, g, ik, trip_targets(f, seed, trip, attempt), from, trip, trip_stops, why);
      if (bad < 0) {
        stops.insert(stops.end(), trip_stops.begin(), trip_stops.end());
        break;
      }
      if (!is_random(f, bad)) {
        throw ConfigError(f.file, f.loop[u(bad)].line, "target out of reach: " + why);
      }
      if (attempt == 99) {
        throw ConfigError(f.file, f.random->line,
                          "no reachable target in the random box for trip " +
                              std::to_string(trip + 1) + " in 100 draws (last: " + why + ")");
      }
    }
  }
  return stops;
}

kinematics::JointTrajectory plan_move(const SimTask& task, const std::vector<Vec6>& via) {
  kinematics::JointBounds bounds;
  bounds.max_speed = to_joints(task.max_speed_rad_s) * task.file->speed_fraction;
  kinematics::TrajectoryOptions options;
  options.shape = kinematics::SegmentShape::kQuintic;
  options.min_segment_duration = task.file->min_move_s;
  std::vector<kinematics::JointVector> points;
  for (const Vec6& v : via) points.push_back(to_joints(v));
  return kinematics::JointTrajectory(points, bounds, options);
}

void add_move(SimTaskPlan& plan, std::vector<SimMotion::Segment>& segs, double& t,
              kinematics::JointTrajectory move) {
  SimMotion::Segment s;
  s.t0 = t;
  s.duration = move.duration();
  s.move = static_cast<int>(plan.moves.size());
  s.from = to_vec6(move.sample(0.0).q);
  s.to = to_vec6(move.sample(move.duration()).q);
  plan.moves.push_back(std::move(move));
  segs.push_back(s);
  t += s.duration;
}

}  // namespace

SimTaskPlan plan_sim_task(const SimTask& task, const SimMotionOptions& o, std::uint64_t seed) {
  for (int j = 0; j < kJoints; ++j) {
    if (!(task.max_speed_rad_s[u(j)] > 0.0)) {
      throw ConfigError(task.file->file, 0,
                        "every joint needs max_speed_rad_s > 0 to plan the task");
    }
  }
  SimTaskPlan plan;
  plan.stops = plan_stops(task, o, seed);
  double t = 0.0;
  add_move(plan, plan.lead_in, t, plan_move(task, {o.home_rad, plan.stops.front().posture}));
  // The loop: rest at stop 0 and at every stop with a dwell; the stops between
  // two rests are via points passed without stopping.
  t = 0.0;
  std::vector<Vec6> via{plan.stops.front().posture};
  std::vector<std::size_t> members{0};  // the stops of `via`
  auto close_move = [&](std::size_t rest_stop) {
    const double t0 = t;
    add_move(plan, plan.loop, t, plan_move(task, via));
    for (std::size_t k = 1; k + 1 < members.size(); ++k) {
      plan.stops[members[k]].arrive_s = t0 + plan.moves.back().via_time(static_cast<int>(k));
    }
    via.assign(1, plan.stops[rest_stop].posture);
    members.assign(1, rest_stop);
  };
  for (std::size_t i = 0; i < plan.stops.size(); ++i) {
    SimTaskPlan::Stop& stop = plan.stops[i];
    const double dwell = task.file->loop[u(stop.step)].dwell_s;
    if (i > 0) {
      via.push_back(stop.posture);
      members.push_back(i);
      if (dwell <= 0.0) continue;  // passed through
      close_move(i);
    }
    stop.arrive_s = t;
    if (dwell > 0.0) {
      plan.loop.push_back(SimMotion::Segment{t, dwell, stop.posture, stop.posture});
      t += dwell;
    }
  }
  via.push_back(plan.stops.front().posture);
  members.push_back(0);
  close_move(0);
  plan.period_s = t;
  return plan;
}

JointTruth sample_move(const SimTaskPlan& plan, int move, double t) noexcept {
  kinematics::TrajectorySample s;
  plan.moves[u(move)].sample(t, s);
  JointTruth out;
  for (int j = 0; j < kJoints; ++j) {
    out.position[u(j)] = s.q[j];
    out.velocity[u(j)] = s.qd[j];
    out.acceleration[u(j)] = s.qdd[j];
  }
  return out;
}

}  // namespace exodaq::drivers::sim
