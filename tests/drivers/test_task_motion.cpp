// The task-driven simulated rig (sim_task.hpp) on config/sim.yaml's default
// reach-grasp-feed task: the planned motion stays within seed 000 Table 5's
// ranges and Table 3's limits, keeps the encoders' speed bounds, reaches every
// palm target (FK of the planned posture), carries every joint across its
// index at least twice a trial, is deterministic for a seed and is sampled
// without allocating; random targets stay in their box; bad task files are
// file:line errors; the hand-made curves stay available (motion: curves).
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "alloc_counter.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/sim_task.hpp"
#include "exodaq/settings/service_config.hpp"
#include "source_sections.hpp"

namespace sim = exodaq::drivers::sim;
namespace settings = exodaq::settings;
using exodaq::drivers::CycleTime;
using exodaq::drivers::EncoderSample;
using exodaq::drivers::SimSource;
using exodaq::drivers::SimSourceSettings;

namespace {

constexpr double kDeg = M_PI / 180.0;
const std::string kConfigDir = std::string(EXODAQ_SOURCE_DIR) + "/config/";

settings::ServiceConfig sim_config() {
  return settings::load_service_config(kConfigDir + "sim.yaml");
}

sim::SimOptions options_of(const settings::ServiceConfig& cfg) {
  return exodaq::drivers::sim_options_from(cfg.source, settings::make_source_context(cfg));
}

// config/sim.yaml with another task file (written next to nothing: absolute paths).
settings::ServiceConfig config_with_task(const std::string& task_yaml) {
  const std::string dir = "/tmp/exodaq-task-test-" + std::to_string(getpid());
  std::ofstream(dir + "-task.yaml") << task_yaml;
  auto cfg = sim_config();
  auto& s = exodaq::test::edit_section<SimSourceSettings>(cfg.source, "sim");
  s.task_path = dir + "-task.yaml";
  s.task = std::make_shared<const sim::SimTaskFile>(sim::load_sim_task(s.task_path));
  s.motion = "task";
  std::remove((dir + "-task.yaml").c_str());
  return cfg;
}

// The default task file, without its random block when `fixed`.
std::string default_task_text(bool fixed) {
  std::ifstream in(kConfigDir + "tasks/reach_grasp_feed.yaml");
  std::stringstream s;
  s << in.rdbuf();
  std::string text = s.str();
  if (fixed) text = text.substr(0, text.find("\n# The mouth is not met"));
  return text + "\n";
}

// Every 1 ms over [from, to): position range per joint, peak speed, limits.
struct Sweep {
  sim::Vec6 lo{}, hi{}, peak_speed{};
  bool within_limits = true;
};

Sweep sweep(const sim::SimMotion& m, double from, double to) {
  Sweep s;
  s.lo.fill(1e9);
  s.hi.fill(-1e9);
  const auto& o = m.options();
  for (double t = from; t < to; t += 1e-3) {
    const auto x = m.truth(t);
    for (std::size_t j = 0; j < 6; ++j) {
      s.lo[j] = std::min(s.lo[j], x.position[j]);
      s.hi[j] = std::max(s.hi[j], x.position[j]);
      s.peak_speed[j] = std::max(s.peak_speed[j], std::abs(x.velocity[j]));
      s.within_limits = s.within_limits && x.position[j] >= o.lower_limit_rad[j] &&
                        x.position[j] <= o.upper_limit_rad[j];
    }
  }
  return s;
}

TEST(SimTask, TheDefaultConfigRunsTheReachGraspFeedLoop) {
  const auto cfg = sim_config();
  const auto* s = cfg.source.section_as<SimSourceSettings>("sim");
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->motion, "task");
  EXPECT_EQ(s->task_path, kConfigDir + "tasks/reach_grasp_feed.yaml");
  const sim::SimRig rig(options_of(cfg));
  const sim::SimTaskPlan* plan = rig.motion().task_plan();
  ASSERT_NE(plan, nullptr);
  // Six trials (the feed target drawn in a box each), four stops each.
  ASSERT_TRUE(s->task->random);
  ASSERT_EQ(plan->stops.size(), 24U);
  const char* names[] = {"table", "reach", "grasp", "feed"};
  for (std::size_t i = 0; i < 24; ++i) {
    EXPECT_EQ(plan->stops[i].step, static_cast<int>(i % 4));
    EXPECT_EQ(plan->stops[i].trip, static_cast<int>(i / 4));
    EXPECT_EQ(s->task->loop[i % 4].name, names[i % 4]);
  }
  // Homing is the curves' (every joint homed by 11 s), then the lead-in.
  EXPECT_GT(rig.motion().homing_end_s(), 11.5);
  EXPECT_LT(rig.motion().homing_end_s(), 15.0);
  // A trial lasts about as long as seed 000's (25 trials in 7 min: 17 s).
  EXPECT_GT(rig.motion().cycle_s(), 6 * 14.0);
  EXPECT_LT(rig.motion().cycle_s(), 6 * 20.0);
  std::printf("homing + lead-in %.3f s, trial %.3f s\n", rig.motion().homing_end_s(),
              rig.motion().cycle_s());
}

TEST(SimTask, MotionStaysWithinTable5RangesAndTheJointLimits) {
  const sim::SimRig rig(options_of(sim_config()));
  const sim::SimMotion& m = rig.motion();
  const Sweep task = sweep(m, m.homing_end_s(), m.homing_end_s() + m.cycle_s());
  EXPECT_TRUE(task.within_limits);
  EXPECT_TRUE(sweep(m, 0.0, m.homing_end_s()).within_limits);  // homing and lead-in
  for (std::size_t j = 0; j < 6; ++j) {
    std::printf("joint %zu: %.2f .. %.2f deg (ROM %.2f, Table 5 %.1f)\n", j + 1, task.lo[j] / kDeg,
                task.hi[j] / kDeg, (task.hi[j] - task.lo[j]) / kDeg, sim::kTaskRomRad[j] / kDeg);
    EXPECT_LE(task.hi[j] - task.lo[j], sim::kTaskRomRad[j]) << "joint " << j + 1;
    EXPECT_GT(task.hi[j] - task.lo[j], 0.5 * sim::kTaskRomRad[j]) << "joint " << j + 1;
  }
}

TEST(SimTask, MotionKeepsTheEncodersSpeedBounds) {
  const auto cfg = sim_config();
  const sim::SimRig rig(options_of(cfg));
  const sim::SimMotion& m = rig.motion();
  const Sweep all = sweep(m, 0.0, m.homing_end_s() + m.cycle_s());
  const double fraction = m.options().task->file->speed_fraction;
  double closest = 0.0;
  for (std::size_t j = 0; j < 6; ++j) {
    const double bound = cfg.encoders.joints[j].max_speed_rad_s;
    EXPECT_LE(all.peak_speed[j], fraction * bound + 1e-9) << "joint " << j + 1;
    closest = std::max(closest, all.peak_speed[j] / (fraction * bound));
  }
  EXPECT_GT(closest, 0.999);  // some joint moves at its bound
  // Table III by anatomy (docs/simulator.md): the config holds these.
  const double expected[] = {0.64, 0.64, 1.06, 1.80, 5.38, 3.0};
  for (std::size_t j = 0; j < 6; ++j) {
    EXPECT_DOUBLE_EQ(cfg.encoders.joints[j].max_speed_rad_s, expected[j]);
  }
}

TEST(SimTask, EveryStopReachesItsPalmTarget) {
  const auto cfg = sim_config();
  const sim::SimRig rig(options_of(cfg));
  const sim::SimMotion& m = rig.motion();
  const sim::SimTaskPlan& plan = *m.task_plan();
  const auto& file = *cfg.source.section_as<SimSourceSettings>("sim")->task;
  for (const auto& stop : plan.stops) {
    const auto& step = file.loop[static_cast<std::size_t>(stop.step)];
    // The truth at the middle of the dwell is the planned posture...
    const double dwell = step.dwell_s;
    const auto x = m.truth(m.homing_end_s() + stop.arrive_s + 0.5 * dwell);
    for (std::size_t j = 0; j < 6; ++j) EXPECT_NEAR(x.position[j], stop.posture[j], 1e-12);
    // ...whose palm is at the stop's target (the file's, or drawn in the
    // random box): the position exactly, the orientation turned by the
    // adjustment that made it reachable (small for the file's own targets).
    exodaq::kinematics::JointVector q(6);
    for (int j = 0; j < 6; ++j) q[j] = stop.posture[static_cast<std::size_t>(j)];
    const exodaq::kinematics::Pose palm = cfg.model.chain.palm(q);
    EXPECT_LT((palm.translation() - stop.target.translation()).norm(), 1e-7) << step.name;
    const double turn = Eigen::AngleAxisd(palm.linear() * step.rotation.transpose()).angle();
    EXPECT_NEAR(turn, stop.adjust_rad, 1e-7) << step.name;
    const bool drawn = stop.step == 3;
    if (!drawn) {
      EXPECT_LT((palm.translation() - step.position_m).norm(), 1e-7) << step.name;
    }
    EXPECT_LT(stop.adjust_rad, (drawn ? 10.0 : 0.1) * kDeg) << step.name;
    // The file's azimuth is the posture's joint 1.
    EXPECT_NEAR(stop.posture[0], *step.azimuth_rad, 1e-9);
    std::printf("%-6s palm (%.1f, %.1f, %.1f) mm, adjusted %.4f deg, arrives %.3f s\n",
                step.name.c_str(), 1e3 * palm.translation().x(), 1e3 * palm.translation().y(),
                1e3 * palm.translation().z(), stop.adjust_rad / kDeg, stop.arrive_s);
  }
}

TEST(SimTask, EveryJointLatchesItsIndexAtLeastTwiceATrial) {
  const auto cfg = sim_config();
  auto o = options_of(cfg);
  sim::SimRig rig(o);
  sim::SimBoard::Frames frames{};
  const auto first = static_cast<std::int64_t>(rig.motion().homing_end_s() * 1000.0);
  const auto last = first + static_cast<std::int64_t>(rig.motion().cycle_s() * 1000.0);
  std::array<int, 6> latches{};
  for (std::int64_t k = 0; k < last; ++k) {
    rig.step(k, frames, 0, 0);
    for (int j = 0; j < 6; ++j) {
      if (k >= first && rig.encoders().latched(j)) ++latches[static_cast<std::size_t>(j)];
    }
  }
  for (std::size_t j = 0; j < 6; ++j) {
    EXPECT_GE(latches[j], 2) << "joint " << j + 1;
    // The index is the calibration's delta_theta0.
    EXPECT_DOUBLE_EQ(o.encoders[j].index_angle_rad, cfg.calibration.encoder_offset_rad[j]);
  }
}

TEST(SimTask, TheStreamIsDeterministicForASeedAndSampledWithoutAllocating) {
  const auto o = options_of(sim_config());
  SimSource a(o), b(o);
  a.start();
  b.start();
  EncoderSample sa, sb;
  std::uint64_t allocations = 0;
  for (std::int64_t k = 0; k < 30'000; ++k) {
    {
      exodaq::test::AllocationScope scope;
      a.read(CycleTime{.cycle = k}, sa);
      allocations += scope.count();
    }
    b.read(CycleTime{.cycle = k}, sb);
    ASSERT_EQ(sa.position, sb.position) << k;
    ASSERT_EQ(sa.index_latched, sb.index_latched) << k;
  }
  EXPECT_EQ(allocations, 0U);
}

TEST(SimTask, RandomTargetsAreDrawnInTheirBoxFromTheSeed) {
  std::string text = default_task_text(true);
  text +=
      "random:\n  steps: [feed, table]\n"
      "  box_mm: {min: [-145, 166, -13], max: [-135, 176, -3]}\n  trips: 4\n";
  const auto cfg = config_with_task(text);
  auto o = options_of(cfg);
  const sim::SimMotion m1(o.motion);
  auto o2 = o.motion;
  o2.seed = 2;
  const sim::SimMotion m2(o2);
  const auto& p1 = *m1.task_plan();
  ASSERT_EQ(p1.stops.size(), 16U);
  bool differs = false;
  for (std::size_t i = 0; i < p1.stops.size(); ++i) {
    const auto& s = p1.stops[i];
    const Eigen::Vector3d at = s.target.translation() * 1e3;
    if (s.step == 3) {
      EXPECT_TRUE(at.x() >= -145 && at.x() <= -135 && at.y() >= 166 && at.y() <= 176 &&
                  at.z() >= -13 && at.z() <= -3)
          << at.transpose();
      // The table keeps its offset from the feed target (of this trip).
      const Eigen::Vector3d d = p1.stops[i - 3].target.translation() * 1e3 - at;
      EXPECT_LT((d - Eigen::Vector3d(9.07, -99.98, -184.56)).norm(), 1e-6) << d.transpose();
    }
    differs =
        differs ||
        (s.target.translation() - m2.task_plan()->stops[i].target.translation()).norm() > 1e-6;
  }
  EXPECT_TRUE(differs);
  const sim::SimMotion again(o.motion);  // same seed, same plan
  for (std::size_t i = 0; i < p1.stops.size(); ++i) {
    EXPECT_EQ(p1.stops[i].posture, again.task_plan()->stops[i].posture);
  }
  // Four distinct trials, every joint still within Table 5 and crossing its index.
  const Sweep s = sweep(m1, m1.homing_end_s(), m1.homing_end_s() + m1.cycle_s());
  EXPECT_TRUE(s.within_limits);
  for (std::size_t j = 0; j < 6; ++j) EXPECT_LE(s.hi[j] - s.lo[j], sim::kTaskRomRad[j]) << j;
}

TEST(SimTask, BadTaskFilesAreFileLineErrors) {
  const std::string base = default_task_text(false);
  auto error_of = [](const std::string& text) -> std::string {
    try {
      const auto cfg = config_with_task(text);
      const sim::SimRig rig(options_of(cfg));
    } catch (const exodaq::ConfigError& e) {
      return std::to_string(e.line()) + ": " + e.reason();
    }
    return "accepted";
  };
  auto replace = [&](const std::string& from, const std::string& to) {
    std::string t = base;
    t.replace(t.find(from), from.size(), to);
    return t;
  };
  EXPECT_EQ(error_of(replace("hand: reaching,", "hand: waving,")),
            "25: no hand named 'waving' under hands");
  EXPECT_EQ(error_of(replace("hand: reaching,", "hand: reaching, rpy_deg: [0, 0, 0],")),
            "25: a step gives its palm orientation as either hand or rpy_deg");
  EXPECT_EQ(error_of(replace("dwell_s: 0.3}", "dwell_s: 0.3, speed: 2}"))
                .rfind("25: unknown key 'speed' in loop[1]", 0),
            0U);
  // 0.4 m from the shoulder: beyond the arm's 0.297 m.
  EXPECT_EQ(error_of(replace("[-115.11, 256.23, -96.31]", "[-115.11, 356.23, -196.31]")),
            "25: target out of reach: no palm orientation reaches its position (too near or too "
            "far)");
  EXPECT_EQ(error_of(replace("{min: [-145.7, 164.7, -14.1], max: [-133.7, 176.7, -2.1]}",
                             "{min: [0, 0, 300], max: [10, 10, 310]}")),
            "33: no reachable target in the random box for trip 1 in 100 draws (last: no palm "
            "orientation reaches its position (too near or too far))");
  // Azimuth 150 deg, beyond joint 1's 140.5 deg limit.
  EXPECT_EQ(error_of(replace("azimuth_deg: 26", "azimuth_deg: 150")),
            "25: target out of reach: no posture within the joint limits reaches it");
}

TEST(SimTask, TheHandMadeCurvesStayAvailable) {
  auto cfg = sim_config();
  exodaq::test::edit_section<SimSourceSettings>(cfg.source, "sim").motion = "curves";
  const sim::SimRig rig(options_of(cfg));
  EXPECT_EQ(rig.motion().task_plan(), nullptr);
  EXPECT_EQ(rig.motion().trip_segments().size(), 16U * 7U);
}

}  // namespace
