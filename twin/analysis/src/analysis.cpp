// The analysis works on the inverse model: the measured force is predicted from measured motion,
// y = y_fixed(baseline) + Σ θ_j x_j, linear in every candidate parameter once its nonlinear
// shape parameter (a period, a distance, a velocity scale) is fixed. So one pass over the data
// accumulates a Gram matrix per time segment, and every fit and held-out score of the forward
// selection is a small solve on sums of those matrices, whatever the recording's length.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/signal.hpp"
#include "statistics.hpp"

namespace maglead::analysis {
namespace {

constexpr double kPi = std::numbers::pi;
using stats::Fit;
using stats::partial_r2;
using stats::robust_sigma;
using stats::sse;

// ---------------------------------------------------------------- columns and candidates
enum Col : int {
  kAcc,
  kVel,
  kSign,
  kAbsV,
  kMoving,
  kStrib0,
  kStrib1,
  kStrib2,
  kStrib3,
  kStrib4,
  kStrib5,
  kOne,
  kSpring,
  kDrift,
  kSinTh,
  kCosTh,
  kSinP,
  kCosP,
  kEnd0,
  kEnd1,
  kEnd2,
  kEnd3,
  kEnd4,
  kEnd5,
  kBacklash,
  kDelay,
  kBurst,
  kGain,
  kLead,
  kNumCols
};
constexpr double kStribeckVel_m_s[6] = {0.5e-3, 1e-3, 2e-3, 4e-3, 8e-3, 16e-3};
constexpr double kEndDist_m[6] = {1e-3, 2e-3, 3e-3, 4e-3, 6e-3, 8e-3};

struct Candidate {
  std::string id;
  std::vector<std::vector<int>> variants;
  bool actuator_only = false;
  bool selectable = true;  // false: only named as an alternative (identifiability)
};

std::vector<Candidate> candidate_library() {
  std::vector<Candidate> c = {
      {"coulomb_friction", {{kSign}}},
      {"viscous_friction", {{kVel}}},
      {"asymmetric_friction", {{kAbsV, kMoving}}},
      {"stribeck_friction", {}},
      {"offset", {{kOne}}},
      {"spring", {{kSpring}}},
      {"mass_error", {{kAcc}}},
      {"gain_drift", {{kDrift}}, true},
      {"angle_ripple", {{kSinTh, kCosTh}}, true},
      {"position_ripple", {{kSinP, kCosP}}},
      {"end_effect", {}, true},
      {"backlash", {{kBacklash}}, true},
      {"sensor_delay", {{kDelay}}, true},
      {"external_disturbance", {{kBurst}}},
      {"coupling_gain_error", {{kGain}}, true, false},
      {"lead_error", {{kLead}}, true, false},
  };
  for (auto& k : c) {
    if (k.id == "stribeck_friction")
      for (int i = 0; i < 6; ++i) k.variants.push_back({kStrib0 + i});
    if (k.id == "end_effect")
      for (int i = 0; i < 6; ++i) k.variants.push_back({kEnd0 + i});
  }
  return c;
}

// ---------------------------------------------------------------- signals
struct Signals {
  std::vector<double> t, p, v, a, y, y_fixed;
  // actuator only
  std::vector<double> theta, phi, fs, fs_slope, play, to_end, burst;
  std::vector<unsigned char> valid;
  double lead_m = 0.006, mid_m = 0.0, pos_period_m = 0.005, moving_speed = 0.0;
  bool actuator = false;
  std::size_t size() const { return t.size(); }
};

double sgn(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

void fill_row(const Signals& s, std::size_t i, const std::vector<int>& cols, double* row) {
  const double v = s.v[i];
  for (std::size_t j = 0; j < cols.size(); ++j) {
    const int c = cols[j];
    double x = 0.0;
    switch (c) {
      case kAcc:
        x = s.a[i];
        break;
      case kVel:
        x = v;
        break;
      case kSign:
        x = sgn(v);
        break;
      case kAbsV:
        x = std::abs(v);
        break;
      case kMoving:
        x = std::abs(v) > s.moving_speed ? 1.0 : 0.0;
        break;
      case kOne:
        x = 1.0;
        break;
      case kSpring:
        x = s.p[i] - s.mid_m;
        break;
      case kSinP:
        x = std::sin(2 * kPi * s.p[i] / s.pos_period_m);
        break;
      case kCosP:
        x = std::cos(2 * kPi * s.p[i] / s.pos_period_m);
        break;
      case kBurst:
        x = s.burst.empty() ? 0.0 : s.burst[i];
        break;
      default:
        if (c >= kStrib0 && c <= kStrib5) {
          const double r = v / kStribeckVel_m_s[c - kStrib0];
          x = sgn(v) * std::exp(-r * r);
          break;
        }
        if (!s.actuator) break;
        switch (c) {
          case kDrift:
            x = s.fs[i] * s.t[i] / 60.0;
            break;
          case kSinTh:
            x = std::sin(s.theta[i]);
            break;
          case kCosTh:
            x = std::cos(s.theta[i]);
            break;
          case kBacklash:
            x = -0.5 * s.play[i] * s.fs_slope[i];
            break;
          case kDelay:
            x = -s.fs_slope[i] * 2 * kPi * v / s.lead_m;
            break;
          case kGain:
            x = s.fs[i];
            break;
          case kLead:
            x = s.fs_slope[i] * 2 * kPi * s.p[i] / (s.lead_m * s.lead_m);
            break;
          default:
            if (c >= kEnd0 && c <= kEnd5)
              x = s.fs[i] * std::clamp(1.0 - s.to_end[i] / kEndDist_m[c - kEnd0], 0.0, 1.0);
        }
    }
    row[j] = x;
  }
}

double median_step(const std::vector<double>& t) {
  std::vector<double> d;
  for (std::size_t i = 1; i < t.size() && d.size() < 10000; ++i) d.push_back(t[i] - t[i - 1]);
  if (d.empty()) throw std::invalid_argument("recording has fewer than two samples");
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

// ---------------------------------------------------------------- Gram per segment
// The shared per-segment normal equations, with the column kinds in matrix order.
struct Grams : stats::Grams {
  std::vector<int> cols;
  int index(int col) const {
    for (std::size_t j = 0; j < cols.size(); ++j)
      if (cols[j] == col) return static_cast<int>(j);
    return -1;
  }
};

Grams accumulate(const Signals& s, const std::vector<int>& cols, int folds,
                 const std::function<void(double)>& progress) {
  const auto m = static_cast<Eigen::Index>(cols.size());
  Grams g{stats::Grams(static_cast<std::size_t>(folds), m), cols};
  const std::size_t n = s.size();
  constexpr std::size_t kChunk = 2048;
  stats::Grams::RowMatrix x(kChunk, m);
  Eigen::VectorXd r(kChunk);
  for (int f = 0; f < folds; ++f) {
    const std::size_t lo = n * static_cast<std::size_t>(f) / static_cast<std::size_t>(folds);
    const std::size_t hi = n * static_cast<std::size_t>(f + 1) / static_cast<std::size_t>(folds);
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

struct Score {
  std::vector<double> heldout_sse;  // per fold
  double total = 0.0;
};

Score heldout(const Grams& g, const std::vector<int>& idx) {
  Score s{stats::heldout(g, idx), 0.0};
  s.total = stats::total(s.heldout_sse);
  return s;
}

Fit fit_all(const Grams& g, const std::vector<int>& idx) { return stats::solve(g, idx); }

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
  const std::size_t step = std::max<std::size_t>(1, x.size() / 200000);
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
    if (b.count[k] >= 5) {
      s.x.push_back(b.centre[k] * x_scale);
      s.y.push_back(b.mean[k]);
    }
  return s;
}

// Regions of a binned residual map that stand out, in words.
std::string describe_regions(const Binned& b, const std::string& what, const std::string& unit,
                             double x_scale, double overall_rms) {
  std::vector<int> hot;
  for (std::size_t k = 0; k < b.centre.size(); ++k) {
    if (b.count[k] < 20) continue;
    const double se = std::sqrt(std::max(b.m2[k], 1e-12) / b.count[k]);
    if (std::abs(b.mean[k]) > 0.5 * overall_rms && std::abs(b.mean[k]) > 4 * se)
      hot.push_back(static_cast<int>(k));
  }
  if (hot.empty()) return "";
  std::ostringstream o;
  o.precision(3);
  o << "over " << what << ": mean residual stands out in ";
  std::size_t i = 0;
  int shown = 0;
  const double w = b.centre.size() > 1 ? b.centre[1] - b.centre[0] : 0.0;
  while (i < hot.size() && shown < 4) {
    std::size_t j = i;
    while (j + 1 < hot.size() && hot[j + 1] == hot[j] + 1 &&
           sgn(b.mean[hot[j + 1]]) == sgn(b.mean[hot[i]]))
      ++j;
    double peak = 0;
    for (std::size_t k = i; k <= j; ++k)
      if (std::abs(b.mean[hot[k]]) > std::abs(peak)) peak = b.mean[hot[k]];
    o << (shown ? "; " : "") << (b.centre[hot[i]] - w / 2) * x_scale << " … "
      << (b.centre[hot[j]] + w / 2) * x_scale << " " << unit << " (up to " << std::showpos << peak
      << std::noshowpos << " N)";
    ++shown;
    i = j + 1;
  }
  return o.str();
}

// ---------------------------------------------------------------- preparation
struct Prepared {
  Signals full;  // every sample (actuator: analysis rate too)
  Signals id;    // identification rate (axis: decimated); same as full when not decimated
  bool decimated = false;
  Eigen::MatrixXd id_columns;  // axis, decimated: parallel-filtered columns (n × kNumCols)
  int decimation = 1;
  double fs_hz = 0, filter_hz = 0, noise_floor_n = 0, bandwidth_hz = 0;
  std::vector<double> y_raw;                  // full-rate measured force, unfiltered
  std::vector<std::pair<double, int>> slips;  // step-outs: time, leads
};

std::vector<int> all_columns() {
  std::vector<int> c(kNumCols);
  std::iota(c.begin(), c.end(), 0);
  return c;
}

}  // namespace

ModelFile actuator_model_from_config(const ActuatorParams& act) {
  ModelFile m;
  m.system = "actuator";
  m.source = "config/actuator.toml (paper model)";
  m.nut_mass_kg = act.nut_mass_kg;
  m.viscous_n_s_per_m = act.viscous_n_s_per_m;
  m.coulomb_n = act.coulomb_n;
  return m;
}

namespace {

// The baseline's fixed force at every sample of a force-driven axis: the known dynamics plus
// every term the model file switches on, in the effect library's names (totals for mass and
// friction). Forces on the moving part along +p (offset, spring, ripple) are what the drive force
// does not have to supply: they subtract.
struct FixedTerms {
  const ModelTerm *st = nullptr, *sp = nullptr, *pr = nullptr;
  double mass = 0, visc = 0, coul = 0;  // fixed values (0: fitted instead)
  double coul_pos = 0, coul_neg = 0, visc_pos = 0, visc_neg = 0;
  double strib_c = 0, strib_n = 0, strib_v = 1.0, offset = 0;
  double spring_k = 0, spring_c = 0, pr_n = 0, pr_per = 1.0, pr_ph = 0;

  double force(const Signals& s, std::size_t i) const {
    const double v = s.v[i];
    double y = mass * s.a[i] + visc * v + (v > 0 ? visc_pos : visc_neg) * v;
    double fc = (st ? strib_c : coul) + (v > 0 ? coul_pos : v < 0 ? coul_neg : 0.0);
    if (st) {
      const double r = v / strib_v;
      fc += strib_n * std::exp(-r * r);
    }
    y += sgn(v) * fc;
    double other = offset;
    if (sp) other -= spring_k * (s.p[i] - spring_c);
    if (pr) other += pr_n * std::sin(2 * kPi * s.p[i] / pr_per + pr_ph);
    return y - other;
  }
};

FixedTerms fixed_terms(const ModelFile& model, double mid_m) {
  auto term_value = [&](const char* id, const char* key, double fallback) {
    const auto* term = model.find(id);
    return term ? term->get(key, fallback) : fallback;
  };
  FixedTerms f;
  f.st = model.find("stribeck_friction");
  f.sp = model.find("spring");
  f.pr = model.find("position_ripple");
  const auto* as = model.find("asymmetric_friction");
  if (!model.fit.count("nut_mass_kg"))
    f.mass = term_value("mass_error", "nut_mass_kg", model.nut_mass_kg);
  if (!model.fit.count("viscous_n_s_per_m"))
    f.visc = term_value("viscous_friction", "viscous_n_s_per_m", model.viscous_n_s_per_m);
  if (!model.fit.count("coulomb_n"))
    f.coul = term_value("coulomb_friction", "coulomb_n", model.coulomb_n);
  // Direction-dependent friction: its levels replace the symmetric ones in their direction.
  if (as) {
    f.coul_pos = as->get("coulomb_pos_n", f.coul) - f.coul;
    f.coul_neg = as->get("coulomb_neg_n", f.coul) - f.coul;
    f.visc_pos = as->get("viscous_pos_n_s_per_m", f.visc) - f.visc;
    f.visc_neg = as->get("viscous_neg_n_s_per_m", f.visc) - f.visc;
  }
  if (f.st) {
    f.strib_c = f.st->get("coulomb_n", f.coul);
    f.strib_n = f.st->get("breakaway_n", f.strib_c) - f.strib_c;
    f.strib_v = f.st->get("stribeck_velocity_m_s", 2e-3);
  }
  f.offset = term_value("offset", "offset_n", 0.0);
  if (f.sp) {
    f.spring_k = f.sp->get("stiffness_n_per_m", 0.0);
    f.spring_c = f.sp->get("rest_position_m", mid_m);
  }
  if (f.pr) {
    f.pr_n = f.pr->get("amplitude_n", 0.0);
    f.pr_per = f.pr->get("period_m", 5e-3);
    f.pr_ph = f.pr->get("phase_rad", 0.0);
  }
  return f;
}

// A noise floor from the force's sample-to-sample roughness (white noise: var(Δ²y) = 6σ²).
double noise_floor(const std::vector<double>& y) {
  std::vector<double> d2;
  for (std::size_t i = 1; i + 1 < y.size(); i += 1) d2.push_back(y[i + 1] - 2 * y[i] + y[i - 1]);
  return robust_sigma(d2) / std::sqrt(6.0);
}

// Identification bandwidth: the lowest frequency below which the acceleration (the most
// demanding regressor) keeps 99 % of its energy; decimate as far as the decimation filter
// (80 % of the new Nyquist frequency) stays above it.
int bandwidth_decimation(Prepared& P) {
  const auto& a = P.full.a;
  double ea = 0;
  for (double x : a) ea += x * x;
  P.bandwidth_hz = 0.25 * P.fs_hz;
  for (double f = 0.5; f < 0.25 * P.fs_hz; f *= 1.1) {
    const auto af = filtfilt_butter4(a, f, P.fs_hz);
    double lost = 0;
    for (std::size_t i = 0; i < a.size(); ++i) lost += (a[i] - af[i]) * (a[i] - af[i]);
    if (lost <= 0.01 * ea) {
      P.bandwidth_hz = f;
      break;
    }
  }
  return std::max(1, static_cast<int>(std::floor(0.4 * P.fs_hz / P.bandwidth_hz)));
}

// Decimation to the identification bandwidth: parallel filtering of every signal.
void decimate_signals(Prepared& P, int nd) {
  P.decimation = nd;
  if (nd <= 1) return;
  const Signals& s = P.full;
  P.decimated = true;
  Signals& d = P.id;
  d = Signals{};
  d.lead_m = s.lead_m;
  d.mid_m = s.mid_m;
  d.moving_speed = s.moving_speed;
  for (std::size_t i = 0; i < s.size(); i += static_cast<std::size_t>(nd)) d.t.push_back(s.t[i]);
  d.p = decimate(s.p, nd, P.fs_hz);
  d.v = decimate(s.v, nd, P.fs_hz);
  d.a = decimate(s.a, nd, P.fs_hz);
  d.y = decimate(s.y, nd, P.fs_hz);
  d.y_fixed = decimate(s.y_fixed, nd, P.fs_hz);
  d.valid.assign(d.t.size(), 1);
}

// A force-driven axis: position filtered zero-phase, velocity and acceleration by central
// differences, the drive force as logged, the baseline's fixed part at every sample.
Prepared prepare(const Recording& rec, const ModelFile& model, const AnalysisOptions& opt) {
  Prepared P;
  for (const char* c : {"t_s", "pos_m", "drive_force_n"})
    stats::require_finite(rec, rec.column(c), c);  // column(): throws naming file and column
  const auto& t = rec.column("t_s");
  if (t.size() < 200)
    throw std::invalid_argument(rec.path + ": too short to analyse (" + std::to_string(t.size()) +
                                " rows)");
  const double dt = median_step(t);
  if (!(dt > 0)) throw std::invalid_argument(rec.path + ": t_s does not advance");
  P.fs_hz = 1.0 / dt;
  P.filter_hz = opt.filter_hz > 0 ? opt.filter_hz : 100.0;
  Signals& s = P.full;
  s.t = t;
  s.p = filtfilt_butter4(rec.column("pos_m"), P.filter_hz, P.fs_hz);
  s.v = central_diff(s.p, dt);
  s.a = central_diff2(s.p, dt);
  P.y_raw = rec.column("drive_force_n");
  P.noise_floor_n = noise_floor(P.y_raw);
  s.valid.assign(s.size(), 1);
  s.mid_m =
      0.5 * (*std::min_element(s.p.begin(), s.p.end()) + *std::max_element(s.p.begin(), s.p.end()));
  const FixedTerms fixed = fixed_terms(model, s.mid_m);
  s.y = P.y_raw;
  s.y_fixed.resize(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) s.y_fixed[i] = fixed.force(s, i);
  s.moving_speed = 0.0;
  decimate_signals(P, opt.decimation > 0 ? opt.decimation : bandwidth_decimation(P));
  return P;
}

// Columns of the decimated axis data are filtered and decimated one by one (parallel
// filtering, as the benchmark does), so a nonlinear column like sign(q̇) is low-passed too.
void decimate_columns(Prepared& P, const std::vector<int>& cols) {
  const std::size_t n = P.full.size(), nd_n = P.id.size();
  P.id_columns.resize(static_cast<Eigen::Index>(nd_n), static_cast<Eigen::Index>(cols.size()));
  std::vector<double> col(n);
  double row[kNumCols];
  for (std::size_t j = 0; j < cols.size(); ++j) {
    const std::vector<int> one{cols[j]};
    for (std::size_t i = 0; i < n; ++i) {
      fill_row(P.full, i, one, row);
      col[i] = row[0];
    }
    const auto d = decimate(col, P.decimation, P.fs_hz);
    for (std::size_t i = 0; i < nd_n; ++i)
      P.id_columns(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = d[i];
  }
}

Grams accumulate_matrix(const Prepared& P, int folds) {
  Grams g;
  g.cols = all_columns();
  const Signals& s = P.id;
  const std::size_t n = s.size();
  for (int f = 0; f < folds; ++f) {
    const std::size_t lo = n * static_cast<std::size_t>(f) / static_cast<std::size_t>(folds);
    const std::size_t hi = n * static_cast<std::size_t>(f + 1) / static_cast<std::size_t>(folds);
    Eigen::VectorXd r(static_cast<Eigen::Index>(hi - lo));
    double yy = 0;
    for (std::size_t i = lo; i < hi; ++i) {
      r[static_cast<Eigen::Index>(i - lo)] = s.y[i] - s.y_fixed[i];
      yy += s.y[i] * s.y[i];
    }
    g.add_segment(
        P.id_columns.middleRows(static_cast<Eigen::Index>(lo), static_cast<Eigen::Index>(hi - lo)),
        r, yy);
  }
  return g;
}

// Prediction of the fitted extra columns at every sample of `s` (streaming; no matrix).
std::vector<double> predict(const Signals& s, const Grams& g, const Fit& fit) {
  std::vector<int> cols;
  for (int k : fit.idx) cols.push_back(g.cols[k]);
  std::vector<double> out(s.size()), row(cols.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    fill_row(s, i, cols, row.data());
    double y = s.y_fixed[i];
    for (std::size_t j = 0; j < cols.size(); ++j)
      y += fit.theta[static_cast<Eigen::Index>(j)] * row[j];
    out[i] = y;
  }
  return out;
}

std::vector<double> predict_decimated(const Prepared& P, const Grams& g, const Fit& fit) {
  std::vector<double> out(P.id.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    double y = P.id.y_fixed[i];
    for (Eigen::Index j = 0; j < fit.theta.size(); ++j)
      y += fit.theta[j] * P.id_columns(static_cast<Eigen::Index>(i), fit.idx[j]);
    out[i] = y;
  }
  (void)g;
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
  Errors r;
  r.rms = n ? std::sqrt(e / static_cast<double>(n)) : 0.0;
  r.rel_pct = yy > 0 ? 100.0 * std::sqrt(e / yy) : 0.0;
  return r;
}

// ---------------------------------------------------------------- physical parameters
struct Params {
  Parameters values;
  bool plausible = true;
  std::string why;
};

Params physical(const std::string& id, const std::vector<int>& cols, const Eigen::VectorXd& c,
                const Signals& s, const ModelFile& model, const Fit& full, const Grams& g) {
  Params p;
  const bool act = s.actuator;
  auto coef = [&](int col) {
    for (std::size_t j = 0; j < cols.size(); ++j)
      if (cols[j] == col) return c[static_cast<Eigen::Index>(j)];
    return 0.0;
  };
  // Value of a baseline quantity: the model file's, or the fitted one when it was unknown.
  auto base = [&](const char* key, int col) {
    if (!model.fit.count(key))
      return key == std::string("nut_mass_kg")         ? model.nut_mass_kg
             : key == std::string("viscous_n_s_per_m") ? model.viscous_n_s_per_m
                                                       : model.coulomb_n;
    const int k = g.index(col);
    for (std::size_t j = 0; j < full.idx.size(); ++j)
      if (full.idx[j] == k) return full.theta[static_cast<Eigen::Index>(j)];
    return 0.0;
  };
  if (id == "coulomb_friction") {
    const double d = coef(kSign);
    set_parameter(p.values, "coulomb_n", base("coulomb_n", kSign) + d);
    p.plausible = parameter_value(p.values, "coulomb_n") >= 0;
  } else if (id == "viscous_friction") {
    const double d = coef(kVel);
    const double b = base("viscous_n_s_per_m", kVel);
    set_parameter(p.values, "viscous_n_s_per_m", b + d);
    p.plausible = b + d >= 0;
  } else if (id == "asymmetric_friction") {
    const double dv = coef(kAbsV), dc = coef(kMoving);
    auto in_full = [&](int col) {
      for (std::size_t j = 0; j < full.idx.size(); ++j)
        if (g.cols[static_cast<std::size_t>(full.idx[j])] == col)
          return full.theta[static_cast<Eigen::Index>(j)];
      return 0.0;
    };
    // The same fit written as the benchmark's direction-dependent model (no separate offset).
    const double fc =
        base("coulomb_n", kSign) + (model.fit.count("coulomb_n") ? 0.0 : in_full(kSign));
    const double fv = base("viscous_n_s_per_m", kVel) +
                      (model.fit.count("viscous_n_s_per_m") ? 0.0 : in_full(kVel));
    const double off = in_full(kOne) + dc;  // constant force in the measured-force domain
    set_parameter(p.values, "coulomb_pos_n", fc + off);
    set_parameter(p.values, "coulomb_neg_n", fc - off);
    set_parameter(p.values, "viscous_pos_n_s_per_m", fv + dv);
    set_parameter(p.values, "viscous_neg_n_s_per_m", fv - dv);
  } else if (id == "stribeck_friction") {
    for (int k = 0; k < 6; ++k)
      if (!cols.empty() && cols[0] == kStrib0 + k) {
        set_parameter(p.values, "stribeck_n", coef(kStrib0 + k));
        set_parameter(p.values, "stribeck_velocity_m_s", kStribeckVel_m_s[k]);
      }
    p.plausible = parameter_value(p.values, "stribeck_n") > 0;
  } else if (id == "offset") {
    // A force on the moving part along +p: the load cell does not see it (actuator) and the drive
    // need not supply it (axis), so both measured forces fall by it.
    set_parameter(p.values, "offset_n", -coef(kOne));
    (void)act;
  } else if (id == "spring") {
    set_parameter(p.values, "spring_n_per_m", coef(kSpring));
    set_parameter(p.values, "free_position_m", s.mid_m);
  } else if (id == "mass_error") {
    const double b = base("nut_mass_kg", kAcc);
    set_parameter(p.values, "nut_mass_kg", b + coef(kAcc));
    // A known mass wrong by more than five times itself is not a mass error but something else.
    p.plausible =
        b + coef(kAcc) > 0 && (model.fit.count("nut_mass_kg") || std::abs(coef(kAcc)) <= 5 * b);
  } else if (id == "gain_drift") {
    set_parameter(p.values, "gain_drift_per_min", coef(kDrift));
    p.plausible = std::abs(coef(kDrift)) < 1.0;
  } else if (id == "angle_ripple" || id == "position_ripple") {
    const bool ang = id == "angle_ripple";
    const double a = -coef(ang ? kSinTh : kSinP), b = -coef(ang ? kCosTh : kCosP);
    set_parameter(p.values, "amplitude_n", std::hypot(a, b));
    set_parameter(p.values, "phase_rad", std::atan2(b, a));
    if (!ang) set_parameter(p.values, "period_m", s.pos_period_m);
  } else if (id == "end_effect") {
    for (int k = 0; k < 6; ++k)
      if (!cols.empty() && cols[0] == kEnd0 + k) {
        set_parameter(p.values, "depth", -coef(kEnd0 + k));
        set_parameter(p.values, "distance_m", kEndDist_m[k]);
      }
    const double d = parameter_value(p.values, "depth");
    p.plausible = d > 0 && d <= 1.0;
  } else if (id == "backlash") {
    set_parameter(p.values, "backlash_rad", coef(kBacklash));
    p.plausible = coef(kBacklash) > 0 && coef(kBacklash) < 0.5;
  } else if (id == "sensor_delay") {
    set_parameter(p.values, "delay_s", coef(kDelay));
    p.plausible = coef(kDelay) > 0 && coef(kDelay) < 0.05;
  } else if (id == "external_disturbance") {
    set_parameter(p.values, "amplitude_n", coef(kBurst));
    p.plausible = coef(kBurst) > 0;
  } else if (id == "coupling_gain_error") {
    set_parameter(p.values, "gain_change", coef(kGain));
  } else if (id == "lead_error") {
    set_parameter(p.values, "lead_change_m", coef(kLead));
  }
  if (!p.plausible) p.why = "implausible sign or size";
  return p;
}

std::string where_text(const std::string& id, const Parameters& v, const Signals& s,
                       const std::vector<std::pair<double, double>>& bursts) {
  std::ostringstream o;
  o.precision(3);
  if (id == "coulomb_friction")
    o << "a step at every velocity reversal, constant while moving";
  else if (id == "viscous_friction")
    o << "grows in proportion to speed";
  else if (id == "asymmetric_friction")
    o << "differs between the two directions of motion";
  else if (id == "stribeck_friction")
    o << "at low speed, below about " << parameter_value(v, "stribeck_velocity_m_s") * 1e3
      << " mm/s, after break-away";
  else if (id == "offset")
    o << "everywhere, the same in both directions";
  else if (id == "spring")
    o << "grows with distance from mid-stroke (" << s.mid_m * 1e3 << " mm)";
  else if (id == "mass_error")
    o << "during accelerations";
  else if (id == "gain_drift")
    o << "grows over time, in proportion to the coupling force";
  else if (id == "angle_ripple")
    o << "once per screw turn (screw angle mod 2π)";
  else if (id == "position_ripple")
    o << "every " << s.pos_period_m * 1e3 << " mm of nut travel";
  else if (id == "end_effect")
    o << "within " << parameter_value(v, "distance_m") * 1e3 << " mm of the stroke ends";
  else if (id == "backlash")
    o << "after each reversal of the screw, in proportion to the coupling stiffness";
  else if (id == "sensor_delay")
    o << "in proportion to nut speed times coupling stiffness";
  else if (id == "external_disturbance") {
    o << bursts.size() << " isolated pulses at t =";
    for (std::size_t i = 0; i < std::min<std::size_t>(bursts.size(), 8); ++i)
      o << (i ? ", " : " ") << bursts[i].first << " s";
    if (bursts.size() > 8) o << " …";
  }
  return o.str();
}

std::vector<std::pair<double, double>> find_bursts(Signals& s, const std::vector<double>& r0,
                                                   double fs_hz, double filter_hz) {
  // Moving average over 50 ms; isolated excursions far beyond the robust spread, shorter than
  // 0.3 s, are pulses (a longer one is a different misfit, not a disturbance).
  const std::size_t n = s.size();
  const auto w = std::max<std::size_t>(1, static_cast<std::size_t>(0.05 * fs_hz));
  std::vector<double> m(n, 0.0), sample;
  double acc = 0;
  std::size_t cnt = 0;
  std::vector<double> rv(n);
  for (std::size_t i = 0; i < n; ++i) rv[i] = s.valid[i] ? r0[i] : 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    acc += rv[i];
    cnt += s.valid[i];
    if (i >= w) {
      acc -= rv[i - w];
      cnt -= s.valid[i - w];
    }
    m[i >= w / 2 ? i - w / 2 : 0] = cnt ? acc / static_cast<double>(cnt) : 0.0;
  }
  for (std::size_t i = 0; i < n; i += 7)
    if (s.valid[i]) sample.push_back(m[i]);
  const double sig = robust_sigma(sample);
  std::vector<std::pair<double, double>> out;
  s.burst.assign(n, 0.0);
  if (!(sig > 0)) return out;
  const double thr = 8.0 * sig;
  for (std::size_t i = 0; i < n;) {
    if (!(s.valid[i] && std::abs(m[i]) > thr)) {
      ++i;
      continue;
    }
    std::size_t j = i;
    double peak = 0;
    while (j < n && std::abs(m[j]) > 0.5 * thr) {
      if (std::abs(m[j]) > std::abs(peak)) peak = m[j];
      ++j;
    }
    std::size_t i0 = i;
    while (i0 > 0 && std::abs(m[i0 - 1]) > 0.5 * thr) --i0;
    if (static_cast<double>(j - i0) / fs_hz < 0.3) {
      out.emplace_back(s.t[i0], peak);
      // The pulse itself: where the smoothed residual is above half its peak (full width at
      // half maximum of a smoothed rectangle is the rectangle).
      for (std::size_t k = i0; k < j; ++k)
        if (std::abs(m[k]) >= 0.5 * std::abs(peak)) s.burst[k] = sgn(peak);  // coefficient: size
    }
    i = j + 1;
  }
  // The measured force was low-passed: so is the pulse column (parallel filtering).
  if (filter_hz > 0 && !out.empty()) s.burst = filtfilt_butter4(s.burst, filter_hz, fs_hz);
  return out;
}

// Dominant period of the residual against nut position (binned, weighted sine fits).
double scan_position_period(const Signals& s, const std::vector<double>& r0, double* amp) {
  double lo = 1e9, hi = -1e9;
  for (std::size_t i = 0; i < s.size(); ++i)
    if (s.valid[i]) {
      lo = std::min(lo, s.p[i]);
      hi = std::max(hi, s.p[i]);
    }
  *amp = 0.0;
  if (!(hi - lo > 2e-3)) return 0.005;
  const int nb = std::clamp(static_cast<int>((hi - lo) / 50e-6), 20, 4000);
  const auto b = bin(s.p, r0, s.valid, lo, hi, nb);
  double best = 0.0, best_p = 0.005;
  for (double per = 1e-3; per <= std::min(20e-3, 0.5 * (hi - lo)); per *= 1.005) {
    // With a straight line beside the sine, so a spring-like trend does not pose as a period.
    Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
    Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
    for (int k = 0; k < nb; ++k) {
      if (b.count[k] < 1) continue;
      const double w = std::sqrt(b.count[k]);  // damp bins with many samples a little
      const Eigen::Vector4d x(1.0, (b.centre[k] - 0.5 * (lo + hi)) / (hi - lo),
                              std::sin(2 * kPi * b.centre[k] / per),
                              std::cos(2 * kPi * b.centre[k] / per));
      a += w * x * x.transpose();
      rhs += w * x * b.mean[k];
    }
    const Eigen::Vector4d c = a.ldlt().solve(rhs);
    const double amp_k = std::hypot(c[2], c[3]);
    if (amp_k > best) {
      best = amp_k;
      best_p = per;
    }
  }
  *amp = best;
  return best_p;
}

// ---------------------------------------------------------------- the axis analysis, in stages
// Everything one axis analysis works on, shared by its stages.
struct AxisRun {
  const Recording& rec;
  const ModelFile& model;
  const AnalysisOptions& opt;
  Prepared P;
  Signals* S = nullptr;  // P.id when decimated, else P.full (no copy: an hour is 3.6 M samples)
  int folds = 3;
  std::vector<int> base_cols;         // baseline terms whose values are unknown (fit = true)
  std::set<std::string> in_baseline;  // effects the model has already: not candidates again
  std::vector<std::pair<double, double>> bursts;
  Grams g;
  double yy_total = 0, n_total = 0;
  AxisRun(const Recording& r, const ModelFile& m, const AnalysisOptions& o)
      : rec(r), model(m), opt(o) {}
  void progress(const std::string& stage, double f) const {
    if (opt.progress) opt.progress(stage, f);
  }
};

void baseline_columns(AxisRun& run) {
  const auto& fit = run.model.fit;
  if (fit.count("nut_mass_kg")) run.base_cols.push_back(kAcc), run.in_baseline.insert("mass_error");
  if (fit.count("viscous_n_s_per_m"))
    run.base_cols.push_back(kVel), run.in_baseline.insert("viscous_friction");
  if (fit.count("coulomb_n"))
    run.base_cols.push_back(kSign), run.in_baseline.insert("coulomb_friction");
  // Terms the model already has are not candidates again (their values are taken as given).
  for (const auto& t : run.model.terms)
    if (t.enabled) run.in_baseline.insert(t.id);
}

std::vector<int> indices(const Grams& g, const std::vector<int>& cols) {
  std::vector<int> idx;
  idx.reserve(cols.size());
  for (int c : cols) idx.push_back(g.index(c));
  return idx;
}

std::vector<double> predict_any(const AxisRun& run, const Grams& g, const Fit& fit) {
  return run.P.decimated ? predict_decimated(run.P, g, fit) : predict(*run.S, g, fit);
}

// The baseline fit alone first: its residual is where the detectors look (the position ripple's
// period, isolated pulses); both become columns of the selection.
void locate_structure(AxisRun& run) {
  Signals& S = *run.S;
  std::vector<double> r0(S.size()), r_scan(S.size());
  // The friction terms every drive has (Coulomb, offset, direction-dependent) dwarf a position
  // ripple in the baseline residual: the ripple's period is looked for once they are out.
  std::vector<int> rich = run.base_cols;
  for (int c : {kSign, kOne, kAbsV, kMoving, kVel})
    if (std::find(rich.begin(), rich.end(), c) == rich.end()) rich.push_back(c);
  Grams gb;
  if (run.P.decimated) {
    decimate_columns(run.P, all_columns());
    gb = accumulate_matrix(run.P, run.folds);
  } else {
    gb = accumulate(S, rich, run.folds, [&](double f) { run.progress("baseline", f); });
  }
  const auto yb = predict_any(run, gb, fit_all(gb, indices(gb, run.base_cols)));
  const auto yr = predict_any(run, gb, fit_all(gb, indices(gb, rich)));
  for (std::size_t i = 0; i < S.size(); ++i) r0[i] = S.y[i] - yb[i], r_scan[i] = S.y[i] - yr[i];
  double pos_amp = 0;
  S.pos_period_m = scan_position_period(S, r_scan, &pos_amp);
  run.P.full.pos_period_m = S.pos_period_m;
  run.bursts = find_bursts(S, r0, run.P.fs_hz / run.P.decimation, 0.0);
  if (run.P.decimated) {
    run.P.full.burst.assign(run.P.full.size(), 0.0);
    decimate_columns(run.P, all_columns());  // now with the period and the bursts
  }
}

// One pass: per-segment Grams of every column.
void accumulate_all(AxisRun& run) {
  run.g = run.P.decimated ? accumulate_matrix(run.P, run.folds)
                          : accumulate(*run.S, all_columns(), run.folds,
                                       [&](double f) { run.progress("gram", f); });
  for (std::size_t f = 0; f < run.g.folds(); ++f) {
    run.yy_total += run.g.yy[f];
    run.n_total += static_cast<double>(run.g.n[f]);
  }
  if (run.n_total < 100)
    throw std::invalid_argument(run.rec.path +
                                ": fewer than 100 usable samples (the axis hardly moves)");
}

// ---------------------------------------------------------------- forward selection
struct Chosen {
  std::string id;
  std::vector<int> cols;  // kinds
  double gain_pct, t_stat, improvement_pct;
  int folds_improved;
  std::vector<Alternative> alternatives;
  std::string note;
  double explained_n = 0, worst = 0;
};

struct Trial {
  std::string id;
  std::vector<int> cols;
  Score sc;
  double gain = 0, t = 0, worst = 0;  // worst: the worst segment's relative gain [%]
  int improved = 0;
  std::size_t ncols = 0;
};

struct Selected {
  std::vector<int> current;  // Gram positions of the baseline and every chosen column
  std::vector<Chosen> chosen;
  std::vector<ValidationStep> validation;
  std::vector<Rejected> rejected;
  double base_heldout = 0;
};

ValidationStep validation_step(const AxisRun& run, const std::string& name, const Score& sc,
                               const std::vector<int>& idx) {
  const Fit f = fit_all(run.g, idx);
  double in = 0;
  for (std::size_t k = 0; k < run.g.xx.size(); ++k) in += sse(run.g, f, k);
  return ValidationStep{name, std::sqrt(sc.total / run.n_total),
                        100.0 * std::sqrt(sc.total / run.yy_total), std::sqrt(in / run.n_total),
                        100.0 * std::sqrt(in / run.yy_total)};
}

// The candidate's best plausible variant by held-out error (nothing if none is plausible).
std::optional<Trial> best_variant(const AxisRun& run, const Candidate& cand,
                                  const std::vector<int>& current) {
  const Grams& g = run.g;
  Trial best;
  best.sc.total = INFINITY;
  for (const auto& var_all : cand.variants) {
    // Columns the model already spans (the constant part of direction-dependent friction
    // once an offset is in) add nothing the data can tell apart: leave them out.
    std::vector<int> var;
    for (int c : var_all)
      if (current.empty() ||
          partial_r2(g, {}, {g.index(c)}, Eigen::VectorXd::Ones(1), current) < 0.999)
        var.push_back(c);
    if (var.empty()) continue;
    std::vector<int> idx = current;
    for (int c : var) idx.push_back(g.index(c));
    Score sc = heldout(g, idx);
    const Fit f = fit_all(g, idx);
    Eigen::VectorXd cv = f.theta.tail(static_cast<Eigen::Index>(var.size()));
    const Params pp = physical(cand.id, var, cv, *run.S, run.model, f, g);
    if (!pp.plausible) continue;  // a term must make physical sense to explain anything
    if (sc.total < best.sc.total) best = Trial{cand.id, var, sc, 0, 0, 0, 0, var.size()};
  }
  if (!std::isfinite(best.sc.total)) return std::nullopt;
  return best;
}

// Consistency over the segments: t statistic of the per-segment relative gains (relative, so an
// effect that grows over time counts in early segments too), the worst segment, the total gain.
void score_trial(Trial& t, const Score& cur) {
  std::vector<double> d;
  for (std::size_t f = 0; f < cur.heldout_sse.size(); ++f) {
    if (!(cur.heldout_sse[f] > 0)) continue;
    d.push_back((cur.heldout_sse[f] - t.sc.heldout_sse[f]) / cur.heldout_sse[f]);
    if (d.back() > 0) ++t.improved;
  }
  t.t = stats::t_statistic(d);
  t.worst = d.empty() ? 0.0 : 100.0 * *std::min_element(d.begin(), d.end());
  t.gain = 100.0 * (cur.total - t.sc.total) / cur.total;
}

std::vector<Trial> trials_of(const AxisRun& run, const std::vector<Candidate>& library,
                             const std::set<std::string>& used, const std::vector<int>& current,
                             const Score& cur) {
  std::vector<Trial> trials;
  for (const auto& cand : library) {
    if (!cand.selectable || used.count(cand.id) || cand.actuator_only) continue;
    if (cand.id == "external_disturbance" && run.bursts.size() < 2) continue;
    auto best = best_variant(run, cand, current);
    if (!best) continue;
    score_trial(*best, cur);
    trials.push_back(std::move(*best));
  }
  // Best (lowest held-out error) first.
  std::sort(trials.begin(), trials.end(),
            [](const Trial& a, const Trial& b) { return a.sc.total < b.sc.total; });
  return trials;
}

// Root-mean-square force a trial explains on top of the current model.
double explained_n(const AxisRun& run, const Score& cur, const Trial& tr) {
  return std::sqrt(std::max(0.0, cur.total - tr.sc.total) / run.n_total);
}

// Significant: a real share of the held-out error, consistent over the segments, and larger
// than the force sensor's own noise per sample (below that a "term" only fits the small
// structure every model leaves: quantization, filter edges). A localized effect (pulses)
// improves only the segments where it occurs: a large total gain that makes no segment worse
// counts as consistent too.
bool significant(const AxisRun& run, const Score& cur, const Trial& tr) {
  const auto& opt = run.opt;
  const bool consistent =
      tr.t >= opt.min_t || (tr.gain >= 10.0 * opt.min_gain_pct && tr.worst > -1.0);
  return tr.gain >= opt.min_gain_pct && consistent &&
         explained_n(run, cur, tr) >= run.P.noise_floor_n;
}

// Parsimony among nested alternatives: a simpler candidate that lies (almost) inside the best
// one's span and brings at least half its gain goes first; the rest is tested next.
std::size_t parsimony_pick(const AxisRun& run, const std::vector<Trial>& trials,
                           const std::vector<int>& current, const Score& cur) {
  const Grams& g = run.g;
  for (std::size_t k = 1; k < trials.size(); ++k) {
    const auto& a = trials[k];
    if (!significant(run, cur, a) || a.ncols >= trials[0].ncols || a.gain < 0.5 * trials[0].gain)
      continue;
    const std::vector<int> aidx = indices(g, a.cols);
    std::vector<int> with = current;
    with.insert(with.end(), aidx.begin(), aidx.end());
    const Eigen::VectorXd wa = fit_all(g, with).theta.tail(static_cast<Eigen::Index>(aidx.size()));
    if (partial_r2(g, current, aidx, wa, indices(g, trials[0].cols)) > 0.98) return k;
  }
  return 0;
}

// Identifiability: other candidates reproducing the chosen term's contribution are named with it.
std::vector<Alternative> alternatives_of(const AxisRun& run, const std::vector<Candidate>& library,
                                         const std::set<std::string>& used, const Trial& tr,
                                         const std::vector<int>& current) {
  const Grams& g = run.g;
  std::vector<int> idx = current;
  const std::vector<int> tidx = indices(g, tr.cols);
  idx.insert(idx.end(), tidx.begin(), tidx.end());
  const Eigen::VectorXd w = fit_all(g, idx).theta.tail(static_cast<Eigen::Index>(tr.cols.size()));
  std::vector<Alternative> out;
  for (const auto& cand : library) {
    if (cand.id == tr.id || cand.actuator_only || used.count(cand.id)) continue;
    double best_r2 = 0;
    std::vector<int> best_var;
    for (const auto& var : cand.variants) {
      const double r2 = partial_r2(g, current, tidx, w, indices(g, var));
      if (r2 > best_r2) best_r2 = r2, best_var = var;
    }
    if (best_r2 <= 0.9) continue;
    std::vector<int> aidx = current;
    for (int c : best_var) aidx.push_back(g.index(c));
    const Fit fa = fit_all(g, aidx);
    const Params pa =
        physical(cand.id, best_var, fa.theta.tail(static_cast<Eigen::Index>(best_var.size())),
                 *run.S, run.model, fa, g);
    out.push_back({cand.id, pa.values, 100.0 * best_r2, pa.plausible});
  }
  return out;
}

Selected select_terms(const AxisRun& run) {
  const auto library = candidate_library();
  Selected sel;
  sel.current = indices(run.g, run.base_cols);
  Score cur = heldout(run.g, sel.current);
  sel.base_heldout = cur.total;
  sel.validation.push_back(validation_step(run, "baseline", cur, sel.current));
  std::set<std::string> used(run.in_baseline.begin(), run.in_baseline.end());
  for (int step = 0; step < run.opt.max_terms; ++step) {
    run.progress("selection", static_cast<double>(step) / run.opt.max_terms);
    const auto trials = trials_of(run, library, used, sel.current, cur);
    if (trials.empty()) break;
    if (!significant(run, cur, trials.front())) {
      const auto& tb = trials.front();
      sel.rejected.push_back({tb.id, tb.gain, tb.t, tb.worst, explained_n(run, cur, tb),
                              "best remaining candidate, below the significance threshold",
                              std::nullopt});
      break;
    }
    const std::size_t pick = parsimony_pick(run, trials, sel.current, cur);
    const Trial& tr = trials[pick];
    Chosen ch{tr.id,   tr.cols, tr.gain, tr.t, 0, tr.improved, {}, "", explained_n(run, cur, tr),
              tr.worst};
    ch.alternatives = alternatives_of(run, library, used, tr, sel.current);
    for (int c : tr.cols) sel.current.push_back(run.g.index(c));
    const Score next = heldout(run.g, sel.current);
    ch.improvement_pct = 100.0 * (1.0 - std::sqrt(next.total / cur.total));
    if (pick != 0)
      ch.note =
          "chosen before '" + trials[0].id + "', which contains it: the simpler explanation first";
    sel.chosen.push_back(ch);
    used.insert(tr.id);
    cur = next;
    sel.validation.push_back(validation_step(run, "+ " + tr.id, cur, sel.current));
  }
  run.progress("selection", 1.0);
  return sel;
}

// ---------------------------------------------------------------- findings
struct Predictions {
  Fit base_fit, final_fit;
  std::vector<double> yb, yf;  // at the identification samples
  Errors eb, ef, eb_full, ef_full;
};

Predictions predictions(AxisRun& run, const Selected& sel) {
  Predictions p;
  const Grams& g = run.g;
  Signals& S = *run.S;
  p.final_fit = fit_all(g, sel.current);
  p.base_fit = fit_all(g, indices(g, run.base_cols));
  p.yb = predict_any(run, g, p.base_fit);
  p.yf = predict_any(run, g, p.final_fit);
  p.eb = errors(S.y, p.yb, S.valid);
  p.ef = errors(S.y, p.yf, S.valid);
  // Full rate: raw force against the model evaluated on every sample (undecimated).
  Signals& F = run.P.full;
  const auto yb_full = run.P.decimated ? predict(F, g, p.base_fit) : p.yb;
  const auto yf_full = run.P.decimated ? predict(F, g, p.final_fit) : p.yf;
  p.eb_full = errors(run.P.y_raw, yb_full, F.valid);
  p.ef_full = errors(run.P.y_raw, yf_full, F.valid);
  return p;
}

std::string fmt(double v) {
  std::ostringstream o;
  o << v;
  return o.str();
}

void describe_method(Findings& J, const AxisRun& run) {
  J.method.domain = "force (inverse model: measured force predicted from measured motion)";
  J.method.filter = "4th-order Butterworth, zero phase (forward-backward), position at " +
                    fmt(run.P.filter_hz) + " Hz; central differences";
  J.method.decimation = run.P.decimation;
  J.method.identification_bandwidth_hz = run.P.bandwidth_hz;
  J.method.folds = run.folds;
  J.method.selection =
      "forward, by held-out error on contiguous time segments; a term must cut the "
      "held-out mean square error by >= " +
      fmt(run.opt.min_gain_pct) + " % with t >= " + fmt(run.opt.min_t) +
      " over the segments (or >= 10x that gain with no segment worse), and explain "
      "more RMS than the force noise floor";
  J.method.moving_only = "all samples";
  J.noise_floor_n = run.P.noise_floor_n;
}

// The baseline's unknown values (fit = true) as the fit gives them.
Parameters fitted_base(const AxisRun& run, const Fit& fit) {
  Parameters b;
  for (const int c : run.base_cols) {
    double v = 0;
    for (std::size_t k = 0; k < fit.idx.size(); ++k)
      if (fit.idx[k] == run.g.index(c)) v = fit.theta[static_cast<Eigen::Index>(k)];
    set_parameter(b,
                  c == kAcc    ? "nut_mass_kg"
                  : c == kVel  ? "viscous_n_s_per_m"
                  : c == kSign ? "coulomb_n"
                               : "offset_n",
                  v);
  }
  return b;
}

EffectFinding finding_of(const AxisRun& run, const Chosen& ch, const Params& pp) {
  EffectFinding e;
  e.id = ch.id;
  e.parameters = pp.values;
  e.where = where_text(ch.id, pp.values, *run.S, run.bursts);
  e.evidence.heldout_gain_pct = ch.gain_pct;
  e.evidence.t_stat = ch.t_stat;
  e.evidence.segments_improved =
      std::to_string(ch.folds_improved) + "/" + std::to_string(run.folds);
  e.evidence.explained_rms_n = ch.explained_n;
  e.evidence.worst_segment_pct = ch.worst;
  e.evidence.noise_floor_n = run.P.noise_floor_n;
  e.evidence.plausible = pp.plausible;
  e.improvement_pct = ch.improvement_pct;
  e.identifiable = ch.alternatives.empty();
  if (!ch.alternatives.empty()) {
    e.alternatives = ch.alternatives;
    std::string names = ch.id;
    for (const auto& a : ch.alternatives) names += " or " + a.id;
    e.finding = "one combined finding: the data cannot tell " + names + " apart";
  }
  e.note = ch.note;
  return e;
}

void fill_findings(Findings& J, const AxisRun& run, const Selected& sel, const Predictions& p) {
  J.recording = run.rec.path;
  J.system = run.model.system;
  J.samples = run.rec.rows();
  J.samples_used = static_cast<std::size_t>(run.n_total);
  describe_method(J, run);
  J.baseline = {p.eb.rms,
                p.eb.rel_pct,
                p.eb_full.rms,
                p.eb_full.rel_pct,
                std::sqrt(sel.base_heldout / run.n_total),
                fitted_base(run, p.base_fit)};
  std::size_t off = run.base_cols.size();
  for (const auto& ch : sel.chosen) {
    const Eigen::VectorXd c = p.final_fit.theta.segment(static_cast<Eigen::Index>(off),
                                                        static_cast<Eigen::Index>(ch.cols.size()));
    off += ch.cols.size();
    J.effects.push_back(
        finding_of(run, ch, physical(ch.id, ch.cols, c, *run.S, run.model, p.final_fit, run.g)));
  }
  J.nothing_missing = sel.chosen.empty();
  J.conclusion =
      sel.chosen.empty()
          ? "nothing is missing: no candidate effect lowers the held-out error significantly"
          : std::to_string(sel.chosen.size()) + " effect(s) found";
  J.not_selected = sel.rejected;
  J.final_fit = {p.ef.rms,          p.ef.rel_pct, p.ef_full.rms,
                 p.ef_full.rel_pct, std::nullopt, fitted_base(run, p.final_fit)};
  J.validation = sel.validation;
  for (const auto& [ts, amp] : run.bursts) {
    Event ev;
    ev.type = "isolated_disturbance";
    ev.t_s = ts;
    ev.residual_n = amp;
    J.events.push_back(ev);
  }
}

// ---------------------------------------------------------------- localisation
// Residuals before and after at the identification samples, and what the maps draw on.
struct Residuals {
  std::vector<double> before, after;
  double rms0 = 0;  // baseline RMS
};

void add_map(AnalysisResult& R, const Signals& S, const Residuals& res, const std::string& name,
             const std::vector<double>& x, const std::string& label, const std::string& unit,
             double scale, std::pair<double, double> range, int nb) {
  const auto b0 = bin(x, res.before, S.valid, range.first, range.second, nb);
  const auto b1 = bin(x, res.after, S.valid, range.first, range.second, nb);
  const std::string text = describe_regions(b0, label, unit, scale, res.rms0);
  if (!text.empty()) R.where.push_back(text);
  Figure fig;
  fig.file = "map_" + name + ".png";
  // The finding already names where ("over velocity: …"): the caption does not repeat it.
  fig.caption = text.empty() ? "Mean residual (measured - model) over " + label
                             : "Mean residual (measured - model) " + text;
  fig.charts.push_back({"Mean residual over " + label,
                        label + " [" + unit + "]",
                        "residual [N]",
                        {to_series("baseline", b0, scale), to_series("corrected", b1, scale)}});
  R.figures.push_back(fig);
}

// Direction dependence in words.
std::string direction_text(const Signals& S, const Residuals& res) {
  double sp = 0, sn = 0, np = 0, nn = 0;
  for (std::size_t i = 0; i < S.size(); ++i) {
    if (!S.valid[i]) continue;
    if (S.v[i] > 0) sp += res.before[i], ++np;
    if (S.v[i] < 0) sn += res.before[i], ++nn;
  }
  if (!(np > 0 && nn > 0)) return "";
  std::ostringstream o;
  o.precision(3);
  o << "by direction: mean residual " << std::showpos << sp / np << " N moving +, " << sn / nn
    << " N moving −" << std::noshowpos;
  if (std::abs(sp / np - sn / nn) > 0.3 * res.rms0) o << " (jumps at velocity reversals)";
  return o.str();
}

void residual_maps(AnalysisResult& R, const Signals& S, const Residuals& res) {
  add_map(R, S, res, "velocity", S.v, "velocity", "mm/s", 1e3,
          percentile_range(S.v, S.valid, 0.005), 60);
  if (auto d = direction_text(S, res); !d.empty()) R.where.push_back(d);
  add_map(R, S, res, "position", S.p, "position", "mm", 1e3, percentile_range(S.p, S.valid, 0.0),
          80);
}

// Residual RMS in time windows, before and after.
struct Windows {
  double win_s = 1.0;
  Curve before{"baseline", {}, {}}, after{"corrected", {}, {}};
};

Windows windowed_rms(const Signals& S, const Residuals& res) {
  Windows w;
  w.win_s = std::max(1.0, (S.t.back() - S.t.front()) / 400.0);
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
    if (c > 10) {
      w.before.x.push_back(t0 + w.win_s / 2);
      w.before.y.push_back(std::sqrt(e0 / static_cast<double>(c)));
      w.after.x.push_back(t0 + w.win_s / 2);
      w.after.y.push_back(std::sqrt(e1 / static_cast<double>(c)));
    }
    i = j;
  }
  return w;
}

// Growth over time, and windows far above the median (events).
void residual_over_time(AnalysisResult& R, const Signals& S, const Residuals& res,
                        double noise_floor_n) {
  const Windows w = windowed_rms(S, res);
  const auto& wr = w.before.y;
  const double win = w.win_s;
  if (wr.size() >= 6) {
    const std::size_t q = wr.size() / 3;
    const double first =
        std::accumulate(wr.begin(), wr.begin() + static_cast<std::ptrdiff_t>(q), 0.0) /
        static_cast<double>(q);
    const double last = std::accumulate(wr.end() - static_cast<std::ptrdiff_t>(q), wr.end(), 0.0) /
                        static_cast<double>(q);
    std::ostringstream o;
    o.precision(3);
    if (last > 1.5 * first && last > 0.3 * res.rms0) {
      o << "over time: the residual grows (RMS " << first << " N in the first third, " << last
        << " N in the last)";
      R.where.push_back(o.str());
    }
    std::vector<double> sorted = wr;
    std::sort(sorted.begin(), sorted.end());
    const double med = sorted[sorted.size() / 2];
    int shown = 0;
    std::ostringstream w2;
    w2.precision(4);
    for (std::size_t k = 0; k < wr.size() && shown < 6; ++k)
      if (wr[k] > 3 * med && wr[k] > noise_floor_n * 3) {
        w2 << (shown ? ", " : "") << w.before.x[k] - win / 2 << "–" << w.before.x[k] + win / 2
           << " s";
        Event ev;
        ev.type = "misfit_window";
        ev.t_s = w.before.x[k] - win / 2;
        ev.duration_s = win;
        ev.rms_n = wr[k];
        R.findings.events.push_back(ev);
        ++shown;
      }
    if (shown)
      R.where.push_back("in time: windows with residual RMS over 3× the median: " + w2.str());
  }
  Figure ft;
  ft.file = "residual_time.png";
  ft.caption = "Residual RMS in time windows";
  ft.charts.push_back({"Residual RMS over time", "time [s]", "RMS [N]", {w.before, w.after}});
  R.figures.push_back(ft);
}

using Onsets = std::vector<std::pair<std::size_t, double>>;  // sample, signed direction

// The residual averaged around events (signed by the new direction), before and after.
void locked_average(AnalysisResult& R, const Signals& S, const Residuals& res, double fs_id,
                    const Onsets& at, const std::string& file, const std::string& what) {
  const int half = static_cast<int>(0.15 * fs_id);
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
  fr.file = file;
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
  fr.charts.push_back(
      {"Residual locked to " + what, "time from event [ms]", "residual x direction [N]", {s0, s1}});
  R.figures.push_back(fr);
}

Onsets reversals(const Signals& S) {
  Onsets rev;
  double last_dir = 0;
  for (std::size_t i = 0; i < S.size(); ++i) {
    const double d = std::abs(S.v[i]) > std::max(S.moving_speed, 1e-6) ? sgn(S.v[i]) : 0.0;
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
    if (std::isfinite(d) && std::abs(d) > 0.05 * (hi - lo) && hi > lo)
      edges.emplace_back(i / static_cast<std::size_t>(decimation), sgn(d));
  }
  return edges;
}

// Event-locked averages: the residual around velocity reversals and input edges.
void event_locked(AnalysisResult& R, const AxisRun& run, const Residuals& res) {
  const Signals& S = *run.S;
  const double fs_id = run.P.fs_hz / run.P.decimation;
  const Onsets rev = reversals(S);
  locked_average(R, S, res, fs_id, rev, "reversal_locked.png", "velocity reversals");
  R.findings.reversals = rev.size();
  // Input edges: steps in a setpoint column, if the recording has one.
  for (const char* col : {"force_set_n", "pos_set_m", "ref_pos_m"}) {
    if (!run.rec.has(col)) continue;
    const Onsets edges = input_edges(run.rec.column(col), run.P.decimation);
    if (!edges.empty()) {
      locked_average(R, S, res, fs_id, edges, std::string("edge_locked_") + col + ".png",
                     std::string("steps of ") + col);
      R.findings.input_edges = edges.size();
    }
    break;
  }
}

// Measured force with both models over time, the held-out error per step, and the fit over time
// (the page's interactive chart, as the actuator path gives it).
void time_figures(AnalysisResult& R, const Signals& S, const Predictions& p, const Residuals& res,
                  bool added) {
  const std::size_t step = std::max<std::size_t>(1, S.size() / 6000);
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
  f.file = "force_time.png";
  f.caption = "Measured force and the models' predictions from measured motion; residuals below";
  f.charts.push_back({"Force", "time [s]", "force [N]", {m, b, c}});
  f.charts.push_back({"Residual (measured - model)", "time [s]", "residual [N]", {rb, rc}});
  R.figures.insert(R.figures.begin(), f);
  Figure v;
  v.file = "heldout.png";
  v.caption = "Held-out RMS error after each added term";
  Curve hs{"held-out RMS", {}, {}};
  for (std::size_t k = 0; k < R.findings.validation.size(); ++k) {
    hs.x.push_back(static_cast<double>(k));
    hs.y.push_back(R.findings.validation[k].heldout_rms_n);
  }
  v.charts.push_back({"Held-out error per step (0 = baseline)", "terms added", "RMS [N]", {hs}});
  R.figures.insert(R.figures.begin() + 1, v);
  R.fit_over_time = {"The fit before and after",
                     "time [s]",
                     "missing force [N]",
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

// One finding into the model: baseline values or a term in the model file's form.
void apply_finding(ModelFile& M, const EffectFinding& e, bool& has_asym) {
  const std::string& id = e.id;
  auto val = [&](const char* k) { return parameter_value(e.parameters, k); };
  auto add = [&](const std::vector<std::pair<std::string, double>>& kv) {
    auto& t = M.term(id);
    t.enabled = true;
    t.note = term_note(e);
    for (const auto& [k, v] : kv) t.set(k, v);
  };
  if (id == "mass_error")
    M.nut_mass_kg = val("nut_mass_kg");
  else if (id == "coulomb_friction")
    M.coulomb_n = val("coulomb_n");
  else if (id == "viscous_friction")
    M.viscous_n_s_per_m = val("viscous_n_s_per_m");
  else if (id == "asymmetric_friction") {
    // The benchmark's direction-dependent form: it already holds any constant force, so a
    // separate offset finding is not written beside it.
    add({{"coulomb_pos_n", val("coulomb_pos_n")},
         {"coulomb_neg_n", val("coulomb_neg_n")},
         {"viscous_pos_n_s_per_m", val("viscous_pos_n_s_per_m")},
         {"viscous_neg_n_s_per_m", val("viscous_neg_n_s_per_m")}});
    std::erase_if(M.terms, [](const ModelTerm& t) { return t.id == "offset"; });
    has_asym = true;
  } else if (id == "offset" && !has_asym)
    add({{"offset_n", val("offset_n")}});
  else if (id == "stribeck_friction")
    add({{"breakaway_n", M.coulomb_n + val("stribeck_n")},
         {"coulomb_n", M.coulomb_n},
         {"stribeck_velocity_m_s", val("stribeck_velocity_m_s")}});
  else if (id == "spring")
    add({{"stiffness_n_per_m", val("spring_n_per_m")},
         {"rest_position_m", val("free_position_m")}});
  else if (id == "position_ripple")
    add({{"amplitude_n", val("amplitude_n")},
         {"period_m", val("period_m")},
         {"phase_rad", val("phase_rad")}});
}

ModelFile corrected_model(const AxisRun& run, const Findings& J, const Fit& final_fit) {
  ModelFile M = run.model;
  M.fit.clear();  // the corrected model is a model: every value fixed, as fitted here
  for (const auto& [name, value, is_count] : fitted_base(run, final_fit)) {
    if (name == "nut_mass_kg") M.nut_mass_kg = value;
    if (name == "viscous_n_s_per_m") M.viscous_n_s_per_m = value;
    if (name == "coulomb_n") M.coulomb_n = value;
  }
  bool has_asym = false;
  for (const auto& e : J.effects) apply_finding(M, e, has_asym);
  M.source = (run.model.source.empty() ? std::string("baseline") : run.model.source) +
             "; corrected by maglead analyze from " + run.rec.path;
  return M;
}

// A force-driven axis (EMPS): prepare → locate → select → findings, maps, corrected model.
AnalysisResult analyze_axis(const Recording& rec, const ModelFile& model,
                            const AnalysisOptions& opt) {
  AxisRun run(rec, model, opt);
  run.progress("prepare", 0.0);
  run.P = prepare(rec, model, opt);
  run.S = run.P.decimated ? &run.P.id : &run.P.full;
  run.folds = std::max(3, opt.folds);
  run.progress("prepare", 1.0);
  baseline_columns(run);
  locate_structure(run);
  accumulate_all(run);
  const Selected sel = select_terms(run);
  const Predictions p = predictions(run, sel);
  AnalysisResult R;
  fill_findings(R.findings, run, sel, p);
  const Signals& S = *run.S;
  Residuals res{std::vector<double>(S.size()), std::vector<double>(S.size()), p.eb.rms};
  for (std::size_t i = 0; i < S.size(); ++i) {
    res.before[i] = S.y[i] - p.yb[i];
    res.after[i] = S.y[i] - p.yf[i];
  }
  residual_maps(R, S, res);
  residual_over_time(R, S, res, run.P.noise_floor_n);
  event_locked(R, run, res);
  time_figures(R, S, p, res, !sel.chosen.empty());
  R.corrected = corrected_model(run, R.findings, p.final_fit);
  R.findings.twin_simulation = TwinSimulation{};
  R.findings.twin_simulation->reason =
      "the twin models the magnetic actuator; this is a force-driven axis";
  run.progress("done", 1.0);
  return R;
}

}  // namespace

AnalysisResult analyze_recording(const Recording& rec, const ModelFile& model,
                                 const ForceCalibration& cal, const ActuatorParams& act,
                                 const AnalysisOptions& opt) {
  if (model.system == "actuator") return analyze_actuator(rec, model, cal, act, opt);
  return analyze_axis(rec, model, opt);
}

}  // namespace maglead::analysis
