#pragma once
// The task-driven motion of the simulated rig: a task file (palm targets in
// O0 with dwell times, optionally drawn in a box) and its plan, joint motion
// by inverse kinematics and joint trajectories. Loading and planning are
// start-up work (they allocate and throw exodaq::ConfigError with file:line);
// sample_move() is allocation-free. File format, planning and the default
// reach-grasp-feed loop: docs/simulator.md ("Task-driven motion").
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "exodaq/drivers/sim_rig.hpp"
#include "exodaq/kinematics/chain.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"
#include "exodaq/kinematics/trajectory.hpp"

namespace exodaq::drivers::sim {

// One step of the task loop: go to a palm pose and stay there for dwell_s.
struct SimTaskStep {
  std::string name;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();    // palm position in O0
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // palm orientation in O0
  double dwell_s = 0.0;                                    // 0: passed through without stopping
  std::optional<double> azimuth_rad;  // joint 1 for the IK; none: nearest to the previous
  int line = 0;                       // in the task file, for errors
};

// Random targets: each trip draws the first listed step's position in the
// box; the other listed steps keep their offset from it.
struct SimTaskRandom {
  std::vector<int> steps;  // indices into SimTaskFile::loop
  Eigen::Vector3d box_min_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d box_max_m = Eigen::Vector3d::Zero();
  int trips = 1;  // distinct trips, then they repeat
  int line = 0;   // of box_mm, for errors
};

struct SimTaskFile {
  std::string file;
  std::vector<SimTaskStep> loop;
  std::optional<SimTaskRandom> random;
  double speed_fraction = 0.8;                  // plan at this share of each joint's max speed
  double min_move_s = 0.3;                      // shortest move between two stops
  double max_adjust_rad = 0.17453292519943295;  // largest turn that makes a target reachable
};

// Reads a task file (strict: unknown keys and bad values are file:line errors).
SimTaskFile load_sim_task(const std::string& path);

// A task file on a rig: the model it plans with and the joints' speed bounds.
struct SimTask {
  std::shared_ptr<const SimTaskFile> file;
  kinematics::Chain chain;
  kinematics::RigKinematicsConfig rig;
  Vec6 max_speed_rad_s{};  // the config's encoders.joints[].max_speed_rad_s
};

// The planned motion: lead-in from home to the first stop, then a loop of
// `period_s` through every trip's stops. Segment times start at 0 in each list;
// a segment with move >= 0 samples moves[move].
struct SimTaskPlan {
  struct Stop {
    int trip = 0;
    int step = 0;
    kinematics::Pose target =
        kinematics::Pose::Identity();  // the palm pose planned for (made reachable)
    double adjust_rad = 0.0;           // how far the target's orientation was turned
    Vec6 posture{};                    // joint angles there
    double arrive_s = 0.0;             // in the loop
  };
  std::vector<Stop> stops;
  std::vector<kinematics::JointTrajectory> moves;
  std::vector<SimMotion::Segment> lead_in;
  std::vector<SimMotion::Segment> loop;
  double period_s = 0.0;
};

// Plans `task` from `o.home_rad`, within o's joint limits, random targets from
// `seed`. Throws exodaq::ConfigError (task file:line) for a target out of reach.
SimTaskPlan plan_sim_task(const SimTask& task, const SimMotionOptions& o, std::uint64_t seed);

// State of move `move` at time t into it (allocation-free).
JointTruth sample_move(const SimTaskPlan& plan, int move, double t) noexcept;

}  // namespace exodaq::drivers::sim
