#include "exodaq/calibration/report.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "exodaq/calibration/python_plot.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/common/yaml_reader.hpp"

namespace exodaq::calibration {

namespace {

std::string f(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

// Pads to a display width (UTF-8 aware: counts code points).
std::string pad(const std::string& s, std::size_t width) {
  std::size_t w = 0;
  for (unsigned char c : s) w += (c & 0xC0) != 0x80 ? 1 : 0;
  return w >= width ? s : s + std::string(width - w, ' ');
}

std::string stats_row(const std::string& name, const ErrorStats& s) {
  std::ostringstream o;
  o << "  " << pad(name, 28);
  for (double v : {s.rms_m, s.mean_m, s.std_m, s.median_m, s.p95_m, s.max_m}) {
    o << f("%9.3f", v * 1e3);
  }
  return o.str();
}

}  // namespace

void print_alignment(std::ostream& o, const std::string& name, const AlignmentStats& s) {
  o << name << ": " << s.marker_samples << " marker samples, " << s.used << " used";
  std::string skipped;
  auto add = [&](std::size_t n, const char* what) {
    if (n) skipped += (skipped.empty() ? "" : ", ") + std::to_string(n) + " " + what;
  };
  add(s.marker_missing, "marker missing");
  add(s.outside_encoder_log, "outside the encoder log");
  add(s.encoder_gap, "encoder gap");
  add(s.unhomed_or_faulted, "unhomed/faulted joints");
  add(s.thinned, "thinned (--max-points)");
  add(s.other_ids, "rows of other marker ids");
  if (!skipped.empty()) o << " (skipped: " << skipped << ")";
  o << "\n";
}

namespace {

void print_errors(std::ostream& o, const Report& r) {
  o << "\n=== Calibration report (seed 000 eq. 6, " << r.points << " points, " << r.residuals
    << " residuals, " << r.free_params << " estimated parameters) ===\n";
  o << "Solver: " << r.iterations << " iterations; " << r.termination << "\n";
  o << "Residual std per axis: " << f("%.3f", r.sigma_m * 1e3) << " mm\n\n";
  o << "Position error (3-D, mm)          RMS     mean      std   median      p95      max\n";
  o << stats_row("before (initial guesses)", r.before) << "\n";
  o << stats_row("after", r.after) << "\n";
  for (const auto& m : r.per_marker) {
    o << stats_row("  after, " + std::string(mount_name(m.site.mount)) + " marker " +
                       std::to_string(m.site.id),
                   m.after)
      << "\n";
  }
  o << "  seed 000 §4.3.1 (their rig)      " << f("%6.2f", kPaperRmsBeforeMm) << " -> "
    << f("%.2f", kPaperRmsAfterMm) << " RMS (mean 13.6 -> 0.95, std 1.35 -> 0.44)\n";
  o << "  mean residual after (x, y, z): " << f("%+.3f", r.after.mean_xyz_m.x() * 1e3) << ", "
    << f("%+.3f", r.after.mean_xyz_m.y() * 1e3) << ", " << f("%+.3f", r.after.mean_xyz_m.z() * 1e3)
    << " mm; RMS per axis " << f("%.3f", r.after.rms_xyz_m.x() * 1e3) << ", "
    << f("%.3f", r.after.rms_xyz_m.y() * 1e3) << ", " << f("%.3f", r.after.rms_xyz_m.z() * 1e3)
    << " mm\n\n";
  if (r.time_offset_hint && r.time_offset_hint->significant()) {
    const TimeOffsetHint& h = *r.time_offset_hint;
    o << "WARNING: the residuals follow the markers' motion: a clock offset of "
      << f("%+.2f", h.offset_s * 1e3) << " ± " << f("%.2f", h.std_s * 1e3)
      << " ms (encoder time = marker time + offset) explains " << f("%.0f", h.explained * 100)
      << " % of them. The two clocks are not aligned: estimate the offset (--estimate-time-offset"
         " or --align-time on) or check the clocks.\n\n";
  }
}

void print_parameters(std::ostream& o, const Report& r) {
  o << "Parameters (eq. 6 order)   initial     estimate      ± std  unit  status\n";
  for (int p = 0; p < kParams; ++p) {
    const ParamResult& pr = r.params[p];
    o << "  " << pad(param_label(p), 8) << f("%19.3f", to_display(p, pr.initial))
      << f("%13.3f", to_display(p, pr.estimate));
    if (pr.status == ParamStatus::kIdentified || pr.status == ParamStatus::kGaugeDependent) {
      o << f("%11.3f", to_display(p, pr.stddev));
    } else {
      o << "          -";
    }
    o << "  " << pad(display_unit(p), 4) << "  " << status_name(pr.status);
    if (!pr.note.empty()) o << ": " << pr.note;
    o << "\n";
  }
  if (r.time_offset_s) {
    o << "  " << pad("τ", 8) << f("%19.3f", 0.0) << f("%13.3f", *r.time_offset_s * 1e3)
      << f("%11.3f", r.time_offset_std_s.value_or(0) * 1e3)
      << "  ms    time offset (encoder = marker + τ)\n";
  }
  o << "\n";
}

std::string labels(const std::vector<int>& params) {
  std::string out;
  for (int p : params) out += (out.empty() ? "" : ", ") + std::string(param_label(p));
  return out;
}

void print_observation_sets(std::ostream& o, const Report& r) {
  if (r.observation_sets.empty()) return;
  o << "Identifiability by observations (what each addition identifies):\n";
  for (const auto& s : r.observation_sets) {
    o << "  " << pad(s.name + ":", 48)
      << (s.unidentifiable.empty() ? "every parameter identifiable"
                                   : "unidentifiable: " + labels(s.unidentifiable));
    if (!s.newly_identifiable.empty()) o << "; identifies " << labels(s.newly_identifiable);
    o << "\n";
  }
}

void print_identifiability(std::ostream& o, const Report& r) {
  if (r.degeneracies.empty()) {
    o << "Identifiability: every free parameter is identifiable from these data.\n";
  } else {
    o << "Unidentifiable directions (the gauge is fixed by holding the named parameter at its\n"
         "prior; parameters marked gauge-dependent follow that choice):\n";
    for (const auto& d : r.degeneracies) o << "  - " << d.describe() << "\n";
  }
  print_observation_sets(o, r);
  if (!r.correlations.empty()) {
    o << "Correlations above the threshold among estimated parameters:\n";
    for (const auto& c : r.correlations) {
      o << "  " << param_label(c.a) << " ~ " << param_label(c.b) << ": " << f("%+.3f", c.r) << "\n";
    }
  }
  if (!r.singular_values.empty()) {
    o << "Singular values of the Jacobian (columns scaled to the identifiability tolerance): max "
      << f("%.3g", r.singular_values.front()) << ", min " << f("%.3g", r.singular_values.back())
      << ", ratio " << f("%.3g", r.singular_values.front() / r.singular_values.back()) << "\n";
  }
}

void print_validation(std::ostream& o, const std::vector<ValidationResult>& val) {
  if (val.empty()) return;
  o << "\nCross-validation (seed 000 §4.3.2)      points  RMS before  RMS after   mean    std    "
       "max\n";
  for (const auto& v : val) {
    o << "  " << pad(v.name, 38) << f("%6.0f", static_cast<double>(v.points))
      << f("%12.3f", v.before.rms_m * 1e3) << f("%11.3f", v.after.rms_m * 1e3)
      << f("%7.3f", v.after.mean_m * 1e3) << f("%7.3f", v.after.std_m * 1e3)
      << f("%7.3f", v.after.max_m * 1e3) << "\n";
  }
}

}  // namespace

void print_report(std::ostream& o, const Report& r, const std::vector<ValidationResult>& val) {
  print_errors(o, r);
  print_parameters(o, r);
  print_identifiability(o, r);
  print_validation(o, val);
}

void write_residual_csv(const std::string& path, const std::vector<std::int64_t>& train_utime,
                        const Report& r, const std::vector<ValidationResult>& val,
                        const std::vector<std::vector<std::int64_t>>& val_utime,
                        const std::vector<std::string>& inputs) {
  std::ostringstream out;
  out << "set,index,utime_us,before_x_mm,before_y_mm,before_z_mm,before_mm,after_x_mm,after_y_mm,"
         "after_z_mm,after_mm\n";
  auto rows = [&](const std::string& set, const std::vector<std::int64_t>& t,
                  const std::vector<Eigen::Vector3d>& b, const std::vector<Eigen::Vector3d>& a) {
    for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) {
      out << set << "," << i << "," << (i < t.size() ? t[i] : 0);
      for (const auto* v : {&b[i], &a[i]}) {
        out << "," << f("%.4f", v->x() * 1e3) << "," << f("%.4f", v->y() * 1e3) << ","
            << f("%.4f", v->z() * 1e3) << "," << f("%.4f", v->norm() * 1e3);
      }
      out << "\n";
    }
  };
  rows("training", train_utime, r.residual_before, r.residual_after);
  for (std::size_t k = 0; k < val.size(); ++k) {
    rows("validate" + std::to_string(k + 1),
         k < val_utime.size() ? val_utime[k] : std::vector<std::int64_t>{}, val[k].residual_before,
         val[k].residual_after);
  }
  files::OutputOptions oo;
  oo.inputs = inputs;
  files::write_output(path, out.str(), oo);
}

bool plot_residuals(const std::string& csv, const std::string& png, std::string& message,
                    const std::vector<std::string>& inputs) {
  const std::string script = find_plot_script("EXODAQ_CALIBRATE_PLOT", "plot_residuals.py");
  if (script.empty()) {
    message = "figure skipped: plot_residuals.py not found (set EXODAQ_CALIBRATE_PLOT)";
    return false;
  }
  if (!run_plot_script(script, {csv}, png, message, inputs)) return false;
  message = "residual figure written to " + png;
  return true;
}

}  // namespace exodaq::calibration
