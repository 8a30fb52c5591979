// Calibration with more observations (issue 18 part 4): several hand markers
// and markers on the exoskeleton's base, and the palm position the daemon
// publishes in O0. Synthetic data from seed 000 Table 4 (truth "Results",
// start "Guess"), 0.3 mm marker noise, 400 marker times per set.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <sstream>

#include "exodaq/calibration/report.hpp"
#include "exodaq/calibration/solver.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/settings/calibration_file.hpp"
#include "synthetic.hpp"

namespace exodaq::calibration {
namespace {

using namespace synth;  // NOLINT

constexpr double kNoise3d = 0.3e-3 * 1.7320508075688772;  // 0.52 mm

std::vector<AlignedSample> aligned(const SyntheticData& d, const MarkerLayout& layout) {
  AlignmentStats s;
  auto pts = align(d.encoders, d.markers, AlignmentOptions{}, s);
  if (!layout.sites.empty()) apply_layout(pts, layout);
  return pts;
}

struct PalmError {
  double position_rms_m = 0;
  double orientation_rms_rad = 0;
};

// The palm pose the daemon publishes in O0 (homing offsets Δθ⁰ + the calibrated
// chain of settings::apply_calibration) against the truth, over the joint
// readings of `points` (one per marker time: the hand marker at the palm).
PalmError palm_error_in_o0(const ParamVector& x, const std::vector<AlignedSample>& points) {
  const NominalModel m = rig_model();
  std::vector<kinematics::JointDescription> joints(6);
  for (int i = 0; i < 6; ++i) joints[i].dh = m.dh[i];
  const kinematics::Chain nominal(kinematics::Convention::kStandardDh, joints,
                                  kinematics::Pose::Identity(), kinematics::Pose::Identity());
  const ParamVector truth = table4_results();
  const kinematics::Chain est = settings::apply_calibration(nominal, to_calibration(x));
  const kinematics::Chain tru = settings::apply_calibration(nominal, to_calibration(truth));
  double sq_p = 0, sq_r = 0;
  std::size_t n = 0;
  for (const auto& p : points) {
    if (p.site.mount != MarkerMount::kHand || p.site.id > 3) continue;
    kinematics::JointVector qe(6), qt(6);
    for (int j = 0; j < 6; ++j) {
      qe[j] = p.theta_r[j] + x[kTheta1 + j];
      qt[j] = p.theta_r[j] + truth[kTheta1 + j];
    }
    const kinematics::Pose pe = est.palm(qe), pt = tru.palm(qt);
    sq_p += (pe.translation() - pt.translation()).squaredNorm();
    const double angle = Eigen::AngleAxisd(pe.linear().transpose() * pt.linear()).angle();
    sq_r += angle * angle;
    ++n;
  }
  const double nn = static_cast<double>(n);
  return {std::sqrt(sq_p / nn), std::sqrt(sq_r / nn)};
}

struct MarkerRun {
  Report report;
  std::vector<AlignedSample> train, held_out;
  PalmError palm;
};

MarkerRun calibrate_with(const MarkerLayout& layout, const Bounds& bounds = guess_bounds()) {
  MarkerRun r;
  TrajectoryOptions o;
  o.layout = layout;
  o.seed = 1;
  r.train = aligned(make_data(o), layout);
  o.seed = 2;
  r.held_out = aligned(make_data(o), layout);
  r.report = calibrate(rig_model(), r.train, bounds, SolveOptions{});
  r.palm = palm_error_in_o0(estimates(r.report), r.held_out);
  std::ostringstream text;
  print_report(text, r.report, {});
  std::cout << text.str() << "palm in O0, held-out postures: position RMS "
            << r.palm.position_rms_m * 1e3 << " mm, orientation RMS "
            << r.palm.orientation_rms_rad / kDeg << " deg\n";
  return r;
}

const MarkerRun& one_marker() {
  static const MarkerRun r = calibrate_with(MarkerLayout{});
  return r;
}
const MarkerRun& base_markers() {
  static const MarkerRun r = calibrate_with(rig_layout(false, true));
  return r;
}
const MarkerRun& all_markers() {
  static const MarkerRun r = calibrate_with(rig_layout(true, true));
  return r;
}

const ObservationSet* find_set(const Report& r, const std::string& prefix) {
  for (const auto& s : r.observation_sets) {
    if (s.name.rfind(prefix, 0) == 0) return &s;
  }
  return nullptr;
}

void expect_identified_near_truth(const Report& r) {
  const ParamVector truth = table4_results();
  for (int p = 0; p < kParams; ++p) {
    const ParamResult& pr = r.params[p];
    if (pr.status != ParamStatus::kIdentified) continue;
    EXPECT_LE(std::abs(pr.estimate - truth[p]), 4.0 * pr.stddev)
        << param_label(p) << ": estimate " << to_display(p, pr.estimate) << " truth "
        << to_display(p, truth[p]) << " std " << to_display(p, pr.stddev);
  }
}

// The defect of issue 18: with one marker the marker fits to the noise but the
// palm the daemon publishes in O0 is off by the held Δθ1 (1.15° here at
// 150-300 mm from z0). No observation sets are printed: nothing to compare.
TEST(CalibrationMarkers, OneMarkerLeavesThePalmInO0OffByTheHeldJointOneOffset) {
  const MarkerRun& r = one_marker();
  EXPECT_LE(r.report.after.rms_m, 1.2 * kNoise3d);
  EXPECT_EQ(r.report.params[kTheta1].status, ParamStatus::kHeld);
  EXPECT_GT(r.palm.position_rms_m, 3e-3);
  EXPECT_GT(r.palm.orientation_rms_rad, 2.0 * kDeg);
  EXPECT_TRUE(r.report.observation_sets.empty());
  EXPECT_TRUE(r.report.per_marker.empty());
}

TEST(CalibrationMarkers, BaseMarkersIdentifyJointOneAndPutThePalmInO0Within1mm) {
  const MarkerRun& r = base_markers();
  EXPECT_LE(r.report.after.rms_m, 1.2 * kNoise3d);
  EXPECT_EQ(r.report.params[kTheta1].status, ParamStatus::kIdentified);
  EXPECT_EQ(r.report.params[kPhiZ].status, ParamStatus::kIdentified);
  // One hand marker still cannot see Δθ6 (exactly) nor tell Δθ5 from Δa5.
  EXPECT_EQ(r.report.params[kTheta5].status, ParamStatus::kHeld);
  EXPECT_EQ(r.report.params[kTheta6].status, ParamStatus::kHeld);
  expect_identified_near_truth(r.report);
  EXPECT_LE(r.palm.position_rms_m, 1e-3);
  // The palm position is the hand marker's point (apply_calibration adds Δpᴹ to
  // the tool), which the data pin down; its orientation still carries the held
  // Δθ5 (3.4° from the truth): the second hand marker is needed for that.
  EXPECT_GT(r.palm.orientation_rms_rad, 2.0 * kDeg);

  const ObservationSet* one = find_set(r.report, "one hand marker (id 3)");
  ASSERT_NE(one, nullptr);
  EXPECT_EQ(one->unidentifiable, (std::vector<int>{kTheta1, kTheta5, kTheta6}));
  const ObservationSet* base = find_set(r.report, "+ base markers 10, 11, 12");
  ASSERT_NE(base, nullptr);
  EXPECT_EQ(base->newly_identifiable, std::vector<int>{kTheta1});
  EXPECT_EQ(base->unidentifiable, (std::vector<int>{kTheta5, kTheta6}));
  ASSERT_EQ(r.report.per_marker.size(), 4u);
  for (const auto& m : r.report.per_marker) EXPECT_LE(m.after.rms_m, 1.3 * kNoise3d) << m.site.id;
}

TEST(CalibrationMarkers, TwoHandMarkersAndBaseMarkersIdentifyAllTwentyParameters) {
  const MarkerRun& r = all_markers();
  EXPECT_LE(r.report.after.rms_m, 1.2 * kNoise3d);
  for (int p = 0; p < kParams; ++p) {
    EXPECT_EQ(r.report.params[p].status, ParamStatus::kIdentified) << param_label(p);
  }
  EXPECT_TRUE(r.report.degeneracies.empty());
  expect_identified_near_truth(r.report);
  EXPECT_LE(r.palm.position_rms_m, 1e-3);
  EXPECT_LE(r.palm.orientation_rms_rad, 0.2 * kDeg);

  const ObservationSet* hand = find_set(r.report, "+ hand markers 4");
  ASSERT_NE(hand, nullptr);
  EXPECT_EQ(hand->unidentifiable, std::vector<int>{kTheta1});
  EXPECT_EQ(hand->newly_identifiable, (std::vector<int>{kTheta5, kTheta6}));
  const ObservationSet* all = find_set(r.report, "all observations");
  ASSERT_NE(all, nullptr);
  EXPECT_TRUE(all->unidentifiable.empty());
  EXPECT_EQ(all->newly_identifiable, (std::vector<int>{kTheta1, kTheta5, kTheta6}));
  std::ostringstream text;
  print_report(text, r.report, {});
  EXPECT_NE(text.str().find("Identifiability by observations"), std::string::npos);
  EXPECT_NE(text.str().find("after, base marker 12"), std::string::npos);
}

// A second hand marker without base markers: Δθ5 and Δθ6 identified, Δθ1
// still exactly traded against φz, so O0 stays turned by the held Δθ1.
TEST(CalibrationMarkers, SecondHandMarkerIdentifiesJointsFiveAndSix) {
  const MarkerRun r = calibrate_with(rig_layout(true, false));
  EXPECT_EQ(r.report.params[kTheta5].status, ParamStatus::kIdentified);
  EXPECT_EQ(r.report.params[kTheta6].status, ParamStatus::kIdentified);
  EXPECT_EQ(r.report.params[kTheta1].status, ParamStatus::kHeld);
  expect_identified_near_truth(r.report);
  EXPECT_GT(r.palm.position_rms_m, 3e-3);
  // Only the held Δθ1 (1.15° from the truth) is left in the orientation.
  EXPECT_NEAR(r.palm.orientation_rms_rad, 1.15 * kDeg, 0.1 * kDeg);
}

// A camera → O0 transform measured independently (fixed in the bounds file,
// here at the truth) identifies Δθ1 as the base markers do.
TEST(CalibrationMarkers, FixedCameraTransformIdentifiesJointOne) {
  Bounds b = guess_bounds();
  const ParamVector truth = table4_results();
  for (int p = kDx; p <= kPhiZ; ++p) b.params[p] = ParamPrior{truth[p], truth[p], truth[p], true};
  const MarkerRun r = calibrate_with(MarkerLayout{}, b);
  EXPECT_EQ(r.report.params[kTheta1].status, ParamStatus::kIdentified);
  expect_identified_near_truth(r.report);
  EXPECT_LE(r.palm.position_rms_m, 1e-3);
  const ObservationSet* fixed = find_set(r.report, "camera transform fixed");
  ASSERT_NE(fixed, nullptr);
  EXPECT_EQ(fixed->newly_identifiable, std::vector<int>{kTheta1});
}

TEST(CalibrationMarkers, ValidationPredictsEveryMarkerFromItsSite) {
  const MarkerRun& r = all_markers();
  const ErrorStats s = evaluate(rig_model(), estimates(r.report), r.held_out);
  EXPECT_EQ(s.n, 5u * 400u);
  EXPECT_LE(s.rms_m, 1.3 * kNoise3d);
}

std::string layout_error(const std::string& text) {
  try {
    load_marker_layout_text(text, "m.yaml");
  } catch (const exodaq::ConfigError& e) {
    return e.what();
  }
  return "no error";
}

TEST(MarkerLayout, ShippedExampleLoads) {
  const MarkerLayout l = load_marker_layout_file(std::string(EXODAQ_SOURCE_DIR) +
                                                 "/config/calibration/markers_example.yaml");
  const MarkerLayout expect = rig_layout(true, true);
  ASSERT_EQ(l.sites.size(), expect.sites.size());
  for (std::size_t k = 0; k < l.sites.size(); ++k) {
    EXPECT_EQ(l.sites[k].id, expect.sites[k].id);
    EXPECT_EQ(l.sites[k].label, expect.sites[k].label);
    EXPECT_EQ(l.sites[k].mount, expect.sites[k].mount);
    for (int i = 0; i < 3; ++i)
      EXPECT_NEAR(l.sites[k].position[i], expect.sites[k].position[i], 1e-15);
  }
  EXPECT_EQ(l.ids(MarkerMount::kBase), (std::vector<int>{10, 11, 12}));
}

TEST(MarkerLayout, ErrorsNameTheLine) {
  const std::string head = "format: exodaq-marker-layout-1\nmarkers:\n";
  EXPECT_EQ(layout_error(head + "  - {id: 3, on: hand, position_mm: [0, 0, 0]}\n"), "no error");
  EXPECT_EQ(layout_error(head + "  - {id: 3, on: hand, position_mm: [0, 0, 0]}\n"
                                "  - {id: 3, on: base, position_mm: [1, 0, 0]}\n"),
            "m.yaml:4: marker id 3 appears twice");
  EXPECT_EQ(layout_error(head + "  - {id: 10, on: base, position_mm: [0, 0, 0]}\n"),
            "m.yaml:3: at least one marker must be 'on: hand' (the base markers see no joint)");
  EXPECT_EQ(layout_error(head + "  - {id: 3, on: hand, position_mm: [0, 0]}\n"),
            "m.yaml:3: 'position_mm' must have 3 numbers, has 2");
  EXPECT_NE(
      layout_error(head + "  - {id: 3, on: elbow, position_mm: [0, 0, 0]}\n").find("m.yaml:3"),
      std::string::npos);
}

TEST(MarkerCsvIds, KeepsTheGivenMarkersAndCountsTheOthers) {
  const std::string csv =
      "utime_us,x_mm,y_mm,z_mm,marker_id\n"
      "1000,1,2,3,3\n1000,4,5,6,4\n1000,7,8,9,99\n"
      "2000,1,2,3,3\n2000,,,,4\n2000,7,8,9,99\n";
  const MarkerSeries m = parse_marker_csv_ids(csv, "m.csv", {3, 4});
  ASSERT_EQ(m.samples.size(), 4u);
  EXPECT_EQ(m.other_ids, 2u);
  EXPECT_EQ(m.samples[1].marker_id, 4);
  EXPECT_DOUBLE_EQ(m.samples[1].x, 4e-3);
  EXPECT_FALSE(m.samples[3].present);
  auto err = [&](const std::string& text, const std::vector<int>& ids) {
    try {
      parse_marker_csv_ids(text, "m.csv", ids);
    } catch (const exodaq::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(err(csv, {3, 5, 6}), "m.csv: no samples of marker_id 5, 6");
  EXPECT_EQ(err("utime_us,x_mm,y_mm,z_mm\n1000,1,2,3\n", {3}),
            "m.csv:1: several markers need the 'marker_id' column");
  EXPECT_EQ(
      err("utime_us,x_mm,y_mm,z_mm,marker_id\n2000,1,2,3,3\n1000,1,2,3,4\n1000,1,2,3,3\n", {3, 4}),
      "m.csv:4: utime_us 1000 does not increase (previous row 2000)");
}

TEST(MarkerCsvIds, MaxPointsThinsEachMarkerAndTheLayoutPlacesThem) {
  TrajectoryOptions o;
  o.layout = rig_layout(true, false);
  const SyntheticData d = make_data(o);
  AlignmentOptions ao;
  ao.max_points = 100;
  AlignmentStats st;
  auto pts = align(d.encoders, d.markers, ao, st);
  EXPECT_EQ(pts.size(), 200u);
  EXPECT_EQ(st.thinned, 600u);
  apply_layout(pts, o.layout);
  EXPECT_EQ(
      std::count_if(pts.begin(), pts.end(), [](const AlignedSample& p) { return p.site.id == 4; }),
      100);
  for (const auto& p : pts) {
    if (p.site.id == 4) {
      EXPECT_DOUBLE_EQ(p.site.position[2], -0.070);
    }
  }
  EXPECT_THROW(apply_layout(pts, rig_layout(false, false)), std::invalid_argument);
}

}  // namespace
}  // namespace exodaq::calibration
