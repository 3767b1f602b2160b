// The actuator analysis as stages: prepare (filtered states and the baseline's force residual on
// sliding samples) → locate → select (forward selection of effect units on held-out time
// segments) → break-away test on stuck episodes → refit and validate → events. Every law and
// regressor comes from the effect library (effects/); nothing here knows an effect's formula.
#include "actuator_analysis.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include "maglead/analysis/signal.hpp"
#include "statistics.hpp"

namespace maglead::analysis::actuator {
namespace {

constexpr double kPi = std::numbers::pi;
using effects::State;
using stats::median_of;
using stats::require_finite;
using stats::robust_sigma;

double sample_rate(const Recording& rec) {
  if (auto s = rec.meta("sample_rate_hz")) {
    try {
      const double f = std::stod(*s);
      if (f > 0) return f;
    } catch (const std::exception&) {
    }
  }
  const auto& t = rec.column("t_s");
  std::vector<double> d;
  for (std::size_t i = 1; i < t.size() && d.size() < 20000; ++i) d.push_back(t[i] - t[i - 1]);
  const double dt = median_of(d);
  if (!(dt > 0)) throw std::invalid_argument(rec.path + ": t_s does not advance");
  return 1.0 / dt;
}

// Coupling force on the nut, F_m = −F̂_s: the polynomial on the calibrated branch, the periodic
// model past it (step-out), so the force is defined for every phase.
struct Coupling {
  const ForceCalibration& cal;
  double force(double phi) const {
    if (phi >= cal.stable_min_rad && phi <= cal.stable_max_rad)
      return -cal.polynomial.load_force_n(phi);
    return -cal.periodic.load_force_n(phi);
  }
  double slope(double phi) const {
    if (phi >= cal.stable_min_rad && phi <= cal.stable_max_rad)
      return -cal.polynomial.slope_n_per_rad(phi);
    return -cal.periodic.slope_n_per_rad(phi);
  }
};

// Step-outs from the raw phase: a slip carries φ past ±π from the branch it sat on.
std::vector<SlipEvent> find_slips(const std::vector<double>& t, const std::vector<double>& phi) {
  std::vector<SlipEvent> out;
  if (phi.empty()) return out;
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
double rising_rate(const std::vector<double>& t, const std::vector<double>& phi,
                   const std::vector<double>& load, const Coupling& cp, std::size_t first,
                   std::size_t last, double window_s) {
  std::size_t k = last;
  while (k > first && t[last] - t[k - 1] <= window_s) --k;
  if (last - k < 3) return 0.0;
  double st = 0, sf = 0, stt = 0, stf = 0;
  const auto m = static_cast<double>(last - k + 1);
  for (std::size_t q = k; q <= last; ++q) {
    const double x = t[q] - t[last], f = cp.force(phi[q]) + load[q];
    st += x, sf += f, stt += x * x, stf += x * f;
  }
  const double den = m * stt - st * st;
  return den > 0 ? (m * stf - st * sf) / den : 0.0;
}

}  // namespace

std::vector<double> angle_column(const Recording& rec, const ActuatorParams& act) {
  if (rec.has("screw_angle_rad")) return rec.column("screw_angle_rad");
  if (rec.has("motor_angle_rad")) {
    double gear = act.gear_ratio;
    if (auto g = rec.meta("gear_ratio")) gear = std::stod(*g);
    auto th = rec.column("motor_angle_rad");
    for (double& x : th) x /= gear;
    return th;
  }
  throw RecordingError(rec.path + ": needs column 'screw_angle_rad' or 'motor_angle_rad'");
}

// ------------------------------------------------------------------------------- prepare
Prepared prepare(const Recording& rec, const Baseline& base, const ForceCalibration& cal,
                 const ActuatorParams& act, const Options& opt) {
  Prepared P;
  for (const char* c : {"t_s", "nut_pos_m", "load_force_n"}) require_finite(rec, rec.column(c), c);
  const auto& t = rec.column("t_s");
  const std::size_t n = t.size();
  if (n < 200)
    throw std::invalid_argument(rec.path + ": too short to analyse (" + std::to_string(n) +
                                " rows)");
  const auto theta_raw = angle_column(rec, act);
  require_finite(rec, theta_raw, "screw_angle_rad");
  const auto& pos_raw = rec.column("nut_pos_m");
  const auto& load_raw = rec.column("load_force_n");
  P.fs_hz = sample_rate(rec);
  // The nut's mechanics (mass on the coupling stiffness) sit near 100 Hz; the effects live
  // below a few tens of Hz. The filter keeps those and averages encoder steps and load-cell noise.
  P.filter_hz = std::min(opt.filter_hz, 0.2 * P.fs_hz);
  const double dt = 1.0 / P.fs_hz;
  P.lead_m = act.lead_m;
  P.count_m = act.linear_count_m;
  if (auto c = rec.meta("linear_encoder_m_per_count")) P.count_m = std::stod(*c);

  const auto p = filtfilt_butter4(pos_raw, P.filter_hz, P.fs_hz);
  const auto th = filtfilt_butter4(theta_raw, P.filter_hz, P.fs_hz);
  const auto load = filtfilt_butter4(load_raw, P.filter_hz, P.fs_hz);
  const auto v = central_diff(p, dt);
  const auto a = central_diff2(p, dt);
  const auto load_rate = central_diff(load, dt);
  std::vector<double> phi(n), phi_raw(n);
  for (std::size_t i = 0; i < n; ++i) {
    phi[i] = th[i] - 2 * kPi * p[i] / act.lead_m;
    phi_raw[i] = theta_raw[i] - 2 * kPi * pos_raw[i] / act.lead_m;
  }
  const auto phi_rate = central_diff(phi, dt);
  P.slips = find_slips(t, phi_raw);

  // Noise of the load cell from its sample-to-sample roughness (white noise: var(Δ²y) = 6σ²).
  {
    std::vector<double> d2;
    d2.reserve(n);
    for (std::size_t i = 1; i + 1 < n; ++i)
      d2.push_back(load_raw[i + 1] - 2 * load_raw[i] + load_raw[i - 1]);
    P.load_noise_n = robust_sigma(d2) / std::sqrt(6.0);
  }

  // Sliding samples: moving in one direction for the whole filter support around the sample,
  // faster than one encoder count per filter time constant (slower, the nut may be stuck and its
  // friction is anywhere in the break-away band), and away from step-outs.
  const double v_min = P.count_m * P.filter_hz;
  P.v_min_m_s = v_min;
  const auto w = static_cast<std::size_t>(std::ceil(P.fs_hz / P.filter_hz));
  std::vector<unsigned char> ok(n, 0);
  for (std::size_t i = 0; i < n; ++i) ok[i] = std::abs(v[i]) > v_min;
  {
    std::size_t i = 0;
    while (i < n) {
      if (!ok[i]) {
        ++i;
        continue;
      }
      std::size_t j = i;
      while (j < n && ok[j] && (v[j] > 0) == (v[i] > 0)) ++j;
      for (std::size_t k = i; k < j; ++k)
        if (k < i + w || k + w >= j) ok[k] = 0;
      i = j;
    }
  }
  for (const auto& s : P.slips)
    for (std::size_t i = 0; i < n; ++i)
      if (t[i] > s.start_s - 0.1 && t[i] < s.t_s + 0.3) ok[i] = 0;

  // Keep every `decim`-th sliding sample: the signals are band-limited to filter_hz, so samples
  // closer than a fifth of its period add no information, only work.
  P.decimation = std::max(1, static_cast<int>(std::floor(P.fs_hz / (5 * P.filter_hz))));
  const Coupling cp{cal};
  P.count_force_n = std::abs(cp.slope(0.0)) * 2 * kPi * P.count_m / act.lead_m;
  // Rounding to a count is uniform over one count (RMS c/√12); both it and the load-cell noise
  // are broadband, and the filter keeps 2 f_c / f_s of their power.
  const double kept = std::sqrt(std::min(1.0, 2.0 * P.filter_hz / P.fs_hz));
  P.floor_n = kept * std::hypot(P.count_force_n / std::sqrt(12.0), P.load_noise_n);
  P.minimum_n =
      opt.min_effect_of_peak * std::max(std::abs(cal.peak_push_n), std::abs(cal.peak_pull_n));
  P.t0_s = t.front();
  auto state_at = [&](std::size_t i) {
    State s;
    s.t_s = t[i] - P.t0_s;
    s.p_m = p[i];
    s.v_m_s = v[i];
    s.a_m_s2 = a[i];
    s.theta_rad = th[i];
    s.phi_rad = phi[i];
    s.phi_rate_rad_s = phi_rate[i];
    s.coupling_n = cp.force(phi[i]);
    s.coupling_slope_n_per_rad = cp.slope(phi[i]);
    s.load_n = load[i];
    s.load_rate_n_s = load_rate[i];
    s.stroke_min_m = act.stroke_min_m;
    s.stroke_max_m = act.stroke_max_m;
    s.lead_m = act.lead_m;
    s.coulomb_n = base.coulomb_n;
    s.viscous_n_s_per_m = base.viscous_n_s_per_m;
    s.nut_mass_kg = base.nut_mass_kg;
    return s;
  };
  auto missing_force = [&](const State& s) {
    // What the baseline leaves out of M p̈ = F_m − C v − F_c sign(v) + F_ext + Σ terms.
    double r = base.nut_mass_kg * s.a_m_s2 - s.coupling_n + base.viscous_n_s_per_m * s.v_m_s +
               base.coulomb_n * effects::sgn(s.v_m_s) - s.load_n;
    for (const auto& term : base.terms) r -= term.effect->force_n(term.params, s);
    return r;
  };
  for (std::size_t i = 0; i < n; i += static_cast<std::size_t>(P.decimation)) {
    if (!ok[i]) continue;
    P.states.push_back(state_at(i));
    P.residual.push_back(missing_force(P.states.back()));
  }
  P.samples = n;
  P.duration_s = t.back() - t.front();

  // Stuck episodes (raw nut count unchanged) and the net force on the nut as each one ends.
  const double hold_s = std::max(0.02, 4.0 / P.fs_hz);
  std::size_t i = 0;
  while (i < n) {
    std::size_t j = i;
    while (j + 1 < n && std::abs(pos_raw[j + 1] - pos_raw[i]) < 0.5 * P.count_m) ++j;
    if (t[j] - t[i] >= hold_s && j + 1 < n) {
      // Released: which way, and did it keep going (a slip, not encoder chatter)?
      const double dir = pos_raw[j + 1] > pos_raw[i] ? 1.0 : -1.0;
      const std::size_t k_end = std::min(n - 1, j + static_cast<std::size_t>(0.03 * P.fs_hz) + 1);
      const bool slipped = dir * (pos_raw[k_end] - pos_raw[i]) >= 2.5 * P.count_m;
      bool near_slip = false;
      for (const auto& s : P.slips) near_slip |= std::abs(t[j] - s.t_s) < 0.3;
      if (slipped && !near_slip) {
        StuckEpisode e;
        e.t_release_s = t[j] - P.t0_s;
        e.dir = dir;
        // Net force just before release, from unfiltered signals: the filter would smear the
        // release into the stuck part.
        State s = state_at(j);
        s.coupling_n = cp.force(phi_raw[j]);
        s.load_n = load_raw[j];
        s.v_m_s = 0;
        s.a_m_s2 = 0;
        e.net_n = s.coupling_n + s.load_n;
        for (const auto& term : base.terms) e.net_n += term.effect->force_n(term.params, s);
        e.state = s;
        e.net_rate_n_s = dir * rising_rate(t, phi_raw, load_raw, cp, i, j, 0.05);
        P.stuck.push_back(e);
      }
    }
    i = j + 1;
  }
  return P;
}

// ------------------------------------------------------------------------------- fitting
namespace {

using stats::Fit;
using stats::Grams;
using stats::heldout;
using stats::partial_r2;
using stats::solve;
using stats::sse;
using stats::t_statistic;
using stats::total;

struct Column {
  const effects::Effect* effect;
  double shape;
  int index;  // within the effect's columns
};

Grams accumulate(const Prepared& P, const std::vector<Column>& cols, int folds) {
  const auto m = static_cast<Eigen::Index>(cols.size());
  Grams g(static_cast<std::size_t>(folds), m);
  Eigen::VectorXd x(m);
  double buf[8];
  for (std::size_t i = 0; i < P.states.size(); ++i) {
    const auto& s = P.states[i];
    for (Eigen::Index j = 0; j < m;) {
      const auto& c = cols[static_cast<std::size_t>(j)];
      c.effect->regressors(c.shape, s, buf);
      const int k = c.effect->columns();
      for (int q = 0; q < k; ++q) x[j + q] = buf[q];
      j += k;
    }
    auto f = static_cast<std::size_t>(
        std::min<double>(folds - 1, std::floor(folds * s.t_s / P.duration_s)));
    g.add_row(f, x, P.residual[i], s.load_n);
  }
  g.symmetrize();
  return g;
}

// Standard error of a chosen term's parameters from the held-out segments: the fit without
// each segment in turn (a jackknife over contiguous time, so slow drifts and correlated noise
// count as they would in a new recording), (K−1)/K times the sum of squared deviations.
effects::Params jackknife_se(const Grams& g, const std::vector<int>& idx, Eigen::Index off,
                             const Candidate& c, const State& model) {
  const auto* e = effects::find(c.id);
  const auto k = static_cast<Eigen::Index>(e->columns());
  std::map<std::string, std::vector<double>, std::less<>> values;
  for (std::size_t f = 0; f < g.xx.size(); ++f) {
    if (g.n[f] == 0) continue;
    const Fit fit = solve(g, idx, static_cast<int>(f));
    if (auto prm = e->parameters(c.shape, fit.theta.segment(off, k).data(), model))
      for (const auto& [name, v] : *prm) values[name].push_back(v);
  }
  effects::Params se;
  for (const auto& [name, v] : values) {
    if (v.size() < 2) continue;
    const double mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
    double ss = 0;
    for (double x : v) ss += (x - mean) * (x - mean);
    const auto kk = static_cast<double>(v.size());
    se[name] = std::sqrt((kk - 1) / kk * ss);
  }
  return se;
}

// Keeps the implausible fit that removes the most held-out error, and where the error it
// leaves is largest (the segment a user should look at first).
void note_implausible(Selection& out, const Grams& g, const std::vector<double>& cur_ho,
                      const std::vector<double>& ho, const effects::Effect& e,
                      const effects::Params& prm, const Prepared& P, std::size_t n_used) {
  const double before = total(cur_ho), after = total(ho);
  if (!(before > 0) || after >= before) return;
  const double gain = 100.0 * (before - after) / before;
  if (out.implausible && out.implausible->gain_pct >= gain) return;
  Implausible imp{std::string(e.id()),
                  prm,
                  gain,
                  0.0,
                  std::sqrt((before - after) / static_cast<double>(n_used)),
                  0.0,
                  0.0};
  std::size_t worst = 0;
  for (std::size_t f = 0; f < ho.size(); ++f)
    if (ho[f] > ho[worst]) worst = f;
  const double seg = P.duration_s / static_cast<double>(g.xx.size());
  imp.worst_t0_s = P.t0_s + seg * static_cast<double>(worst);
  imp.worst_t1_s = imp.worst_t0_s + seg;
  out.implausible = imp;
}

}  // namespace

// ------------------------------------------------------------------------------- select
Selection select(const Prepared& P, const Options& opt,
                 const std::function<void(double)>& progress) {
  Selection out;
  const int folds = std::max(4, opt.folds);
  // Every candidate column, once.
  std::vector<Column> cols;
  struct Variant {
    const effects::Effect* effect;
    double shape;
    std::vector<int> idx;
  };
  std::vector<Variant> variants;
  for (const effects::Effect* e : effects::library()) {
    if (!e->selectable() || e->columns() == 0) continue;
    bool in_base = false;
    for (const auto& id : opt.exclude) in_base |= id == e->id();
    if (in_base) continue;
    auto shapes = e->shapes();
    if (shapes.empty()) shapes.push_back(0.0);
    for (double sh : shapes) {
      Variant v{e, sh, {}};
      for (int k = 0; k < e->columns(); ++k) {
        v.idx.push_back(static_cast<int>(cols.size()));
        cols.push_back({e, sh, k});
      }
      variants.push_back(v);
    }
  }
  const Grams g = accumulate(P, cols, folds);
  std::size_t n_used = 0;
  for (auto c : g.n) n_used += c;
  out.samples_used = n_used;
  if (n_used < 50) {
    out.too_little_sliding = true;
    return out;
  }
  const State model = P.states.empty() ? State{} : P.states.front();
  std::vector<int> current;
  std::vector<double> cur_ho = heldout(g, current);
  out.baseline_heldout_sse = total(cur_ho);
  out.baseline_sse = total(g.rr);
  out.measured_ss = total(g.yy);
  std::vector<const effects::Effect*> used;
  for (int step = 0; step < opt.max_terms; ++step) {
    if (progress) progress(static_cast<double>(step) / opt.max_terms);
    struct Trial {
      const Variant* var = nullptr;
      std::vector<double> ho;
      double gain = 0, t = 0;
      int improved = 0;
      effects::Params params;
    };
    std::vector<Trial> trials;
    for (const auto* e : effects::library()) {
      if (std::find(used.begin(), used.end(), e) != used.end()) continue;
      Trial best;
      double best_sse = INFINITY;
      for (const auto& var : variants) {
        if (var.effect != e) continue;
        std::vector<int> idx = current;
        idx.insert(idx.end(), var.idx.begin(), var.idx.end());
        const Fit full = solve(g, idx, -1);
        const auto prm = e->parameters(
            var.shape, full.theta.tail(static_cast<Eigen::Index>(var.idx.size())).data(), model);
        if (!prm) continue;
        auto ho = heldout(g, idx);
        const double s = total(ho);
        if (!effects::plausible(*e, *prm)) {
          note_implausible(out, g, cur_ho, ho, *e, *prm, P, n_used);
          continue;
        }
        if (s < best_sse) {
          best_sse = s;
          best.var = &var;
          best.ho = std::move(ho);
          best.params = *prm;
        }
      }
      if (!best.var) continue;
      // Consistency over the segments where the term acts (its fitted contribution carries at
      // least a tenth of the segment's error; elsewhere it predicts nothing and tells nothing,
      // as a drift early in a recording): t statistic of the error each one removes.
      const Fit full = [&] {
        std::vector<int> idx = current;
        idx.insert(idx.end(), best.var->idx.begin(), best.var->idx.end());
        return solve(g, idx, -1);
      }();
      const auto k = static_cast<Eigen::Index>(best.var->idx.size());
      const Eigen::VectorXd w = full.theta.tail(k);
      std::vector<double> d, rel;
      for (std::size_t f = 0; f < cur_ho.size(); ++f) {
        if (!(cur_ho[f] > 0)) continue;
        Eigen::MatrixXd xx(k, k);
        for (Eigen::Index r = 0; r < k; ++r)
          for (Eigen::Index c = 0; c < k; ++c)
            xx(r, c) = g.xx[f](best.var->idx[static_cast<std::size_t>(r)],
                               best.var->idx[static_cast<std::size_t>(c)]);
        if (w.dot(xx * w) < opt.acting_share * cur_ho[f]) continue;
        d.push_back(cur_ho[f] - best.ho[f]);
        rel.push_back(d.back() / cur_ho[f]);
        best.improved += d.back() > 0;
      }
      // Relative gains weigh every segment alike (an effect spread over the recording); the
      // error removed weighs segments by what is at stake (an effect that grows, as a drift).
      // Either must be consistent.
      best.t = std::max(t_statistic(d), t_statistic(rel));
      best.gain = 100.0 * (total(cur_ho) - best_sse) / total(cur_ho);
      trials.push_back(std::move(best));
    }
    if (trials.empty()) break;
    auto it = std::max_element(trials.begin(), trials.end(),
                               [](const Trial& a, const Trial& b) { return a.gain < b.gain; });
    // Parsimony: an explanation with fewer parameters that achieves nearly all of the best one's
    // reduction (the data cannot prefer the richer one) is named instead; the richer one then
    // appears as its alternative.
    for (auto jt = trials.begin(); jt != trials.end(); ++jt) {
      const bool fewer = jt->var->idx.size() < it->var->idx.size();
      if (fewer && jt->gain >= opt.parsimony * it->gain) it = jt;
    }
    // Significant: a real share of the held-out error, consistent over the segments, and a
    // force worth a model term (a tenth of what one encoder count resolves).
    const double explained_n =
        std::sqrt(std::max(0.0, total(cur_ho) - total(it->ho)) / static_cast<double>(n_used));
    const bool significant = it->gain >= opt.min_gain_pct && it->t >= opt.min_t &&
                             explained_n >= std::max(P.floor_n, P.minimum_n);
    if (!significant) {
      // What a plausible term could not explain may still be an implausible fit's: reported
      // only when it would have stood out (its gain beyond what was left untaken).
      if (out.implausible && (out.implausible->gain_pct < opt.min_gain_pct ||
                              out.implausible->explained_n < std::max(P.floor_n, P.minimum_n)))
        out.implausible.reset();
      out.next_best = Candidate{
          std::string(it->var->effect->id()), it->params, it->gain, it->t, it->improved, folds, {}};
      break;
    }
    Candidate c{
        std::string(it->var->effect->id()), it->params, it->gain, it->t, it->improved, folds, {}};
    c.shape = it->var->shape;
    // Alternatives: other effects whose columns reproduce this one's contribution.
    const Fit full_new = [&] {
      std::vector<int> idx = current;
      idx.insert(idx.end(), it->var->idx.begin(), it->var->idx.end());
      return solve(g, idx, -1);
    }();
    const Eigen::VectorXd w = full_new.theta.tail(static_cast<Eigen::Index>(it->var->idx.size()));
    for (const auto* e : effects::library()) {
      if (e == it->var->effect || std::find(used.begin(), used.end(), e) != used.end()) continue;
      double best_r2 = 0;
      const Variant* best_v = nullptr;
      for (const auto& var : variants) {
        if (var.effect != e) continue;
        const double r2 = partial_r2(g, current, it->var->idx, w, var.idx);
        if (r2 > best_r2) best_r2 = r2, best_v = &var;
      }
      if (!best_v || best_r2 < opt.alternative_r2) continue;
      std::vector<int> idx = current;
      idx.insert(idx.end(), best_v->idx.begin(), best_v->idx.end());
      const Fit fa = solve(g, idx, -1);
      const auto pa =
          e->parameters(best_v->shape,
                        fa.theta.tail(static_cast<Eigen::Index>(best_v->idx.size())).data(), model);
      if (!pa || !effects::plausible(*e, *pa)) continue;
      c.alternatives.push_back({std::string(e->id()), *pa, 100.0 * best_r2});
    }
    out.implausible.reset();  // judged against what the next step leaves
    current.insert(current.end(), it->var->idx.begin(), it->var->idx.end());
    used.push_back(it->var->effect);
    cur_ho = it->ho;
    out.chosen.push_back(std::move(c));
    out.heldout_sse_after.push_back(total(cur_ho));
  }
  // Final fit on everything: parameters and the corrected residual.
  const Fit final_fit = solve(g, current, -1);
  out.final_sse = 0;
  for (std::size_t f = 0; f < g.xx.size(); ++f) out.final_sse += sse(g, final_fit, f);
  out.final_residual = P.residual;
  {
    std::vector<Column> used_cols;
    used_cols.reserve(current.size());
    for (int k : current) used_cols.push_back(cols[static_cast<std::size_t>(k)]);
    double buf[8];
    for (std::size_t i = 0; i < P.states.size(); ++i) {
      std::size_t j = 0;
      while (j < used_cols.size()) {
        const auto& c = used_cols[j];
        c.effect->regressors(c.shape, P.states[i], buf);
        for (int q = 0; q < c.effect->columns(); ++q, ++j)
          out.final_residual[i] -= final_fit.theta[static_cast<Eigen::Index>(j)] * buf[q];
      }
    }
  }
  std::size_t off = 0;
  for (auto& c : out.chosen) {
    const auto* e = effects::find(c.id);
    const auto k = static_cast<Eigen::Index>(e->columns());
    if (auto prm = e->parameters(
            c.shape, final_fit.theta.segment(static_cast<Eigen::Index>(off), k).data(), model))
      c.params = *prm;
    c.standard_errors = jackknife_se(g, current, static_cast<Eigen::Index>(off), c, model);
    off += static_cast<std::size_t>(k);
  }
  return out;
}

// ------------------------------------------------------------------------------- break-away
BreakawayTest breakaway_test(const Prepared& P, const Baseline& base,
                             const std::vector<Candidate>& chosen) {
  BreakawayTest out;
  // The model's break-away level per direction, with the terms found so far.
  std::vector<std::pair<const effects::Effect*, effects::Params>> terms;
  terms.reserve(chosen.size());
  for (const auto& c : chosen) terms.emplace_back(effects::find(c.id), c.params);
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
    if (excess.size() < 3) continue;
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
        std::min(0.75 * s.lag_bound_n,
                 rdot * std::sqrt(M * c / std::max(s.median_excess_n, 0.5 * s.count_force_n)));
    // Spread of the median: 1.25 σ/√n for a normal sample, σ from the median deviation.
    s.se_n = 1.2533 * robust_sigma(excess) / std::sqrt(static_cast<double>(excess.size()));
  }
  return out;
}

}  // namespace maglead::analysis::actuator

namespace maglead::analysis::actuator {

// Break-away above the kinetic level in both directions is static friction (Stribeck's law).
// The release is seen only once the nut has crossed an encoder count: the force read then is
// late by up to the lag bound (breakaway_test), and the phase it is computed from is known to
// half a count's coupling force. Only an excess beyond both is physics.
std::optional<Candidate> stribeck_from_breakaway(const Prepared& P, const Baseline& base,
                                                 const Selection& sel, const BreakawayTest& bt,
                                                 const Options& opt) {
  // A kinetic level found by the sliding fit stays: Stribeck's law carries it as its coulomb_n.
  double kinetic_n = base.coulomb_n;
  for (const auto& c : sel.chosen) {
    if (c.id == "stribeck_friction") return std::nullopt;
    if (c.id == "coulomb_friction") kinetic_n = c.params.at("coulomb_n");
  }
  for (const auto& id : opt.exclude)
    if (id == "stribeck_friction") return std::nullopt;
  auto margin = [&](const BreakawayTest::Side& s) {
    if (s.episodes < 3 || !(s.se_n > 0)) return -std::numeric_limits<double>::infinity();
    return (s.median_excess_n - s.lag_bound_n - 0.5 * s.count_force_n) / s.se_n;
  };
  const double t_pos = margin(bt.pos), t_neg = margin(bt.neg);
  if (std::min(t_pos, t_neg) < opt.breakaway_sigmas) return std::nullopt;
  // The break-away corrected for the force that rose while the nut crossed its first count.
  const double excess = 0.5 * (bt.pos.median_excess_n - bt.pos.lag_expected_n +
                               bt.neg.median_excess_n - bt.neg.lag_expected_n);
  const auto* e = effects::find("stribeck_friction");
  State model = P.states.empty() ? State{} : P.states.front();
  model.coulomb_n = kinetic_n;
  // The Stribeck velocity: the one whose low-speed friction rise best fits the sliding residual.
  // Without slow sliding the data say nothing about it: then the middle of the scanned range
  // (on a log scale), and the finding says so.
  const auto shapes = e->shapes();
  double best_vs = std::sqrt(shapes.front() * shapes.back()), best_sse = INFINITY, worst_sse = 0;
  for (double vs : shapes) {
    double s = 0, x = 0;
    for (std::size_t i = 0; i < P.states.size(); ++i) {
      e->regressors(vs, P.states[i], &x);
      const double r = sel.final_residual[i] - excess * x;
      s += r * r;
    }
    worst_sse = std::max(worst_sse, s);
    if (s < best_sse) best_sse = s, best_vs = vs;
  }
  const bool determined = worst_sse - best_sse > 0.01 * worst_sse;
  if (!determined) best_vs = std::sqrt(shapes.front() * shapes.back());
  Candidate c;
  c.id = "stribeck_friction";
  c.shape = best_vs;
  const double coef = excess;
  c.params = *e->parameters(best_vs, &coef, model);
  c.t_stat = std::min(t_pos, t_neg);
  c.velocity_determined = determined;
  c.segments = static_cast<int>(bt.pos.episodes + bt.neg.episodes);
  return c;
}

}  // namespace maglead::analysis::actuator

namespace maglead::analysis::actuator {

// Force pulses no input explains: short runs of the corrected residual far outside its own
// spread (robust σ) and larger than one encoder count's worth of force, few and far between.
// A model that is merely wrong leaves structure everywhere, not a handful of isolated pulses.
std::vector<Pulse> find_pulses(const Prepared& P, const Selection& sel, const Options& opt) {
  std::vector<Pulse> out;
  const auto& r = sel.final_residual;
  if (r.size() < 100) return out;
  const double sigma = robust_sigma(r);
  const double thr = std::max(opt.pulse_sigmas * sigma, P.count_force_n);
  const double dt = static_cast<double>(P.decimation) / P.fs_hz;
  std::size_t i = 0;
  while (i < r.size()) {
    if (std::abs(r[i]) <= thr) {
      ++i;
      continue;
    }
    std::size_t j = i;
    double peak = 0;
    // One pulse: consecutive samples (no gap in time) beyond the threshold.
    while (j < r.size() && std::abs(r[j]) > thr &&
           (j == i || P.states[j].t_s - P.states[j - 1].t_s < 1.5 * dt)) {
      if (std::abs(r[j]) > std::abs(peak)) peak = r[j];
      ++j;
    }
    const double duration = P.states[j - 1].t_s - P.states[i].t_s + dt;
    // Shorter than the filter resolves is ringing of a transition, not a force that acted.
    if (duration <= opt.pulse_max_s && duration >= 0.5 / P.filter_hz)
      out.push_back({P.states[i].t_s, duration, peak});
    i = j;
  }
  // Isolated: pulses every few seconds at most; more is a misfit, not a disturbance.
  if (static_cast<double>(out.size()) > P.duration_s / opt.pulse_min_spacing_s) out.clear();
  return out;
}

}  // namespace maglead::analysis::actuator
