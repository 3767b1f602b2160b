// The one final fit with standard errors both analysis paths use (stats::estimate, internal to
// twin/analysis): a constant fitted to four segments, against the jackknife computed by hand.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <optional>
#include <vector>

#include "statistics.hpp"

namespace {

using maglead::analysis::stats::Estimates;
using maglead::analysis::stats::Fit;
using maglead::analysis::stats::Grams;
using maglead::analysis::stats::Named;

// Four segments of two samples each; one column of ones, so a fit is the mean residual of the
// segments it uses: 2.5 on all, 16/6, 16/6, 10/6 and 18/6 without each segment in turn.
Grams four_segments() {
  const std::vector<std::vector<double>> r = {{1, 3}, {2, 2}, {4, 6}, {0, 2}};
  Grams g(r.size(), 1);
  const Eigen::VectorXd one = Eigen::VectorXd::Ones(1);
  for (std::size_t f = 0; f < r.size(); ++f)
    for (double v : r[f]) g.add_row(f, one, v, v);
  g.symmetrize();
  return g;
}

// √((K−1)/K Σ(x − x̄)²) over the given leave-one-out values.
double jackknife(const std::vector<double>& x) {
  const auto k = static_cast<double>(x.size());
  double mean = 0;
  for (double v : x) mean += v / k;
  double ss = 0;
  for (double v : x) ss += (v - mean) * (v - mean);
  return std::sqrt((k - 1) / k * ss);
}

// stats::solve's ridge (1e-9 of the diagonal) shrinks each fit by about that share.
void expect_close(double got, double want) { EXPECT_NEAR(got, want, 1e-8 * std::abs(want)); }

TEST(StatsEstimate, FinalFitAndJackknifeErrorsPerGroup) {
  const Grams g = four_segments();
  // Group 0: the mean and twice it; group 1: the mean only where it is below 2.8 (so the fit
  // without the last segment, 3.0, gives no value there and is left out of its error).
  const Estimates est = estimate(g, {0}, [](const Fit& fit) {
    const double m = fit.theta[0];
    std::vector<std::optional<Named>> out{Named{{"mean", m}, {"twice", 2 * m}}};
    out.push_back(m < 2.8 ? std::optional<Named>(Named{{"mean", m}}) : std::nullopt);
    return out;
  });
  ASSERT_EQ(est.values.size(), 2U);
  ASSERT_EQ(est.standard_errors.size(), 2U);
  expect_close(est.fit.theta[0], 2.5);
  ASSERT_TRUE(est.values[0] && est.values[1]);
  expect_close(est.values[0]->at("twice"), 5.0);
  const double all = jackknife({16.0 / 6, 16.0 / 6, 10.0 / 6, 18.0 / 6});
  expect_close(est.standard_errors[0].at("mean"), all);
  expect_close(est.standard_errors[0].at("twice"), 2 * all);
  expect_close(est.standard_errors[1].at("mean"), jackknife({16.0 / 6, 16.0 / 6, 10.0 / 6}));
}

}  // namespace
