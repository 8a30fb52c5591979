// exodaq example-session: a session to follow docs/calibration.md and
// docs/shoulder-cor.md with, before the first real one.
//   exodaq example-session DIR [-c CONFIG] [--seconds 90] [--seed 1]
// The simulated rig of CONFIG (default: the shipped config/sim.yaml) moves
// every joint through most of its range after homing; its CAN frames are
// replayed into an LCM log as the daemon would have published them
// (session.lcm, with the raw channel). A motion-capture system watches the
// five markers of markers.yaml from a chosen camera pose, from its own clock
// (time 0 a few seconds after homing), and exports the capture in every
// format calibrate reads: markers.csv (the long CSV, epoch times), markers.c3d,
// markers_vicon.csv, markers_motive.csv. bounds.yaml brackets the truth
// (truth.yaml: the rig's true parameters, for comparison), and shoulder.c3d /
// shoulder.csv hold a capture of torso and upper-arm markers whose centre of
// rotation rises with elevation as in seed 001 Table II. Deterministic: the
// same options give the same files.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "command.hpp"
#include "exodaq/calibration/capture_writer.hpp"
#include "exodaq/calibration/marker_layout.hpp"
#include "exodaq/calibration/solver.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/settings/calibration_file.hpp"
#include "exodaq/settings/model_file.hpp"
#include "exodaq/settings/service_config.hpp"

namespace exodaq::tools {
namespace {

namespace cal = exodaq::calibration;
namespace sim = exodaq::drivers::sim;

constexpr double kDeg = 0.017453292519943295;
constexpr std::int64_t kWallStartNs = 1'767'261'600'000'000'000LL;  // 2026-01-01T10:00:00Z
constexpr double kMocapRateHz = 100.0;
constexpr double kNoiseMm = 0.3;

struct ExampleOptions {
  std::string dir, config;
  double seconds = 90.0;
  std::uint64_t seed = 1;
};

// The shipped simulated-rig config, next to the default model.
std::string default_sim_config() {
  const std::filesystem::path model = settings::default_model_path();
  return (model.parent_path().parent_path() / "sim.yaml").string();
}

void write(const std::string& path, const std::string& bytes) {
  files::write_output(path, bytes);
}

// The config's text with its relative model, calibration and task paths made
// absolute (absolute and quoted ones are kept), so the copy works from the
// example folder.
std::string portable_config(const settings::ServiceConfig& cfg) {
  std::ifstream in(cfg.file);
  std::stringstream text;
  text << in.rdbuf();
  std::string s = text.str();
  const std::string dir = std::filesystem::absolute(cfg.file).parent_path().string();
  for (const char* key : {"model", "calibration", "task"}) {
    const std::regex line("(^|\\n)(\\s*" + std::string(key) + ":\\s*)([^\\s#/\"'][^\\s#]*)");
    s = std::regex_replace(s, line, "$1$2" + dir + "/$3");
  }
  return s;
}

// --- the recording ----------------------------------------------------------------

// A calibration motion: after homing, rest-to-rest moves between random
// postures spanning most of every joint's range (seed 000 §4: "all six
// joints through as much of their range as possible").
sim::SimOptions calibration_motion(const settings::ServiceConfig& cfg, std::uint64_t seed) {
  const drivers::SourceContext ctx = settings::make_source_context(cfg);
  sim::SimOptions o = drivers::sim_options_from(cfg.source, ctx);
  o.seed = seed;
  o.faults.clear();
  o.loss_percent = 0;
  o.jitter_ns = 0;
  o.motion.task.reset();
  o.motion.grasp_hold_s = o.motion.feed_hold_s = o.motion.home_hold_s = 0.1;
  for (int j = 0; j < sim::kJoints; ++j) {
    const auto i = static_cast<std::size_t>(j);
    const double home = o.motion.home_rad[i];
    o.motion.task_lower_rad[i] =
        std::min(home, std::max(o.motion.lower_limit_rad[i] + 8 * kDeg, home - 60 * kDeg));
    o.motion.task_upper_rad[i] =
        std::max(home, std::min(o.motion.upper_limit_rad[i] - 8 * kDeg, home + 60 * kDeg));
  }
  return o;
}

std::string candump_line(const drivers::can::CanFrame& f) {
  char buf[96];
  int n = std::snprintf(buf, sizeof buf, "(%lld.%06lld) can0 %03X#",
                        static_cast<long long>(f.wall_ns / 1'000'000'000),
                        static_cast<long long>((f.wall_ns % 1'000'000'000) / 1000), f.id);
  for (int i = 0; i < f.dlc && i < 8; ++i) {
    n += std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), "%02X",
                       f.data[static_cast<std::size_t>(i)]);
  }
  return std::string(buf) + "\n";
}

// The rig's CAN frames as candump -l writes them, replayed into session.lcm.
void write_recording(const ExampleOptions& o, const sim::SimOptions& so, const std::string& config,
                     std::int64_t cycles) {
  TempDir tmp("example");
  const std::string dump = tmp.file("session.candump");
  {
    std::ofstream out(dump);
    sim::SimRig rig(so);
    sim::SimBoard::Frames frames{};
    for (std::int64_t k = 0; k < cycles; ++k) {
      const int n = rig.step(k, frames, kWallStartNs, 0);
      for (int i = 0; i < n; ++i) out << candump_line(frames[static_cast<std::size_t>(i)]);
    }
    if (!out) throw std::runtime_error(dump + ": cannot write");
  }
  const int rc =
      run_child({self_path(), "replay", dump, "-c", config, "-o", o.dir + "/session.lcm", "-q"});
  if (rc != 0)
    throw std::runtime_error("exodaq replay of the simulated frames failed (exit " +
                             std::to_string(rc) + ")");
}

// --- the motion capture of the calibration markers --------------------------------------

// The rig as the markers see it: the sim's encoder offsets (its index
// angles), small deviations of the nominal model, and the camera pose chosen.
cal::ParamVector true_parameters(const settings::ServiceConfig& cfg) {
  cal::ParamVector x{};
  for (int j = 0; j < cal::kJoints; ++j) {
    x[cal::kTheta1 + j] = cfg.calibration.encoder_offset_rad[static_cast<std::size_t>(j)];
  }
  const double mm = 1e-3;
  x[cal::kDd2] = 0.8 * mm;
  x[cal::kDd3] = -0.5 * mm;
  x[cal::kDd5] = 1.5 * mm;
  x[cal::kDa3] = -2.0 * mm;
  x[cal::kDa5] = 0.6 * mm;
  x[cal::kPx] = 0.4 * mm;
  x[cal::kPy] = -0.3 * mm;
  x[cal::kPz] = -6.0 * mm;
  x[cal::kDx] = 250.0 * mm;
  x[cal::kDy] = 880.0 * mm;
  x[cal::kDz] = 260.0 * mm;
  x[cal::kPhiX] = -90.0 * kDeg;
  x[cal::kPhiY] = 0.5 * kDeg;
  x[cal::kPhiZ] = -120.0 * kDeg;
  return x;
}

// config/calibration/markers_example.yaml's markers.
cal::MarkerLayout example_layout() {
  cal::MarkerLayout l;
  l.source = "markers.yaml";
  l.sites = {{3, cal::MarkerMount::kHand, {0.0, 0.0, 0.0}, "palm"},
             {4, cal::MarkerMount::kHand, {0.020, 0.0, -0.070}, "forearm"},
             {10, cal::MarkerMount::kBase, {-0.120, 0.080, -0.060}, "base1"},
             {11, cal::MarkerMount::kBase, {-0.120, -0.080, -0.060}, "base2"},
             {12, cal::MarkerMount::kBase, {-0.180, 0.0, 0.050}, "base3"}};
  return l;
}

std::string layout_yaml(const cal::MarkerLayout& l) {
  std::string s =
      "# The example session's markers (docs/calibration.md §3.5): `id` in markers.csv,\n"
      "# `label` in markers.c3d, markers_vicon.csv and markers_motive.csv. Positions in mm.\n"
      "format: exodaq-marker-layout-1\nmarkers:\n";
  for (const auto& site : l.sites) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "  - {id: %d, label: %s, on: %s, position_mm: [%g, %g, %g]}\n",
                  site.id, site.label.c_str(), cal::mount_name(site.mount), site.position[0] * 1e3,
                  site.position[1] * 1e3, site.position[2] * 1e3);
    s += buf;
  }
  return s;
}

// The bounds: initial guesses a few degrees and millimetres off the truth, as
// measured by hand; the ranges of config/calibration/bounds_seed000.yaml.
std::string bounds_yaml(const cal::ParamVector& truth) {
  const double off[cal::kParams] = {2.0, -1.5, 2.5, -1.0, 3.0, -2.0, 0,  0,   0,    0,
                                    0,   0,    0,   0,    20,  -15,  25, 2.0, -1.5, 3.0};
  std::string s =
      "# Bounds and initial guesses for the example session (docs/calibration.md §3.2):\n"
      "# the guesses are a few degrees and millimetres off the rig's truth (truth.yaml).\n"
      "format: exodaq-calibration-bounds-1\nparameters:\n";
  for (int p = 0; p < cal::kParams; ++p) {
    const double half = cal::is_angle(p) ? 10.0 : (p >= cal::kDx ? 100.0 : 20.0);
    const double initial = cal::to_display(p, truth[p]) + off[p];
    char buf[160];
    std::snprintf(buf, sizeof buf, "  %s: {initial: %.3f, lower: %.3f, upper: %.3f}\n",
                  cal::param_key(p), initial, initial - half, initial + half);
    s += buf;
  }
  return s + "time_offset_ms: {initial: 0, lower: -50, upper: 50}\n";
}

// The capture from t0 for `seconds` at 100 Hz: 0.3 mm noise, the forearm
// marker hidden now and then, base2 hidden for half a second.
cal::Capture calibration_capture(const settings::ServiceConfig& cfg, const sim::SimMotion& motion,
                                 const cal::ParamVector& truth, double t0, double seconds,
                                 std::uint64_t seed) {
  const cal::NominalModel model = cal::nominal_from_chain(cfg.model.chain);
  const cal::MarkerLayout layout = example_layout();
  cal::Capture c;
  c.rate_hz = kMocapRateHz;
  for (const auto& site : layout.sites) {
    c.labels.push_back(site.label);
    c.ids.push_back(site.id);
  }
  std::mt19937_64 rng(seed * 7919 + 17);
  std::normal_distribution<double> noise(0.0, kNoiseMm);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto n = static_cast<int>(seconds * kMocapRateHz);
  for (int k = 0; k < n; ++k) {
    const double t = t0 + k / kMocapRateHz;
    const auto q = motion.position(t);
    std::array<double, cal::kJoints> theta_r{};
    for (int j = 0; j < cal::kJoints; ++j) {
      const auto i = static_cast<std::size_t>(j);
      theta_r[i] = q[i] - cfg.calibration.encoder_offset_rad[i];
    }
    std::vector<std::optional<Eigen::Vector3d>> frame;
    for (const auto& site : layout.sites) {
      Eigen::Vector3d p = cal::predict_marker(model, truth, theta_r, site) * 1e3;
      p += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      const bool hidden =
          (site.id == 4 && u(rng) < 0.02) || (site.id == 11 && k >= 1000 && k < 1050);
      frame.push_back(hidden ? std::nullopt : std::optional<Eigen::Vector3d>(p));
    }
    c.frames.push_back(std::move(frame));
  }
  return c;
}

// --- the shoulder capture ------------------------------------------------------------

// Seed 001 Table II: the centre's rise (mm) at the centres of the 20° bins.
constexpr double kTable2Mm[] = {0, 4, 13, 27, 43, 62};

double rise_m(double e) {
  const double x = std::clamp(e / (20 * kDeg) - 0.5, 0.0, 5.0);
  const auto i = std::min<std::size_t>(4, static_cast<std::size_t>(x));
  return (kTable2Mm[i] + (x - static_cast<double>(i)) * (kTable2Mm[i + 1] - kTable2Mm[i])) * 1e-3;
}

// Five torso markers (T1 cranial, T2 caudal) and seven on the upper arm (H1
// proximal, H2 distal); the arm raised 5..115° and back every 60 s while its
// plane of elevation and axial rotation vary; the torso sways.
cal::Capture shoulder_capture(double seconds, std::uint64_t seed) {
  const Eigen::Vector3d torso[5] = {{0.0, 0.05, 0.02},
                                    {0.0, -0.10, 0.02},
                                    {0.06, 0.0, 0.03},
                                    {-0.06, 0.0, 0.03},
                                    {0.03, -0.05, 0.05}};
  const Eigen::Vector3d arm[7] = {{0.0, -0.020, 0.012},    {0.0, -0.110, 0.012},
                                  {0.015, -0.040, 0.0},    {-0.015, -0.060, 0.010},
                                  {0.012, -0.080, -0.012}, {-0.010, -0.095, -0.010},
                                  {0.0, -0.050, -0.016}};
  cal::Capture c;
  c.rate_hz = kMocapRateHz;
  for (int m = 0; m < 5; ++m) {
    c.labels.push_back("T" + std::to_string(m + 1));
    c.ids.push_back(m + 1);
  }
  for (int m = 0; m < 7; ++m) {
    c.labels.push_back("H" + std::to_string(m + 1));
    c.ids.push_back(m + 11);
  }
  std::mt19937_64 rng(seed * 104729 + 3);
  std::normal_distribution<double> noise(0.0, kNoiseMm * 1e-3);
  const auto n = static_cast<int>(seconds * kMocapRateHz);
  for (int k = 0; k < n; ++k) {
    const double t = k / kMocapRateHz;
    const double e = (5.0 + 110.0 * (0.5 - 0.5 * std::cos(2 * M_PI * t / 60.0))) * kDeg;
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(35 * kDeg * std::sin(2 * M_PI * t / 7.3), Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(e, Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(40 * kDeg * std::sin(2 * M_PI * t / 5.1 + 1.0),
                           Eigen::Vector3d::UnitY()))
            .toRotationMatrix();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() =
        Eigen::Vector3d(0.30, 0.90, 0.50) +
        0.015 * Eigen::Vector3d(std::sin(2 * M_PI * t / 11.0), std::sin(2 * M_PI * t / 13.0 + 0.5),
                                std::sin(2 * M_PI * t / 17.0 + 1.0));
    T.linear() =
        (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(8 * kDeg * std::sin(2 * M_PI * t / 12.0),
                           Eigen::Vector3d(std::sin(t / 1.4), std::cos(t / 2.2), 0.5).normalized()))
            .toRotationMatrix();
    const double v = rise_m(e);
    const Eigen::Vector3d centre(0.07, v, v / 3.0);
    std::vector<std::optional<Eigen::Vector3d>> frame;
    for (const auto& p : torso)
      frame.emplace_back((T * p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))) * 1e3);
    for (const auto& p : arm) {
      frame.emplace_back(
          (T * (centre + R * p) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))) * 1e3);
    }
    c.frames.push_back(std::move(frame));
  }
  return c;
}

// --- the command ------------------------------------------------------------------------

int run_example(const ExampleOptions& o) {
  const std::string config_in = o.config.empty() ? default_sim_config() : o.config;
  const settings::ServiceConfig cfg = settings::load_service_config(config_in);
  std::filesystem::create_directories(o.dir);
  const std::string config = o.dir + "/exodaqd.yaml";
  write(config, portable_config(cfg));

  const sim::SimOptions so = calibration_motion(cfg, o.seed);
  const sim::SimRig timing(so);
  const double homed = timing.motion().homing_end_s();
  const auto cycles = static_cast<std::int64_t>(
      std::ceil((homed + o.seconds) * 1e9 / static_cast<double>(so.period_ns)));
  std::cout << "recording: the simulated rig of " << config_in << ", homing for " << homed
            << " s, then " << o.seconds << " s of calibration motion" << std::endl;
  write_recording(o, so, config, cycles);

  const cal::ParamVector truth = true_parameters(cfg);
  const double t0 = homed + 2.0, span = o.seconds - 4.0;
  const cal::Capture c = calibration_capture(cfg, timing.motion(), truth, t0, span, o.seed);
  const auto epoch_us = static_cast<std::int64_t>(kWallStartNs / 1000 + std::llround(t0 * 1e6));
  write(o.dir + "/markers.csv", cal::long_csv_bytes(c, epoch_us));
  write(o.dir + "/markers.c3d", cal::c3d_bytes(c));
  write(o.dir + "/markers_vicon.csv", cal::vicon_csv_bytes(c, "exo"));
  write(o.dir + "/markers_motive.csv", cal::motive_csv_bytes(c, "2026-01-01 11.00.00.000 AM"));
  write(o.dir + "/markers.yaml", layout_yaml(example_layout()));
  write(o.dir + "/bounds.yaml", bounds_yaml(truth));
  settings::write_calibration_file(o.dir + "/truth.yaml", cal::to_calibration(truth));

  const cal::Capture shoulder = shoulder_capture(120.0, o.seed);
  write(o.dir + "/shoulder.c3d", cal::c3d_bytes(shoulder));
  write(o.dir + "/shoulder.csv", cal::long_csv_bytes(shoulder, kWallStartNs / 1000));

  std::cout << "written to " << o.dir << ":\n"
            << "  exodaqd.yaml        the simulated rig's config (its calibration: the encoder "
               "offsets the sim uses)\n"
            << "  session.lcm         the recording (raw counts and joint states), " << cycles
            << " cycles\n"
            << "  markers.csv         the motion capture, long CSV with epoch times (the capture "
               "starts "
            << t0 << " s into the recording)\n"
            << "  markers.c3d, markers_vicon.csv, markers_motive.csv\n"
            << "                      the same capture on the mocap's own clock (time 0 at its "
               "first frame)\n"
            << "  markers.yaml        where the five markers sit\n"
            << "  bounds.yaml         initial guesses and bounds\n"
            << "  truth.yaml          the parameters the capture was made with\n"
            << "  shoulder.c3d, shoulder.csv  a torso and upper-arm capture for shoulder-cor\n";
  return kExitOk;
}

}  // namespace

EXODAQ_REGISTER_COMMAND(
    example_session, "example-session",
    "Write an example session to follow docs/calibration.md and docs/shoulder-cor.md with: a "
    "recording of the simulated rig, its motion capture in every supported format, bounds",
    [](CLI::App& app) -> std::function<int()> {
      auto o = std::make_shared<ExampleOptions>();
      app.add_option("dir", o->dir, "folder to write (created)")->required();
      app.add_option("-c,--config", o->config,
                     "the simulated rig's config (default: the shipped sim.yaml)");
      app.add_option("--seconds", o->seconds, "seconds of motion after homing (default 90)")
          ->check(CLI::Range(30.0, 600.0));
      app.add_option("--seed", o->seed, "the motion and the noise (default 1)");
      return [o]() -> int { return run_example(*o); };
    });

}  // namespace exodaq::tools
