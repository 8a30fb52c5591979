// exodaq calibrate: offline kinematic calibration (seed 000 §4, issue 8).
//   exodaq calibrate --encoders LOG.csv --markers MOCAP.csv --bounds B.yaml --out cal.yaml
//                    [--model M] [--validate [ENC.csv,]MOCAP.csv ...] [--robust huber|cauchy]
//                    [--estimate-time-offset] [--plot out.png] [--max-points N]
// docs/calibration.md describes the procedure, the files and the report.
#include <chrono>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/calibration/inputs.hpp"
#include "exodaq/calibration/report.hpp"
#include "exodaq/calibration/solver.hpp"
#include "exodaq/config/calibration_file.hpp"
#include "exodaq/config/model_file.hpp"
#include "exodaq/version.hpp"

namespace exodaq::tools {
namespace {

namespace cal = exodaq::calibration;

struct CalibrateOptions {
  std::string encoders, markers, model, bounds, out, plot, residuals;
  std::vector<std::string> validate;
  std::string robust = "none";
  double robust_scale_mm = 1.0;
  bool estimate_time_offset = false;
  std::size_t max_points = 0;
  int marker_id = -1;
  double max_gap_ms = 5.0;
  bool quiet = false;
};

std::string utc_now() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string mm(double m) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", m * 1e3);
  return buf;
}

int run_calibrate(const CalibrateOptions& o) {
  auto progress = [&](const std::string& s) {
    if (!o.quiet) std::cout << s << std::endl;
  };
  const std::string model_path = o.model.empty() ? config::default_model_path() : o.model;
  const config::KinematicModel model = config::load_model_file(model_path);
  const cal::NominalModel nominal = cal::nominal_from_chain(model.chain);
  const cal::Bounds bounds = cal::load_bounds_file(o.bounds);
  progress("model " + model_path + " (" + model.name + "), bounds " + o.bounds);

  cal::SolveOptions so;
  if (o.robust == "huber") so.loss = cal::RobustLoss::kHuber;
  if (o.robust == "cauchy") so.loss = cal::RobustLoss::kCauchy;
  so.loss_scale_m = o.robust_scale_mm * 1e-3;
  so.estimate_time_offset = o.estimate_time_offset;
  so.progress = progress;

  cal::AlignmentOptions ao;
  ao.max_points = o.max_points;
  ao.max_gap_us = static_cast<std::int64_t>(o.max_gap_ms * 1000.0);
  if (o.estimate_time_offset) {
    ao.guard_us = static_cast<std::int64_t>(
        1e6 * std::max(std::abs(bounds.time_offset.lower_s), std::abs(bounds.time_offset.upper_s)));
  }

  const cal::EncoderSeries enc = cal::read_encoder_log(o.encoders);
  const cal::MarkerSeries mk = cal::read_marker_csv(o.markers, o.marker_id);
  progress("encoders " + o.encoders + ": " + std::to_string(enc.samples.size()) + " samples");
  cal::AlignmentStats st;
  const auto points = cal::align(enc, mk, ao, st);
  cal::print_alignment(std::cout, o.markers, st);

  const cal::Report report = cal::calibrate(nominal, points, bounds, so, &enc);
  const cal::ParamVector x = cal::estimates(report);
  const cal::ParamVector x0 = cal::initial_params(bounds);

  std::vector<cal::ValidationResult> validation;
  std::vector<std::vector<std::int64_t>> validation_utime;
  std::vector<std::string> inputs = {o.encoders, o.markers};
  for (const std::string& v : o.validate) {
    const auto comma = v.find(',');
    const std::string venc_path = comma == std::string::npos ? o.encoders : v.substr(0, comma);
    const std::string vmk_path = comma == std::string::npos ? v : v.substr(comma + 1);
    const cal::EncoderSeries venc =
        venc_path == o.encoders ? enc : cal::read_encoder_log(venc_path);
    const cal::MarkerSeries vmk = cal::read_marker_csv(vmk_path, o.marker_id);
    cal::ValidationResult r;
    r.name = vmk_path;
    cal::AlignmentOptions vao = ao;
    vao.guard_us = 0;
    auto vpts = cal::align(venc, vmk, vao, r.alignment);
    cal::print_alignment(std::cout, "validate " + vmk_path, r.alignment);
    if (report.time_offset_s) {
      // Apply the estimated clock offset: shift the marker times.
      cal::MarkerSeries shifted = vmk;
      for (auto& s : shifted.samples) {
        s.utime_us += static_cast<std::int64_t>(std::llround(*report.time_offset_s * 1e6));
      }
      vpts = cal::align(venc, shifted, vao, r.alignment);
    }
    r.points = vpts.size();
    r.before = cal::evaluate(nominal, x0, vpts, &r.residual_before);
    r.after = cal::evaluate(nominal, x, vpts, &r.residual_after);
    std::vector<std::int64_t> t;
    for (const auto& p : vpts) t.push_back(p.utime_us);
    validation_utime.push_back(std::move(t));
    validation.push_back(std::move(r));
    inputs.push_back("validate: " + venc_path + " + " + vmk_path);
  }

  cal::print_report(std::cout, report, validation);

  config::Calibration out = cal::to_calibration(x);
  auto& p = out.provenance;
  p.created_by = std::string("exodaq calibrate ") + kVersion + " (" + kGitDescribe + ")";
  p.date = utc_now();
  p.model = model_path;
  p.inputs = inputs;
  p.rms_before_m = report.before.rms_m;
  p.rms_after_m = report.after.rms_m;
  p.samples = static_cast<int>(report.points);
  std::string notes = "bounds " + o.bounds + "; robust loss " + o.robust;
  std::string held, gauge, bound;
  for (int k = 0; k < cal::kParams; ++k) {
    const auto s = report.params[k].status;
    const std::string name = cal::param_key(k);
    if (s == cal::ParamStatus::kHeld) held += (held.empty() ? "" : ", ") + name;
    if (s == cal::ParamStatus::kGaugeDependent) gauge += (gauge.empty() ? "" : ", ") + name;
    if (s == cal::ParamStatus::kAtBound) bound += (bound.empty() ? "" : ", ") + name;
  }
  if (!held.empty()) notes += "; unidentifiable, held at prior: " + held;
  if (!gauge.empty()) notes += "; gauge-dependent (follow the held priors): " + gauge;
  if (!bound.empty()) notes += "; at bound: " + bound;
  if (report.time_offset_s) notes += "; time offset " + mm(*report.time_offset_s) + " ms";
  for (const auto& v : validation) {
    notes += "; validate " + v.name + ": RMS " + mm(v.after.rms_m) + " mm";
  }
  p.notes = notes;
  config::write_calibration_file(o.out, out);
  std::cout << "\ncalibration written to " << o.out << " (RMS " << mm(report.before.rms_m) << " -> "
            << mm(report.after.rms_m) << " mm)\n";

  if (!o.plot.empty() || !o.residuals.empty()) {
    std::string csv = o.residuals;
    if (csv.empty()) {
      const auto dot = o.plot.rfind('.');
      csv = (dot == std::string::npos ? o.plot : o.plot.substr(0, dot)) + "_residuals.csv";
    }
    std::vector<std::int64_t> t;
    for (const auto& pt : points) t.push_back(pt.utime_us);
    cal::write_residual_csv(csv, t, report, validation, validation_utime);
    std::cout << "residuals written to " << csv << "\n";
    if (!o.plot.empty()) {
      std::string message;
      cal::plot_residuals(csv, o.plot, message);
      std::cout << message << "\n";
    }
  }
  return kExitOk;
}

}  // namespace

EXODAQ_REGISTER_COMMAND(
    calibrate, "calibrate",
    "Identify encoder offsets, DH deviations, marker offset and camera transform from an encoder "
    "log and motion-capture data (seed 000 §4); writes the calibration file the daemon reads",
    [](CLI::App& app) -> std::function<int()> {
      auto o = std::make_shared<CalibrateOptions>();
      app.add_option("--encoders", o->encoders,
                     "encoder log: CSV utime_us,j1_rad..j6_rad[,homed_mask,fault_mask]")
          ->required();
      app.add_option("--markers", o->markers, "mocap CSV utime_us,x_mm,y_mm,z_mm[,marker_id]")
          ->required();
      app.add_option("--bounds", o->bounds, "bounds and initial guesses (YAML)")->required();
      app.add_option("--out", o->out, "calibration file to write")->required();
      app.add_option("--model", o->model, "kinematic model file (default: macaque_exo.yaml)");
      app.add_option("--validate", o->validate,
                     "cross-validation sets: MOCAP.csv (same encoder log) or ENC.csv,MOCAP.csv");
      app.add_option("--robust", o->robust, "robust loss")
          ->check(CLI::IsMember({"none", "huber", "cauchy"}));
      app.add_option("--robust-scale-mm", o->robust_scale_mm,
                     "residual per axis where the robust loss bends (default 1 mm)");
      app.add_flag("--estimate-time-offset", o->estimate_time_offset,
                   "estimate a constant offset between the two clocks");
      app.add_option("--plot", o->plot, "residual figure (PNG; needs python3-matplotlib)");
      app.add_option("--residuals", o->residuals, "residual CSV (default: next to --plot)");
      app.add_option("--max-points", o->max_points, "use at most N points, evenly spread");
      app.add_option("--marker-id", o->marker_id, "marker to use when the CSV holds several");
      app.add_option("--max-gap-ms", o->max_gap_ms,
                     "largest encoder gap to interpolate across (default 5 ms)");
      app.add_flag("--quiet", o->quiet, "no solver progress");
      return [o] { return run_calibrate(*o); };
    });

}  // namespace exodaq::tools
