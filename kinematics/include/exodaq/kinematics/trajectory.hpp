#pragma once
// Joint trajectories through via points: one cubic or quintic polynomial per
// segment, at rest at the first and last point, each segment's duration
// stretched until every joint keeps its speed bound (seed 001 Table III) and
// acceleration bound. Planning allocates and throws std::invalid_argument on bad
// input; a planned trajectory is a value whose sample(t) allocates nothing and
// throws nothing. Explanations: docs/kinematics.md, "Joint trajectories".
#include <vector>

#include "exodaq/kinematics/chain.hpp"

namespace exodaq::kinematics {

enum class SegmentShape {
  kCubic,    // position and velocity continuous at the via points
  kQuintic,  // position, velocity and acceleration continuous
};

struct JointBounds {
  JointVector max_speed;         // rad/s per joint, > 0
  JointVector max_acceleration;  // rad/s^2 per joint, > 0; empty: no bound
};

struct TrajectoryOptions {
  SegmentShape shape = SegmentShape::kQuintic;
  double min_segment_duration = 1e-3;  // s: also the duration of a segment that does not move
};

struct TrajectorySample {
  JointVector q;    // rad
  JointVector qd;   // rad/s
  JointVector qdd;  // rad/s^2
};

class JointTrajectory {
 public:
  JointTrajectory() = default;  // empty: duration 0, no joints
  // Through `via_points` (at least two, each with one angle per joint, in order).
  JointTrajectory(const std::vector<JointVector>& via_points, const JointBounds& bounds,
                  const TrajectoryOptions& options = {});

  int joint_count() const noexcept { return joints_; }
  int segment_count() const noexcept { return static_cast<int>(durations_.size()); }
  double duration() const noexcept { return times_.empty() ? 0.0 : times_.back(); }
  // Time at via point k (0 .. segment_count()).
  double via_time(int k) const noexcept { return times_[static_cast<std::size_t>(k)]; }
  SegmentShape shape() const noexcept { return shape_; }

  // State at time t (s); t is clamped to [0, duration()], so before the start and
  // after the end the trajectory rests at its first and last point.
  void sample(double t, TrajectorySample& out) const noexcept;
  TrajectorySample sample(double t) const noexcept;

  // Largest |qd| and |qdd| per joint over the whole trajectory (exact extrema of
  // the polynomials, computed when planning).
  const JointVector& peak_speed() const noexcept { return peak_speed_; }
  const JointVector& peak_acceleration() const noexcept { return peak_acceleration_; }

 private:
  // q(tau) = sum_k c[k] tau^k on [0, T] of one segment, per joint.
  struct Segment {
    JointVector c[6];
  };
  SegmentShape shape_ = SegmentShape::kQuintic;
  int joints_ = 0;
  std::vector<double> times_;      // segment_count() + 1 breakpoints, times_[0] = 0
  std::vector<double> durations_;  // per segment
  std::vector<Segment> segments_;
  JointVector peak_speed_;
  JointVector peak_acceleration_;
};

}  // namespace exodaq::kinematics
