#pragma once
// Statistics both analysis engines share (internal to twin/analysis): robust spread, per-segment
// normal equations, least squares on the segments, held-out errors and partial R².
#include <Eigen/Dense>
#include <cmath>
#include <cstddef>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "maglead/recording/recording.hpp"

namespace maglead::analysis::stats {

double median_of(std::vector<double> x);
/// Standard deviation from the median absolute deviation (normal data), robust to outliers.
double robust_sigma(std::vector<double> x);
/// Mean over its standard error (one-sample t); large when every value is positive alike.
double t_statistic(const std::vector<double>& x);
double total(const std::vector<double>& x);

/// Throws RecordingError naming the file, the column and the data row of the first non-number.
void require_finite(const Recording& rec, const std::vector<double>& x, const std::string& name);
/// The columns every analysis reads: each present and finite (require_finite), and enough rows
/// to analyse; throws naming the file otherwise.
void require_analysable(const Recording& rec, const std::vector<std::string>& columns);
/// Standard deviation of white noise on a smooth signal, from its sample-to-sample roughness
/// (var(Δ²y) = 6σ²; robust to the signal's own steps).
double white_noise_sigma(const std::vector<double>& y);
/// The step a column is logged in: the smallest gap between its distinct values when every gap
/// is a whole multiple of it; 0 when the values share no step (a continuous column).
double logging_step(const std::vector<double>& y);
/// A sensor's noise floor: its white noise, but never below the rounding error of its logging
/// step (step/√12), which a column logged in steps coarser than its noise hides from the second
/// differences (most are 0). `measured` is false when the floor rests on the step alone.
struct SensorNoise {
  double sigma = 0.0, step = 0.0;
  bool measured = true;
};
SensorNoise sensor_noise(const std::vector<double>& y);

/// RMS and relative error of a sum of squares over `n_used` samples whose measured force has
/// the sum of squares `measured_ss`.
struct ErrorScale {
  double n_used, measured_ss;
  double rms(double s) const { return std::sqrt(s / n_used); }
  double rel(double s) const { return measured_ss > 0 ? 100.0 * std::sqrt(s / measured_ss) : 0.0; }
};

/// The held-out segment of a sample `since_start_s` after the recording's start: its span `span_s`
/// cut into `folds` equal times. By time, not by sample count: the same cut whatever the logger's
/// spacing, gaps or samples left out (with a uniform logger the two coincide).
std::size_t fold_of(double since_start_s, double span_s, int folds);
/// Where each segment starts in the non-decreasing time stamps `t` (fold_of from `start_s`):
/// folds + 1 positions, segment f being [starts[f], starts[f + 1]).
std::vector<std::size_t> fold_starts(const std::vector<double>& t, double start_s, double span_s,
                                     int folds);

/// Per-segment normal equations over a set of columns; a fit is a small solve on their sums.
struct Grams {
  using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  std::vector<Eigen::MatrixXd> xx;
  std::vector<Eigen::VectorXd> xr;
  std::vector<double> rr, yy;  // residual and measured force, sums of squares
  std::vector<std::size_t> n;
  /// Per column, the sum of squares over every sample of the noise it carries from a noisy
  /// measurement (the load cell through the filter); empty or zero: a noise-free column.
  Eigen::VectorXd noise_ss;

  Grams() = default;
  Grams(std::size_t folds, Eigen::Index columns);
  /// One sample: regressors x, residual r, measured force y; fills the lower triangle only.
  void add_row(std::size_t fold, const Eigen::VectorXd& x, double r, double y);
  /// A block of rows into segment `fold` (lower triangle only, as add_row); yy_sum is their Σy².
  void add_rows(std::size_t fold, const Eigen::Ref<const RowMatrix>& x,
                const Eigen::Ref<const Eigen::VectorXd>& r, double yy_sum);
  /// Copies the lower triangle of every segment's X'X to its upper one (after add_row).
  void symmetrize();
  /// A whole segment at once: rows of regressors, residuals and Σy².
  void add_segment(const Eigen::Ref<const Eigen::MatrixXd>& x, const Eigen::VectorXd& r,
                   double yy_sum);
  std::size_t folds() const { return xx.size(); }
};

struct Fit {
  std::vector<int> idx;   // column positions in the Grams
  Eigen::VectorXd theta;  // in the order of idx
};

/// Least squares on every segment but `skip_fold` (−1: all of them).
Fit solve(const Grams& g, const std::vector<int>& idx, int skip_fold = -1);
/// Squared error of `fit` on segment f.
double sse(const Grams& g, const Fit& fit, std::size_t f);
/// Squared error of `fit` on every segment (in-sample).
double sse(const Grams& g, const Fit& fit);
/// Held-out error per segment: fit on the others, score on this one.
std::vector<double> heldout(const Grams& g, const std::vector<int>& idx);
/// The fit without each segment in turn (a segment without samples is skipped).
std::vector<Fit> leave_one_out(const Grams& g, const std::vector<int>& idx);
/// Named values (parameters by name), as the effect units give them.
using Named = std::map<std::string, double, std::less<>>;
/// Jackknife standard errors from named values in each leave-one-out fit: √((K−1)/K Σ(x − x̄)²)
/// over the K fits that give the name (fewer than two: no error).
Named jackknife_se(const std::vector<Named>& leave_one_out_values);
/// A model's named values at one fit, in groups (a term's parameters, in a fixed order); none:
/// that group gives no value at this fit.
using GroupValues = std::function<std::vector<std::optional<Named>>(const Fit&)>;
/// The final model: columns `idx` fitted on every segment, its values group by group, and each
/// group's standard errors from the held-out segments (jackknife_se over the fits without each
/// segment in turn, those where the group gives a value).
struct Estimates {
  Fit fit;
  std::vector<std::optional<Named>> values;
  std::vector<Named> standard_errors;
};
Estimates estimate(const Grams& g, const std::vector<int>& idx, const GroupValues& values);
/// X'X of the columns `idx` (in that order) over every segment.
Eigen::MatrixXd summed_gram(const Grams& g, const std::vector<int>& idx);
/// Share of `a`'s fitted contribution wa (beyond `base`) that columns `b` reproduce, between
/// the columns' noise-free parts (Grams::noise_ss taken off their sums of squares): a column
/// made from a noisy measurement reproduces a law no worse for the noise it carries.
double partial_r2(const Grams& g, const std::vector<int>& base, const std::vector<int>& a,
                  const Eigen::VectorXd& wa, const std::vector<int>& b);

}  // namespace maglead::analysis::stats
