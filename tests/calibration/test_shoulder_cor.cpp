// Shoulder centre of rotation (seed 001 §II.B, issue 18 part 5): the rigid
// transform fit, the rotation axis of a displacement, the least-squares
// centre, and the whole analysis on synthetic motion capture whose centre
// rises with elevation as in seed 001 Table II.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "exodaq/calibration/shoulder_cor.hpp"
#include "shoulder_synthetic.hpp"

namespace exodaq::calibration {
namespace {

using namespace shoulder_synth;  // NOLINT

Eigen::Matrix3d rotation(double angle, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

TEST(RigidTransform, RecoversAKnownTransform) {
  Eigen::Matrix3Xd from(3, 5);
  from << 0.1, -0.2, 0.3, 0.05, 0.0,  //
      0.0, 0.1, 0.2, -0.3, 0.15,      //
      0.4, 0.0, -0.1, 0.2, 0.3;
  const Eigen::Matrix3d R = rotation(1.1, Eigen::Vector3d(1, -2, 0.5));
  const Eigen::Vector3d t(0.3, -0.2, 0.9);
  const Eigen::Matrix3Xd to = (R * from).colwise() + t;
  const auto fit = fit_rigid_transform(from, to);
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT((fit->rotation - R).norm(), 1e-12);
  EXPECT_LT((fit->translation - t).norm(), 1e-12);
}

TEST(RigidTransform, PlanarPointsGiveAProperRotationAndLinesNone) {
  Eigen::Matrix3Xd from(3, 4);
  from << 0, 1, 0, 1,  //
      0, 0, 1, 1,      //
      0, 0, 0, 0;
  const Eigen::Matrix3d R = rotation(2.5, Eigen::Vector3d(0.3, 1, 0.2));
  const auto fit = fit_rigid_transform(from, R * from);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->rotation.determinant(), 1.0, 1e-12);  // not the reflection
  EXPECT_LT((fit->rotation - R).norm(), 1e-12);
  Eigen::Matrix3Xd line(3, 3);
  line << 0, 1, 2, 0, 1, 2, 0, 1, 2;
  EXPECT_FALSE(fit_rigid_transform(line, line).has_value());
  EXPECT_FALSE(fit_rigid_transform(from.leftCols(2), from.leftCols(2)).has_value());
}

TEST(RotationAxis, LocatesTheAxisOfARotationAboutAPoint) {
  const Eigen::Vector3d c(0.2, -0.1, 0.5), v = Eigen::Vector3d(1, 1, 0.3).normalized();
  RigidTransform T;
  T.rotation = rotation(0.7, v);
  T.translation = c - T.rotation * c;  // x -> R (x - c) + c
  const RotationAxis a = rotation_axis(T);
  EXPECT_NEAR(a.angle_rad, 0.7, 1e-12);
  EXPECT_NEAR(std::abs(a.direction.dot(v)), 1.0, 1e-12);
  EXPECT_NEAR(a.slide_m, 0.0, 1e-12);
  EXPECT_NEAR(distance_to_axis(c, a), 0.0, 1e-12);
  EXPECT_NEAR(a.point.dot(a.direction), 0.0, 1e-12);  // the axis point closest to the origin
  T.translation += 0.01 * v;                          // a screw: the slide is reported apart
  EXPECT_NEAR(std::abs(rotation_axis(T).slide_m), 0.01, 1e-12);
  EXPECT_NEAR(distance_to_axis(c, rotation_axis(T)), 0.0, 1e-12);
}

TEST(RotationAxis, ClosestPointAndSphereCentre) {
  const Eigen::Vector3d c(0.1, 0.2, 0.3);
  std::vector<RotationAxis> axes;
  for (const Eigen::Vector3d& v : {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 1).normalized(),
                                   Eigen::Vector3d(1, 1, 1).normalized()}) {
    RotationAxis a;
    a.direction = v;
    a.point = c + 0.4 * v;
    axes.push_back(a);
  }
  const auto p = closest_point_to_axes(axes);
  ASSERT_TRUE(p.has_value());
  EXPECT_LT((*p - c).norm(), 1e-12);
  axes[1].direction = axes[2].direction = axes[0].direction;  // all parallel
  EXPECT_FALSE(closest_point_to_axes(axes).has_value());

  std::vector<Eigen::Matrix3Xd> tracks(3, Eigen::Matrix3Xd(3, 20));
  for (int m = 0; m < 3; ++m) {
    for (int k = 0; k < 20; ++k) {
      const Eigen::Vector3d d(std::cos(0.3 * k + m), std::sin(0.3 * k + m) * std::cos(0.2 * k),
                              std::sin(0.3 * k + m) * std::sin(0.2 * k));
      tracks[m].col(k) = c + (0.05 + 0.02 * m) * d;
    }
  }
  const auto s = fit_sphere_centre(tracks);
  ASSERT_TRUE(s.has_value());
  EXPECT_LT((*s - c).norm(), 1e-12);
}

void print(const CorResult& r) {
  for (const auto& b : r.bins) {
    std::cout << "  bin " << b.elevation_lo_rad / kDeg << "-" << b.elevation_hi_rad / kDeg
              << " deg: frames " << b.frames << ", axes " << b.axes << " (" << b.outliers
              << " outliers, " << b.pairs_small << " small), vertical " << b.vertical_m * 1e3
              << " mm, axis rms " << b.axis_rms_m * 1e3 << " mm\n";
  }
}

// The centre as the analysis assumes it: constant within each 20° bin, rising
// by Table II between them; torso swaying by 8° and 15 mm.
TEST(ShoulderCor, RecoversAMovingCentreWithin1mm) {
  const CorResult r = analyse_shoulder_cor(make_frames(Options{}), ShoulderAxes{}, CorOptions{});
  print(r);
  EXPECT_EQ(r.frames, 12000u);
  EXPECT_EQ(r.frames_used, 12000u);
  EXPECT_LT((r.cranial - torso_pose(0).linear() * Eigen::Vector3d::UnitY()).norm(), 0.01);
  ASSERT_EQ(r.bins.size(), 6u);
  for (std::size_t k = 0; k < 6; ++k) {
    const CorBin& b = r.bins[k];
    ASSERT_TRUE(b.valid) << k << ": " << b.why;
    const double err = (b.centre - true_centre(k)).norm();
    std::cout << "bin " << k << ": centre error " << err * 1e3 << " mm, vertical "
              << b.vertical_m * 1e3 << " mm (Table II " << kTable2Mm[k] << ")\n";
    EXPECT_LT(err, 1e-3) << "bin " << k;
    EXPECT_NEAR(b.vertical_m, kTable2Mm[k] * 1e-3, 1e-3) << "bin " << k;
    EXPECT_GT(b.axes, 100u);
  }
}

// Occluded humerus markers and frames with a marker 20 mm off (a camera
// switching error, seed 001): the outlying axes are dropped.
TEST(ShoulderCor, OcclusionsAndSwappedMarkersStayWithin1mm) {
  Options o;
  o.seed = 2;
  o.occluded_fraction = 0.05;
  o.swapped_fraction = 0.03;
  const CorResult r = analyse_shoulder_cor(make_frames(o), ShoulderAxes{}, CorOptions{});
  print(r);
  ASSERT_EQ(r.bins.size(), 6u);
  std::size_t outliers = 0;
  for (std::size_t k = 0; k < 6; ++k) {
    ASSERT_TRUE(r.bins[k].valid) << k << ": " << r.bins[k].why;
    EXPECT_LT((r.bins[k].centre - true_centre(k)).norm(), 1e-3) << "bin " << k;
    outliers += r.bins[k].outliers;
  }
  EXPECT_GT(outliers, 0u);
}

// The realistic case: the centre moves continuously with elevation (Table II
// at the bin centres, linear between: a kink at each bin centre). The moving-
// centre model is linear within a bin; the bin's centre is compared with the
// mean of the true centre over the frames whose true elevation lies in the
// bin: within 0.5 mm (3-D), 0.4 mm in the vertical (docs/shoulder-cor.md; the
// centre at rest of seed 001 was 4.8 mm and 2.1 mm off).
TEST(ShoulderCor, ContinuouslyMovingCentreIsNearTheBinAverage) {
  Options o;
  o.piecewise = false;
  const CorResult r = analyse_shoulder_cor(make_frames(o), ShoulderAxes{}, CorOptions{});
  print(r);
  ASSERT_EQ(r.bins.size(), 6u);
  std::array<Eigen::Vector3d, 6> mean;
  mean.fill(Eigen::Vector3d::Zero());
  std::array<int, 6> n{};
  for (std::size_t k = 0; k < 12000; ++k) {
    const double e = elevation_at(static_cast<double>(k) / o.rate_hz);
    const auto bin = static_cast<std::size_t>(e / (20 * kDeg));
    mean[bin] += torso_pose(0.0) * centre_local(e, false);
    ++n[bin];
  }
  for (std::size_t k = 0; k < 6; ++k) {
    ASSERT_TRUE(r.bins[k].valid) << k;
    const Eigen::Vector3d expect = mean[k] / n[k];
    const Eigen::Vector3d d = r.bins[k].centre - expect;
    std::cout << "bin " << k << ": centre - bin average of the true centre " << d.norm() * 1e3
              << " mm (vertical " << d.dot(r.cranial) * 1e3 << " mm) \n";
    EXPECT_LT(d.norm(), 1e-3) << "bin " << k;
    EXPECT_LT(std::abs(d.dot(r.cranial)), 0.6e-3) << "bin " << k;
  }
}

TEST(ShoulderCor, NoCompleteTorsoIsAClearError) {
  std::vector<MocapFrame> frames = make_frames(Options{.duration_s = 1.0});
  for (auto& f : frames) f.torso.col(2).setConstant(NAN);
  try {
    analyse_shoulder_cor(frames, ShoulderAxes{}, CorOptions{});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(),
                 "no frame shows all torso markers (at least 3 needed to hold the torso still)");
  }
}

}  // namespace
}  // namespace exodaq::calibration

namespace exodaq::calibration {
namespace {

using namespace shoulder_synth;  // NOLINT

// Issue 28 part 3: a centre moving linearly with elevation (0.5 mm/deg up,
// a third of that forward), 20 seeds: the true centre at each bin's mean
// elevation lies inside the reported 95 % interval of each axis in at least
// 90 % of the (bin, axis) cases and in its 95 % ellipsoid in 90 % of the
// bins; the lowest bin, whose vertical is six times less determined than its
// best direction, is flagged.
TEST(ShoulderCorUncertainty, TheTruthLiesInsideThe95PercentIntervals) {
  int inside = 0, cases = 0, inside_3d = 0, bins = 0, flagged = 0;
  double sum_d2 = 0;  // Mahalanobis distances squared: 3 on average when the covariance is right
  double widest = 0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    Options o;
    o.seed = seed;
    o.piecewise = false;
    o.linear_mm_per_deg = 0.5;
    o.duration_s = 60.0;
    CorOptions co;
    co.seed = seed;
    co.pairs_per_bin = 1000;
    const std::vector<MocapFrame> frames = make_frames(o);
    const CorResult r = analyse_shoulder_cor(frames, ShoulderAxes{}, co);
    // The analysis' torso frame is the first frame's as measured: the true
    // torso markers carried onto the measured ones.
    Eigen::Matrix3Xd torso0(3, 5);
    for (int m = 0; m < 5; ++m) torso0.col(m) = torso_pose(0.0) * kTorso[m];
    const RigidTransform frame = *fit_rigid_transform(torso0, frames.front().torso);
    // The bins hold frames by measured elevation (the torso's axis from two
    // noisy markers tilts it by ~0.2 deg): the truth is the centre at the true
    // mean elevation of the frames in each bin.
    CorResult unused;
    const std::vector<MocapFrame> norm = normalise_to_torso(frames, unused);
    const Eigen::Vector3d caudal = (norm[0].torso.col(1) - norm[0].torso.col(0)).normalized();
    std::vector<double> true_sum(r.bins.size(), 0.0), count(r.bins.size(), 0.0);
    for (std::size_t k = 0; k < norm.size(); ++k) {
      const auto bin = static_cast<std::size_t>(humerus_elevation(norm[k], ShoulderAxes{}, caudal) /
                                                co.bin_width_rad);
      if (bin >= r.bins.size()) continue;
      true_sum[bin] += elevation_at(static_cast<double>(k) / o.rate_hz);
      count[bin] += 1;
    }
    for (std::size_t k = 0; k < r.bins.size(); ++k) {
      const CorBin& b = r.bins[k];
      if (!b.valid) continue;
      const Eigen::Vector3d truth = frame.apply(
          torso_pose(0.0) * centre_local(true_sum[k] / count[k], false, o.linear_mm_per_deg));
      const Eigen::Vector3d err = b.centre - truth;
      for (int k = 0; k < 3; ++k) {
        ++cases;
        inside += std::abs(err[k]) <= b.ci95_m[k] ? 1 : 0;
      }
      // The 3-D 95 % ellipsoid: chi-square with 3 degrees of freedom, 7.815.
      ++bins;
      const double d2 = err.dot(b.covariance.ldlt().solve(err));
      inside_3d += d2 <= 7.815 ? 1 : 0;
      sum_d2 += d2;
      flagged += b.warning.empty() ? 0 : 1;
      // The lowest bin turns mostly about near-vertical axes: flagged.
      if (k == 0) {
        EXPECT_TRUE(b.vertical_poor) << "seed " << seed;
      }
      widest = std::max(widest, b.ci95_m.maxCoeff());
      if (seed == 1) {
        std::cout << "bin " << b.elevation_lo_rad / kDeg << ": error " << err.transpose() * 1e3
                  << " mm, 95 % half-widths " << b.ci95_m.transpose() * 1e3 << " mm, spread "
                  << b.axis_spread_rad / kDeg << " deg " << b.warning << "\n";
      }
    }
  }
  std::cout << inside << " of " << cases << " axis intervals and " << inside_3d << " of " << bins
            << " ellipsoids hold the truth (mean squared Mahalanobis distance " << sum_d2 / bins
            << ", 3 expected); " << flagged << " bins flagged; widest half-width " << widest * 1e3
            << " mm\n";
  EXPECT_GE(inside, 0.9 * cases);
  EXPECT_GE(inside_3d, 0.9 * bins);
  EXPECT_LE(inside, 0.995 * cases);  // intervals that always hold would be too wide to be honest
}

}  // namespace
}  // namespace exodaq::calibration

namespace exodaq::calibration {
namespace {

using namespace shoulder_synth;  // NOLINT

// The case: near 0° elevation the rotations within a bin turn about
// nearly vertical axes (axial rotation, plane of elevation) and the centre's
// vertical component is poorly determined. An arm kept between 8° and 12°:
// the bin is flagged, its vertical interval is wide against the horizontal
// ones (and holds the truth).
TEST(ShoulderCorUncertainty, ABinTurningAboutNearlyParallelAxesIsFlagged) {
  Options o;
  o.duration_s = 60.0;
  o.elevation_lo_deg = 8.0;
  o.elevation_hi_deg = 12.0;
  const std::vector<MocapFrame> frames = make_frames(o);
  const CorResult r = analyse_shoulder_cor(frames, ShoulderAxes{}, CorOptions{});
  ASSERT_EQ(r.bins.size(), 1u);
  const CorBin& b = r.bins[0];
  ASSERT_TRUE(b.valid) << b.why;
  std::cout << "half-widths " << b.ci95_m.transpose() * 1e3 << " mm, spread "
            << b.axis_spread_rad / kDeg << " deg, weakest ±" << b.weak_ci95_m * 1e3 << " mm along "
            << b.weak_direction.transpose() << ": " << b.warning << "\n";
  EXPECT_TRUE(b.ill_conditioned);
  EXPECT_TRUE(b.vertical_poor);
  EXPECT_NE(b.warning.find("poorly determined: vertical ±"), std::string::npos) << b.warning;
  // The weak direction is the torso's vertical (cranial).
  EXPECT_GT(std::abs(b.weak_direction.dot(r.cranial)), 0.9);
  Eigen::Matrix3Xd torso0(3, 5);
  for (int m = 0; m < 5; ++m) torso0.col(m) = torso_pose(0.0) * kTorso[m];
  const Eigen::Vector3d truth = fit_rigid_transform(torso0, frames.front().torso)
                                    ->apply(torso_pose(0.0) * centre_local(10.0 * kDeg, true));
  const double vertical_error = (b.centre - truth).dot(r.cranial);
  const double vertical_ci = kZ95 * std::sqrt(r.cranial.dot(b.covariance * r.cranial));
  EXPECT_LE(std::abs(vertical_error), 2 * vertical_ci);  // within about 4 standard deviations
  // Across the vertical, five times better determined.
  const Eigen::Vector3d across = r.cranial.unitOrthogonal();
  EXPECT_GT(vertical_ci, 5 * kZ95 * std::sqrt(across.dot(b.covariance * across)));
}

}  // namespace
}  // namespace exodaq::calibration
