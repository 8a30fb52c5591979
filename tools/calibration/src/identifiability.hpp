#pragma once
// Identifiability analysis on the Jacobian at a solution (docs/calibration.md
// §5): which columns the data cannot determine, the degeneracies they form,
// correlations and singular values. Eigen only (no Ceres); private to the library.
// J has one row per residual (mm) and kParams + 1 columns (SI; the last is τ).
#include <Eigen/Core>
#include <array>
#include <vector>

#include "exodaq/calibration/solver.hpp"

namespace exodaq::calibration::detail {

using ColumnMask = std::array<bool, kParams>;

Eigen::MatrixXd columns(const Eigen::MatrixXd& J, const std::vector<int>& cols);

// The resolution a column should be determined to (max_std_*; 1 ms for τ).
double tolerance(const IdentifiabilityOptions& o, int col);

// Per-axis residual std (mm): from the sum of squares, or with a robust loss
// from the median absolute residual (outliers would inflate the former).
double residual_sigma_mm(const Eigen::VectorXd& r, std::size_t nfree, bool robust);

// The candidate columns the data cannot determine to their tolerance with
// noise sigma_mm. Columns are admitted from the end of eq. (6) to the front
// (camera, marker, DH deviations, encoder offsets), so where two parameters
// cannot be told apart the encoder offset is the one returned; then the kept
// set as a whole must be well conditioned (SVD check). τ, when estimated, is
// always kept. Returned in the order found.
std::vector<int> unobservable(const Eigen::MatrixXd& J, const ColumnMask& candidate, bool with_tau,
                              double sigma_mm, const IdentifiabilityOptions& o);

// Singular values of the estimated columns scaled to their tolerances.
std::vector<double> scaled_singular_values(const Eigen::MatrixXd& J, const std::vector<int>& est,
                                           const IdentifiabilityOptions& o);

// For every held column: what the estimated columns make of it (Degeneracy),
// the notes of the held parameter, and the estimated parameters that follow
// its prior (status kGaugeDependent). rep.params must hold the std devs.
void describe_degeneracies(const Eigen::MatrixXd& J, const std::vector<int>& est,
                           const ColumnMask& held, double sigma_mm, const Bounds& bounds,
                           Report& rep);

// |r| above the threshold among the estimated columns of a covariance matrix.
std::vector<Correlation> correlations(const Eigen::MatrixXd& cov, const std::vector<int>& est,
                                      double threshold);

// Which parameters each kind of observation identifies (Report::observation_sets):
// row subsets of J by marker (one hand marker, + the other hand markers, +
// the base markers) and column sets (camera free as in seed 000, or as the
// bounds file says). Empty with one marker and a free camera (nothing to compare).
std::vector<ObservationSet> observation_sets(const Eigen::MatrixXd& J,
                                             const std::vector<AlignedSample>& points,
                                             const ColumnMask& estimable, bool with_tau,
                                             double sigma_mm, const Bounds& bounds);

}  // namespace exodaq::calibration::detail
