// exodaq calibrate: offline kinematic calibration (seed 000 §4, issues 8 and 18).
//   exodaq calibrate --encoders ENC --markers MOCAP.csv --bounds B.yaml -o cal.yaml
//                    [-c CONFIG] [--recorded-calibration FILE] [--prefix P]
//                    [--model M] [--marker-layout L.yaml | --marker-id N]
//                    [--validate [ENC,]MOCAP.csv ...] [--robust huber|cauchy]
//                    [--estimate-time-offset] [--plot out.png] [--max-points N]
// ENC: calibrate's own CSV (θᴿ), the CSV of `exodaq export`, or an LCM log
// (lcm-logger, exodaq replay). The project's recordings hold calibrated
// angles: with -c CONFIG an LCM log's raw channel is re-processed by `exodaq
// replay` (θᴿ whatever calibration the rig ran with); otherwise the joint
// angles less the offsets of --recorded-calibration (default: the config's).
// Every output is a files::OutputFile. docs/calibration.md describes the
// procedure, the files and the report.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "command.hpp"
#include "exodaq/calibration/inputs.hpp"
#include "exodaq/calibration/report.hpp"
#include "exodaq/calibration/solver.hpp"
#include "exodaq/config/calibration_file.hpp"
#include "exodaq/config/model_file.hpp"
#include "exodaq/config/service_config.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/version.hpp"

namespace exodaq::tools {
namespace {

namespace cal = exodaq::calibration;

struct CalibrateOptions {
  std::string encoders, markers, model, bounds, out, plot, residuals, marker_layout;
  std::string config, recorded_calibration, prefix;
  std::vector<std::string> validate;
  std::string robust = "none";
  double robust_scale_mm = 1.0;
  bool estimate_time_offset = false;
  std::size_t max_points = 0;
  int marker_id = -1;
  double max_gap_ms = 5.0;
  bool quiet = false;  // common -q
  // Every file read, so no output replaces one.
  std::vector<std::string> inputs() const {
    std::vector<std::string> in{
        encoders, markers, bounds, model, marker_layout, config, recorded_calibration};
    for (const auto& v : validate) {
      const auto comma = v.find(',');
      in.push_back(v.substr(0, comma));
      if (comma != std::string::npos) in.push_back(v.substr(comma + 1));
    }
    return in;
  }
};

// How encoder logs are read: the offsets of the calibration the recorded
// angles were computed with (--recorded-calibration, else the config's).
struct EncoderSource {
  cal::EncoderReadOptions read;
  std::optional<config::ServiceConfig> config;
};

EncoderSource encoder_source(const CalibrateOptions& o) {
  EncoderSource src;
  if (!o.config.empty()) src.config = config::load_service_config(o.config);
  if (!o.recorded_calibration.empty()) {
    src.read.recorded_offsets_rad =
        config::load_calibration_file(o.recorded_calibration).encoder_offset_rad;
    src.read.recorded_calibration = o.recorded_calibration;
  } else if (src.config) {
    src.read.recorded_offsets_rad = src.config->calibration.encoder_offset_rad;
    src.read.recorded_calibration =
        src.config->calibration_path + " (the calibration of " + o.config + ")";
  }
  if (!o.prefix.empty()) src.read.prefix = o.prefix;
  return src;
}

bool is_lcm_log(const std::string& path) {
  try {
    msg::LogReader probe(path);
    return true;
  } catch (const msg::LogError&) {
    return false;
  }
}

// The raw channel an LCM log holds for the rig, "" when none.
std::string raw_channel(const std::string& path, const std::optional<std::string>& prefix) {
  std::string found;
  for (const auto& [channel, n] : msg::scan_channels(path)) {
    const auto parts = msg::split_channel(channel);
    if (!parts || parts->kind != msg::Kind::kEncoderRaw) continue;
    if (prefix && parts->prefix != *prefix) continue;
    if (!found.empty()) return "";  // several rigs: let the joint-state reader say so
    found = channel;
  }
  return found;
}

// θᴿ from an LCM log's raw channel: `exodaq replay` with the config (its
// encoders and calibration), then the replayed joint states less that
// calibration's offsets. Independent of the calibration the rig ran with.
cal::EncoderSeries read_raw_log(const std::string& path, const std::string& channel,
                                const CalibrateOptions& o, const EncoderSource& src) {
  TempDir tmp("calibrate");
  const std::string replayed = tmp.file("replayed.lcm");
  const int rc = run_child(
      {self_path(), "replay", path, "-c", o.config, "-o", replayed, "--channel", channel, "-q"});
  if (rc != 0) {
    throw std::runtime_error(path +
                             ": re-processing its raw channel with exodaq replay failed "
                             "(exit " +
                             std::to_string(rc) + ")");
  }
  cal::EncoderReadOptions ro = src.read;
  ro.recorded_offsets_rad = src.config->calibration.encoder_offset_rad;
  ro.recorded_calibration = src.config->calibration_path;
  ro.prefix.reset();
  cal::EncoderSeries s = cal::read_joint_state_log(replayed, ro);
  s.source = path;
  s.notes.clear();
  s.notes.push_back(path + ": " + std::to_string(s.samples.size()) + " samples from " + channel +
                    ", re-processed with " + o.config + " (theta_R from the raw counts)");
  return s;
}

cal::EncoderSeries read_encoders(const std::string& path, const CalibrateOptions& o,
                                 const EncoderSource& src) {
  if (src.config && o.recorded_calibration.empty() && is_lcm_log(path)) {
    const std::string raw = raw_channel(path, src.read.prefix);
    if (!raw.empty()) return read_raw_log(path, raw, o, src);
  }
  return cal::read_encoder_log(path, src.read);
}

// What the command reads besides the data.
struct Setup {
  EncoderSource encoders;
  std::string model_path;
  cal::NominalModel nominal;
  cal::Bounds bounds;
  std::optional<cal::MarkerLayout> layout;
};

// The training data and the validation sets, aligned.
struct Data {
  cal::EncoderSeries encoders;
  std::vector<cal::AlignedSample> points;
  std::vector<cal::ValidationResult> validation;
  std::vector<std::vector<std::int64_t>> validation_utime;
  std::vector<std::string> inputs;  // for the provenance
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

Setup load_setup(const CalibrateOptions& o) {
  Setup s;
  s.encoders = encoder_source(o);
  s.model_path = o.model.empty() ? config::default_model_path() : o.model;
  const config::KinematicModel model = config::load_model_file(s.model_path);
  s.nominal = cal::nominal_from_chain(model.chain);
  s.bounds = cal::load_bounds_file(o.bounds);
  if (!o.marker_layout.empty()) s.layout = cal::load_marker_layout_file(o.marker_layout);
  if (!o.quiet) {
    std::cout << "model " << s.model_path << " (" << model.name << "), bounds " << o.bounds
              << (s.layout ? ", marker layout " + o.marker_layout : std::string()) << std::endl;
  }
  return s;
}

cal::SolveOptions solve_options(const CalibrateOptions& o) {
  cal::SolveOptions so;
  if (o.robust == "huber") so.loss = cal::RobustLoss::kHuber;
  if (o.robust == "cauchy") so.loss = cal::RobustLoss::kCauchy;
  so.loss_scale_m = o.robust_scale_mm * 1e-3;
  so.estimate_time_offset = o.estimate_time_offset;
  if (!o.quiet) so.progress = [](const std::string& s) { std::cout << s << std::endl; };
  return so;
}

cal::AlignmentOptions alignment_options(const CalibrateOptions& o, const cal::Bounds& bounds) {
  cal::AlignmentOptions ao;
  ao.max_points = o.max_points;
  ao.max_gap_us = static_cast<std::int64_t>(o.max_gap_ms * 1000.0);
  if (o.estimate_time_offset) {
    ao.guard_us = static_cast<std::int64_t>(
        1e6 * std::max(std::abs(bounds.time_offset.lower_s), std::abs(bounds.time_offset.upper_s)));
  }
  return ao;
}

// The marker CSV: the layout's markers, or one marker (--marker-id).
cal::MarkerSeries read_markers(const std::string& path, const CalibrateOptions& o, const Setup& s) {
  return s.layout ? cal::read_marker_csv_ids(path, s.layout->ids())
                  : cal::read_marker_csv(path, o.marker_id);
}

std::vector<cal::AlignedSample> align_points(const cal::EncoderSeries& enc,
                                             const cal::MarkerSeries& markers,
                                             const cal::AlignmentOptions& ao, const Setup& s,
                                             const std::string& label, cal::AlignmentStats& st) {
  auto points = cal::align(enc, markers, ao, st);
  if (s.layout) cal::apply_layout(points, *s.layout);
  cal::print_alignment(std::cout, label, st);
  return points;
}

// Apply the estimated clock offset to a validation set: shift the marker times.
cal::MarkerSeries shifted(cal::MarkerSeries m, const cal::Report& report) {
  if (report.time_offset_s) {
    for (auto& s : m.samples) {
      s.utime_us += static_cast<std::int64_t>(std::llround(*report.time_offset_s * 1e6));
    }
  }
  return m;
}

void validate_one(const std::string& spec, const CalibrateOptions& o, const Setup& s,
                  const cal::Report& report, Data& d) {
  const auto comma = spec.find(',');
  const std::string venc_path = comma == std::string::npos ? o.encoders : spec.substr(0, comma);
  const std::string vmk_path = comma == std::string::npos ? spec : spec.substr(comma + 1);
  const cal::EncoderSeries venc =
      venc_path == o.encoders ? d.encoders : read_encoders(venc_path, o, s.encoders);
  const cal::MarkerSeries vmk = shifted(read_markers(vmk_path, o, s), report);
  cal::AlignmentOptions vao = alignment_options(o, s.bounds);
  vao.guard_us = 0;
  cal::ValidationResult r;
  r.name = vmk_path;
  const auto vpts = align_points(venc, vmk, vao, s, "validate " + vmk_path, r.alignment);
  r.points = vpts.size();
  r.before = cal::evaluate(s.nominal, cal::initial_params(s.bounds), vpts, &r.residual_before);
  r.after = cal::evaluate(s.nominal, cal::estimates(report), vpts, &r.residual_after);
  std::vector<std::int64_t> t;
  for (const auto& p : vpts) t.push_back(p.utime_us);
  d.validation_utime.push_back(std::move(t));
  d.validation.push_back(std::move(r));
  d.inputs.push_back("validate: " + venc_path + " + " + vmk_path);
}

std::string provenance_notes(const CalibrateOptions& o, const Setup& s, const cal::Report& report,
                             const Data& d) {
  std::string notes = "bounds " + o.bounds + "; robust loss " + o.robust;
  if (s.layout) notes += "; marker layout " + o.marker_layout;
  std::string held, gauge, bound;
  for (int k = 0; k < cal::kParams; ++k) {
    const auto st = report.params[k].status;
    const std::string name = cal::param_key(k);
    if (st == cal::ParamStatus::kHeld) held += (held.empty() ? "" : ", ") + name;
    if (st == cal::ParamStatus::kGaugeDependent) gauge += (gauge.empty() ? "" : ", ") + name;
    if (st == cal::ParamStatus::kAtBound) bound += (bound.empty() ? "" : ", ") + name;
  }
  if (!held.empty()) notes += "; unidentifiable, held at prior: " + held;
  if (!gauge.empty()) notes += "; gauge-dependent (follow the held priors): " + gauge;
  if (!bound.empty()) notes += "; at bound: " + bound;
  if (report.time_offset_s) notes += "; time offset " + mm(*report.time_offset_s) + " ms";
  for (const auto& v : d.validation) {
    notes += "; validate " + v.name + ": RMS " + mm(v.after.rms_m) + " mm";
  }
  return notes;
}

void write_calibration(const CalibrateOptions& o, const Setup& s, const cal::Report& report,
                       const Data& d) {
  config::Calibration out = cal::to_calibration(cal::estimates(report));
  auto& p = out.provenance;
  p.created_by = std::string("exodaq calibrate ") + kVersion + " (" + kGitDescribe + ")";
  p.date = utc_now();
  p.model = s.model_path;
  p.inputs = d.inputs;
  p.rms_before_m = report.before.rms_m;
  p.rms_after_m = report.after.rms_m;
  p.samples = static_cast<int>(report.points);
  p.notes = provenance_notes(o, s, report, d);
  config::write_calibration_file(o.out, out, o.inputs());
  std::cout << "\ncalibration written to " << o.out << " (RMS " << mm(report.before.rms_m) << " -> "
            << mm(report.after.rms_m) << " mm)\n";
}

void write_residuals(const CalibrateOptions& o, const cal::Report& report, const Data& d) {
  if (o.plot.empty() && o.residuals.empty()) return;
  std::string csv = o.residuals;
  if (csv.empty()) {
    const auto dot = o.plot.rfind('.');
    csv = (dot == std::string::npos ? o.plot : o.plot.substr(0, dot)) + "_residuals.csv";
  }
  std::vector<std::int64_t> t;
  for (const auto& pt : d.points) t.push_back(pt.utime_us);
  std::vector<std::string> inputs = o.inputs();
  inputs.push_back(o.out);
  cal::write_residual_csv(csv, t, report, d.validation, d.validation_utime, inputs);
  std::cout << "residuals written to " << csv << "\n";
  if (!o.plot.empty()) {
    std::string message;
    inputs.push_back(csv);
    cal::plot_residuals(csv, o.plot, message, inputs);
    std::cout << message << "\n";
  }
}

// The outputs, checked before anything is read or computed.
void check_outputs(const CalibrateOptions& o) {
  files::OutputOptions oo;
  oo.inputs = o.inputs();
  files::check_output(o.out, oo);
  if (!o.residuals.empty()) files::check_output(o.residuals, oo);
  if (!o.plot.empty()) files::check_output(o.plot, oo);
}

int run_calibrate(const CalibrateOptions& o) {
  check_outputs(o);
  const Setup s = load_setup(o);
  Data d;
  d.encoders = read_encoders(o.encoders, o, s.encoders);
  const cal::MarkerSeries mk = read_markers(o.markers, o, s);
  if (!o.quiet) {
    std::cout << "encoders " << o.encoders << ": " << d.encoders.samples.size() << " samples"
              << std::endl;
    for (const auto& n : d.encoders.notes) std::cout << "  " << n << std::endl;
  }
  cal::AlignmentStats st;
  d.points = align_points(d.encoders, mk, alignment_options(o, s.bounds), s, o.markers, st);
  d.inputs = {o.encoders, o.markers};
  const cal::Report report =
      cal::calibrate(s.nominal, d.points, s.bounds, solve_options(o), &d.encoders);
  for (const std::string& v : o.validate) validate_one(v, o, s, report, d);
  cal::print_report(std::cout, report, d.validation);
  write_calibration(o, s, report, d);
  write_residuals(o, report, d);
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
                     "encoder log: CSV utime_us,j1_rad..j6_rad[,homed_mask,fault_mask], the CSV "
                     "of exodaq export, or an LCM log (lcm-logger, exodaq replay)")
          ->required();
      app.add_option("--markers", o->markers, "mocap CSV utime_us,x_mm,y_mm,z_mm[,marker_id]")
          ->required();
      app.add_option("--bounds", o->bounds, "bounds and initial guesses (YAML)")->required();
      app.add_option("-o,--out", o->out, "calibration file to write")->required();
      app.add_option("-c,--config", o->config,
                     "the rig's service config: an LCM log's raw channel is re-processed with "
                     "it; its calibration is the recorded one of an export CSV or joint states");
      app.add_option("--recorded-calibration", o->recorded_calibration,
                     "the calibration the recorded joint angles were computed with (export CSV, "
                     "LCM joint states; default: the config's)");
      app.add_option("--prefix", o->prefix,
                     "LCM log: the rig's channel prefix (default: the only one in the log)");
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
      app.add_option("--max-points", o->max_points,
                     "use at most N points of each marker, evenly spread");
      auto* id =
          app.add_option("--marker-id", o->marker_id, "marker to use when the CSV holds several");
      app.add_option("--marker-layout", o->marker_layout,
                     "several markers: which marker_id sits where on the hand and on the base "
                     "(YAML, config/calibration/markers_example.yaml)")
          ->excludes(id);
      app.add_option("--max-gap-ms", o->max_gap_ms,
                     "largest encoder gap to interpolate across (default 5 ms)");
      return [o]() -> int {
        o->quiet = common_options().quiet;
        return run_calibrate(*o);  // errors: main.cpp prints them, exit 2
      };
    });

}  // namespace exodaq::tools
