#pragma once
// Printing the calibration report (seed 000 §4.3 figures for the user's data),
// the residual CSV and the residual figure.
#include <ostream>
#include <string>
#include <vector>

#include "exodaq/calibration/solver.hpp"

namespace exodaq::calibration {

struct ValidationResult {
  std::string name;
  std::size_t points = 0;
  AlignmentStats alignment;
  ErrorStats before, after;  // with the initial guesses / with the calibration
  std::vector<Eigen::Vector3d> residual_before, residual_after;
};

// Paper figures (seed 000 §4.3.1), printed next to the user's for comparison.
inline constexpr double kPaperRmsBeforeMm = 13.6;
inline constexpr double kPaperRmsAfterMm = 1.05;

void print_alignment(std::ostream& o, const std::string& name, const AlignmentStats& s);
void print_report(std::ostream& o, const Report& r,
                  const std::vector<ValidationResult>& validation);

// CSV: set,index,utime_us,before_x_mm,before_y_mm,before_z_mm,before_mm,after_x_mm,...,after_mm
// Written as a files::OutputFile (never one of `inputs`); throws files::FileError.
void write_residual_csv(const std::string& path, const std::vector<std::int64_t>& train_utime,
                        const Report& r, const std::vector<ValidationResult>& validation,
                        const std::vector<std::vector<std::int64_t>>& validation_utime,
                        const std::vector<std::string>& inputs = {});

// Runs tools/calibration/plot_residuals.py (installed next to the binary or in the
// source tree) on the CSV (run_plot_script: the PNG is written whole or not at
// all). Returns false with `message` set when Python or matplotlib is
// missing; the calibration itself is unaffected.
bool plot_residuals(const std::string& csv, const std::string& png, std::string& message,
                    const std::vector<std::string>& inputs = {});

}  // namespace exodaq::calibration
