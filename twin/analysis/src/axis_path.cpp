// The analysis of a force-driven axis works on the inverse model: the measured drive force is
// predicted from measured motion, y = y_fixed(baseline) + Σ θ_j x_j, with the columns x_j and
// the parameters from θ given by the effect units (effects/, their axis form), linear in every
// coefficient once the unit's shape value (a period, a velocity scale) is fixed. So one pass over
// the data accumulates a Gram matrix per time segment, and every fit and held-out score of the
// forward selection is a small solve on sums of those matrices, whatever the recording's length.
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "candidates.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/reading.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/analysis/signal.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "maglead/effects/effect.hpp"
#include "path.hpp"
#include "pulses.hpp"
#include "selection.hpp"
#include "statistics.hpp"

namespace maglead::analysis {
namespace {

using stats::Fit;
using stats::partial_r2;
using stats::robust_sigma;
using stats::sse;

// Plumbing of the "where" maps and charts (what they show, not what the analysis decides).
// Samples the percentile ranges are read from, and the charts' points: quick on an hour.
constexpr std::size_t kPercentileProbe = 200000, kChartPoints = 6000;
// A map's bin is drawn from this many samples; at most this many regions and windows are listed.
constexpr double kMinCurveBinSamples = 5;
constexpr int kMostRegionsListed = 4;
constexpr std::size_t kMostWindowsListed = 6;
constexpr double kTinyVariance = 1e-12;  // N²: a bin of equal residuals still has an error
// The maps' bins over velocity (its extreme tails left out) and over position.
constexpr int kVelocityBins = 60, kPositionBins = 80;
constexpr double kVelocityTail = 0.005;
// Time windows: at most this many over the recording, at least 1 s; one is shown with more than
// this many samples; growth and outliers need this many windows (thirds of them compared).
constexpr double kMostTimeWindows = 400.0;
constexpr std::size_t kMinWindowSamples = 10, kMinWindows = 6, kThirds = 3;
// The event-locked average spans this long either side of each event.
constexpr double kLockedHalfSpan_s = 0.15;
// The bandwidth scan: from this frequency up by this factor, below this share of the rate.
constexpr double kBandwidthScanStartHz = 0.5, kBandwidthScanStep = 1.1, kBandwidthScanTop = 0.25;
// A residual shorter than this is left unfiltered (the filter's padding needs more).
constexpr std::size_t kMinFilteredSamples = 12;

// ---------------------------------------------------------------- columns from the effect units
// A column of the axis fit is one of an effect unit's axis columns at one shape value
// (candidates.hpp). The drive supplies what the effects take from the moving part, so a column
// is the unit's regressor with its sign turned and its coefficient is the unit's own
// (effects::Effect::axis_parameters).

// The model file's own totals (mass, viscous and Coulomb friction): the effect whose one
// parameter is that total states it (mass_error: nut_mass_kg, ...).
double* total_field(effects::State& s, const std::string& name) {
  if (name == "nut_mass_kg") return &s.nut_mass_kg;
  if (name == "viscous_n_s_per_m") return &s.viscous_n_s_per_m;
  if (name == "coulomb_n") return &s.coulomb_n;
  return nullptr;
}
double* total_field(ModelFile& m, const std::string& name) {
  if (name == "nut_mass_kg") return &m.nut_mass_kg;
  if (name == "viscous_n_s_per_m") return &m.viscous_n_s_per_m;
  if (name == "coulomb_n") return &m.coulomb_n;
  return nullptr;
}
// The total an effect's one parameter is, or empty (a term of its own in the model file).
std::string total_of(const effects::Effect& e) {
  const auto p = e.params();
  effects::State probe;
  return p.size() == 1 && total_field(probe, p[0].name) ? p[0].name : std::string();
}
const effects::Effect* effect_of_total(const std::string& name) {
  for (const effects::Effect* e : effects::library())
    if (e->on_axis() && total_of(*e) == name) return e;
  return nullptr;
}

// ---------------------------------------------------------------- signals
struct AxisSignals {
  std::vector<double> t, p, v, a, y, y_fixed;
  std::vector<unsigned char> valid;
  double stroke_min_m = 0.0, stroke_max_m = 0.0;
  double start_s = 0.0, span_s = 0.0;  // the recording's time span (decimated or not)
  std::size_t size() const { return t.size(); }
  // Where each held-out segment starts: the span cut by time, as on the actuator.
  std::vector<std::size_t> fold_starts(int folds) const {
    return stats::fold_starts(t, start_s, span_s, folds);
  }
  effects::State state(std::size_t i) const {
    effects::State s;
    s.t_s = t[i];
    s.p_m = p[i];
    s.v_m_s = v[i];
    s.a_m_s2 = a[i];
    // No axis unit reads the jerk (sensor_delay is a law of the coupling): a central difference
    // of the acceleration where it has neighbours, rather than one more filtered column.
    if (i > 0 && i + 1 < t.size()) s.jerk_m_s3 = (a[i + 1] - a[i - 1]) / (t[i + 1] - t[i - 1]);
    s.stroke_min_m = stroke_min_m;
    s.stroke_max_m = stroke_max_m;
    return s;
  }
  double mid_m() const { return 0.5 * (stroke_min_m + stroke_max_m); }
};

double sgn(double x) { return effects::sgn(x); }

// The columns `cols` at sample i: the units' axis regressors with their sign turned.
void fill_row(const AxisSignals& s, std::size_t i, const std::vector<Column>& cols, double* row) {
  unit_row(Form::axis, cols, s.state(i), row);
  for (std::size_t j = 0; j < cols.size(); ++j) row[j] = -row[j];
}

// ---------------------------------------------------------------- Gram per segment
// The shared per-segment normal equations, with the columns in matrix order.
struct AxisGrams : stats::Grams {
  std::vector<Column> cols;
};

std::vector<Column> columns_at(const AxisGrams& g, const std::vector<int>& idx) {
  std::vector<Column> cols;
  cols.reserve(idx.size());
  for (int k : idx) cols.push_back(g.cols[static_cast<std::size_t>(k)]);
  return cols;
}

AxisGrams accumulate_full_rate(const AxisSignals& s, const std::vector<Column>& cols, int folds,
                               const std::function<void(double)>& progress) {
  const auto m = static_cast<Eigen::Index>(cols.size());
  AxisGrams g{stats::Grams(static_cast<std::size_t>(folds), m), cols};
  const auto starts = s.fold_starts(folds);
  constexpr std::size_t kChunk = 2048;
  stats::Grams::RowMatrix x(kChunk, m);
  Eigen::VectorXd r(kChunk);
  for (int f = 0; f < folds; ++f) {
    const std::size_t lo = starts[static_cast<std::size_t>(f)];
    const std::size_t hi = starts[static_cast<std::size_t>(f) + 1];
    for (std::size_t i0 = lo; i0 < hi; i0 += kChunk) {
      Eigen::Index k = 0;
      double yy = 0;
      for (std::size_t i = i0; i < std::min(hi, i0 + kChunk); ++i) {
        if (!s.valid[i]) continue;
        fill_row(s, i, cols, x.row(k).data());
        r[k] = s.y[i] - s.y_fixed[i];
        yy += s.y[i] * s.y[i];
        ++k;
      }
      g.add_rows(static_cast<std::size_t>(f), x.topRows(k), r.head(k), yy);
    }
    if (progress) progress(static_cast<double>(f + 1) / folds);
  }
  g.symmetrize();
  return g;
}

Fit fit_all(const AxisGrams& g, const std::vector<int>& idx) { return stats::solve(g, idx); }

// ---------------------------------------------------------------- binned maps
struct Binned {
  std::vector<double> centre, mean, count, m2;
};

Binned bin(const std::vector<double>& x, const std::vector<double>& r,
           const std::vector<unsigned char>& valid, double lo, double hi, int nb) {
  Binned b;
  b.centre.resize(nb);
  b.mean.assign(nb, 0.0);
  b.count.assign(nb, 0.0);
  b.m2.assign(nb, 0.0);
  for (int k = 0; k < nb; ++k) b.centre[k] = lo + (hi - lo) * (k + 0.5) / nb;
  if (!(hi > lo)) return b;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!valid[i] || !std::isfinite(x[i])) continue;
    const int k = static_cast<int>(std::floor((x[i] - lo) / (hi - lo) * nb));
    if (k < 0 || k >= nb) continue;
    b.mean[k] += r[i];
    b.m2[k] += r[i] * r[i];
    b.count[k] += 1;
  }
  for (int k = 0; k < nb; ++k)
    if (b.count[k] > 0) {
      b.mean[k] /= b.count[k];
      b.m2[k] = b.m2[k] / b.count[k] - b.mean[k] * b.mean[k];
    }
  return b;
}

std::pair<double, double> percentile_range(const std::vector<double>& x,
                                           const std::vector<unsigned char>& valid, double q) {
  std::vector<double> v;
  const std::size_t step = std::max<std::size_t>(1, x.size() / kPercentileProbe);
  for (std::size_t i = 0; i < x.size(); i += step)
    if (valid[i]) v.push_back(x[i]);
  if (v.empty()) return {0, 1};
  std::sort(v.begin(), v.end());
  const auto at = [&](double f) {
    return v[static_cast<std::size_t>(std::clamp(f, 0.0, 1.0) * static_cast<double>(v.size() - 1))];
  };
  return {at(q), at(1 - q)};
}

Curve to_series(const std::string& label, const Binned& b, double x_scale = 1.0) {
  Curve s{label, {}, {}};
  for (std::size_t k = 0; k < b.centre.size(); ++k)
    if (b.count[k] >= kMinCurveBinSamples) {
      s.x.push_back(b.centre[k] * x_scale);
      s.y.push_back(b.mean[k]);
    }
  return s;
}

// Regions of a binned residual map that stand out, in words.
std::string describe_regions(const Binned& b, const std::string& what, const std::string& unit,
                             double x_scale, double overall_rms, std::string_view drive_unit) {
  std::vector<int> hot;
  for (std::size_t k = 0; k < b.centre.size(); ++k) {
    if (b.count[k] < rules::kWhereMinBinSamples) continue;
    const double se = std::sqrt(std::max(b.m2[k], kTinyVariance) / b.count[k]);
    if (std::abs(b.mean[k]) > rules::kWhereBinOfRms * overall_rms &&
        std::abs(b.mean[k]) > rules::kWhereBinSigmas * se)
      hot.push_back(static_cast<int>(k));
  }
  if (hot.empty()) return "";
  std::ostringstream o;
  o.precision(3);
  o << "over " << what << ": mean residual stands out in ";
  std::size_t i = 0;
  int shown = 0;
  const double w = b.centre.size() > 1 ? b.centre[1] - b.centre[0] : 0.0;
  // A bin's ends at the digits its width needs (1140 … 1145 rad, never 1.14e+03 … 1.14e+03): the
  // magnitude's digits down to the width's leading one; 3 at least.
  const double largest = std::max(std::abs(b.centre.front()), std::abs(b.centre.back())) * x_scale;
  const double width = std::abs(w * x_scale);
  const int digits =
      largest > 0 && width > 0
          ? static_cast<int>(std::floor(std::log10(largest)) - std::floor(std::log10(width))) + 1
          : 3;
  const auto end_text = [&](double v) {
    std::ostringstream e;
    e.precision(std::clamp(digits, 3, 12));
    e << v;
    return e.str();
  };
  while (i < hot.size() && shown < kMostRegionsListed) {
    std::size_t j = i;
    while (j + 1 < hot.size() && hot[j + 1] == hot[j] + 1 &&
           sgn(b.mean[hot[j + 1]]) == sgn(b.mean[hot[i]]))
      ++j;
    double peak = 0;
    for (std::size_t k = i; k <= j; ++k)
      if (std::abs(b.mean[hot[k]]) > std::abs(peak)) peak = b.mean[hot[k]];
    o << (shown ? "; " : "") << end_text((b.centre[hot[i]] - w / 2) * x_scale) << " … "
      << end_text((b.centre[hot[j]] + w / 2) * x_scale) << " " << unit << " (up to " << std::showpos
      << peak << std::noshowpos << " " << drive_unit << ")";
    ++shown;
    i = j + 1;
  }
  return o.str();
}

// ---------------------------------------------------------------- preparation
struct AxisPrepared {
  AxisSignals full;  // every sample
  AxisSignals id;    // identification rate (decimated); same as full when not decimated
  bool decimated = false;
  Eigen::MatrixXd id_columns;  // decimated: parallel-filtered columns (n × columns)
  int decimation = 1;
  double fs_hz = 0, filter_hz = 0, noise_floor_n = 0, bandwidth_hz = 0;
  std::optional<double> noise_step_n;  // the logging step the noise rests on (not measured)
  std::vector<double> y_raw;           // full-rate measured force, unfiltered
  effects::Scales scales;              // the units' plausible ranges are stated in these
  std::vector<unsigned char> held;     // full rate: the axis held still (holds(), not widened)
  double held_s = 0;                   // their total time
  double count = 0;                    // the position's encoder count (its smallest step)
};

// ---------------------------------------------------------------- holds
// A held axis (stopped between moves, a servo holding it against stiction) takes any force up to
// its break-away, which no sliding law gives: such samples are left out of the fit, as the
// actuator leaves out its stuck ones. The encoder's count, from the data: its smallest step.
double position_count(const std::vector<double>& p) {
  double c = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < p.size(); ++i) {
    const double d = std::abs(p[i] - p[i - 1]);
    if (d > 0 && d < c) c = d;  // NaN compares false
  }
  return std::isfinite(c) ? c : 0.0;
}

// Stretches of at least `min_len` samples whose raw position stays within `tol` of the
// stretch's first sample (an unquantised position has a tiny count: nothing is held).
std::vector<unsigned char> holds(const std::vector<double>& raw, double tol, std::size_t min_len) {
  const std::size_t n = raw.size();
  std::vector<unsigned char> held(n, 0);
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i + 1;
    while (j < n && std::abs(raw[j] - raw[i]) <= tol) ++j;
    if (j - i >= min_len)
      std::fill(held.begin() + static_cast<std::ptrdiff_t>(i),
                held.begin() + static_cast<std::ptrdiff_t>(j), 1);
    i = j;
  }
  return held;
}

// Valid samples at every `step`-th full-rate sample: none within `margin` samples of a hold (a
// filter spreads the hold's force that far) or of the recording's ends (where it spreads the
// padding it invents).
std::vector<unsigned char> valid_outside(const std::vector<unsigned char>& held, std::size_t margin,
                                         std::size_t step) {
  const std::size_t n = held.size();
  std::vector<std::size_t> before(n + 1, 0);  // held samples before i
  for (std::size_t i = 0; i < n; ++i) before[i + 1] = before[i] + held[i];
  std::vector<unsigned char> valid;
  valid.reserve(n / step + 1);
  for (std::size_t i = 0; i < n; i += step) {
    const std::size_t lo = i > margin ? i - margin : 0, hi = std::min(n, i + margin + 1);
    const bool inside = i >= margin && i + margin < n;
    valid.push_back(inside && before[hi] == before[lo] ? 1 : 0);
  }
  return valid;
}

// Samples of `periods` periods of a filter with corner `hz`.
std::size_t filter_samples(double periods, double hz, double fs_hz) {
  return static_cast<std::size_t>(std::lround(periods * fs_hz / hz));
}

double max_abs(const std::vector<double>& x) {
  double m = 0;
  for (double v : x) m = std::max(m, std::abs(v));
  return m;
}

// The model file's totals as a state: what its terms' laws are differences from. A total the
// analysis fits (fit = [...]) is zero here: the fit supplies all of it.
effects::State model_totals(const ModelFile& model) {
  effects::State s;
  s.nut_mass_kg = model.fit.count("nut_mass_kg") ? 0.0 : model.nut_mass_kg;
  s.viscous_n_s_per_m = model.fit.count("viscous_n_s_per_m") ? 0.0 : model.viscous_n_s_per_m;
  s.coulomb_n = model.fit.count("coulomb_n") ? 0.0 : model.coulomb_n;
  return s;
}

// The baseline's fixed force at every sample of a force-driven axis: the drive supplies the
// known dynamics M a + C v + F_c sign(v) and whatever every term of the model file takes from
// the moving part (the units' laws, the same the twin runs). A term whose total is fitted here
// is left to the fit. The law is the actuator's (missing_force; no coupling or load here).
void fixed_force(AxisSignals& s, const ModelFile& model) {
  std::vector<BaselineTerm> terms;
  for (const auto& t : model.terms) {
    const auto* e = effects::find(t.id);
    if (!t.enabled || !e) continue;
    if (const auto total = total_of(*e); !total.empty() && model.fit.count(total)) continue;
    terms.push_back({e, effects::Params(t.parameters.begin(), t.parameters.end())});
  }
  const effects::State totals = model_totals(model);
  s.y_fixed.resize(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    effects::State st = s.state(i);
    st.nut_mass_kg = totals.nut_mass_kg;
    st.viscous_n_s_per_m = totals.viscous_n_s_per_m;
    st.coulomb_n = totals.coulomb_n;
    s.y_fixed[i] = missing_force(st, terms);
  }
}

// Identification bandwidth: the lowest frequency below which the acceleration (the most
// demanding regressor) keeps 99 % of its energy; decimate as far as the decimation filter
// (80 % of the new Nyquist frequency) stays above it.
int bandwidth_decimation(AxisPrepared& P) {
  const auto& a = P.full.a;
  double ea = 0;
  for (double x : a) ea += x * x;
  P.bandwidth_hz = kBandwidthScanTop * P.fs_hz;
  for (double f = kBandwidthScanStartHz; f < kBandwidthScanTop * P.fs_hz; f *= kBandwidthScanStep) {
    const auto af = filtfilt_butter4(a, f, P.fs_hz);
    double lost = 0;
    for (std::size_t i = 0; i < a.size(); ++i) lost += (a[i] - af[i]) * (a[i] - af[i]);
    if (lost <= rules::kAxisBandwidthEnergyLost * ea) {
      P.bandwidth_hz = f;
      break;
    }
  }
  return std::max(
      1, static_cast<int>(std::floor(rules::kAxisDecimationOfRate * P.fs_hz / P.bandwidth_hz)));
}

// Decimation to the identification bandwidth: parallel filtering of every signal.
void decimate_signals(AxisPrepared& P, int nd) {
  P.decimation = nd;
  if (nd <= 1) return;
  const AxisSignals& s = P.full;
  P.decimated = true;
  AxisSignals& d = P.id;
  d = AxisSignals{};
  d.stroke_min_m = s.stroke_min_m;
  d.stroke_max_m = s.stroke_max_m;
  d.start_s = s.start_s;
  d.span_s = s.span_s;
  for (std::size_t i = 0; i < s.size(); i += static_cast<std::size_t>(nd)) d.t.push_back(s.t[i]);
  d.p = decimate(s.p, nd, P.fs_hz);
  d.v = decimate(s.v, nd, P.fs_hz);
  d.a = decimate(s.a, nd, P.fs_hz);
  d.y = decimate(s.y, nd, P.fs_hz);
  d.y_fixed = decimate(s.y_fixed, nd, P.fs_hz);
  d.valid = valid_outside(
      P.held,
      filter_samples(rules::kAxisRestFilterPeriods, decimation_cutoff_hz(nd, P.fs_hz), P.fs_hz),
      static_cast<std::size_t>(nd));
}

// A force-driven axis: position filtered zero-phase, velocity and acceleration by central
// differences, the drive force as logged, the baseline's fixed part at every sample.
AxisPrepared prepare_axis(const Recording& rec, const ModelFile& model, const AnalysisOptions& opt,
                          const effects::AxisKind& kind) {
  AxisPrepared P;
  const std::string position(kind.position), drive(kind.drive);
  stats::require_analysable(rec, {"t_s", position, drive});
  check_axis_rows(rec);  // and a rate the analysis resolves (t_s in milliseconds reads as 1 Hz)
  const auto& t = rec.column("t_s");
  P.fs_hz = maglead::sample_rate_hz(rec);
  const double dt = 1.0 / P.fs_hz;
  // As on the actuator: a slow logger still resolves the filter's corner.
  P.filter_hz = std::min(opt.filter_hz > 0 ? opt.filter_hz : rules::kAxisFilterHz,
                         rules::kFilterMaxOfRate * P.fs_hz);
  AxisSignals& s = P.full;
  s.t = t;
  s.start_s = t.front();
  s.span_s = t.back() - t.front();
  s.p = filtfilt_butter4(rec.column(position), P.filter_hz, P.fs_hz);
  s.v = central_diff(s.p, dt);
  s.a = central_diff2(s.p, dt);
  P.y_raw = rec.column(drive);
  const stats::SensorNoise noise = stats::sensor_noise(P.y_raw);  // the force sensor's noise
  P.noise_floor_n = noise.sigma;
  if (!noise.measured) P.noise_step_n = noise.step;
  P.scales = {max_abs(P.y_raw), max_abs(s.v)};  // what the drive produced and reached
  const std::size_t hold_len = filter_samples(rules::kAxisRestFilterPeriods, P.filter_hz, P.fs_hz);
  P.count = position_count(rec.column(position));
  P.held = holds(rec.column(position), rules::kAxisRestCounts * P.count, hold_len);
  P.held_s = static_cast<double>(std::count(P.held.begin(), P.held.end(), 1)) * dt;
  s.valid = valid_outside(P.held, hold_len, 1);
  // The travel the recording covers stands for the stroke (the spring's mid-stroke).
  s.stroke_min_m = *std::min_element(s.p.begin(), s.p.end());
  s.stroke_max_m = *std::max_element(s.p.begin(), s.p.end());
  P.scales.travel_m = s.stroke_max_m - s.stroke_min_m;
  s.y = P.y_raw;
  fixed_force(s, model);
  // Slow smooth motion has a narrow bandwidth: every held-out segment keeps 100 samples still.
  const auto keep = static_cast<int>(
      s.size() / (rules::kAxisMinSegmentSamples *
                  static_cast<std::size_t>(std::max(rules::kAxisMinFolds, opt.folds))));
  decimate_signals(P, opt.axis.decimation > 0
                          ? opt.axis.decimation
                          : std::clamp(bandwidth_decimation(P), 1, std::max(1, keep)));
  return P;
}

// Columns of the decimated axis data are filtered and decimated one by one (parallel
// filtering, as the benchmark does), so a nonlinear column like sign(q̇) is low-passed too.
void decimate_columns(AxisPrepared& P, const std::vector<Column>& cols) {
  const std::size_t n = P.full.size(), nd_n = P.id.size();
  P.id_columns.resize(static_cast<Eigen::Index>(nd_n), static_cast<Eigen::Index>(cols.size()));
  std::vector<double> col(n);
  for (std::size_t j = 0; j < cols.size(); ++j) {
    const std::vector<Column> one{cols[j]};
    for (std::size_t i = 0; i < n; ++i) fill_row(P.full, i, one, &col[i]);
    const auto d = decimate(col, P.decimation, P.fs_hz);
    for (std::size_t i = 0; i < nd_n; ++i)
      P.id_columns(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = d[i];
  }
}

AxisGrams accumulate_decimated(const AxisPrepared& P, const std::vector<Column>& cols, int folds) {
  AxisGrams g;
  g.cols = cols;
  const AxisSignals& s = P.id;
  const auto starts = s.fold_starts(folds);
  for (int f = 0; f < folds; ++f) {
    const std::size_t lo = starts[static_cast<std::size_t>(f)];
    const std::size_t hi = starts[static_cast<std::size_t>(f) + 1];
    std::vector<Eigen::Index> rows;  // the segment's valid samples (holds left out)
    for (std::size_t i = lo; i < hi; ++i)
      if (s.valid[i]) rows.push_back(static_cast<Eigen::Index>(i));
    Eigen::VectorXd r(static_cast<Eigen::Index>(rows.size()));
    double yy = 0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const auto i = static_cast<std::size_t>(rows[k]);
      r[static_cast<Eigen::Index>(k)] = s.y[i] - s.y_fixed[i];
      yy += s.y[i] * s.y[i];
    }
    const auto n = static_cast<Eigen::Index>(hi - lo);
    if (static_cast<Eigen::Index>(rows.size()) == n)  // every row valid: the block as it stands
      g.add_segment(P.id_columns.middleRows(static_cast<Eigen::Index>(lo), n), r, yy);
    else
      g.add_segment(P.id_columns(rows, Eigen::all), r, yy);
  }
  return g;
}

// Prediction of the fitted extra columns at every sample of `s` (streaming; no matrix): the
// fixed force plus each column θ_j (−u_j), u the unit's axis regressor (less_fitted).
std::vector<double> predict(const AxisSignals& s, const AxisGrams& g, const Fit& fit) {
  const std::vector<Column> cols = columns_at(g, fit.idx);
  std::vector<double> out(s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    out[i] = less_fitted(Form::axis, cols, s.state(i), fit.theta, s.y_fixed[i]);
  return out;
}

std::vector<double> predict_decimated(const AxisPrepared& P, const Fit& fit) {
  std::vector<double> out(P.id.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    double y = P.id.y_fixed[i];
    for (Eigen::Index j = 0; j < fit.theta.size(); ++j)
      y += fit.theta[j] * P.id_columns(static_cast<Eigen::Index>(i), fit.idx[j]);
    out[i] = y;
  }
  return out;
}

struct Errors {
  double rms = 0, rel_pct = 0;
};
Errors errors(const std::vector<double>& y, const std::vector<double>& yhat,
              const std::vector<unsigned char>& valid) {
  double e = 0, yy = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < y.size(); ++i) {
    if (!valid[i]) continue;
    e += (y[i] - yhat[i]) * (y[i] - yhat[i]);
    yy += y[i] * y[i];
    ++n;
  }
  if (n == 0) return {};
  const stats::ErrorScale es{static_cast<double>(n), yy};
  return {es.rms(e), es.rel(e)};
}

// ---------------------------------------------------------------- physical parameters
// The unit's parameters from the fitted coefficients of its columns `idx` (a column left out,
// because the model already spans it, counts zero); none where the unit gives no value.
std::optional<effects::Params> axis_params(const AxisGrams& g, const effects::Effect& e,
                                           double shape, const std::vector<int>& idx,
                                           const Eigen::VectorXd& theta,
                                           const effects::State& totals) {
  std::vector<double> c(static_cast<std::size_t>(e.axis_columns()), 0.0);
  for (std::size_t j = 0; j < idx.size(); ++j)
    c[static_cast<std::size_t>(g.cols[static_cast<std::size_t>(idx[j])].index)] =
        theta[static_cast<Eigen::Index>(j)];
  return e.axis_parameters(shape, c.data(), totals);
}

// ---------------------------------------------------------------- the axis analysis, in stages
// Everything one axis analysis works on, shared by its stages.
struct AxisRun {
  const Recording& rec;
  const ModelFile& model;
  const AnalysisOptions& opt;
  const effects::AxisKind& kind;  // its columns, units and parameter names
  AxisPrepared P;
  AxisSignals* S = nullptr;  // P.id when decimated, else P.full (no copy: an hour is 3.6 M samples)
  int folds = 3;
  Candidates cand;                    // every column the units give an axis
  std::vector<int> base_cols;         // baseline totals whose values are unknown (fit = [...])
  std::set<std::string> in_baseline;  // effects the model has already: not candidates again
  std::vector<pulses::Pulse> pulses;
  AxisGrams g;
  double yy_total = 0, n_total = 0;
  AxisRun(const Recording& r, const ModelFile& m, const AnalysisOptions& o,
          const effects::AxisKind& k)
      : rec(r), model(m), opt(o), kind(k), cand(candidate_columns(Form::axis, k.not_offered)) {}
  void progress(const std::string& stage, double f) const {
    if (opt.progress) opt.progress(stage, f);
  }
};

// A total the model file leaves to the fit is the column of the unit that states it.
void baseline_columns(AxisRun& run) {
  for (const auto& total : run.model.fit) {
    const effects::Effect* e = effect_of_total(total);
    const Variant* v = e ? run.cand.of(e) : nullptr;
    if (!v) throw std::invalid_argument("model: no effect states the total '" + total + "'");
    run.base_cols.insert(run.base_cols.end(), v->idx.begin(), v->idx.end());
    run.in_baseline.insert(std::string(e->id()));
  }
  // Terms the model already has are not candidates again (their values are taken as given).
  for (const auto& t : run.model.terms)
    if (t.enabled) run.in_baseline.insert(t.id);
}

std::vector<double> predict_any(const AxisRun& run, const Fit& fit) {
  return run.P.decimated ? predict_decimated(run.P, fit) : predict(*run.S, run.g, fit);
}

// The totals the fitted parameters are differences from: the model file's, the fitted ones
// where the file leaves them to the fit, and a total found by the selection (Coulomb friction
// found on an axis), as the units that state them give them; `except`'s own is left out (its
// parameter is that total).
effects::State fitted_totals(const AxisRun& run, const Fit& fit,
                             const effects::Effect* except = nullptr) {
  effects::State s = model_totals(run.model);
  s.stroke_min_m = run.S->stroke_min_m;
  s.stroke_max_m = run.S->stroke_max_m;
  for (std::size_t j = 0; j < fit.idx.size(); ++j) {
    const Column& c = run.g.cols[static_cast<std::size_t>(fit.idx[j])];
    const std::string total = total_of(*c.effect);
    if (total.empty() || c.effect == except) continue;
    const double coef = fit.theta[static_cast<Eigen::Index>(j)];
    if (const auto p = c.effect->axis_parameters(c.shape, &coef, s))
      *total_field(s, total) = p->at(total);
  }
  return s;
}

// One pass: per-segment Grams of every column (decimated: each column filtered first).
void accumulate_axis(AxisRun& run) {
  if (run.P.decimated) {
    decimate_columns(run.P, run.cand.cols);
    run.g = accumulate_decimated(run.P, run.cand.cols, run.folds);
  } else {
    run.g = accumulate_full_rate(*run.S, run.cand.cols, run.folds,
                                 [&](double f) { run.progress("gram", f); });
  }
  for (std::size_t f = 0; f < run.g.folds(); ++f) {
    run.yy_total += run.g.yy[f];
    run.n_total += static_cast<double>(run.g.n[f]);
  }
  if (run.n_total < rules::kAxisMinUsableSamples)
    throw std::invalid_argument(run.rec.path + ": fewer than " +
                                std::to_string(static_cast<int>(rules::kAxisMinUsableSamples)) +
                                " usable samples (the axis hardly moves)");
}

// ---------------------------------------------------------------- forward selection
// A step of the validation: the held-out error of the model with columns `idx` and its fit on
// every segment.
ValidationStep validation_step(const AxisRun& run, const std::string& name, double heldout_sse,
                               const std::vector<int>& idx) {
  const double in = sse(run.g, fit_all(run.g, idx));
  const stats::ErrorScale es{run.n_total, run.yy_total};
  return ValidationStep{name, es.rms(heldout_sse), es.rel(heldout_sse), es.rms(in), es.rel(in)};
}

// The axis's rules for the one selection: the units' axis parameters beside the fitted totals,
// and a force larger than the force sensor's own noise per sample (below that a "term" only fits
// the small structure every model leaves: quantization, filter edges).
class AxisRules : public selection::Rules {
 public:
  explicit AxisRules(const AxisRun& run) : run_(run) {}
  std::optional<effects::Params> parameters(const Variant& var, const std::vector<int>& cols,
                                            const Fit& fit) const override {
    const auto k = static_cast<Eigen::Index>(cols.size());
    return axis_params(run_.g, *var.effect, var.shape, cols, fit.theta.tail(k),
                       fitted_totals(run_, fit, var.effect));
  }
  bool resolved(const selection::Trial& /*tr*/, double explained_n,
                const selection::Acting& /*where*/,
                const std::vector<selection::Term>& /*model*/) const override {
    return explained_n >= floor_n({});
  }
  double floor_n(const std::vector<selection::Term>& /*model*/) const override {
    return run_.P.noise_floor_n;
  }

 private:
  const AxisRun& run_;
};

// No segment filter (a drive force acts everywhere); a simpler candidate with at least half the
// best one's gain goes first; a column the model already spans (the constant part of
// direction-dependent friction once an offset is in) is left out.
selection::Settings axis_settings(const AnalysisOptions& opt, const effects::AxisKind& kind,
                                  const effects::Scales& scales = {}) {
  return {.max_terms = opt.axis.max_terms,
          .min_gain_pct = opt.min_gain_pct,
          .min_t = opt.min_t,
          .acting_share = 0,
          .parsimony = rules::kAxisParsimony,
          .leave_out_spanned = true,
          .scales = scales,
          .drive_unit = kind.drive_unit};
}

// The validation: the baseline, then each term taken (+) or dropped by the backward check (−).
std::vector<ValidationStep> validation_of(const AxisRun& run, const selection::Result& r) {
  std::vector<ValidationStep> out{
      validation_step(run, "baseline", r.start_heldout_sse, run.base_cols)};
  for (const auto& st : r.steps)
    out.push_back(validation_step(run, st.model, st.heldout_sse, st.current));
  return out;
}

// The terms not selected: the best remaining one and those the backward check dropped.
std::vector<Rejected> not_selected_of(const selection::Result& r) {
  std::vector<Rejected> out;
  if (r.stopped_at) out.push_back(selection::best_left_out(*r.stopped_at, r.stopped_reason));
  out.insert(out.end(), r.dropped.begin(), r.dropped.end());
  out.insert(out.end(), r.refused.begin(), r.refused.end());
  return out;
}

selection::Result select_terms(const AxisRun& run) {
  std::vector<const effects::Effect*> in_baseline;
  for (const auto* e : effects::library())
    if (run.in_baseline.count(std::string(e->id()))) in_baseline.push_back(e);
  const AxisRules rules(run);
  const auto o = selection::select(run.g, run.cand, rules,
                                   axis_settings(run.opt, run.kind, run.P.scales), run.base_cols,
                                   in_baseline, [&](double f) { run.progress("selection", f); });
  const selection::Span span{.n_used = run.n_total,
                             .t0_s = run.S->start_s,
                             .duration_s = run.S->span_s,
                             .floor_n = run.P.noise_floor_n,
                             .min_gain_pct = run.opt.min_gain_pct};
  return selection::result_of(o, run.folds, span);
}

// ---------------------------------------------------------------- findings
struct Predictions {
  Fit base_fit, final_fit;
  std::vector<double> yb, yf;  // at the identification samples
  Errors eb, ef, eb_full, ef_full;
};

Predictions predictions(AxisRun& run, const selection::Result& sel) {
  Predictions p;
  const AxisGrams& g = run.g;
  AxisSignals& S = *run.S;
  p.final_fit = fit_all(g, sel.current);
  p.base_fit = fit_all(g, run.base_cols);
  p.yb = predict_any(run, p.base_fit);
  p.yf = predict_any(run, p.final_fit);
  p.eb = errors(S.y, p.yb, S.valid);
  p.ef = errors(S.y, p.yf, S.valid);
  // Full rate: raw force against the model evaluated on every sample (undecimated).
  AxisSignals& F = run.P.full;
  const auto yb_full = run.P.decimated ? predict(F, g, p.base_fit) : p.yb;
  const auto yf_full = run.P.decimated ? predict(F, g, p.final_fit) : p.yf;
  p.eb_full = errors(run.P.y_raw, yb_full, F.valid);
  p.ef_full = errors(run.P.y_raw, yf_full, F.valid);
  return p;
}

void describe_method(Findings& J, const AxisRun& run) {
  J.method.domain =
      run.kind.words("force (inverse model: measured force predicted from measured motion)");
  J.method.filter = run.kind.words("4th-order Butterworth, zero phase (forward-backward), ") +
                    std::string(run.kind.motion) + " at " + number_text(run.P.filter_hz, 6) +
                    " Hz; central differences";
  J.method.decimation = run.P.decimation;
  J.method.identification_bandwidth_hz = run.P.bandwidth_hz;
  J.method.folds = run.folds;
  J.method.selection = selection::describe(axis_settings(run.opt, run.kind)) +
                       run.kind.words(", and explain more RMS than the force noise floor");
  J.method.moving_only = "all samples";
  J.noise_floor_n = run.P.noise_floor_n;
  J.noise_step_n = run.P.noise_step_n;
}

// The baseline's unknown totals (fit = [...]) as the fit gives them.
Parameters fitted_base(const AxisRun& run, const Fit& fit) {
  effects::State s = fitted_totals(run, fit);
  Parameters b;
  for (const auto& total : run.model.fit) set_parameter(b, total, *total_field(s, total));
  return b;
}

// A term's plausible alternatives, as on the actuator: one outside its physical range (no
// parameters to show) explains nothing here.
std::vector<Alternative> finding_alternatives(const selection::Found& f) {
  std::vector<Alternative> out;
  for (const auto& a : f.alternatives)
    if (a.plausible && a.params)
      out.push_back({a.id, selection::parameters_of(*a.params), a.explains_pct, true});
  return out;
}

EffectFinding axis_finding(const AxisRun& run, const selection::Found& f) {
  EffectFinding e;
  e.id = f.id;
  e.parameters = selection::parameters_of(f.params);
  e.summary = summary_text(e.parameters, selection::parameters_of(f.standard_errors));
  e.standard_errors = stated_errors(e.parameters, selection::parameters_of(f.standard_errors));
  e.where = run.kind.words("all samples; the missing force follows ") + run.kind.law(*f.effect);
  e.evidence.heldout_gain_pct = f.gain_pct;
  e.evidence.t_stat = f.t_stat;
  e.evidence.segments_improved =
      std::to_string(f.segments_improved) + "/" + std::to_string(f.segments);
  e.evidence.explained_rms_n = f.explained_n;
  e.evidence.worst_segment_pct = f.worst_pct;
  e.evidence.noise_floor_n = run.P.noise_floor_n;
  e.evidence.plausible = f.plausible;
  e.improvement_pct = f.improvement_pct;
  e.alternatives = finding_alternatives(f);
  e.identifiable = e.alternatives.empty();
  if (!e.alternatives.empty()) {
    std::string names = e.id;
    for (const auto& a : e.alternatives) names += " or " + a.id;
    e.finding = "one combined finding: the data cannot tell " + names + " apart";
  }
  if (f.over)
    e.note = "chosen before '" + std::string(f.over->id()) +
             "', which contains it: the simpler explanation first";
  return e;
}

stats::Named named(const Parameters& p) {
  stats::Named out;
  for (const auto& q : p) out[q.name] = q.value;
  return out;
}

// Each chosen term's parameters at one fit of the model (the baseline's columns first); none
// where the unit gives no value.
std::vector<std::optional<effects::Params>> axis_term_params(
    const AxisRun& run, const std::vector<selection::Found>& chosen, const Fit& fit) {
  std::vector<std::optional<effects::Params>> out;
  auto off = static_cast<Eigen::Index>(run.base_cols.size());
  for (const auto& f : chosen) {
    const auto n = static_cast<Eigen::Index>(f.idx.size());
    const effects::State totals = fitted_totals(run, fit, f.effect);
    out.push_back(axis_params(run.g, *f.effect, f.shape, f.idx, fit.theta.segment(off, n), totals));
    off += n;
  }
  return out;
}

// Every fitted parameter of the model at one fit: the baseline's fitted totals, then each chosen
// term's, as the findings report them.
std::vector<std::optional<stats::Named>> model_parameters(
    const AxisRun& run, const std::vector<selection::Found>& chosen, const Fit& fit) {
  std::vector<std::optional<stats::Named>> out{named(fitted_base(run, fit))};
  for (const auto& p : axis_term_params(run, chosen, fit))
    out.emplace_back(p.value_or(stats::Named{}));
  return out;
}

// ---------------------------------------------------------------- the drive's timing
// A logged drive value and the position beside it share a time stamp, but what the drive value
// stands for in time no recording states: a setpoint held over the period after its stamp (a
// zero-order hold acts half a period later on average), a current averaged over the period
// before it, a reading at the stamp. The motion's derivatives are central at the stamp, so the
// force the fit pairs with them may be up to half a sample early or late: a bias every segment
// shares, which the jackknife cannot see and the data hardly resolve (it is the jerk times the
// mass times half a period). So the model is fitted again with the motion moved by ±that offset
// (x(t + δ) ≈ x + δ ẋ, the columns' rates by central differences at the logger's rate, then
// decimated as the columns are), and each parameter's largest change, as a uniform uncertainty
// over the interval (÷√3), is added to its standard error in quadrature.

// The time derivatives of the columns `idx` and of the fixed force at the identification samples:
// decimated, from the full-rate columns (as decimate_columns makes them); at full rate, from each
// sample's neighbours when asked (an hour's matrix would take hundreds of MB).
class Rates {
 public:
  Rates(const AxisRun& run, const std::vector<int>& idx)
      : run_(run), cols_(columns_at(run.g, idx)) {
    if (!run.P.decimated) return;
    const AxisSignals& F = run.P.full;
    const double dt = 1.0 / run.P.fs_hz;
    d_.resize(static_cast<Eigen::Index>(run.P.id.size()), static_cast<Eigen::Index>(idx.size()));
    std::vector<double> col(F.size());
    for (std::size_t j = 0; j < cols_.size(); ++j) {
      const std::vector<Column> one{cols_[j]};
      for (std::size_t i = 0; i < F.size(); ++i) fill_row(F, i, one, &col[i]);
      const auto d = decimate(central_diff(col, dt), run.P.decimation, run.P.fs_hz);
      for (std::size_t i = 0; i < run.P.id.size(); ++i)
        d_(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = d[i];
    }
    fixed_ = decimate(central_diff(F.y_fixed, dt), run.P.decimation, run.P.fs_hz);
  }
  // The columns at sample i into x, their rates into dx; returns the fixed force's rate.
  double at(std::size_t i, const std::vector<int>& idx, Eigen::VectorXd& x,
            Eigen::VectorXd& dx) const {
    const AxisSignals& S = *run_.S;
    if (run_.P.decimated) {
      for (std::size_t j = 0; j < idx.size(); ++j)
        x[static_cast<Eigen::Index>(j)] = run_.P.id_columns(static_cast<Eigen::Index>(i), idx[j]);
      dx = d_.row(static_cast<Eigen::Index>(i)).transpose();
      return fixed_[i];
    }
    const std::size_t lo = i > 0 ? i - 1 : i, hi = std::min(S.size() - 1, i + 1);
    Eigen::VectorXd before(x.size()), after(x.size());
    fill_row(S, i, cols_, x.data());
    fill_row(S, lo, cols_, before.data());
    fill_row(S, hi, cols_, after.data());
    const double span_s = S.t[hi] - S.t[lo];
    if (!(span_s > 0)) return dx.setZero(), 0.0;
    dx = (after - before) / span_s;
    return (S.y_fixed[hi] - S.y_fixed[lo]) / span_s;
  }

 private:
  const AxisRun& run_;
  std::vector<Column> cols_;
  Eigen::MatrixXd d_;
  std::vector<double> fixed_;
};

// The model `idx` fitted on every sample with the motion moved later and earlier by the drive's
// unstated timing (rules::kAxisDriveTimingSamples logger periods).
std::array<Fit, 2> moved_fits(const AxisRun& run, const std::vector<int>& idx) {
  const double delta_s = rules::kAxisDriveTimingSamples / run.P.fs_hz;
  const auto k = static_cast<Eigen::Index>(idx.size());
  const Rates rates(run, idx);
  std::array<stats::Grams, 2> g{stats::Grams(1, k), stats::Grams(1, k)};
  Eigen::VectorXd x(k), dx(k);
  const AxisSignals& S = *run.S;
  for (std::size_t i = 0; i < S.size(); ++i) {
    if (!S.valid[i]) continue;
    const double dfixed = rates.at(i, idx, x, dx), r = S.y[i] - S.y_fixed[i];
    g[0].add_row(0, x + delta_s * dx, r - delta_s * dfixed, S.y[i]);
    g[1].add_row(0, x - delta_s * dx, r + delta_s * dfixed, S.y[i]);
  }
  std::vector<int> all(static_cast<std::size_t>(k));
  std::iota(all.begin(), all.end(), 0);
  std::array<Fit, 2> out;
  for (std::size_t s = 0; s < 2; ++s) {
    g[s].symmetrize();
    out[s] = Fit{idx, stats::solve(g[s], all).theta};
  }
  return out;
}

// stats::estimate of the model `idx` (the baseline's columns, then `chosen`'s), each standard
// error widened by the parameter's change over the drive's unstated timing.
stats::Estimates timed_estimate(const AxisRun& run, const std::vector<int>& idx,
                                const std::vector<selection::Found>& chosen) {
  const auto values = [&](const Fit& fit) { return model_parameters(run, chosen, fit); };
  auto est = stats::estimate(run.g, idx, values);
  if (idx.empty()) return est;
  std::vector<stats::Named> change(est.values.size());
  for (const Fit& moved : moved_fits(run, idx)) {
    const auto v = values(moved);
    for (std::size_t k = 0; k < change.size() && k < v.size(); ++k) {
      if (!v[k] || !est.values[k]) continue;
      for (const auto& [name, x] : *v[k])
        if (const auto at = est.values[k]->find(name); at != est.values[k]->end())
          change[k][name] = std::max(change[k][name], std::abs(x - at->second));
    }
  }
  for (std::size_t k = 0; k < change.size(); ++k)
    for (auto& [name, se] : est.standard_errors[k])
      if (const auto c = change[k].find(name); c != change[k].end())
        se = std::hypot(se, c->second / std::sqrt(3.0));
  return est;
}

// The final fit on every segment (stats::estimate, as on the actuator): each term's parameters
// there, whether they lie in the unit's physical range, and their standard errors from the fits
// without each segment in turn, widened by the drive's unstated timing (timed_estimate). Returns
// the baseline's fitted totals' standard errors.
Parameters finish_axis_terms(const AxisRun& run, selection::Result& sel) {
  const auto est = timed_estimate(run, sel.current, sel.terms);
  const auto prm = axis_term_params(run, sel.terms, est.fit);
  for (std::size_t k = 0; k < sel.terms.size(); ++k) {
    auto& f = sel.terms[k];
    f.params = prm[k].value_or(effects::Params{});
    f.plausible = prm[k].has_value() && effects::plausible(*f.effect, *prm[k], run.P.scales);
    f.standard_errors = est.standard_errors[k + 1];
  }
  return selection::parameters_of(est.standard_errors.front());
}

// The baseline's fitted totals' standard errors with columns `idx`.
Parameters base_standard_errors(const AxisRun& run, const std::vector<int>& idx) {
  return selection::parameters_of(timed_estimate(run, idx, {}).standard_errors.front());
}

// The fitted totals' standard errors and their printed form (none when nothing is fitted).
void add_errors(FitErrors& e, const Parameters& standard_errors) {
  if (!e.fitted_parameters || e.fitted_parameters->empty()) return;
  e.standard_errors = standard_errors;
  e.summary = summary_text(*e.fitted_parameters, standard_errors);
}

void fill_findings(Findings& J, const AxisRun& run, const selection::Result& sel,
                   const Predictions& p, const Parameters& final_base_se) {
  J.recording = run.rec.path;
  J.system = run.model.system;
  J.samples = run.rec.rows();
  J.samples_used = static_cast<std::size_t>(run.n_total);
  describe_method(J, run);
  J.baseline = {p.eb.rms,
                p.eb.rel_pct,
                p.eb_full.rms,
                p.eb_full.rel_pct,
                std::sqrt(sel.start_heldout_sse / run.n_total),
                fitted_base(run, p.base_fit),
                {},
                {}};
  for (const auto& f : sel.terms) J.effects.push_back(axis_finding(run, f));
  J.nothing_missing = sel.terms.empty() && !sel.implausible;
  J.not_selected = not_selected_of(sel);
  if (sel.implausible)
    J.unexplained = selection::unexplained_of(
        *sel.implausible,
        "units and sign of " + std::string(run.kind.drive) + " and " +
            std::string(run.kind.position) +
            ", the drive's force constant, the encoder scale and the model file's values (is it "
            "this axis's?)");
  J.final_fit = {p.ef.rms,
                 p.ef.rel_pct,
                 p.ef_full.rms,
                 p.ef_full.rel_pct,
                 std::nullopt,
                 fitted_base(run, p.final_fit),
                 {},
                 {}};
  add_errors(J.baseline, base_standard_errors(run, run.base_cols));
  add_errors(J.final_fit, final_base_se);
  J.validation = validation_of(run, sel);
  pulses::report(J, run.pulses);
  conclude(J, {.terms_named = sel.terms.size(),
               .implausible = sel.implausible.has_value(),
               .unresolved = "",
               .check = "the drive's force constant, the encoder scale and loads the recording "
                        "does not log",
               .kind = &run.kind});
}

// A reversal is a hold too short for holds() to find: the axis may stick there for a few
// milliseconds with any force within its break-away, where the friction law only flips sign. A
// pulse within the filters' spread (`spread_s`) of a reversal and no larger than the model's own
// force swing there (`yf`, which that flip is part of) is that stick, not an event.
std::vector<pulses::Pulse> off_reversals(const AxisSignals& S, const std::vector<double>& yf,
                                         double spread_s, std::vector<pulses::Pulse> found) {
  std::erase_if(found, [&](const pulses::Pulse& p) {
    const auto from = static_cast<std::size_t>(
        std::lower_bound(S.t.begin(), S.t.end(), p.t_s - spread_s) - S.t.begin());
    const double to_s = p.t_s + p.duration_s + spread_s;
    bool reversal = false;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = from; i < S.size() && S.t[i] <= to_s; ++i) {
      if (!S.valid[i]) continue;
      lo = std::min(lo, yf[i]), hi = std::max(hi, yf[i]);
      reversal |= i + 1 < S.size() && S.v[i] * S.v[i + 1] < 0.0;
    }
    return reversal && std::abs(p.peak_n) <= hi - lo;
  });
  return found;
}

// Isolated pulses in the corrected residual (the one pulse finder, as on the actuator): events,
// a force no input explains (not a library law's where the axis was: pulses::unexplained), above
// the force sensor's noise. The residual's band limit is the
// decimation filter's, or at full rate the position's filter, applied to the residual here.
void axis_pulses(AxisRun& run, const std::vector<double>& yf, const std::vector<int>& model) {
  const AxisSignals& S = *run.S;
  pulses::Floors f;
  f.min_n = run.P.noise_floor_n;
  f.fs_hz = run.P.fs_hz;
  f.step_s = static_cast<double>(run.P.decimation) / run.P.fs_hz;
  f.start_s = S.start_s;
  f.span_s = S.span_s;
  f.filter_hz = run.P.decimated ? decimation_cutoff_hz(run.P.decimation, f.fs_hz) : run.P.filter_hz;
  std::vector<double> t, r;
  for (std::size_t i = 0; i < S.size(); ++i) {
    if (!S.valid[i]) continue;
    t.push_back(S.t[i]);
    r.push_back(S.y[i] - yf[i]);
  }
  if (!run.P.decimated && r.size() > kMinFilteredSamples)
    r = filtfilt_butter4(r, f.filter_hz, f.fs_hz);
  auto found =
      off_reversals(S, yf, rules::kAxisRestFilterPeriods / f.filter_hz, pulses::find(t, r, f));
  run.pulses.clear();
  if (found.empty()) return;
  std::vector<effects::State> states;  // only where there is a pulse to judge (a long full-rate
  states.reserve(t.size());            // recording's states would take hundreds of MB)
  for (std::size_t i = 0; i < S.size(); ++i)
    if (S.valid[i]) states.push_back(S.state(i));
  run.pulses = pulses::unexplained(t, r, states, Form::axis, run.cand, model, f, std::move(found));
}

// ---------------------------------------------------------------- localisation
// Residuals before and after at the identification samples, and what the maps draw on.
struct Residuals {
  std::vector<double> before, after;
  double rms0 = 0;                          // baseline RMS
  const effects::AxisKind* kind = nullptr;  // what the residual and the motion are in
  std::string unit() const { return std::string(kind->drive_unit); }  // the residual's
};

void add_map(AnalysisResult& R, const AxisSignals& S, const Residuals& res,
             const std::vector<double>& x, const std::string& label, const std::string& unit,
             double scale, std::pair<double, double> range, int nb) {
  const auto b0 = bin(x, res.before, S.valid, range.first, range.second, nb);
  const auto b1 = bin(x, res.after, S.valid, range.first, range.second, nb);
  const std::string text = describe_regions(b0, label, unit, scale, res.rms0, res.unit());
  if (!text.empty()) R.where.push_back(text);
  Figure fig;
  // The finding already names where ("over velocity: …"): the caption does not repeat it.
  fig.caption = text.empty() ? "Mean residual (measured - model) over " + label
                             : "Mean residual (measured - model) " + text;
  fig.charts.push_back({"Mean residual over " + label,
                        label + " [" + unit + "]",
                        "residual [" + res.unit() + "]",
                        {to_series("baseline", b0, scale), to_series("corrected", b1, scale)}});
  R.figures.push_back(fig);
}

// Direction dependence in words.
std::string direction_text(const AxisSignals& S, const Residuals& res) {
  double sp = 0, sn = 0, np = 0, nn = 0;
  for (std::size_t i = 0; i < S.size(); ++i) {
    if (!S.valid[i]) continue;
    if (S.v[i] > 0) sp += res.before[i], ++np;
    if (S.v[i] < 0) sn += res.before[i], ++nn;
  }
  if (!(np > 0 && nn > 0)) return "";
  std::ostringstream o;
  o.precision(3);
  o << "by direction: mean residual " << std::showpos << sp / np << " " << res.unit()
    << " moving +, " << sn / nn << " " << res.unit() << " moving −" << std::noshowpos;
  if (std::abs(sp / np - sn / nn) > rules::kWhereReversalJumpOfRms * res.rms0)
    o << " (jumps at velocity reversals)";
  return o.str();
}

void residual_maps(AnalysisResult& R, const AxisSignals& S, const Residuals& res) {
  const effects::AxisKind& k = *res.kind;
  add_map(R, S, res, S.v, "velocity", std::string(k.map_rate_unit), k.map_scale,
          percentile_range(S.v, S.valid, kVelocityTail), kVelocityBins);
  if (auto d = direction_text(S, res); !d.empty()) R.where.push_back(d);
  add_map(R, S, res, S.p, std::string(k.motion), std::string(k.map_unit), k.map_scale,
          percentile_range(S.p, S.valid, 0.0), kPositionBins);
}

// Residual RMS in time windows, before and after.
struct Windows {
  double win_s = 1.0;
  Curve before{"baseline", {}, {}}, after{"corrected", {}, {}};
};

Windows windowed_rms(const AxisSignals& S, const Residuals& res) {
  Windows w;
  w.win_s = std::max(1.0, (S.t.back() - S.t.front()) / kMostTimeWindows);
  for (std::size_t i = 0; i < S.size();) {
    const double t0 = S.t[i];
    double e0 = 0, e1 = 0;
    std::size_t c = 0, j = i;
    for (; j < S.size() && S.t[j] < t0 + w.win_s; ++j)
      if (S.valid[j]) {
        e0 += res.before[j] * res.before[j];
        e1 += res.after[j] * res.after[j];
        ++c;
      }
    if (c > kMinWindowSamples) {
      w.before.x.push_back(t0 + w.win_s / 2);
      w.before.y.push_back(std::sqrt(e0 / static_cast<double>(c)));
      w.after.x.push_back(t0 + w.win_s / 2);
      w.after.y.push_back(std::sqrt(e1 / static_cast<double>(c)));
    }
    i = j;
  }
  return w;
}

// The time windows whose residual RMS stands out (at most kMostWindowsListed, with at least
// kMinWindows windows): this many times the median window's and the noise floor.
std::vector<std::size_t> misfit_windows(const Windows& w, double noise_floor_n) {
  std::vector<std::size_t> out;
  const auto& wr = w.before.y;
  if (wr.size() < kMinWindows) return out;
  std::vector<double> sorted = wr;
  std::sort(sorted.begin(), sorted.end());
  const double med = sorted[sorted.size() / 2];
  for (std::size_t k = 0; k < wr.size() && out.size() < kMostWindowsListed; ++k)
    if (wr[k] > rules::kWhereWindowOverMedian * med &&
        wr[k] > noise_floor_n * rules::kWhereWindowOverMedian)
      out.push_back(k);
  return out;
}

// Those windows as the findings' events (misfit_window).
void add_misfit_windows(Findings& J, const Windows& w, const std::vector<std::size_t>& at) {
  for (const std::size_t k : at) {
    Event ev;
    ev.type = "misfit_window";
    ev.t_s = w.before.x[k] - w.win_s / 2;
    ev.duration_s = w.win_s;
    ev.rms_n = w.before.y[k];
    J.events.push_back(ev);
  }
}

// Growth over time, and the misfit windows `at` (misfit_windows) in words.
void residual_over_time(AnalysisResult& R, const Windows& w, const std::vector<std::size_t>& at,
                        const Residuals& res) {
  const auto& wr = w.before.y;
  const double win = w.win_s;
  if (wr.size() >= kMinWindows) {
    const std::size_t q = wr.size() / kThirds;
    const double first =
        std::accumulate(wr.begin(), wr.begin() + static_cast<std::ptrdiff_t>(q), 0.0) /
        static_cast<double>(q);
    const double last = std::accumulate(wr.end() - static_cast<std::ptrdiff_t>(q), wr.end(), 0.0) /
                        static_cast<double>(q);
    std::ostringstream o;
    o.precision(3);
    if (last > rules::kWhereGrowthFactor * first && last > rules::kWhereGrowthOfRms * res.rms0) {
      o << "over time: the residual grows (RMS " << first << " " << res.unit()
        << " in the first third, " << last << " " << res.unit() << " in the last)";
      R.where.push_back(o.str());
    }
    std::ostringstream w2;
    w2.precision(4);
    for (std::size_t k : at)
      w2 << (k == at.front() ? "" : ", ") << w.before.x[k] - win / 2 << "–"
         << w.before.x[k] + win / 2 << " s";
    if (!at.empty())
      R.where.push_back("in time: windows with residual RMS over 3× the median: " + w2.str());
  }
  Figure ft;
  ft.caption = "Residual RMS in time windows";
  ft.charts.push_back(
      {"Residual RMS over time", "time [s]", "RMS [" + res.unit() + "]", {w.before, w.after}});
  R.figures.push_back(ft);
}

using Onsets = std::vector<std::pair<std::size_t, double>>;  // sample, signed direction

// The residual averaged around events (signed by the new direction), before and after.
void locked_average(AnalysisResult& R, const AxisSignals& S, const Residuals& res, double fs_id,
                    const Onsets& at, const std::string& what) {
  const int half = static_cast<int>(kLockedHalfSpan_s * fs_id);
  std::vector<double> acc0(static_cast<std::size_t>(2 * half + 1), 0.0), acc1(acc0.size(), 0.0),
      cnt(acc0.size(), 0.0);
  for (const auto& [i, d] : at)
    for (int k = -half; k <= half; ++k) {
      const auto ii = static_cast<std::ptrdiff_t>(i) + k;
      if (ii < 0 || ii >= static_cast<std::ptrdiff_t>(S.size()) ||
          !S.valid[static_cast<std::size_t>(ii)])
        continue;
      const int lag = k + half;  // in an int first: the sum is never negative
      const auto kk = static_cast<std::size_t>(lag);
      acc0[kk] += d * res.before[static_cast<std::size_t>(ii)];
      acc1[kk] += d * res.after[static_cast<std::size_t>(ii)];
      cnt[kk] += 1;
    }
  Figure fr;
  fr.caption = "Residual averaged around " + std::to_string(at.size()) + " " + what +
               " (signed by the new direction)";
  Curve s0{"baseline", {}, {}}, s1{"corrected", {}, {}};
  for (std::size_t k = 0; k < cnt.size(); ++k)
    if (cnt[k] > 0) {
      const double tt = (static_cast<double>(k) - half) / fs_id;
      s0.x.push_back(tt * 1e3);
      s0.y.push_back(acc0[k] / cnt[k]);
      s1.x.push_back(tt * 1e3);
      s1.y.push_back(acc1[k] / cnt[k]);
    }
  fr.charts.push_back({"Residual locked to " + what,
                       "time from event [ms]",
                       "residual x direction [" + res.unit() + "]",
                       {s0, s1}});
  R.figures.push_back(fr);
}

Onsets reversals(const AxisSignals& S) {
  Onsets rev;
  double last_dir = 0;
  for (std::size_t i = 0; i < S.size(); ++i) {
    const double d = std::abs(S.v[i]) > 1e-6 ? sgn(S.v[i]) : 0.0;
    if (d != 0 && last_dir != 0 && d != last_dir) rev.emplace_back(i, d);
    if (d != 0) last_dir = d;
  }
  return rev;
}

// Steps of a setpoint column larger than 5 % of its range, at the identification rate.
Onsets input_edges(const std::vector<double>& x, int decimation) {
  double lo = INFINITY, hi = -INFINITY;
  for (double e : x)
    if (std::isfinite(e)) lo = std::min(lo, e), hi = std::max(hi, e);
  Onsets edges;
  for (std::size_t i = 1; i < x.size(); ++i) {
    const double d = x[i] - x[i - 1];
    if (std::isfinite(d) && std::abs(d) > rules::kWhereEdgeOfRange * (hi - lo) && hi > lo)
      edges.emplace_back(i / static_cast<std::size_t>(decimation), sgn(d));
  }
  return edges;
}

// Input edges: steps in the first setpoint column the recording has, with its name (none: it has
// none).
std::optional<std::pair<std::string, Onsets>> setpoint_edges(const AxisRun& run) {
  for (const std::string_view name : run.kind.setpoints) {
    std::string col(name);
    if (run.rec.has(col)) {
      Onsets edges = input_edges(run.rec.column(col), run.P.decimation);
      return std::pair{std::move(col), std::move(edges)};
    }
  }
  return std::nullopt;
}

// How many velocity reversals and input edges the event-locked averages are over.
void count_onsets(Findings& J, const AxisRun& run) {
  J.reversals = reversals(*run.S).size();
  if (const auto edges = setpoint_edges(run); edges && !edges->second.empty())
    J.input_edges = edges->second.size();
}

// Event-locked averages: the residual around velocity reversals and input edges.
void event_locked(AnalysisResult& R, const AxisRun& run, const Residuals& res) {
  const AxisSignals& S = *run.S;
  const double fs_id = run.P.fs_hz / run.P.decimation;
  locked_average(R, S, res, fs_id, reversals(S), "velocity reversals");
  if (const auto edges = setpoint_edges(run); edges && !edges->second.empty())
    locked_average(R, S, res, fs_id, edges->second, "steps of " + edges->first);
}

// Measured force with both models over time, the held-out error per step, and the fit over time
// (the page's interactive chart, as the actuator path gives it).
void time_figures(AnalysisResult& R, const AxisSignals& S, const Predictions& p,
                  const Residuals& res, bool added) {
  const std::size_t step = std::max<std::size_t>(1, S.size() / kChartPoints);
  Curve m{"measured", {}, {}}, b{"baseline", {}, {}}, c{"corrected", {}, {}},
      rb{"baseline", {}, {}}, rc{"corrected", {}, {}};
  for (std::size_t i = 0; i < S.size(); i += step) {
    m.x.push_back(S.t[i]), m.y.push_back(S.y[i]);
    b.x.push_back(S.t[i]), b.y.push_back(p.yb[i]);
    c.x.push_back(S.t[i]), c.y.push_back(p.yf[i]);
    if (!S.valid[i]) continue;
    rb.x.push_back(S.t[i]), rb.y.push_back(S.y[i] - p.yb[i]);
    rc.x.push_back(S.t[i]), rc.y.push_back(S.y[i] - p.yf[i]);
  }
  Figure f;
  f.caption = "Measured " + std::string(res.kind->quantity) +
              " and the models' predictions from measured motion; residuals below";
  const std::string u = "[" + res.unit() + "]", quantity(res.kind->quantity);
  std::string title = quantity;
  title.front() = static_cast<char>(std::toupper(static_cast<unsigned char>(title.front())));
  f.charts.push_back({title, "time [s]", quantity + " " + u, {m, b, c}});
  f.charts.push_back({"Residual (measured - model)", "time [s]", "residual " + u, {rb, rc}});
  R.figures.insert(R.figures.begin(), f);
  Figure v;
  v.caption = "Held-out RMS error after each added term";
  Curve hs{"held-out RMS", {}, {}};
  for (std::size_t k = 0; k < R.findings.validation.size(); ++k) {
    hs.x.push_back(static_cast<double>(k));
    hs.y.push_back(R.findings.validation[k].heldout_rms_n);
  }
  v.charts.push_back({"Held-out error per step (0 = baseline)", "terms added", "RMS " + u, {hs}});
  R.figures.insert(R.figures.begin() + 1, v);
  R.fit_over_time = {"The fit before and after",
                     "time [s]",
                     "missing " + quantity + " " + u,
                     {{added ? "before (the model as configured)" : "the model (nothing added)",
                       S.t, res.before}}};
  if (added) R.fit_over_time.curves.push_back({"after (with the effects found)", S.t, res.after});
}

// ---------------------------------------------------------------- corrected model file
std::string term_note(const EffectFinding& e) {
  std::ostringstream note;
  note.precision(3);
  note << "maglead analyze: " << e.where;
  if (e.evidence.heldout_gain_pct)
    note << "; held-out gain " << *e.evidence.heldout_gain_pct << " %";
  if (!e.finding.empty()) note << "; " << e.finding;
  return note.str();
}

// One finding into the model, in the unit's file form: a total the model file holds itself
// (mass, viscous or Coulomb friction) becomes that value, any other effect a term with the
// unit's parameters.
void apply_finding(ModelFile& M, const EffectFinding& e) {
  const effects::Effect* unit = effects::find(e.id);
  if (unit && !unit->selectable()) return;  // events (pulses) are reported, not a force law
  if (const auto total = unit ? total_of(*unit) : std::string(); !total.empty()) {
    *total_field(M, total) = parameter_value(e.parameters, total);
    return;
  }
  auto& t = M.term(e.id);
  t.enabled = true;
  t.note = term_note(e);
  for (const auto& p : e.parameters) t.set(p.name, p.value);
}

ModelFile axis_corrected_model(const AxisRun& run, const std::vector<EffectFinding>& effects,
                               const Fit& final_fit) {
  ModelFile M = run.model;
  M.fit.clear();  // the corrected model is a model: every value fixed, as fitted here
  for (const auto& p : fitted_base(run, final_fit)) *total_field(M, p.name) = p.value;
  for (const auto& e : effects) apply_finding(M, e);
  M.source = (run.model.source.empty() ? std::string("baseline") : run.model.source) +
             "; corrected by maglead analyze from " + run.rec.path;
  return M;
}

// ---------------------------------------------------------------- the axis's kind
bool has_columns(const Recording& rec, const effects::AxisKind& k) {
  return rec.has(std::string(k.position)) && rec.has(std::string(k.drive));
}

// A stated axis whose header has neither kind's columns.
bool neither_kind(const Recording& rec) {
  return rec.meta("axis") && !has_columns(rec, effects::linear_axis()) &&
         !has_columns(rec, effects::rotary_axis());
}

std::string kind_columns(const effects::AxisKind& k) {
  return "t_s, " + std::string(k.position) + ", " + std::string(k.drive);
}

// The kind whose columns the recording has (nullptr: neither's). When header, model and columns
// disagree the columns decide the fix: they are what was logged, a header line or a model file is
// what was typed.
const effects::AxisKind* logged_kind(const Recording& rec) {
  for (const effects::AxisKind* k : {&effects::linear_axis(), &effects::rotary_axis()})
    if (has_columns(rec, *k)) return k;
  return nullptr;
}

std::string model_words(const effects::AxisKind& k) {
  return std::string(k.name == "rotary" ? "a rotary model" : "a linear axis's model") +
         " (system = \"" + std::string(k.system) + "\", " + k.name_of("nut_mass_kg") + ", " +
         k.name_of("viscous_n_s_per_m") + ", " + k.name_of("coulomb_n") + ")";
}

// What the header says of the kind, for a refusal: "the header says '# axis: linear'", or that
// it has no '# axis: rotary' line.
std::string header_words(const Recording& rec) {
  const auto stated = rec.meta("axis");
  return stated ? "the header says '# axis: " + *stated + "'"
                : std::string("the header has no '# axis: rotary' line");
}

// What to change so that the header and the model agree with the columns the file has.
std::string agreeing_fix(const Recording& rec, const effects::AxisKind& logged,
                         const effects::AxisKind& stated, const effects::AxisKind* modelled) {
  std::string fix;
  if (&logged != &stated && logged.name == "rotary")
    fix = rec.meta("axis")
              ? "change the header line '# axis: " + *rec.meta("axis") + "' to '# axis: rotary'"
              : std::string("add the header line '# axis: rotary'");
  else if (&logged != &stated)
    fix = "remove the header line '# axis: rotary'";
  if (modelled && modelled != &logged)
    fix += (fix.empty() ? "give " : " and give ") + model_words(logged);
  return fix;
}

// The stated kind's columns missing: which, the columns there are, and one that looks like a
// missing column in another unit (angle_deg for angle_rad) with what to convert.
std::string missing_columns_text(const Recording& rec, const effects::AxisKind& kind) {
  std::string msg = rec.path + ": a " + std::string(kind.name) + " axis needs the columns " +
                    kind_columns(kind) + " (optional:";
  for (const auto c : kind.setpoints) msg += " " + std::string(c);
  // With '# axis:' and neither kind's columns, or without t_s, the reader keeps every column
  // (columns_read).
  const std::string listed = neither_kind(rec) || !rec.has("t_s") ? "header has" : "columns read";
  const std::string list = missing_column_detail(rec.names, "", listed);
  msg += ")" + list;
  for (const std::string_view c : {std::string_view("t_s"), kind.position, kind.drive})
    if (!rec.has(std::string(c)))
      msg += missing_column_detail(rec.names, std::string(c), listed).substr(list.size());
  return msg;
}

// The kind the recording states (`# axis: rotary`; none: linear) must be the model's (system
// "axis" or "rotary") and its columns must be there; an error says what to type, following the
// columns the file has (a header line missing or too many, or the other kind's model).
const effects::AxisKind& kind_of(const Recording& rec, const ModelFile& model) {
  const std::string stated = rec.meta("axis").value_or("");
  const effects::AxisKind* kind = effects::axis_kind(stated);
  if (!kind)
    throw std::invalid_argument(rec.path + ": header '# axis: " + stated +
                                "' names no axis kind (expected linear or rotary)");
  const effects::AxisKind* modelled = effects::axis_kind_of_system(model.system);
  const effects::AxisKind* logged = logged_kind(rec);
  if (logged == kind && (!modelled || modelled == kind)) {
    if (!rec.has("t_s")) throw RecordingError(missing_columns_text(rec, *kind));
    return *kind;
  }
  const bool rotary = kind->name == "rotary";
  // The header alone is wrong (no model: `inspect` checks the header against the columns).
  if (logged && (!modelled || modelled == logged))
    throw std::invalid_argument(
        rec.path + ": the columns are a " + std::string(logged->name) + " axis's (" +
        kind_columns(*logged) + ")" + (modelled ? ", as the model is," : "") + " but " +
        header_words(rec) + ": " + agreeing_fix(rec, *logged, *kind, modelled));
  if (logged == kind)  // the model alone is wrong
    throw std::invalid_argument(rec.path + ": the recording is a " + std::string(kind->name) +
                                " axis (columns " + kind_columns(*kind) + ") but the model is a " +
                                std::string(modelled->name) + " axis's (system = \"" +
                                model.system +
                                "\"): " + agreeing_fix(rec, *logged, *kind, modelled));
  if (!logged && modelled && modelled != kind)  // no columns to decide: header against model
    throw std::invalid_argument(
        rotary ? rec.path +
                     ": the recording is a rotary axis ('# axis: rotary') but the model is "
                     "a linear axis's (system = \"axis\"): give " +
                     model_words(effects::rotary_axis())
               : rec.path +
                     ": the model is a rotary axis's (system = \"rotary\") but the "
                     "recording does not say so (" +
                     header_words(rec) +
                     "): " + agreeing_fix(rec, effects::rotary_axis(), *kind, modelled) +
                     " (columns " + kind_columns(effects::rotary_axis()) + ")");
  std::string msg = missing_columns_text(rec, *kind);
  if (logged)
    msg += "; this recording has a " + std::string(logged->name) + " axis's (" +
           kind_columns(*logged) + "): " + agreeing_fix(rec, *logged, *kind, modelled);
  throw RecordingError(msg);
}

// The findings in the kind's names (a rotary axis's carry its units: inertia_kg_m2, …): the
// selection and the fits work on the units' own names throughout, so this is the one renaming.
void name_in_kind(Findings& J, const effects::AxisKind& kind) {
  if (kind.name == "linear") return;
  const auto rename = [&](Parameters& ps) {
    for (auto& p : ps) p.name = kind.name_of(p.name);
  };
  for (auto& e : J.effects) {
    rename(e.parameters);
    rename(e.standard_errors);
    for (auto& a : e.alternatives) rename(a.parameters);
    e.summary = summary_text(e.parameters, e.standard_errors);
    // The one pulse finder speaks of force pulses (pulses.cpp): on a shaft they are torque's.
    e.where = kind.words(e.where);
  }
  for (auto& r : J.not_selected) {
    if (r.parameters) rename(*r.parameters);
    if (r.reason) r.reason = kind.words(*r.reason);
  }
  if (J.unexplained) {
    // Its message quotes the parameters as "name = value" (selection::unexplained_of).
    std::string& m = J.unexplained->message;
    for (const auto& p : J.unexplained->parameters) {
      const std::string from = " " + p.name + " = ", to = " " + kind.name_of(p.name) + " = ";
      for (auto at = m.find(from); at != std::string::npos; at = m.find(from, at + to.size()))
        m.replace(at, from.size(), to);
    }
    rename(J.unexplained->parameters);
  }
  for (FitErrors* f : {&J.baseline, &J.final_fit}) {
    if (!f->fitted_parameters) continue;
    rename(*f->fitted_parameters);
    rename(f->standard_errors);
    if (!f->summary.empty()) f->summary = summary_text(*f->fitted_parameters, f->standard_errors);
  }
}

// What the holds took out of the fit, in words ("" when the axis never stood still).
std::string held_text(const AxisRun& run) {
  if (!(run.P.held_s > 0)) return "";
  const auto& kind = run.kind;
  const double span_s = run.P.full.span_s,
               hold_ms = 1e3 * rules::kAxisRestFilterPeriods / run.P.filter_hz;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "held still %.1f s of %.1f s (within %g encoder counts of %.3g %s for %.0f ms or "
                "longer): not fitted, nor the filters' spread around each hold; a held axis "
                "takes any %s up to its break-away",
                run.P.held_s, span_s, rules::kAxisRestCounts, run.P.count * kind.map_scale,
                std::string(kind.map_unit).c_str(), hold_ms, std::string(kind.quantity).c_str());
  return buf;
}

// A force-driven axis (EMPS; a rotary one alike): prepare → columns → select → findings, maps,
// corrected model.
class AxisPath final : public AnalysisPath {
 public:
  AxisPath(const Recording& rec, const ModelFile& model, const AnalysisOptions& opt)
      : run_(rec, model, opt, kind_of(rec, model)) {}

  void prepare() override {
    run_.P = prepare_axis(run_.rec, run_.model, run_.opt, run_.kind);
    run_.S = run_.P.decimated ? &run_.P.id : &run_.P.full;
    run_.folds = std::max(rules::kAxisMinFolds, run_.opt.folds);
  }

  void select() override {
    baseline_columns(run_);
    accumulate_axis(run_);
    sel_ = select_terms(run_);
    final_base_se_ = finish_axis_terms(run_, sel_);
  }

  // In the kind's names (name_in_kind); the corrected model takes the units' own, kept aside.
  Findings findings() override {
    p_ = predictions(run_, sel_);
    axis_pulses(run_, p_.yf, sel_.current);
    const AxisSignals& S = *run_.S;
    res_ = {std::vector<double>(S.size()), std::vector<double>(S.size()), p_.eb.rms, &run_.kind};
    for (std::size_t i = 0; i < S.size(); ++i) {
      res_.before[i] = S.y[i] - p_.yb[i];
      res_.after[i] = S.y[i] - p_.yf[i];
    }
    windows_ = windowed_rms(S, res_);
    misfit_at_ = misfit_windows(windows_, run_.P.noise_floor_n);
    Findings J;
    fill_findings(J, run_, sel_, p_, final_base_se_);
    add_misfit_windows(J, windows_, misfit_at_);
    count_onsets(J, run_);
    J.twin_simulation = TwinSimulation{};
    J.twin_simulation->reason =
        run_.kind.words("the twin models the magnetic actuator; this is a force-driven axis");
    unit_named_ = J.effects;
    name_in_kind(J, run_.kind);
    return J;
  }

  void figures(AnalysisResult& R) override {
    if (auto h = held_text(run_); !h.empty()) R.where.push_back(std::move(h));
    const AxisSignals& S = *run_.S;
    residual_maps(R, S, res_);
    residual_over_time(R, windows_, misfit_at_, res_);
    event_locked(R, run_, res_);
    time_figures(R, S, p_, res_, !sel_.terms.empty());
  }

  void corrected_model(AnalysisResult& R) override {
    R.corrected = axis_corrected_model(run_, unit_named_, p_.final_fit);
  }

 private:
  AxisRun run_;
  selection::Result sel_;
  Parameters final_base_se_;  // the baseline's fitted totals' standard errors (finish_axis_terms)
  Predictions p_;
  Residuals res_;  // before and after, at the identification samples
  Windows windows_;
  std::vector<std::size_t> misfit_at_;     // the windows that stand out (misfit_windows)
  std::vector<EffectFinding> unit_named_;  // the findings' effects before name_in_kind
};

}  // namespace

std::unique_ptr<AnalysisPath> axis_path(const Recording& rec, const ModelFile& baseline,
                                        const AnalysisOptions& options) {
  return std::make_unique<AxisPath>(rec, baseline, options);
}

void check_axis_columns(const Recording& rec) {
  if (!rec.meta("axis") && !logged_kind(rec)) return;  // the actuator's, or no axis's at all
  (void)kind_of(rec, ModelFile{});  // the model unknown: the header and the columns decide
}

std::vector<std::string> columns_read(const Recording& header) {
  std::vector<std::string> cols;
  // The actuator path's (actuator_analysis.cpp, and force_set_n for the twin's check): the
  // motor's angle only where the screw's is missing. An axis's recording never takes it.
  if (!header.meta("axis"))
    cols = {"t_s", "nut_pos_m", "load_force_n", "force_set_n",
            header.has("screw_angle_rad") ? "screw_angle_rad" : "motor_angle_rad"};
  // Every axis kind's, not only the stated one's: kind_of names the other kind's columns when
  // the stated kind's are missing, and without `# axis:` the model decides the path. Setpoints
  // only where the kind's own columns are, as only then does the axis path get to them: an
  // actuator's pos_set_m (a linear axis's setpoint) is not read.
  cols.emplace_back("t_s");
  // A stated axis with neither kind's columns is refused, as is a recording without t_s: its
  // message lists the whole header and a column in another unit (angle_deg, t_ms), so every
  // column is kept for it.
  if (neither_kind(header) || !header.has("t_s"))
    cols.insert(cols.end(), header.names.begin(), header.names.end());
  for (const effects::AxisKind* kind : {&effects::linear_axis(), &effects::rotary_axis()}) {
    cols.emplace_back(kind->position);
    cols.emplace_back(kind->drive);
    if (has_columns(header, *kind))
      cols.insert(cols.end(), kind->setpoints.begin(), kind->setpoints.end());
  }
  return cols;
}

}  // namespace maglead::analysis
