// exodaq shoulder-cor: the shoulder's centre of rotation by humerus elevation
// from motion capture of torso and humerus markers (seed 001 §II.B, Table II).
//   exodaq shoulder-cor --markers MOCAP --torso 1,2,3,4,5 --humerus 11,...,17
//                       --torso-axis 1,2 --humerus-axis 11,12 [--bin-deg 20]
//                       [--pairs 2000] [--min-rotation-deg 15] [--csv bins.csv] [--plot cor.png]
// MOCAP: the long CSV, C3D, a Vicon Nexus or OptiTrack Motive CSV export;
// markers by id or by label. docs/shoulder-cor.md describes the recording,
// the method and the output.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/calibration/inputs.hpp"
#include "exodaq/calibration/python_plot.hpp"
#include "exodaq/calibration/shoulder_cor.hpp"
#include "exodaq/common/files.hpp"

namespace exodaq::tools {
namespace {

namespace cal = exodaq::calibration;

constexpr double kDeg = 0.017453292519943295;
// Seed 001 Table II (macaque): CoR vertical motion (mm) for 0-20, ..., 100-120°.
constexpr double kTable2Mm[] = {0, 4, 13, 27, 43, 62};

struct CorCommandOptions {
  std::string markers, csv, plot;
  std::vector<std::string> torso, humerus, torso_axis, humerus_axis;  // ids or labels
  double bin_deg = 20.0, min_rotation_deg = 15.0;
  std::size_t pairs = 2000, min_axes = 10;
  std::uint64_t seed = 1;
  std::string centre_model = "moving";
  double max_ci_mm = 2.0;
};

std::string f(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

int index_of(const std::vector<std::string>& ids, const std::string& id, const char* option,
             const char* group) {
  for (std::size_t k = 0; k < ids.size(); ++k) {
    if (ids[k] == id) return static_cast<int>(k);
  }
  throw std::invalid_argument(std::string(option) + ": marker " + id + " is not one of the " +
                              group + " markers");
}

// Marker ids: at least three per segment, none twice; the axis markers are
// markers of their segment. Returns the axis columns.
cal::ShoulderAxes check_ids(const CorCommandOptions& o) {
  if (o.torso.size() < 3 || o.humerus.size() < 3) {
    throw std::invalid_argument("--torso and --humerus need at least 3 markers each (seed 001)");
  }
  std::set<std::string> all;
  for (const auto* ids : {&o.torso, &o.humerus}) {
    for (const std::string& id : *ids) {
      if (!all.insert(id).second) throw std::invalid_argument("marker " + id + " is given twice");
    }
  }
  cal::ShoulderAxes a;
  a.torso_cranial = index_of(o.torso, o.torso_axis[0], "--torso-axis", "--torso");
  a.torso_caudal = index_of(o.torso, o.torso_axis[1], "--torso-axis", "--torso");
  a.humerus_proximal = index_of(o.humerus, o.humerus_axis[0], "--humerus-axis", "--humerus");
  a.humerus_distal = index_of(o.humerus, o.humerus_axis[1], "--humerus-axis", "--humerus");
  if (a.torso_cranial == a.torso_caudal || a.humerus_proximal == a.humerus_distal) {
    throw std::invalid_argument("an axis needs two different markers");
  }
  return a;
}

// The samples grouped into frames by time; markers not seen are NaN.
std::vector<cal::MocapFrame> read_frames(const CorCommandOptions& o, std::size_t& other_rows) {
  std::vector<cal::MarkerRef> refs;
  for (const auto* ids : {&o.torso, &o.humerus}) {
    for (const std::string& id : *ids) refs.push_back(cal::marker_ref(id));
  }
  const cal::MarkerSeries series = cal::read_markers(o.markers, refs);
  other_rows = series.other_ids;
  std::map<int, std::pair<bool, int>> column;  // resolved id -> (torso?, column)
  for (std::size_t k = 0; k < series.ids.size(); ++k) {
    const bool torso = k < o.torso.size();
    column[series.ids[k]] = {torso, static_cast<int>(torso ? k : k - o.torso.size())};
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::map<std::int64_t, cal::MocapFrame> frames;
  for (const cal::MarkerSample& s : series.samples) {
    auto [it, fresh] = frames.try_emplace(s.utime_us);
    cal::MocapFrame& fr = it->second;
    if (fresh) {
      fr.utime_us = s.utime_us;
      fr.torso = Eigen::Matrix3Xd::Constant(3, static_cast<Eigen::Index>(o.torso.size()), nan);
      fr.humerus = Eigen::Matrix3Xd::Constant(3, static_cast<Eigen::Index>(o.humerus.size()), nan);
    }
    if (!s.present) continue;
    const auto [torso, col] = column.at(s.marker_id);
    (torso ? fr.torso : fr.humerus).col(col) = Eigen::Vector3d(s.x, s.y, s.z);
  }
  std::vector<cal::MocapFrame> out;
  out.reserve(frames.size());
  for (auto& [t, fr] : frames) out.push_back(std::move(fr));
  return out;
}

std::string table2(const cal::CorBin& b, double bin_deg) {
  const auto k = static_cast<std::size_t>(std::lround(b.elevation_lo_rad / kDeg / 20.0));
  if (std::abs(bin_deg - 20.0) > 1e-9 || k >= 6) return "";
  return f("%18.0f", kTable2Mm[k]);
}

std::string pm(double v, double ci, const char* format) {
  return f(format, v * 1e3) + " ±" + f("%5.2f", ci * 1e3);
}

void print_result(const cal::CorResult& r, const CorCommandOptions& o) {
  const bool table2_bins = std::abs(o.bin_deg - 20.0) < 1e-9;
  std::cout << "\n=== Shoulder centre of rotation by humerus elevation (seed 001 §II.B) ===\n"
            << "Torso frame = the camera frame of the first frame with every torso marker; "
               "vertical = cranial (torso axis markers).\n"
            << "Every value ± its 95 % confidence half-width; vertical and horizontal relative to "
               "the first bin (both bins' uncertainty combined).\n\n"
            << "Humerus elevation  frames   axes  outliers spread         CoR x mm         CoR y mm"
               "         CoR z mm      vertical mm    horizontal mm axis RMS mm"
            << (table2_bins ? " seed 001 Table II" : "") << "\n";
  for (const auto& b : r.bins) {
    const std::string range =
        f("%.0f", b.elevation_lo_rad / kDeg) + "-" + f("%.0f", b.elevation_hi_rad / kDeg) + " deg";
    std::cout << "  " << std::string(range.size() < 15 ? 15 - range.size() : 0, ' ') << range
              << f("%8.0f", double(b.frames)) << f("%7.0f", double(b.axes))
              << f("%10.0f", double(b.outliers));
    if (!b.valid) {
      std::cout << "   no centre: " << b.why << "\n";
      continue;
    }
    std::cout << f("%6.0f", b.axis_spread_rad / kDeg) << " deg"
              << pm(b.centre.x(), b.ci95_m.x(), "%10.1f")
              << pm(b.centre.y(), b.ci95_m.y(), "%10.1f")
              << pm(b.centre.z(), b.ci95_m.z(), "%10.1f")
              << pm(b.vertical_m, b.vertical_ci95_m, "%10.1f")
              << pm(b.horizontal_m, b.horizontal_ci95_m, "%10.1f")
              << f("%12.2f", b.axis_rms_m * 1e3) << table2(b, o.bin_deg) << "\n";
  }
  double vmin = 0, vmax = 0, hmin = 0, hmax = 0;
  for (const auto& b : r.bins) {
    if (!b.valid) continue;
    vmin = std::min(vmin, b.vertical_m), vmax = std::max(vmax, b.vertical_m);
    hmin = std::min(hmin, b.horizontal_m), hmax = std::max(hmax, b.horizontal_m);
  }
  std::cout << "CoR range over the bins: vertical " << f("%.1f", (vmax - vmin) * 1e3)
            << " mm, horizontal " << f("%.1f", (hmax - hmin) * 1e3)
            << " mm (seed 001 Table I, macaque: cranial 53, ventral 37, lateral 34 mm)\n";
  for (const auto& b : r.bins) {
    if (!b.valid || b.warning.empty()) continue;
    std::cout << "WARNING: bin " << f("%.0f", b.elevation_lo_rad / kDeg) << "-"
              << f("%.0f", b.elevation_hi_rad / kDeg) << " deg: " << b.warning << "\n";
  }
}

void write_csv(const std::string& path, const cal::CorResult& r, const std::string& input) {
  std::ostringstream out;
  out << "bin,elevation_lo_deg,elevation_hi_deg,mean_elevation_deg,frames,pairs,axes,outliers,"
         "valid,x_mm,y_mm,z_mm,vertical_mm,horizontal_mm,axis_rms_mm,x_ci95_mm,y_ci95_mm,"
         "z_ci95_mm,vertical_ci95_mm,horizontal_ci95_mm,axis_spread_deg,flags\n";
  for (std::size_t k = 0; k < r.bins.size(); ++k) {
    const auto& b = r.bins[k];
    out << k << "," << f("%.3f", b.elevation_lo_rad / kDeg) << ","
        << f("%.3f", b.elevation_hi_rad / kDeg) << "," << f("%.3f", b.mean_elevation_rad / kDeg)
        << "," << b.frames << "," << b.pairs << "," << b.axes << "," << b.outliers << ","
        << (b.valid ? 1 : 0);
    for (double v :
         {b.centre.x(), b.centre.y(), b.centre.z(), b.vertical_m, b.horizontal_m, b.axis_rms_m,
          b.ci95_m.x(), b.ci95_m.y(), b.ci95_m.z(), b.vertical_ci95_m, b.horizontal_ci95_m}) {
      out << "," << f("%.4f", v * 1e3);
    }
    std::string flags;
    if (b.vertical_poor) flags += "vertical";
    if (b.horizontal_poor) flags += std::string(flags.empty() ? "" : ";") + "horizontal";
    if (b.ill_conditioned) flags += std::string(flags.empty() ? "" : ";") + "ill-conditioned";
    out << "," << f("%.2f", b.axis_spread_rad / kDeg) << "," << flags << "\n";
  }
  files::OutputOptions oo;
  oo.inputs = {input};
  files::write_output(path, out.str(), oo);
}

void write_outputs(const CorCommandOptions& o, const cal::CorResult& r) {
  std::string csv = o.csv;
  if (csv.empty() && !o.plot.empty()) {  // cor.png -> cor_bins.csv, cor_bins.png -> cor_bins.csv
    const auto dot = o.plot.rfind('.');
    const std::string stem = dot == std::string::npos ? o.plot : o.plot.substr(0, dot);
    const bool tagged = stem.size() >= 5 && stem.compare(stem.size() - 5, 5, "_bins") == 0;
    csv = stem + (tagged ? "" : "_bins") + ".csv";
  }
  if (csv.empty()) return;
  write_csv(csv, r, o.markers);
  std::cout << "bins written to " << csv << "\n";
  if (o.plot.empty()) return;
  const std::string script =
      cal::find_plot_script("EXODAQ_SHOULDER_COR_PLOT", "plot_shoulder_cor.py");
  std::string message = "figure written to " + o.plot;
  if (script.empty()) {
    message = "figure skipped: plot_shoulder_cor.py not found (set EXODAQ_SHOULDER_COR_PLOT)";
  } else {
    cal::run_plot_script(script, {csv}, o.plot, message, {o.markers, csv});
  }
  std::cout << message << "\n";
}

int run_shoulder_cor(const CorCommandOptions& o) {
  const cal::ShoulderAxes axes = check_ids(o);
  std::size_t other_rows = 0;
  const std::vector<cal::MocapFrame> frames = read_frames(o, other_rows);
  cal::CorOptions co;
  co.bin_width_rad = o.bin_deg * kDeg;
  co.pairs_per_bin = o.pairs;
  co.min_rotation_rad = o.min_rotation_deg * kDeg;
  co.min_axes = o.min_axes;
  co.seed = o.seed;
  co.moving_centre = o.centre_model == "moving";
  co.max_ci95_m = o.max_ci_mm * 1e-3;
  const cal::CorResult r = cal::analyse_shoulder_cor(frames, axes, co);
  std::cout << o.markers << ": " << r.frames << " frames, " << r.frames_used << " used";
  if (r.frames_torso_missing || r.frames_humerus_missing || other_rows) {
    std::cout << " (skipped: " << r.frames_torso_missing << " torso not fitted, "
              << r.frames_humerus_missing << " humerus markers not seen; " << other_rows
              << " rows of other marker ids)";
  }
  std::cout << "\n";
  print_result(r, o);
  write_outputs(o, r);
  const bool any = std::any_of(r.bins.begin(), r.bins.end(), [](const auto& b) { return b.valid; });
  return any ? kExitOk : kExitFailure;
}

}  // namespace

EXODAQ_REGISTER_COMMAND(
    shoulder_cor, "shoulder-cor",
    "Shoulder centre of rotation by humerus elevation from torso and humerus markers "
    "(seed 001 §II.B, Table II)",
    [](CLI::App& app) -> std::function<int()> {
      auto o = std::make_shared<CorCommandOptions>();
      app.add_option("--markers", o->markers,
                     "motion capture: the long CSV utime_us,x_mm,y_mm,z_mm,marker_id, C3D, or a "
                     "Vicon Nexus or OptiTrack Motive CSV export")
          ->required();
      app.add_option("--torso", o->torso, "torso markers, ids or labels (3 or more)")
          ->required()
          ->delimiter(',');
      app.add_option("--humerus", o->humerus, "upper-arm markers, ids or labels (3 or more)")
          ->required()
          ->delimiter(',');
      app.add_option("--torso-axis", o->torso_axis,
                     "CRANIAL,CAUDAL: two torso markers along the torso, top first")
          ->required()
          ->expected(2)
          ->delimiter(',');
      app.add_option("--humerus-axis", o->humerus_axis,
                     "PROXIMAL,DISTAL: two humerus markers along the arm, shoulder end first")
          ->required()
          ->expected(2)
          ->delimiter(',');
      app.add_option("--bin-deg", o->bin_deg, "elevation bin width (default 20, as Table II)")
          ->check(CLI::Range(1.0, 90.0));
      app.add_option("--pairs", o->pairs, "frame pairs tried per bin (default 2000)");
      app.add_option("--min-rotation-deg", o->min_rotation_deg,
                     "pairs turning less are rejected (default 15)");
      app.add_option("--min-axes", o->min_axes, "fewest axes for a bin's centre (default 10)");
      app.add_option("--seed", o->seed, "random pair selection (default 1)");
      app.add_option("--centre-model", o->centre_model,
                     "moving: the centre may move linearly with elevation within a bin (default); "
                     "static: seed 001's centre at rest, the point closest to the axes")
          ->check(CLI::IsMember({"moving", "static"}));
      app.add_option("--max-ci-mm", o->max_ci_mm,
                     "flag components whose 95 % confidence half-width exceeds this (default 2)");
      app.add_option("--csv", o->csv, "bins CSV (default: next to --plot)");
      app.add_option("--plot", o->plot, "figure (PNG; needs python3-matplotlib)");
      return [o]() -> int {
        try {
          return run_shoulder_cor(*o);
        } catch (const std::exception& e) {
          print_error(e.what());
          return kExitUsage;
        }
      };
    });

}  // namespace exodaq::tools
