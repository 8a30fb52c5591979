// exodaq calibrate: offline kinematic calibration (seed 000 §4, issues 8 and 18).
//   exodaq calibrate --encoders ENC --markers MOCAP.csv --bounds B.yaml -o cal.yaml
//                    [-c CONFIG] [--recorded-calibration FILE] [-p PREFIX]
//                    [--model M] [--marker-layout L.yaml | --marker-id N|LABEL]
//                    [--validate [ENC,]MOCAP ...] [--robust huber|cauchy]
//                    [--align-time auto|on|off] [--estimate-time-offset]
//                    [--plot out.png] [--max-points N]
// MOCAP: the long CSV, C3D, a Vicon Nexus or an OptiTrack Motive CSV export.
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
#include "exodaq/calibration/time_alignment.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/settings/calibration_file.hpp"
#include "exodaq/settings/model_file.hpp"
#include "exodaq/settings/service_config.hpp"
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
  std::string align_time = "auto";
  std::size_t max_points = 2000;
  std::string marker_id;  // an id or a label
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
  std::optional<settings::ServiceConfig> config;
};

EncoderSource encoder_source(const CalibrateOptions& o) {
  EncoderSource src;
  if (!o.config.empty()) src.config = settings::load_service_config(o.config);
  if (!o.recorded_calibration.empty()) {
    src.read.recorded_offsets_rad =
        settings::load_calibration_file(o.recorded_calibration).encoder_offset_rad;
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
    messages::LogReader probe(path);
    return true;
  } catch (const messages::LogError&) {
    return false;
  }
}

// The raw channel an LCM log holds for the rig, "" when none.
std::string raw_channel(const std::string& path, const std::optional<std::string>& prefix) {
  std::string found;
  for (const auto& [channel, n] : messages::scan_channels(path)) {
    const auto parts = messages::split_channel(channel);
    if (!parts || parts->kind != messages::Kind::kEncoderRaw) continue;
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
  double clock_offset_s = 0;  // coarse alignment applied to the markers (0: none)
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
  s.model_path = o.model.empty() ? settings::default_model_path() : o.model;
  const settings::KinematicModel model = settings::load_model_file(s.model_path);
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

// The markers of a file: the layout's, or one marker (--marker-id: an id or
// a label). With a layout, the sites' ids as the file resolved them.
struct Markers {
  cal::MarkerSeries series;
  std::optional<cal::MarkerLayout> layout;
};

Markers read_markers(const std::string& path, const CalibrateOptions& o, const Setup& s) {
  Markers m;
  if (s.layout) {
    m.series = cal::read_markers(path, cal::layout_refs(*s.layout));
    m.layout = cal::resolved_layout(*s.layout, m.series);
  } else {
    m.series = cal::read_markers(
        path, o.marker_id.empty() ? std::vector<cal::MarkerRef>{}
                                  : std::vector<cal::MarkerRef>{cal::marker_ref(o.marker_id)});
  }
  for (const auto& n : m.series.info.notes) std::cout << "  " << n << "\n";
  return m;
}

// The hand marker whose speed the time alignment compares.
cal::MarkerSite alignment_site(const Markers& m) {
  if (m.layout) {
    for (const auto& site : m.layout->sites) {
      if (site.mount == cal::MarkerMount::kHand) return site;
    }
  }
  cal::MarkerSite site;
  site.id = m.series.ids.empty() ? -1 : m.series.ids.front();
  return site;
}

bool align_clocks(const CalibrateOptions& o, const cal::EncoderSeries& enc, const Markers& m) {
  if (o.align_time == "on") return true;
  if (o.align_time == "off") return false;
  return cal::needs_time_alignment(enc, m.series);
}

// τ's range after a coarse alignment: the bounds file's, at least ±100 ms.
cal::TimeOffsetPrior coarse_refinement(cal::TimeOffsetPrior p) {
  p.initial_s = 0;
  p.lower_s = std::min(p.lower_s, -0.1);
  p.upper_s = std::max(p.upper_s, 0.1);
  return p;
}

// The coarse clock offset (speed cross-correlation), printed; the markers
// come back in encoder time.
double coarse_align(const std::string& label, const cal::NominalModel& model,
                    const cal::ParamVector& x, const cal::EncoderSeries& enc, Markers& m) {
  const cal::CoarseOffset c = cal::coarse_time_offset(model, x, enc, m.series, alignment_site(m));
  std::cout << label << ": " << cal::format_name(m.series.info.format)
            << (m.series.info.epoch_times ? " outside the encoder log's time" : " without an epoch")
            << ": clock offset (encoder = marker + offset) " << c.describe() << std::endl;
  if (!m.series.info.start_time.empty()) {
    std::cout << "  (the file's own capture start time: " << m.series.info.start_time
              << ", not used: its clock and time zone are the mocap host's)" << std::endl;
  }
  if (c.ambiguous()) {
    std::cout << "WARNING: " << label << ": the speed profiles match almost as well "
              << c.runner_up_at_s - c.offset_s
              << " s away: the clock offset is ambiguous (a repetitive motion?)" << std::endl;
  }
  m.series = cal::shifted_markers(std::move(m.series), c.offset_s);
  return c.offset_s;
}

std::vector<cal::AlignedSample> align_points(const cal::EncoderSeries& enc, const Markers& m,
                                             const cal::AlignmentOptions& ao,
                                             const std::string& label, cal::AlignmentStats& st) {
  auto points = cal::align(enc, m.series, ao, st);
  if (m.layout) cal::apply_layout(points, *m.layout);
  cal::print_alignment(std::cout, label, st);
  return points;
}

// A validation capture's own clock offset, refined with the calibration: the
// RMS error against the offset over ±3 coarse steps, and the parabola
// through the least three.
double refine_validation_offset(const cal::NominalModel& model, const cal::ParamVector& x,
                                const cal::EncoderSeries& enc, const Markers& m,
                                cal::AlignmentOptions ao, double step_s) {
  ao.max_points = std::min<std::size_t>(ao.max_points == 0 ? 400 : ao.max_points, 400);
  const double span = 3 * std::max(step_s, 1e-3), h = span / 15;
  std::vector<double> taus, rms;
  for (double tau = -span; tau <= span + 1e-12; tau += h) {
    cal::AlignmentStats st;
    auto pts = cal::align(enc, cal::shifted_markers(m.series, tau), ao, st);
    if (m.layout) cal::apply_layout(pts, *m.layout);
    if (pts.empty()) continue;
    taus.push_back(tau);
    rms.push_back(cal::evaluate(model, x, pts).rms_m);
  }
  if (taus.size() < 3) return 0;
  const auto k = static_cast<std::size_t>(std::min_element(rms.begin(), rms.end()) - rms.begin());
  if (k == 0 || k + 1 == taus.size()) return taus[k];
  const double a = rms[k - 1], b = rms[k], c = rms[k + 1];
  const double denom = a - 2 * b + c;
  return taus[k] + (denom > 0 ? 0.5 * h * (a - c) / denom : 0.0);
}

void validate_one(const std::string& spec, const CalibrateOptions& o, const Setup& s,
                  const cal::Report& report, Data& d) {
  const auto comma = spec.find(',');
  const std::string venc_path = comma == std::string::npos ? o.encoders : spec.substr(0, comma);
  const std::string vmk_path = comma == std::string::npos ? spec : spec.substr(comma + 1);
  const cal::EncoderSeries venc =
      venc_path == o.encoders ? d.encoders : read_encoders(venc_path, o, s.encoders);
  Markers vmk = read_markers(vmk_path, o, s);
  cal::AlignmentOptions vao = alignment_options(o, s.bounds);
  vao.guard_us = 0;
  const cal::ParamVector x = cal::estimates(report);
  if (align_clocks(o, venc, vmk)) {
    const double coarse = coarse_align("validate " + vmk_path, s.nominal, x, venc, vmk);
    const double fine = refine_validation_offset(s.nominal, x, venc, vmk, vao, 0.002);
    vmk.series = cal::shifted_markers(std::move(vmk.series), fine);
    std::cout << "validate " << vmk_path << ": clock offset " << coarse + fine << " s" << std::endl;
  } else if (report.time_offset_s) {
    vmk.series = cal::shifted_markers(std::move(vmk.series), *report.time_offset_s);
  }
  cal::ValidationResult r;
  r.name = vmk_path;
  const auto vpts = align_points(venc, vmk, vao, "validate " + vmk_path, r.alignment);
  r.points = vpts.size();
  r.before = cal::evaluate(s.nominal, cal::initial_params(s.bounds), vpts, &r.residual_before);
  r.after = cal::evaluate(s.nominal, x, vpts, &r.residual_after);
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
  if (d.clock_offset_s != 0) {
    notes += "; mocap clock aligned by " + std::to_string(d.clock_offset_s) + " s (speed profiles)";
  }
  if (report.time_offset_s) notes += "; time offset " + mm(*report.time_offset_s) + " ms";
  for (const auto& v : d.validation) {
    notes += "; validate " + v.name + ": RMS " + mm(v.after.rms_m) + " mm";
  }
  return notes;
}

void write_calibration(const CalibrateOptions& o, const Setup& s, const cal::Report& report,
                       const Data& d) {
  settings::Calibration out = cal::to_calibration(cal::estimates(report));
  auto& p = out.provenance;
  p.created_by = std::string("exodaq calibrate ") + kVersion + " (" + kGitDescribe + ")";
  p.date = utc_now();
  p.model = s.model_path;
  p.inputs = d.inputs;
  p.rms_before_m = report.before.rms_m;
  p.rms_after_m = report.after.rms_m;
  p.samples = static_cast<int>(report.points);
  p.notes = provenance_notes(o, s, report, d);
  settings::write_calibration_file(o.out, out, o.inputs());
  std::cout << "\ncalibration written to " << o.out << " (RMS " << mm(report.before.rms_m) << " -> "
            << mm(report.after.rms_m) << " mm)\n";
}

void write_residuals(const CalibrateOptions& o, const cal::Report& report, const Data& d) {
  if (o.plot.empty() && o.residuals.empty()) return;
  std::string csv = o.residuals;
  if (csv.empty()) {  // next to the figure: x.png -> x_residuals.csv, x_residuals.png ->
                      // x_residuals.csv
    const auto dot = o.plot.rfind('.');
    const std::string stem = dot == std::string::npos ? o.plot : o.plot.substr(0, dot);
    const std::string tag = "_residuals";
    const bool tagged =
        stem.size() >= tag.size() && stem.compare(stem.size() - tag.size(), tag.size(), tag) == 0;
    csv = stem + (tagged ? "" : tag) + ".csv";
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

// The clock offset found: coarse + τ, and where the capture's first frame
// falls on the encoder clock when that is the epoch's.
void print_clock_offset(const Data& d, const cal::Report& report) {
  const double offset = d.clock_offset_s + *report.time_offset_s;
  std::printf(
      "Clock offset (encoder time = mocap time + offset): %.6f s ± %.3f ms (coarse %.6f s "
      "from the speed profiles, refined by %+.3f ms in the least squares)\n",
      offset, report.time_offset_std_s.value_or(0) * 1e3, d.clock_offset_s,
      *report.time_offset_s * 1e3);
  if (offset > 1e9) {
    const auto whole = static_cast<std::time_t>(std::floor(offset));
    std::tm tm{};
    gmtime_r(&whole, &tm);
    char buf[40];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
    std::printf("  the capture's time 0 is %s.%06dZ on the encoder clock\n", buf,
                static_cast<int>(std::llround((offset - std::floor(offset)) * 1e6)) % 1000000);
  }
  std::fflush(stdout);
}

// The rig's recorded calibration against the bounds: a start outside them
// cannot be reached, whatever the data say.
void check_recorded_against_bounds(const Setup& s) {
  if (!s.encoders.read.recorded_offsets_rad) return;
  const auto& off = *s.encoders.read.recorded_offsets_rad;
  std::string outside;
  for (int j = 0; j < cal::kJoints; ++j) {
    const auto& b = s.bounds.params[cal::kTheta1 + j];
    if (off[j] >= b.lower && off[j] <= b.upper) continue;
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s %.2f outside %.2f..%.2f", cal::param_key(cal::kTheta1 + j),
                  cal::to_display(cal::kTheta1 + j, off[j]),
                  cal::to_display(cal::kTheta1 + j, b.lower),
                  cal::to_display(cal::kTheta1 + j, b.upper));
    outside += (outside.empty() ? "" : ", ") + std::string(buf);
  }
  if (!outside.empty()) {
    std::cout << "WARNING: the rig's calibration " << s.encoders.read.recorded_calibration
              << " has encoder offsets outside the bounds of " << s.bounds.source << ": " << outside
              << ". Are these bounds for this rig?" << std::endl;
  }
}

int run_calibrate(const CalibrateOptions& o) {
  check_outputs(o);
  const Setup s = load_setup(o);
  check_recorded_against_bounds(s);
  Data d;
  d.encoders = read_encoders(o.encoders, o, s.encoders);
  if (!o.quiet) {
    std::cout << "encoders " << o.encoders << ": " << d.encoders.samples.size() << " samples"
              << std::endl;
    for (const auto& n : d.encoders.notes) std::cout << "  " << n << std::endl;
  }
  cal::SolveOptions so = solve_options(o);
  cal::AlignmentOptions ao = alignment_options(o, s.bounds);
  {
    Markers mk = read_markers(o.markers, o, s);
    if (align_clocks(o, d.encoders, mk)) {
      d.clock_offset_s =
          coarse_align(o.markers, s.nominal, cal::initial_params(s.bounds), d.encoders, mk);
      // Refined in the least squares: the speed profiles of a model at its
      // initial guesses can put the coarse offset tens of ms off.
      so.estimate_time_offset = true;
      so.time_offset = coarse_refinement(s.bounds.time_offset);
      ao = alignment_options(o, s.bounds);
      ao.guard_us = static_cast<std::int64_t>(
          1e6 * std::max(std::abs(so.time_offset->lower_s), std::abs(so.time_offset->upper_s)));
    }
    cal::AlignmentStats st;
    d.points = align_points(d.encoders, mk, ao, o.markers, st);
  }
  d.inputs = {o.encoders, o.markers};
  const cal::Report report = cal::calibrate(s.nominal, d.points, s.bounds, so, &d.encoders);
  for (const std::string& v : o.validate) validate_one(v, o, s, report, d);
  cal::print_report(std::cout, report, d.validation);
  if (d.clock_offset_s != 0 && report.time_offset_s) print_clock_offset(d, report);
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
      app.add_option("--markers", o->markers,
                     "motion capture: the long CSV utime_us,x_mm,y_mm,z_mm[,marker_id], C3D, or a "
                     "Vicon Nexus or OptiTrack Motive CSV export (told apart by content)")
          ->required();
      app.add_option("--bounds", o->bounds, "bounds and initial guesses (YAML)")->required();
      app.add_option("-o,--out", o->out, "calibration file to write")->required();
      app.add_option("-c,--config", o->config,
                     "the rig's service config: an LCM log's raw channel is re-processed with "
                     "it; its calibration is the recorded one of an export CSV or joint states");
      app.add_option("--recorded-calibration", o->recorded_calibration,
                     "the calibration the recorded joint angles were computed with (export CSV, "
                     "LCM joint states; default: the config's)");
      add_prefix_option(app, o->prefix, "LCM log; default: the only one in the log");
      app.add_option("--model", o->model, "kinematic model file (default: macaque_exo.yaml)");
      app.add_option("--validate", o->validate,
                     "cross-validation sets: MOCAP.csv (same encoder log) or ENC.csv,MOCAP.csv");
      app.add_option("--robust", o->robust, "robust loss")
          ->check(CLI::IsMember({"none", "huber", "cauchy"}));
      app.add_option("--robust-scale-mm", o->robust_scale_mm,
                     "residual per axis where the robust loss bends (default 1 mm)");
      app.add_flag("--estimate-time-offset", o->estimate_time_offset,
                   "estimate a constant offset between the two clocks within the bounds file's "
                   "time_offset_ms");
      app.add_option("--align-time", o->align_time,
                     "align the mocap clock to the encoders' by the speed profiles, then refine "
                     "in the least squares: auto (when the markers carry no epoch or lie outside "
                     "the encoder log), on, off")
          ->check(CLI::IsMember({"auto", "on", "off"}));
      app.add_option("--plot", o->plot, "residual figure (PNG; needs python3-matplotlib)");
      app.add_option("--residuals", o->residuals, "residual CSV (default: next to --plot)");
      app.add_option("--max-points", o->max_points,
                     "use at most N points of each marker, evenly spread (default 2000)")
          ->check(CLI::Range(1, 10000));
      auto* id =
          app.add_option("--marker-id", o->marker_id,
                         "marker to use when the file holds several: its id, or its label in a "
                         "C3D, Vicon or Motive file");
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
