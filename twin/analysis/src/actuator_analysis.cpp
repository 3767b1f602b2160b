// The actuator analysis as stages: prepare (filtered states and the baseline's force residual on
// sliding samples) → locate → select (forward selection of effect units on held-out time
// segments) → break-away test on stuck episodes → refit and validate → events. Every law and
// regressor comes from the effect library (effects/); nothing here knows an effect's formula.
#include "actuator_analysis.hpp"
#include "maglead/analysis/reading.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <tuple>

#include "candidates.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/analysis/signal.hpp"
#include "pulses.hpp"
#include "selection.hpp"
#include "statistics.hpp"

namespace maglead::analysis::actuator {
namespace {

constexpr double kPi = std::numbers::pi;
// The filter's impulse response has died out within this many filter periods either side.
constexpr double kResponseFilterPeriods = 8.0;
// A mass no model has: guards the ringing frequency against a zero mass.
constexpr double kLeastMass_kg = 1e-9;
using effects::State;
using stats::median_of;
using stats::require_finite;
using stats::robust_sigma;

// Coupling force on the nut, F_m = −F̂_s, at every phase (ForceCalibration::load_force_n).
struct Coupling {
  const ForceCalibration& cal;
  double force(double phi) const { return -cal.load_force_n(phi); }
  double slope(double phi) const { return -cal.slope_n_per_rad(phi); }
};

// Step-outs from the raw phase: a slip carries φ past ±π from the branch it sat on.
template <class Phase>
std::vector<SlipEvent> find_slips(const std::vector<double>& t, const Phase& phi) {
  std::vector<SlipEvent> out;
  if (phi.size() == 0) return out;
  double branch = 2 * kPi * std::round(phi[0] / (2 * kPi));
  std::size_t left_stable = 0;  // last sample inside the stable branch
  for (std::size_t i = 0; i < phi.size(); ++i) {
    const double rel = phi[i] - branch;
    if (std::abs(rel) <= kPi / 2) left_stable = i;
    if (std::abs(rel) > kPi) {
      const double new_branch = 2 * kPi * std::round(phi[i] / (2 * kPi));
      const int leads = static_cast<int>(std::lround((new_branch - branch) / (2 * kPi)));
      out.push_back({t[i], t[left_stable], leads});
      branch = new_branch;
    }
  }
  return out;
}

// Least-squares slope of the raw net driving force (coupling + load) over the last `window_s`
// of a stuck episode [first, last]: how fast the force that will break the nut loose rises.
template <class Phase>
double rising_rate(const std::vector<double>& t, const Phase& phi, const std::vector<double>& load,
                   const Coupling& cp, std::size_t first, std::size_t last, double window_s) {
  std::size_t k = last;
  while (k > first && t[last] - t[k - 1] <= window_s) --k;
  constexpr std::size_t kMinSlopeSteps = 3;  // a slope from fewer samples is noise
  if (last - k < kMinSlopeSteps) return 0.0;
  double st = 0, sf = 0, stt = 0, stf = 0;
  const auto m = static_cast<double>(last - k + 1);
  for (std::size_t q = k; q <= last; ++q) {
    const double x = t[q] - t[last], f = cp.force(phi[q]) + load[q];
    st += x, sf += f, stt += x * x, stf += x * f;
  }
  const double den = m * stt - st * st;
  return den > 0 ? (m * stf - st * sf) / den : 0.0;
}

// A value as the recording's header states it, else the configuration's.
double stated(const Recording& rec, const char* key, double configured) {
  const auto v = rec.meta(key);
  return v ? std::stod(*v) : configured;
}

// One count of the phase φ = θ − 2π p / lead: the coarser of the linear encoder's and the motor
// encoder's at the screw, each as the recording's header states it, else the configuration.
double phase_count_rad(const Recording& rec, const ActuatorParams& act, double linear_count_m) {
  const double gear = stated(rec, "gear_ratio", act.gear_ratio);
  const double counts = stated(rec, "motor_encoder_counts_per_rev", act.motor_counts_per_rev);
  return std::max(2 * kPi * linear_count_m / act.lead_m, 2 * kPi / (counts * gear));
}

}  // namespace

const std::vector<double>& angle_column(const Recording& rec, const ActuatorParams& act,
                                        std::vector<double>& geared) {
  if (rec.has("screw_angle_rad")) return rec.column("screw_angle_rad");
  if (rec.has("motor_angle_rad")) {
    const double gear = stated(rec, "gear_ratio", act.gear_ratio);
    geared = rec.column("motor_angle_rad");
    for (double& x : geared) x /= gear;
    return geared;
  }
  throw RecordingError(rec.path + ": needs column 'screw_angle_rad' or 'motor_angle_rad'");
}

// ------------------------------------------------------------------------------- prepare
namespace {

// ActuatorSignals derived from stored ones where they are read: each full-rate array would cost 8
// bytes a sample (29 MB for an hour at 1 kHz), a read costs a subtraction or two. The arithmetic is
// central_diff's and central_diff2's (signal.hpp), so the values are theirs to the bit.
struct PhaseOf {  // φ = θ − 2π p / lead
  const std::vector<double>& theta_rad;
  const std::vector<double>& pos_m;
  double lead_m;
  double operator[](std::size_t i) const noexcept {
    return theta_rad[i] - 2 * kPi * pos_m[i] / lead_m;
  }
  std::size_t size() const noexcept { return pos_m.size(); }
};
template <class X>
struct RateOf {  // central difference, one-sided at the ends
  const X& x;
  double dt_s;
  double operator[](std::size_t i) const noexcept {
    const std::size_t n = x.size();
    if (n < 2) return 0.0;
    if (i == 0) return (x[1] - x[0]) / dt_s;
    if (i + 1 == n) return (x[n - 1] - x[n - 2]) / dt_s;
    return (x[i + 1] - x[i - 1]) / (2.0 * dt_s);
  }
  std::size_t size() const noexcept { return x.size(); }
};
struct CurvatureOf {  // second central difference, the ends take their neighbour's
  const std::vector<double>& x;
  double dt_s;
  double operator[](std::size_t i) const noexcept {
    const std::size_t n = x.size();
    if (n < 3) return 0.0;
    const std::size_t k = std::clamp<std::size_t>(i, 1, n - 2);
    return (x[k + 1] - 2.0 * x[k] + x[k - 1]) / (dt_s * dt_s);
  }
  std::size_t size() const noexcept { return x.size(); }
};

const std::vector<double>& finite_angle(const Recording& rec, const ActuatorParams& act,
                                        std::vector<double>& geared) {
  const auto& theta = angle_column(rec, act, geared);
  require_finite(rec, theta, "screw_angle_rad");
  return theta;
}

// The recording's signals, raw and filtered, with the derivatives the force balance needs.
// `geared` holds the screw angle when only the motor's is logged (angle_column). The derived
// signals refer to the stored ones: a ActuatorSignals is built in place and never copied.
struct ActuatorSignals {
  ActuatorSignals(const Recording& rec, const ActuatorParams& act, const ActuatorPrepared& P,
                  std::vector<double>& geared);
  ActuatorSignals(const ActuatorSignals&) = delete;
  ActuatorSignals& operator=(const ActuatorSignals&) = delete;
  const std::vector<double>& t;
  const std::vector<double>& pos_raw;
  const std::vector<double>& load_raw;
  const std::vector<double>& theta_raw;
  const double dt_s, lead_m;
  const std::vector<double> p, th, load;  // filtered
  const RateOf<std::vector<double>> v{p, dt_s}, load_rate{load, dt_s};
  const CurvatureOf a{p, dt_s};
  const RateOf<CurvatureOf> jerk{a, dt_s};  // zero-phase like the filter: a sensor delay's term
  const PhaseOf phi{th, p, lead_m}, phi_raw{theta_raw, pos_raw, lead_m};
  const RateOf<PhaseOf> phi_rate{phi, dt_s};
};

ActuatorSignals::ActuatorSignals(const Recording& rec, const ActuatorParams& act,
                                 const ActuatorPrepared& P, std::vector<double>& geared)
    : t(rec.column("t_s")),
      pos_raw(rec.column("nut_pos_m")),
      load_raw(rec.column("load_force_n")),
      theta_raw(finite_angle(rec, act, geared)),
      dt_s(1.0 / P.fs_hz),
      lead_m(act.lead_m),
      p(filtfilt_butter4(pos_raw, P.filter_hz, P.fs_hz)),
      th(filtfilt_butter4(theta_raw, P.filter_hz, P.fs_hz)),
      load(filtfilt_butter4(load_raw, P.filter_hz, P.fs_hz)) {}

// The standard deviation of white load-cell noise after the filter, and of its rate (the
// filter's and the derivative's impulse response, summed in squares).
std::pair<double, double> filtered_noise(const ActuatorPrepared& P) {
  const auto half =
      static_cast<std::size_t>(kResponseFilterPeriods * std::ceil(P.fs_hz / P.filter_hz));
  std::vector<double> x(2 * half + 1, 0.0);
  x[half] = 1.0;
  const auto h = filtfilt_butter4(x, P.filter_hz, P.fs_hz);
  const auto d = central_diff(h, 1.0 / P.fs_hz);
  double hh = 0, dd = 0;
  for (std::size_t k = 0; k < h.size(); ++k) hh += h[k] * h[k], dd += d[k] * d[k];
  return {P.load_noise_n * std::sqrt(hh), P.load_noise_n * std::sqrt(dd)};
}

// Stops the filter hides: a raw count held for longer than twice the time the filtered speed
// needs to cross one count means the nut stood still (or nearly) in between, as in stick-slip,
// where it sticks and jumps several times within one filter period. Each stop, widened by the
// filter's support either side (the samples whose filtered values it reaches), as times since t0.
std::vector<ActuatorPrepared::Window> hidden_stops(const ActuatorSignals& s,
                                                   const ActuatorPrepared& P) {
  std::vector<ActuatorPrepared::Window> out;
  const std::size_t n = s.t.size();
  const double reach_s = std::ceil(P.fs_hz / P.filter_hz) / P.fs_hz;
  std::size_t i = 0;
  while (i < n) {
    std::size_t j = i;
    while (j + 1 < n &&
           std::abs(s.pos_raw[j + 1] - s.pos_raw[i]) < rules::kHeldCountCounts * P.count_m)
      ++j;
    // The count was held at least from sample i to sample j (sampling adds, never removes).
    const double held_s = s.t[j] - s.t[i];
    if (std::abs(s.v[(i + j) / 2]) * held_s > rules::kHiddenStopCounts * P.count_m)
      out.push_back({s.t[i] - P.t0_s - reach_s, s.t[j] - P.t0_s + reach_s});
    i = j + 1;
  }
  return out;
}

// Sliding samples: moving in one direction for the whole filter support around the sample,
// faster than one encoder count per filter time constant (slower, the nut may be stuck and its
// friction is anywhere in the break-away band), and away from step-outs.
std::vector<unsigned char> sliding_mask(const ActuatorSignals& s, const ActuatorPrepared& P) {
  const std::size_t n = s.t.size();
  const auto w = static_cast<std::size_t>(std::ceil(P.fs_hz / P.filter_hz));
  std::vector<unsigned char> ok(n, 0);
  for (std::size_t i = 0; i < n; ++i) ok[i] = std::abs(s.v[i]) > P.v_min_m_s;
  std::size_t i = 0;
  while (i < n) {
    if (!ok[i]) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < n && ok[j] && (s.v[j] > 0) == (s.v[i] > 0)) ++j;
    for (std::size_t k = i; k < j; ++k)
      if (k < i + w || k + w >= j) ok[k] = 0;
    i = j;
  }
  for (const auto& sl : P.slips)
    for (std::size_t k = 0; k < n; ++k)
      if (s.t[k] > sl.start_s - rules::kStepOutBefore_s && s.t[k] < sl.t_s + rules::kStepOutAfter_s)
        ok[k] = 0;
  return ok;
}

// The nut rings on its coupling faster than the filter, as under a loop that reads it late: its
// mass M on the coupling's stiffness k_c = F_m'(0) 2π/L (the count's force over the count), at
// ω = √(k_c/M) with the model's mass.
double ring_rad_s(const ActuatorPrepared& P, const Baseline& base) {
  return std::sqrt(P.count_force_n / P.count_m / std::max(base.nut_mass_kg, kLeastMass_kg));
}

// Per sample, 1 where the nut's ringing reverses it: the ringing's speed, √2 σ ω from the raw
// count's RMS excursion σ about the filtered position over the filter's support (less the
// count's own rounding, c²/12), reaches the filtered speed. The nut then runs back and forth
// each cycle and its friction averages over the cycle, less than F_c sign(v) the slower it goes:
// no friction law of the filtered speed holds there (a lower Coulomb level, and a sensor delay
// read 40 % long, took it up on the other actuator). The samples stay for what they show as
// events; the fits leave them out.
std::vector<unsigned char> ringing(const ActuatorSignals& s, const ActuatorPrepared& P,
                                   double omega_rad_s) {
  const std::size_t n = s.t.size();
  const auto w = static_cast<std::size_t>(std::ceil(P.fs_hz / P.filter_hz));
  const double rounding2 = P.count_m * P.count_m / 12.0;
  std::vector<double> sum2(n + 1, 0.0);  // running sum of the squared excursion
  for (std::size_t k = 0; k < n; ++k) sum2[k + 1] = sum2[k] + std::pow(s.pos_raw[k] - s.p[k], 2);
  std::vector<unsigned char> out(n, 0);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t a = k > w ? k - w : 0, b = std::min(n, k + w + 1);
    const double excursion2 = (sum2[b] - sum2[a]) / static_cast<double>(b - a) - rounding2;
    out[k] = std::sqrt(2.0 * std::max(0.0, excursion2)) * omega_rad_s > std::abs(s.v[k]);
  }
  return out;
}

// Per sample, the run in which the raw count's advance per sample repeats with a short period q
// for longer than the filter's support (−1: none), and each run's q: the count rate is locked to
// the sample clock (a steady move at q samples per whole number of counts). The rounding error
// then repeats every q samples: the filter removes its ripple but keeps its mean, which the
// phase of the move sets anywhere within half a count over q. Periods whose mean the white
// rounding floor already covers (c / 2q below the filtered c / √12) are not looked for.
LockedRuns locked_runs(const ActuatorSignals& s, const ActuatorPrepared& P) {
  const std::size_t n = s.t.size();
  const auto w = static_cast<std::size_t>(std::ceil(P.fs_hz / P.filter_hz));
  const double kept = std::sqrt(std::min(1.0, 2.0 * P.filter_hz / P.fs_hz));
  const auto q_max = static_cast<std::size_t>(std::floor(0.5 * std::sqrt(12.0) / kept));
  LockedRuns out{std::vector<int>(n, -1), {}};
  std::vector<long> step;
  step.reserve(n > 0 ? n - 1 : 0);
  for (std::size_t i = 0; i + 1 < n; ++i)
    step.push_back(std::lround((s.pos_raw[i + 1] - s.pos_raw[i]) / P.count_m));
  for (std::size_t q = 1; q <= q_max; ++q) {
    std::size_t i = q;
    while (i < step.size()) {
      std::size_t j = i;
      while (j < step.size() && step[j] == step[j - q]) ++j;
      if (j - i > w) {
        const auto id = static_cast<int>(out.period.size());
        out.period.push_back(static_cast<int>(q));
        for (std::size_t k = i - q; k <= j && k < n; ++k)
          if (out.run[k] < 0) out.run[k] = id;
      }
      i = j + 1;
    }
  }
  return out;
}

// What a finding must exceed: the force of one count, what the recording resolves and the
// stated minimum.
void set_floors(ActuatorPrepared& P, const Coupling& cp, const ForceCalibration& cal,
                const ActuatorParams& act, const StageOptions& opt) {
  P.count_force_n = std::abs(cp.slope(0.0)) * 2 * kPi * P.count_m / act.lead_m;
  // Rounding to a count is uniform over one count (RMS c/√12); both it and the load-cell noise
  // are broadband, and the filter keeps 2 f_c / f_s of their power.
  const double kept = std::sqrt(std::min(1.0, 2.0 * P.filter_hz / P.fs_hz));
  P.floor_n = kept * std::hypot(P.count_force_n / std::sqrt(12.0), P.load_noise_n);
  P.scales.force_n = std::max(std::abs(cal.peak_push_n), std::abs(cal.peak_pull_n));
  P.minimum_n = opt.calibration_accuracy_n > 0
                    ? opt.calibration_accuracy_n
                    : std::max(opt.min_effect_of_peak * P.scales.force_n, opt.bench_accuracy_n);
}

// Where the count is locked the rounding error's mean is one unknown value per run, kept whole by
// the filter, and repeated moves lock alike, so it need not average out: it may hold the force
// off by up to half a count's force over the run's period, as a constant over each run.
void set_locked_floor(ActuatorPrepared& P) {
  std::size_t locked = 0;
  double held2 = 0;  // mean square of the most each sample's locked rounding may hold
  for (int r : P.locked_run) {
    if (r < 0) continue;
    ++locked;
    const double q = P.locked_period[static_cast<std::size_t>(r)];
    held2 += std::pow(0.5 * P.count_force_n / q, 2);
  }
  const auto n = static_cast<double>(std::max<std::size_t>(1, P.states.size()));
  P.locked_share = static_cast<double>(locked) / n;
  P.locked_floor_n = std::hypot(P.floor_n, std::sqrt(held2 / n));
}

// Max − min of a state's value over the samples (pulses.cpp's span_of is a time window).
double spread_of(const std::vector<State>& states, double State::*value) {
  if (states.empty()) return 0.0;
  const auto [lo, hi] =
      std::minmax_element(states.begin(), states.end(),
                          [&](const State& a, const State& b) { return a.*value < b.*value; });
  return (*hi).*value - (*lo).*value;
}

// The effect library's view of one filtered sample.
struct StateAt {
  const ActuatorSignals& s;
  const Coupling& cp;
  const ActuatorParams& act;
  const Baseline& base;
  double t0_s;
  State operator()(std::size_t i) const {
    State x;
    x.t_s = s.t[i] - t0_s;
    x.p_m = s.p[i];
    x.v_m_s = s.v[i];
    x.a_m_s2 = s.a[i];
    x.jerk_m_s3 = s.jerk[i];
    x.theta_rad = s.th[i];
    x.phi_rad = s.phi[i];
    x.phi_rate_rad_s = s.phi_rate[i];
    x.coupling_n = cp.force(s.phi[i]);
    x.coupling_slope_n_per_rad = cp.slope(s.phi[i]);
    x.load_n = s.load[i];
    x.load_rate_n_s = s.load_rate[i];
    x.stroke_min_m = act.stroke_min_m;
    x.stroke_max_m = act.stroke_max_m;
    x.lead_m = act.lead_m;
    x.coulomb_n = base.coulomb_n;
    x.viscous_n_s_per_m = base.viscous_n_s_per_m;
    x.nut_mass_kg = base.nut_mass_kg;
    return x;
  }
};

// Sample k of a nut standing still, from unfiltered signals (the filter would smear a release into
// the stuck part).
State held_state(const ActuatorSignals& s, const StateAt& state_at, std::size_t k) {
  State x = state_at(k);
  x.coupling_n = state_at.cp.force(s.phi_raw[k]);
  x.load_n = s.load_raw[k];
  x.v_m_s = 0;
  x.a_m_s2 = 0;
  x.jerk_m_s3 = 0;
  return x;
}

// The net force driving a standing nut: coupling, load and the model's terms.
double net_drive_n(const Baseline& base, const State& x) {
  double net = x.coupling_n + x.load_n;
  for (const auto& term : base.terms) net += term.effect->force_n(term.params, x);
  return net;
}

// The drive the stand from i to j held for three quarters of it (its lower quartile along the
// release's direction) and that sample's state.
void hold_for_most(const ActuatorSignals& s, const Baseline& base, const StateAt& state_at,
                   std::size_t i, std::size_t j, StuckEpisode& e) {
  std::vector<std::pair<double, std::size_t>> held;  // (net along dir, sample)
  held.reserve(j - i + 1);
  for (std::size_t k = i; k <= j; ++k)
    held.emplace_back(e.dir * net_drive_n(base, held_state(s, state_at, k)), k);
  constexpr std::size_t kQuartile = 4;  // the lower quartile: held for three quarters
  const auto q = held.begin() + static_cast<std::ptrdiff_t>(held.size() / kQuartile);
  std::nth_element(held.begin(), q, held.end());
  e.held_net_n = e.dir * q->first;
  e.held = held_state(s, state_at, q->second);
}

// A move, not encoder chatter: the raw count went rules::kReleaseMoveCounts along dir from sample
// a to b, looked for within rules::kReleaseWindow_s after a stand (it slipped on) or before it (it
// was moving).
bool moved(const ActuatorSignals& s, const ActuatorPrepared& P, std::size_t a, std::size_t b,
           double dir) {
  return dir * (s.pos_raw[b] - s.pos_raw[a]) >= rules::kReleaseMoveCounts * P.count_m;
}

// The stuck episode that ends at sample j (the raw count unchanged since sample i), if the nut
// then slipped on (not encoder chatter) away from any step-out.
std::optional<StuckEpisode> released_at(const ActuatorSignals& s, const ActuatorPrepared& P,
                                        const Baseline& base, const StateAt& state_at,
                                        std::size_t i, std::size_t j) {
  const std::size_t n = s.t.size();
  const double dir = s.pos_raw[j + 1] > s.pos_raw[i] ? 1.0 : -1.0;
  const auto w = static_cast<std::size_t>(rules::kReleaseWindow_s * P.fs_hz) + 1;
  const bool slipped = moved(s, P, i, std::min(n - 1, j + w), dir);
  bool near_slip = false;
  for (const auto& sl : P.slips) near_slip |= std::abs(s.t[j] - sl.t_s) < rules::kStepOutAfter_s;
  if (!slipped || near_slip) return std::nullopt;
  StuckEpisode e;
  e.t_release_s = s.t[j] - P.t0_s;
  e.dir = dir;
  // Net force just before release, from unfiltered signals: the filter would smear the release
  // into the stuck part.
  e.state = held_state(s, state_at, j);
  e.net_n = net_drive_n(base, e.state);
  e.net_rate_n_s =
      dir * rising_rate(s.t, s.phi_raw, s.load_raw, state_at.cp, i, j, rules::kReleaseRateWindow_s);
  e.held_s = s.t[j] - s.t[i];
  e.interrupts = moved(s, P, i - std::min(i, w), i, dir);
  if (e.interrupts) hold_for_most(s, base, state_at, i, j, e);  // only a stall can be a pulse's
  return e;
}

// The stands: samples [i, j] whose raw count stays within half a count of sample i's for at least
// rules::kMinHold_s (and rules::kMinHoldSamples samples); shorter is encoder chatter.
std::vector<std::pair<std::size_t, std::size_t>> stands(const ActuatorSignals& s,
                                                        const ActuatorPrepared& P) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  const std::size_t n = s.t.size();
  const double hold_s = std::max(rules::kMinHold_s, rules::kMinHoldSamples / P.fs_hz);
  std::size_t i = 0;
  while (i < n) {
    std::size_t j = i;
    while (j + 1 < n &&
           std::abs(s.pos_raw[j + 1] - s.pos_raw[i]) < rules::kHeldCountCounts * P.count_m)
      ++j;
    if (s.t[j] - s.t[i] >= hold_s) out.emplace_back(i, j);
    i = j + 1;
  }
  return out;
}

// Stuck episodes (raw nut count unchanged) and the net force on the nut as each one ends.
std::vector<StuckEpisode> stuck_episodes(const ActuatorSignals& s, const ActuatorPrepared& P,
                                         const Baseline& base, const StateAt& state_at) {
  std::vector<StuckEpisode> out;
  for (const auto& [i, j] : stands(s, P))
    if (j + 1 < s.t.size())
      if (auto e = released_at(s, P, base, state_at, i, j)) out.push_back(*e);
  return out;
}

// The jump from the stand that ends at sample a to the one that starts at sample b: the work the
// recorded forces did over it from the raw samples (trapezoids: the coupling is smooth between
// two samples), unless it is no move (less than rules::kReleaseMoveCounts of travel) or the phase
// left its branch (a step-out: the calibration holds on the stable branch only).
std::optional<Jump> jump_between(const ActuatorSignals& s, const ActuatorPrepared& P,
                                 const Baseline& base, const StateAt& state_at, std::size_t a,
                                 std::size_t b) {
  for (const auto& sl : P.slips)
    if (s.t[b] > sl.start_s - rules::kStepOutBefore_s && s.t[a] < sl.t_s + rules::kStepOutAfter_s)
      return std::nullopt;
  Jump jp;
  jp.t_s = s.t[a] - P.t0_s;
  jp.duration_s = s.t[b] - s.t[a];
  jp.from = held_state(s, state_at, a);
  double prev_n = net_drive_n(base, jp.from);
  for (std::size_t k = a; k < b; ++k) {
    const State x = held_state(s, state_at, k + 1);
    const double next_n = net_drive_n(base, x), dp = s.pos_raw[k + 1] - s.pos_raw[k];
    jp.work_j += 0.5 * (prev_n + next_n) * dp;
    jp.path_m += std::abs(dp);
    if (jp.dir == 0 && std::abs(s.pos_raw[k + 1] - s.pos_raw[a]) >= 0.5 * P.count_m)
      jp.dir = s.pos_raw[k + 1] > s.pos_raw[a] ? 1.0 : -1.0;
    prev_n = next_n;
    if (k + 1 == b) jp.to = x;
  }
  if (jp.path_m < rules::kReleaseMoveCounts * P.count_m) return std::nullopt;
  return jp;
}

// The jumps between consecutive stands no longer than a pulse (`max_s`), each marked whether it
// left a sliding sample (`sliding`, per recording sample) where the residual sees what moved it.
std::vector<Jump> jumps(const ActuatorSignals& s, const ActuatorPrepared& P, const Baseline& base,
                        const StateAt& state_at, const std::vector<unsigned char>& sliding,
                        double max_s) {
  std::vector<Jump> out;
  const auto st = stands(s, P);
  for (std::size_t q = 0; q + 1 < st.size(); ++q) {
    const std::size_t a = st[q].second, b = st[q + 1].first;
    if (s.t[b] - s.t[a] > max_s) continue;
    auto jp = jump_between(s, P, base, state_at, a, b);
    if (!jp) continue;
    jp->slides = std::any_of(sliding.begin() + static_cast<std::ptrdiff_t>(a),
                             sliding.begin() + static_cast<std::ptrdiff_t>(b) + 1,
                             [](unsigned char k) { return k != 0; });
    out.push_back(*jp);
  }
  return out;
}

// Every `step`-th element of `full`, which is freed: the per-sample masks and runs are read only
// at the decimated samples, and at full rate (an hour at 1 kHz: 3.6 MB each mask, 14 MB the
// runs) they would sit beside the States at the analysis's peak of memory.
template <class T>
std::vector<T> every_nth(std::vector<T> full, std::size_t step) {
  std::vector<T> out;
  out.reserve((full.size() + step - 1) / step);
  for (std::size_t i = 0; i < full.size(); i += step) out.push_back(full[i]);
  return out;
}

}  // namespace

// A load cell in another unit or of the other sign: the force the calibrated coupling carries
// is the load the cell reads plus friction and inertia (fitted beside it: a load that follows
// the motion's direction must not pass for the coupling's). Where that fit explains most of it,
// the load's coefficient is about 1; beyond kScaleFactor either way by 4 standard errors, or
// negative, it is a unit or a sign, not physics (a coupling error within any plausible range
// moves it by tens of per cent).
void check_load_cell_scale(const std::string& path, const ActuatorSignals& s, const Coupling& cp) {
  // A load cell reading one value over the whole recording (unplugged, stuck, a column of
  // zeros) carries no load: the force left out of the balance would be the whole coupling's,
  // and no fit against it judges the model.
  if (const auto [lo, hi] = std::minmax_element(s.load_raw.begin(), s.load_raw.end());
      lo != s.load_raw.end() && *lo == *hi) {
    char b[64];
    std::snprintf(b, sizeof b, "%.4g", *lo);
    throw LoadCellUnitError(
        path + ": not judged: the load cell reads a constant " + b +
            " N over the whole recording (column load_force_n), so it carries no "
            "load to judge the model against; check its wiring",
        *lo);
  }
  constexpr double kMinExplained = 0.5;  // R² of the fit: the balance holds at all
  constexpr double kScaleFactor = 3.0;
  constexpr double kSure = 4.0;        // standard errors beyond the bound
  constexpr double kLoadShare = 0.25;  // of the force's variance the load alone explains
  const std::size_t n = s.load.size(), stride = std::max<std::size_t>(1, n / 20000);
  Eigen::Matrix<double, 5, 5> xtx = Eigen::Matrix<double, 5, 5>::Zero();
  Eigen::Matrix<double, 5, 1> xty = Eigen::Matrix<double, 5, 1>::Zero();
  double sy = 0, syy = 0, m = 0;
  for (std::size_t i = 0; i < n; i += stride) {
    const double v = s.v[i], y = -cp.force(s.phi[i]);
    Eigen::Matrix<double, 5, 1> x;
    x << s.load[i], (v > 0) - (v < 0), v, s.a[i], 1.0;
    if (!x.allFinite() || !std::isfinite(y)) continue;
    xtx += x * x.transpose(), xty += x * y, sy += y, syy += y * y, m += 1;
  }
  if (m < 100) return;
  const auto solver = xtx.completeOrthogonalDecomposition();
  const Eigen::Matrix<double, 5, 1> beta = solver.solve(xty);
  const double total = syy - sy * sy / m, left = syy - beta.dot(xty);  // least squares' SSE
  if (!(total > 0) || 1.0 - left / total < kMinExplained) return;
  // The load's own share: the fit without it (friction and inertia alone) must explain much less,
  // else the load is a bystander whose coefficient says nothing of its unit.
  const auto rest = xtx.bottomRightCorner<4, 4>().completeOrthogonalDecomposition();
  const Eigen::Matrix<double, 4, 1> xty_rest = xty.tail<4>();
  const double left_rest = syy - rest.solve(xty_rest).dot(xty_rest);
  if ((left_rest - left) / total < kLoadShare) return;
  const double k = beta[0];  // calibrated force per newton the load cell reads
  const double se = std::sqrt(std::max(0.0, left / (m - 5)) * solver.pseudoInverse()(0, 0));
  if (k - kSure * se <= kScaleFactor && k + kSure * se >= 1.0 / kScaleFactor) return;
  struct Guess {
    double per_newton;
    const char* unit;
  };
  static constexpr Guess kGuesses[] = {{1e-3, "kilonewtons (values 1/1000 of newtons)"},
                                       {1e3, "millinewtons (values 1000x newtons)"},
                                       {1.0 / 4.44822, "pound-force (values 1/4.45 of newtons)"},
                                       {-1.0, "newtons of the other sign (load_force_n negated)"}};
  const char* unit = "not a force in newtons along this recording's +p";
  for (const auto& g : kGuesses)
    if (std::abs(k * g.per_newton - 1.0) < 0.5) unit = g.unit;
  char b[200];
  std::snprintf(b, sizeof b,
                "beside friction and inertia the calibrated coupling carries %.4g ± %.2g N per "
                "newton it reads (R² %.2f)",
                k, se, 1.0 - left / total);
  throw LoadCellUnitError(path + ": column load_force_n cannot be the load in newtons: " + b +
                          "; likely unit: " + unit);
}

namespace {

// The rate, the filter and the counts the signals are built with.
void set_rates(ActuatorPrepared& P, const Recording& rec, const ActuatorParams& act,
               double filter_hz) {
  P.fs_hz = maglead::sample_rate_hz(rec);
  // The nut's mechanics (mass on the coupling stiffness) sit near 100 Hz; the effects live
  // below a few tens of Hz. The filter keeps those and averages encoder steps and load-cell noise.
  P.filter_hz = std::min(filter_hz, rules::kFilterMaxOfRate * P.fs_hz);
  P.lead_m = act.lead_m;
  P.count_m = stated(rec, "linear_encoder_m_per_count", act.linear_count_m);
  P.scales.phase_count_rad = phase_count_rad(rec, act, P.count_m);
}

}  // namespace

void judge_load_cell(const Recording& rec, const ForceCalibration& cal, const ActuatorParams& act) {
  ActuatorPrepared P;
  set_rates(P, rec, act, StageOptions{}.filter_hz);
  std::vector<double> geared;
  const ActuatorSignals s(rec, act, P, geared);
  check_load_cell_scale(rec.path, s, Coupling{cal});
}

ActuatorPrepared prepare_actuator(const Recording& rec, const Baseline& base,
                                  const ForceCalibration& cal, const ActuatorParams& act,
                                  const StageOptions& opt) {
  ActuatorPrepared P;
  check_actuator_rows(rec);
  const auto& t = rec.column("t_s");
  const std::size_t n = t.size();
  set_rates(P, rec, act, opt.filter_hz);
  std::vector<double> geared;
  const ActuatorSignals s(rec, act, P, geared);
  P.slips = find_slips(t, s.phi_raw);
  const stats::SensorNoise noise = stats::sensor_noise(s.load_raw);  // the load cell's noise
  P.load_noise_n = noise.sigma;
  if (!noise.measured) P.load_noise_step_n = noise.step;
  std::tie(P.load_filtered_noise_n, P.load_rate_noise_n_s) = filtered_noise(P);
  P.v_min_m_s = P.count_m * P.filter_hz;
  // Keep every `decim`-th sliding sample: the signals are band-limited to filter_hz, so samples
  // closer than a fifth of its period add no information, only work.
  P.decimation = std::max(
      1, static_cast<int>(std::floor(P.fs_hz / (rules::kSamplesPerFilterPeriod * P.filter_hz))));
  const auto step = static_cast<std::size_t>(P.decimation);
  // Per decimated sample (k at sample k * step), as the loop below reads them.
  const auto sliding = sliding_mask(s, P);  // kept whole for the jumps (one byte a sample)
  const auto ok = every_nth(sliding, step);
  const Coupling cp{cal};
  check_load_cell_scale(rec.path, s, cp);
  set_floors(P, cp, cal, act, opt);
  const double ring_rad_per_s = ring_rad_s(P, base);
  P.scales.sample_rate_hz = P.fs_hz;
  P.scales.ring_hz = ring_rad_per_s / (2 * kPi);
  const auto rings = every_nth(ringing(s, P, ring_rad_per_s), step);
  P.t0_s = t.front();
  const StateAt state_at{s, cp, act, base, P.t0_s};
  LockedRuns runs = locked_runs(s, P);
  const auto run_of = every_nth(std::move(runs.run), step);
  std::size_t kept = 0;  // counted first: one allocation each, no regrowth of the large States
  for (const unsigned char k : ok) kept += k;
  P.states.reserve(kept);
  P.residual.reserve(kept);
  P.locked_run.reserve(kept);
  for (std::size_t k = 0; k < ok.size(); ++k) {
    if (!ok[k]) continue;
    P.states.push_back(state_at(k * step));
    P.residual.push_back(missing_force(P.states.back(), base.terms));
    P.locked_run.push_back(run_of[k]);
    P.ringing.push_back(rings[k]);
    P.scales.speed_m_s = std::max(P.scales.speed_m_s, std::abs(P.states.back().v_m_s));
  }
  P.scales.travel_m = spread_of(P.states, &State::p_m);
  P.scales.turn_rad = spread_of(P.states, &State::theta_rad);
  P.locked_period = runs.period;
  set_locked_floor(P);
  P.samples = n;
  P.duration_s = t.back() - t.front();
  P.stuck = stuck_episodes(s, P, base, state_at);
  P.stops = hidden_stops(s, P);
  P.jumps = jumps(s, P, base, state_at, sliding, opt.pulse_max_s);
  return P;
}

StopSamples take_stops(ActuatorPrepared& P) {
  StopSamples aside;
  std::size_t kept = 0;
  auto w = P.stops.begin();
  for (std::size_t i = 0; i < P.states.size(); ++i) {
    const double t = P.states[i].t_s;
    while (w != P.stops.end() && w->to_s < t) ++w;
    if (w != P.stops.end() && w->from_s <= t) {
      aside.at.push_back(i);
      aside.push(P, i);
      continue;
    }
    // Kept samples close up in place: one pass, nothing else allocated.
    P.set(kept++, P, i);
  }
  P.resize(kept);
  set_locked_floor(P);
  return aside;
}

void put_back(ActuatorPrepared& P, const StopSamples& aside) {
  const std::size_t n = P.states.size() + aside.at.size();
  P.resize(n);
  // From the back, so every kept sample moves once to its place and none is overwritten first.
  std::size_t from = n - aside.at.size(), k = aside.at.size();
  for (std::size_t i = n; i-- > 0;) {
    if (k > 0 && aside.at[k - 1] == i) {
      P.set(i, aside, --k);
      continue;
    }
    P.set(i, P, --from);
  }
  set_locked_floor(P);
}

// ------------------------------------------------------------------------------- fitting
namespace {

using stats::Fit;
using stats::Grams;
using stats::solve;
using stats::sse;
using stats::total;

// Per column, the sum of squares of the load-cell noise it carries: each column's change when
// the filtered load and its rate move by their noise's standard deviation (the columns are linear
// in them, as the effect units' regressors are), on up to 2000 samples spread over the sliding
// ones, scaled to all of them. Zero for columns made from motion alone.
Eigen::VectorXd column_noise(const ActuatorPrepared& P, const std::vector<Column>& cols) {
  const auto m = static_cast<Eigen::Index>(cols.size());
  Eigen::VectorXd out = Eigen::VectorXd::Zero(m);
  constexpr std::size_t kProbeSamples = 2000;  // enough for a noise scale, little work
  const std::size_t n = P.states.size(), step = std::max<std::size_t>(1, n / kProbeSamples);
  std::size_t used = 0;
  Eigen::VectorXd x0(m), x1(m), x2(m);
  for (std::size_t i = 0; i < n; i += step, ++used) {
    State load = P.states[i], rate = P.states[i];
    load.load_n += P.load_filtered_noise_n;
    rate.load_rate_n_s += P.load_rate_noise_n_s;
    unit_row(Form::nut, cols, P.states[i], x0.data());
    unit_row(Form::nut, cols, load, x1.data());
    unit_row(Form::nut, cols, rate, x2.data());
    for (Eigen::Index j = 0; j < m; ++j)
      out[j] += (x1[j] - x0[j]) * (x1[j] - x0[j]) + (x2[j] - x0[j]) * (x2[j] - x0[j]);
  }
  return used > 0 ? Eigen::VectorXd(out * (static_cast<double>(n) / static_cast<double>(used)))
                  : out;
}

Grams accumulate_sliding(const ActuatorPrepared& P, const std::vector<Column>& cols, int folds) {
  const auto m = static_cast<Eigen::Index>(cols.size());
  Grams g(static_cast<std::size_t>(folds), m);
  Eigen::VectorXd x(m);
  for (std::size_t i = 0; i < P.states.size(); ++i) {
    if (P.ringing[i]) continue;
    const auto& s = P.states[i];
    unit_row(Form::nut, cols, s, x.data());
    g.add_row(stats::fold_of(s.t_s, P.duration_s, folds), x, P.residual[i], s.load_n);
  }
  g.symmetrize();
  g.noise_ss = column_noise(P, cols);
  return g;
}

}  // namespace

// ------------------------------------------------------------------------------- select
namespace {

// The nut's balance as the selection's rules: the units' parameters at the first sliding state,
// and a force must exceed the recording's floors (ActuatorPrepared::floor_n, locked_floor_n,
// minimum_n).
class NutRules : public selection::Rules {
 public:
  NutRules(const ActuatorPrepared& P, State model, double min_t)
      : P_(P), model_(model), min_t_(min_t) {}
  std::optional<effects::Params> parameters(const Variant& var, const std::vector<int>& cols,
                                            const Fit& fit) const override {
    const auto k = static_cast<Eigen::Index>(cols.size());
    return var.effect->parameters(var.shape, fit.theta.tail(k).data(), model_);
  }
  bool resolved(const selection::Trial& tr, double explained_n, const selection::Acting& where,
                const std::vector<selection::Term>& model) const override;
  selection::Acting acting(const selection::Trial& tr) const override;
  double minimum_n(const std::vector<selection::Term>& model) const override;
  double floor_n(const std::vector<selection::Term>& model) const override {
    return std::max(P_.floor_n, minimum_n(model));
  }
  const State& model() const { return model_; }

 private:
  const ActuatorPrepared& P_;
  State model_;
  double min_t_;  // the t that makes a trial consistent (Settings::min_t)
  std::vector<double> contribution(const selection::Trial& tr) const;
  double beyond_locked_rounding(const selection::Trial& tr) const;
};

// The trial's fitted contribution at each sliding sample.
std::vector<double> NutRules::contribution(const selection::Trial& tr) const {
  const auto k = static_cast<Eigen::Index>(tr.idx.size());
  std::vector<double> z(P_.states.size());
  double x[8];
  for (std::size_t i = 0; i < z.size(); ++i) {
    tr.var->effect->regressors(tr.var->shape, P_.states[i], x);
    z[i] = Eigen::Map<const Eigen::VectorXd>(x, k).dot(tr.w);
  }
  return z;
}

// RMS of the trial's fitted contribution less its mean over each locked run: the part of it a
// locked count's rounding (a constant per run) cannot make.
double NutRules::beyond_locked_rounding(const selection::Trial& tr) const {
  const auto z = contribution(tr);
  std::vector<double> run_sum(P_.locked_period.size(), 0.0), run_n(P_.locked_period.size(), 0.0);
  for (std::size_t i = 0; i < z.size(); ++i)
    if (const int r = P_.locked_run[i]; r >= 0)
      run_sum[static_cast<std::size_t>(r)] += z[i], run_n[static_cast<std::size_t>(r)] += 1.0;
  double ss = 0;
  for (std::size_t i = 0; i < z.size(); ++i) {
    const int r = P_.locked_run[i];
    const auto ri = static_cast<std::size_t>(r);
    const double d = r >= 0 ? z[i] - run_sum[ri] / run_n[ri] : z[i];
    ss += d * d;
  }
  return z.empty() ? 0.0 : std::sqrt(ss / static_cast<double>(z.size()));
}

// Where the trial's fitted law is not zero (beyond a billionth of its largest value) on the
// sliding samples: a law with compact support, as an end zone, changes the force only there.
selection::Acting NutRules::acting(const selection::Trial& tr) const {
  auto z = contribution(tr);
  if (z.empty()) return {1.0, 0.0};
  double top = 0;
  for (double& v : z) top = std::max(top, v = std::abs(v));
  double ss = 0, n = 0;
  for (double v : z)
    if (v > rules::kActingLawShare * top) ss += v * v, n += 1;
  return {std::max(1.0, n) / static_cast<double>(z.size()), n > 0 ? std::sqrt(ss / n) : 0.0};
}

// The stated minimum is how well the calibration is known; its error reaches the model's force
// through the coupling gain the model holds, so beside a gain g found it is g times that (never
// less than stated).
double NutRules::minimum_n(const std::vector<selection::Term>& model) const {
  static const effects::Effect* const gain_error = effects::find("coupling_gain_error");
  double gain = 1.0;
  for (const auto& t : model)
    if (t.trial.var->effect == gain_error)
      if (const auto g = t.trial.params.find("gain"); g != t.trial.params.end()) gain = g->second;
  return P_.minimum_n * std::max(1.0, gain);
}

// A force the recording resolves and a user would act on (given where the trial's law acts: a
// coupling 50 % weaker in the end zones is no smaller for the nut spending little time there):
// beyond the minimum and the floor; where the count is locked, beyond what its rounding may hold
// (ActuatorPrepared::locked_floor_n) unless the term varies within the locked runs by more than the
// floor.
bool NutRules::resolved(const selection::Trial& tr, double explained_n,
                        const selection::Acting& where,
                        const std::vector<selection::Term>& model) const {
  const double least_n = minimum_n(model);
  const double floor_n = this->floor_n(model);
  if (explained_n < floor_n) return false;
  if (P_.locked_share > 0 && explained_n < std::max(P_.locked_floor_n, least_n) &&
      beyond_locked_rounding(tr) < floor_n)
    return false;
  // What a trial explains counts the other terms refitted beside it too; a law whose own force
  // where it acts stays within the calibration's accuracy (an offset of 0.06 N beside a ripple,
  // whose refit made up the rest) is one a calibration error makes as well. Less one standard
  // error it must still beat the minimum, where t says how sure the gain is (t over the held-out
  // segments; the gain goes as the force squared): an offset of 0.075 ± 0.013 N at t 6.2 against
  // a minimum of 0.070 N does not. A trial consistent by the localized rule has no such t.
  const double sure = tr.t >= min_t_ ? std::sqrt(1.0 - 1.0 / tr.t) : 1.0;
  return where.own_rms_n * sure >= least_n;
}

selection::Settings actuator_settings(const StageOptions& opt, const effects::Scales& scales = {}) {
  return {.max_terms = opt.max_terms,
          .min_gain_pct = opt.min_gain_pct,
          .min_t = opt.min_t,
          .acting_share = opt.acting_share,
          .parsimony = opt.parsimony,
          .leave_out_spanned = false,
          .scales = scales};
}

// The chosen terms' parameters at a fit, in their order (none: the unit gives no value there).
std::vector<std::optional<stats::Named>> sliding_term_parameters(
    const std::vector<selection::Found>& chosen, const Fit& fit, const State& model) {
  std::vector<std::optional<stats::Named>> out;
  Eigen::Index off = 0;
  for (const auto& c : chosen) {
    const auto k = static_cast<Eigen::Index>(c.effect->columns());
    out.push_back(c.effect->parameters(c.shape, fit.theta.segment(off, k).data(), model));
    off += k;
  }
  return out;
}

// The most a force error of at most `error_n` on every sample moves each fitted column: the
// fit moves by A⁻¹ Σ xᵢ eᵢ (A = Σ xᵢxᵢᵀ over the samples it used), so column j moves by at most
// error_n Σ |(A⁻¹ xᵢ)ⱼ|, each column's worst error taking the sign of its own weights. A
// calibration error is one function of φ for the whole recording, which the jackknife over
// segments cannot see; φ differs by direction, so that worst sign is within its reach.
Eigen::VectorXd calibration_shift(const ActuatorPrepared& P, const Grams& g,
                                  const std::vector<Column>& cols, const std::vector<int>& current,
                                  double error_n) {
  const auto m = static_cast<Eigen::Index>(current.size());
  const Eigen::MatrixXd a_inv =
      stats::summed_gram(g, current).completeOrthogonalDecomposition().pseudoInverse();
  Eigen::VectorXd x(m), weight_sum = Eigen::VectorXd::Zero(m);
  for (std::size_t i = 0; i < P.states.size(); ++i) {
    if (P.ringing[i]) continue;  // the samples accumulate_sliding() used
    unit_row(Form::nut, cols, P.states[i], x.data());
    weight_sum += (a_inv * x).cwiseAbs();
  }
  return error_n * weight_sum;
}

// Each term's calibration errors: the change of its parameters when each of its columns moves
// by its calibration shift, summed over its columns (linear in the shifts, as the fit is).
void set_calibration_errors(const Eigen::VectorXd& theta, const Eigen::VectorXd& shift,
                            const State& model, std::vector<selection::Found>& terms) {
  Eigen::Index off = 0;
  for (auto& c : terms) {
    const auto k = static_cast<Eigen::Index>(c.effect->columns());
    const auto at = c.effect->parameters(c.shape, theta.segment(off, k).data(), model);
    for (Eigen::Index j = 0; at && j < k; ++j) {
      Eigen::VectorXd moved = theta.segment(off, k);
      moved[j] += shift[off + j];
      const auto to = c.effect->parameters(c.shape, moved.data(), model);
      if (!to) continue;
      for (const auto& [name, value] : *at)  // a value on a scanned grid does not move here
        if (const auto q = to->find(name); q != to->end() && q->second != value)
          c.calibration_errors[name] += std::abs(q->second - value);
    }
    off += k;
  }
}

// Final fit on everything: the corrected residual, the parameters and their standard errors.
void finish_sliding(const ActuatorPrepared& P, const Grams& g, const Candidates& cand,
                    const State& model, const std::vector<int>& current, SlidingSelection& out) {
  const auto est = stats::estimate(
      g, current, [&](const Fit& fit) { return sliding_term_parameters(out.terms, fit, model); });
  const Fit& final_fit = est.fit;
  out.final_sse = sse(g, final_fit);
  out.final_residual = P.residual;
  std::vector<Column> used_cols;
  used_cols.reserve(current.size());
  for (int k : current) used_cols.push_back(cand.cols[static_cast<std::size_t>(k)]);
  for (std::size_t i = 0; i < P.states.size(); ++i)
    out.final_residual[i] =
        less_fitted(Form::nut, used_cols, P.states[i], final_fit.theta, out.final_residual[i]);
  for (std::size_t k = 0; k < out.terms.size(); ++k) {
    auto& term = out.terms[k];
    if (est.values[k]) term.params = *est.values[k];
    term.plausible = effects::plausible(*term.effect, term.params, P.scales);
    term.standard_errors = est.standard_errors[k];
  }
  if (!current.empty())
    set_calibration_errors(final_fit.theta,
                           calibration_shift(P, g, used_cols, current, P.minimum_n), model,
                           out.terms);
}

}  // namespace

std::string selection_rule(const StageOptions& opt) {
  return selection::describe(actuator_settings(opt));
}

namespace {
// Each one-column effect's smallest change the recording could name beside the final model's
// terms (Resolvable): the part of its column the model's columns leave (what the fit could give
// to it alone), as an RMS over the samples used, against what a finding must explain.
std::vector<Resolvable> resolvable_of(const Grams& g, const Candidates& cand, const State& model,
                                      const std::vector<int>& current, double floor_n,
                                      double n_used) {
  std::vector<Resolvable> out;
  if (g.xx.empty() || !(n_used > 0)) return out;
  Eigen::MatrixXd xx = Eigen::MatrixXd::Zero(g.xx.front().rows(), g.xx.front().cols());
  for (const auto& m : g.xx) xx += m;
  const auto n = static_cast<Eigen::Index>(current.size());
  const auto solver = stats::summed_gram(g, current).ldlt();
  for (const auto& v : cand.variants) {
    if (v.idx.size() != 1 || cand.of(v.effect) != &v || v.effect->params().empty()) continue;
    const int col = v.idx.front();
    if (std::find(current.begin(), current.end(), col) != current.end()) continue;
    Eigen::VectorXd b(n);
    for (Eigen::Index i = 0; i < n; ++i) b(i) = xx(current[i], col);
    const double own_ss = xx(col, col) - (n > 0 ? b.dot(solver.solve(b)) : 0.0);
    if (!(own_ss > 0)) continue;
    const double c = floor_n / std::sqrt(own_ss / n_used), none = 0.0;
    const auto at = v.effect->parameters(v.shape, &c, model);
    const auto at_zero = v.effect->parameters(v.shape, &none, model);
    const std::string name = v.effect->params().front().name;
    if (!at || !at_zero || !at->contains(name) || !at_zero->contains(name)) continue;
    const double change = std::abs(at->at(name) - at_zero->at(name));
    if (std::isfinite(change))
      out.push_back({std::string(v.effect->id()), name, unit_of_parameter(name), change});
  }
  return out;
}
}  // namespace

SlidingSelection select_sliding(const ActuatorPrepared& P, const StageOptions& opt,
                                const std::function<void(double)>& progress) {
  SlidingSelection out;
  const Candidates cand = candidate_columns(Form::nut, opt.exclude);
  const int folds = std::max(rules::kMinFolds, opt.folds);
  const Grams g = accumulate_sliding(P, cand.cols, folds);
  std::size_t n_used = 0;
  for (auto c : g.n) n_used += c;
  out.samples_used = n_used;
  out.baseline_sse = out.final_sse = total(g.rr);
  out.measured_ss = total(g.yy);
  out.final_residual = P.residual;  // nothing fitted yet: what the baseline leaves
  if (n_used < rules::kMinSlidingSamples) {
    out.too_little_sliding = true;
    return out;
  }
  const NutRules rules(P, P.states.empty() ? State{} : P.states.front(), opt.min_t);
  const auto o =
      selection::select(g, cand, rules, actuator_settings(opt, P.scales), {}, {}, progress);
  const selection::Span span{.n_used = static_cast<double>(n_used),
                             .t0_s = P.t0_s,
                             .duration_s = P.duration_s,
                             .floor_n = std::max(P.floor_n, P.minimum_n),
                             .min_gain_pct = opt.min_gain_pct};
  static_cast<selection::Result&>(out) = selection::result_of(o, folds, span);
  finish_sliding(P, g, cand, rules.model(), out.current, out);
  out.resolvable = resolvable_of(g, cand, rules.model(), out.current, span.floor_n, span.n_used);
  return out;
}

// ------------------------------------------------------------------------------- break-away
Breakaway breakaway_test(const ActuatorPrepared& P, const Baseline& base,
                         const std::vector<selection::Found>& chosen) {
  Breakaway out;
  // The model's break-away level per direction, with the terms found so far.
  std::vector<std::pair<const effects::Effect*, effects::Params>> terms;
  terms.reserve(chosen.size());
  for (const auto& c : chosen) terms.emplace_back(c.effect, c.params);
  for (int side = 0; side < 2; ++side) {
    const double dir = side == 0 ? 1.0 : -1.0;
    std::vector<double> excess, count_force, rate;
    for (const auto& e : P.stuck) {
      if (e.dir != dir) continue;
      double net = e.net_n;
      double level = base.coulomb_n;
      for (const auto& t : base.terms) level += t.effect->breakaway_extra_n(t.params, e.state, dir);
      for (const auto& [eff, prm] : terms) {
        net += eff->force_n(prm, e.state);  // forces that act while stuck (offset, gain …)
        level += eff->breakaway_extra_n(prm, e.state, dir);
      }
      // At release the net driving force equals the break-away friction.
      excess.push_back(dir * net - level);
      count_force.push_back(std::abs(e.state.coupling_slope_n_per_rad) * 2 * kPi * P.count_m /
                            P.lead_m);
      rate.push_back(std::max(0.0, e.net_rate_n_s));
    }
    auto& s = side == 0 ? out.pos : out.neg;
    s.episodes = excess.size();
    if (excess.size() < rules::kMinReleases) continue;
    s.median_excess_n = median_of(excess);
    s.count_force_n = median_of(count_force);
    // The release is seen once the nut has moved one count; meanwhile the driving force keeps
    // rising at Ḟ. A nut that breaks away at its kinetic level (no hump) is pushed by the excess
    // Ḟt alone: x = Ḟt³/(6M), so one count c takes t = (6Mc/Ḟ)^⅓ and the force seen at release
    // is up to (6McḞ²)^⅓ above the true break-away. With a hump ΔF the nut jumps off at once:
    // half a count (the mean distance to the next edge) in √(Mc/ΔF), Ḟ times that.
    const double rdot = median_of(rate), M = base.nut_mass_kg, c = P.count_m;
    s.lag_bound_n = std::cbrt(6.0 * M * c * rdot * rdot);
    s.lag_expected_n =
        std::min(rules::kExpectedLagOfBound * s.lag_bound_n,
                 rdot * std::sqrt(M * c / std::max(s.median_excess_n, 0.5 * s.count_force_n)));
    // Spread of the median: 1.25 σ/√n for a normal sample, σ from the median deviation.
    s.se_n = rules::kMedianSeFactor * robust_sigma(excess) /
             std::sqrt(static_cast<double>(excess.size()));
  }
  return out;
}

}  // namespace maglead::analysis::actuator

namespace maglead::analysis::actuator {

double breakaway_margin(const Breakaway::Side& s) {
  if (s.episodes < rules::kMinReleases || !(s.se_n > 0))
    return -std::numeric_limits<double>::infinity();
  return (s.median_excess_n - s.lag_bound_n - rules::kReleasePhaseCounts * s.count_force_n) /
         s.se_n;
}

// Stribeck's law is a break-away above the kinetic level; the sliding fit sees only friction
// that falls with speed, which a misfit can make too (beside gear play the Coulomb term that
// stands for it left 0.2 N at 5 mm/s, 0.05 N at 20 mm/s and none at 50 mm/s, with no break-away
// beyond the first-count lag at the releases). Where the recording has releases in both
// directions, the hump must show there as well, by the test stribeck_from_breakaway names it on.
std::optional<std::string> stribeck_unseen_at_rest(const ActuatorPrepared& P, const Baseline& base,
                                                   const SlidingSelection& sel,
                                                   const StageOptions& opt) {
  auto without = sel.terms;
  const auto n_before = without.size();
  std::erase_if(without, [](const selection::Found& c) { return c.id == "stribeck_friction"; });
  if (without.size() == n_before) return std::nullopt;
  const auto bt = breakaway_test(P, base, without);
  if (bt.pos.episodes < rules::kMinReleases || bt.neg.episodes < rules::kMinReleases)
    return std::nullopt;
  const double t = std::min(breakaway_margin(bt.pos), breakaway_margin(bt.neg));
  if (t >= opt.breakaway_sigmas) return std::nullopt;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "friction falls with speed while sliding, but the %zu + %zu releases show no "
                "break-away above the kinetic level beyond the first-count lag (excess %.2f / "
                "%.2f N, lag up to %.2f / %.2f N, half a count %.2f N): not Stribeck's law",
                bt.pos.episodes, bt.neg.episodes, bt.pos.median_excess_n, bt.neg.median_excess_n,
                bt.pos.lag_bound_n, bt.neg.lag_bound_n,
                rules::kReleasePhaseCounts * bt.pos.count_force_n);
  return std::string(buf);
}

namespace {

struct StribeckVelocity {
  double value = 0, low = 0, high = 0;  // the estimate and the scanned values the data allow
  bool determined = false;
};

// The Stribeck velocity: the one whose low-speed friction rise best fits the sliding residual.
// Every scanned value within 1 % of the worst fit's error of the best one fits as well (without
// slow sliding, every value: all predict nothing there). The velocity is determined when one
// value stands alone; otherwise the middle (on a log scale) of those the data allow, and the
// finding says so.
StribeckVelocity stribeck_velocity(const ActuatorPrepared& P, const SlidingSelection& sel,
                                   const effects::Effect& e, double excess_n) {
  const auto shapes = e.shapes();
  std::vector<double> sse;
  for (double vs : shapes) {
    double s = 0, x = 0;
    for (std::size_t i = 0; i < P.states.size(); ++i) {
      e.regressors(vs, P.states[i], &x);
      const double r = sel.final_residual[i] - excess_n * x;
      s += r * r;
    }
    sse.push_back(s);
  }
  const double best = *std::min_element(sse.begin(), sse.end());
  const double worst = *std::max_element(sse.begin(), sse.end());
  StribeckVelocity out{0, INFINITY, 0, false};
  int allowed = 0;
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    if (sse[k] - best > rules::kStribeckVelocityFitShare * worst) continue;
    ++allowed;
    out.low = std::min(out.low, shapes[k]);
    out.high = std::max(out.high, shapes[k]);
  }
  out.determined = allowed == 1;
  out.value = std::sqrt(out.low * out.high);
  return out;
}

}  // namespace

// Break-away above the kinetic level in both directions is static friction (Stribeck's law).
// The release is seen only once the nut has crossed an encoder count: the force read then is
// late by up to the lag bound (breakaway_test), and the phase it is computed from is known to
// half a count's coupling force. Only an excess beyond both is physics.
std::optional<selection::Found> stribeck_from_breakaway(const ActuatorPrepared& P,
                                                        const Baseline& base,
                                                        const SlidingSelection& sel,
                                                        const Breakaway& bt,
                                                        const StageOptions& opt) {
  // A kinetic level found by the sliding fit stays: Stribeck's law carries it as its coulomb_n.
  double kinetic_n = base.coulomb_n;
  for (const auto& c : sel.terms) {
    if (c.id == "stribeck_friction") return std::nullopt;
    if (c.id == "coulomb_friction") kinetic_n = c.params.at("coulomb_n");
  }
  for (const auto& id : opt.exclude)
    if (id == "stribeck_friction") return std::nullopt;
  const double t_pos = breakaway_margin(bt.pos), t_neg = breakaway_margin(bt.neg);
  if (std::min(t_pos, t_neg) < opt.breakaway_sigmas) return std::nullopt;
  // The break-away corrected for the force that rose while the nut crossed its first count.
  const double excess = 0.5 * (bt.pos.median_excess_n - bt.pos.lag_expected_n +
                               bt.neg.median_excess_n - bt.neg.lag_expected_n);
  const auto* e = effects::find("stribeck_friction");
  State model = P.states.empty() ? State{} : P.states.front();
  model.coulomb_n = kinetic_n;
  const auto vs = stribeck_velocity(P, sel, *e, excess);
  selection::Found c;
  c.id = "stribeck_friction";
  c.effect = e;
  c.shape = vs.value;
  const double coef = excess;
  c.params = *e->parameters(vs.value, &coef, model);
  c.t_stat = std::min(t_pos, t_neg);
  c.from_releases = selection::Found::FromReleases{vs.determined, {vs.low, vs.high}, 0};
  c.segments = static_cast<int>(bt.pos.episodes + bt.neg.episodes);
  return c;
}

// At a release in +p the driving force the model sees is B − F_o, in −p it is B + F_o (an offset
// F_o along +p unseen by the load cell): half the difference of the two sides' excesses, each
// corrected for its first-count lag, is F_o, whatever the break-away B (Stribeck's hump or none).
// The phase at each release is known to half a count's force, so the difference must exceed
// that by opt.breakaway_sigmas standard errors, and the floors a sliding finding must beat.
std::optional<selection::Found> offset_from_breakaway(const ActuatorPrepared& P,
                                                      const SlidingSelection& sel,
                                                      const Breakaway& bt,
                                                      const StageOptions& opt) {
  if (!sel.too_little_sliding || bt.pos.episodes < rules::kMinReleases ||
      bt.neg.episodes < rules::kMinReleases)
    return std::nullopt;
  for (const auto& id : opt.exclude)
    if (id == "offset") return std::nullopt;
  const double pos = bt.pos.median_excess_n - bt.pos.lag_expected_n;
  const double neg = bt.neg.median_excess_n - bt.neg.lag_expected_n;
  const double offset_n = 0.5 * (neg - pos);
  const double se_n = 0.5 * std::hypot(bt.pos.se_n, bt.neg.se_n);
  const double margin =
      (std::abs(offset_n) -
       rules::kReleasePhaseCounts * std::max(bt.pos.count_force_n, bt.neg.count_force_n)) /
      se_n;
  if (!(margin >= opt.breakaway_sigmas) || std::abs(offset_n) < std::max(P.floor_n, P.minimum_n))
    return std::nullopt;
  const auto* e = effects::find("offset");
  const double coef = offset_n;
  selection::Found c;
  c.id = "offset";
  c.effect = e;
  c.params = *e->parameters(0.0, &coef, State{});
  c.standard_errors = {{"offset_n", se_n}};
  c.plausible = effects::plausible(*e, c.params, P.scales);
  if (!c.plausible) return std::nullopt;
  c.t_stat = margin;
  c.segments = static_cast<int>(bt.pos.episodes + bt.neg.episodes);
  return c;
}

}  // namespace maglead::analysis::actuator

namespace maglead::analysis::actuator {

namespace {
// Pulses that stall a sliding nut leave no sliding sample: friction held it while they acted. A
// stall (a stop in the middle of a move, no longer than a pulse) whose drive, for three quarters
// of it, exceeded every break-away the recording's starts from rest show in that direction by more
// than the pulse threshold, was held by a force no input explains: at least that excess, against
// the motion. Both are measured with the final model's terms (a spring it names drives the nut
// too). Stick-slip stalls hold no more than the break-away, so they are not pulses.
void add_stalls(const ActuatorPrepared& P, const std::vector<selection::Found>& terms, double thr,
                const pulses::Floors& f, std::vector<pulses::Pulse>& found) {
  const auto along = [&](double dir, double net_n, const State& x) {
    for (const auto& c : terms) net_n += c.effect->force_n(c.params, x);
    return dir * net_n;
  };
  std::vector<pulses::Pulse> stalls;
  for (const double dir : {1.0, -1.0}) {
    std::optional<double> breakaway_n;
    for (const auto& e : P.stuck)
      if (e.dir == dir && !e.interrupts)
        breakaway_n = std::max(breakaway_n.value_or(std::numeric_limits<double>::lowest()),
                               along(dir, e.net_n, e.state));
    if (!breakaway_n) continue;  // nothing to tell a stall's hold from friction's
    for (const auto& e : P.stuck) {
      if (e.dir != dir || !e.interrupts || e.held_s > f.max_s) continue;
      const double t0 = e.t_release_s - e.held_s;
      const double excess = along(dir, e.held_net_n, e.held) - *breakaway_n;
      const bool seen = std::any_of(found.begin(), found.end(), [&](const pulses::Pulse& q) {
        return q.t_s < e.t_release_s && t0 < q.t_s + q.duration_s;
      });
      if (excess > thr && !seen) stalls.push_back({t0, e.held_s, -dir * excess});
    }
  }
  // Isolated, as the residual's pulses: many such stalls are a friction the model lacks.
  if (static_cast<double>(found.size() + stalls.size()) > f.span_s / f.min_spacing_s) return;
  found.insert(found.end(), stalls.begin(), stalls.end());
  std::sort(found.begin(), found.end(),
            [](const pulses::Pulse& a, const pulses::Pulse& b) { return a.t_s < b.t_s; });
}

// The work the final model's terms (beyond the baseline's, which the jump's work holds) did over
// a jump, from its two stands (a trapezoid: the laws are smooth over a jump's few counts).
double terms_work_j(const std::vector<selection::Found>& terms, const Jump& jp) {
  double from_n = 0, to_n = 0;
  for (const auto& c : terms)
    from_n += c.effect->force_n(c.params, jp.from), to_n += c.effect->force_n(c.params, jp.to);
  return 0.5 * (from_n + to_n) * (jp.to.p_m - jp.from.p_m);
}

// Pulses that throw a standing nut to its next stand quicker than the filter resolves: no sliding
// sample shows them. Friction only takes work out: from stand to stand the recorded forces do at
// least the kinetic friction times the travel (the rest goes into viscous friction and the load's
// damping), so the jumps' work per metre, per direction, is that friction level. A jump short of
// its direction's level (at least rules::kMinReleases jumps) by more than the pulse threshold and
// the pulse sigmas of the jumps' own robust spread was pushed along by a force no input explains:
// at least that shortfall, over the jump (the stand it reaches may hold the rest of the pulse).
void add_throws(const ActuatorPrepared& P, const std::vector<selection::Found>& terms, double thr,
                const pulses::Floors& f, std::vector<pulses::Pulse>& found) {
  std::vector<pulses::Pulse> throws;
  const double reach_s = rules::kPulseFlankFilterPeriods / f.filter_hz;
  for (const double dir : {1.0, -1.0}) {
    std::vector<double> per_m;  // each jump's work per metre of travel [N]
    std::vector<const Jump*> side;
    for (const auto& jp : P.jumps) {
      if (jp.dir != dir) continue;
      per_m.push_back((jp.work_j + terms_work_j(terms, jp)) / jp.path_m);
      side.push_back(&jp);
    }
    if (per_m.size() < rules::kMinReleases) continue;  // no level to fall short of
    const double level_n = stats::median_of(per_m);
    const double limit_n = std::max(thr, f.sigmas * stats::robust_sigma(per_m));
    for (std::size_t q = 0; q < side.size(); ++q) {
      const Jump& jp = *side[q];
      // One pulse is one event: a jump within a found pulse's flanks is that pulse's.
      const auto near = [&](const pulses::Pulse& p) {
        return p.t_s - reach_s < jp.t_s + jp.duration_s && jp.t_s < p.t_s + p.duration_s + reach_s;
      };
      const bool seen = std::any_of(found.begin(), found.end(), near) ||
                        std::any_of(throws.begin(), throws.end(), near);
      if (level_n - per_m[q] > limit_n && !seen && !jp.slides)
        throws.push_back({jp.t_s, jp.duration_s, dir * (level_n - per_m[q])});
    }
  }
  // Isolated, as the residual's pulses: many such jumps are a friction the model lacks.
  if (static_cast<double>(found.size() + throws.size()) > f.span_s / f.min_spacing_s) return;
  found.insert(found.end(), throws.begin(), throws.end());
  std::sort(found.begin(), found.end(),
            [](const pulses::Pulse& a, const pulses::Pulse& b) { return a.t_s < b.t_s; });
}
}  // namespace

// Force pulses no input explains in the corrected residual on the sliding samples (the one
// pulse finder), above one encoder count's worth of force and not a library law's force where
// the nut was (pulses::unexplained); pulses that stall a sliding nut or throw a standing one.
std::vector<pulses::Pulse> actuator_pulses(const ActuatorPrepared& P, const SlidingSelection& sel,
                                           const StageOptions& opt) {
  pulses::Floors f;
  f.min_n = P.count_force_n;
  f.sigmas = opt.pulse_sigmas;
  f.max_s = opt.pulse_max_s;
  f.min_spacing_s = opt.pulse_min_spacing_s;
  f.filter_hz = P.filter_hz;
  f.fs_hz = P.fs_hz;
  f.step_s = static_cast<double>(P.decimation) / P.fs_hz;
  f.span_s = P.duration_s;
  std::vector<double> t(P.states.size());
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = P.states[i].t_s;
  const auto& r = sel.final_residual;
  auto found =
      pulses::unexplained(t, r, P.states, Form::nut, candidate_columns(Form::nut, opt.exclude),
                          sel.current, f, pulses::find(t, r, f));
  const double thr = pulses::threshold(r, f);
  add_stalls(P, sel.terms, thr, f, found);
  add_throws(P, sel.terms, thr, f, found);
  return found;
}

}  // namespace maglead::analysis::actuator
