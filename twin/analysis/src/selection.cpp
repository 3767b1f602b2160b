// The one forward selection of the analysis (see selection.hpp): held-out segments decide, the
// effect units give the columns and parameters, and Rules/Settings say what differs.
#include "selection.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "maglead/analysis/rules.hpp"

namespace maglead::analysis::selection {
namespace {

using stats::Fit;
using stats::total;

// The rules (maglead/analysis/rules.hpp): nested_r2, alternative_r2, localized_gain_factor and
// localized_worst_segment_pct, spanned_r2.
using rules::kAlternativeR2;
using rules::kNestedR2;

// The search's state: the model so far and its held-out error.
struct Search {
  const stats::Grams& g;
  const Candidates& cand;
  const Rules& rules;
  const Settings& st;
  double n_used = 0;
  std::vector<int> current;
  std::vector<double> cur_ho;
  std::vector<const effects::Effect*> used;
  const std::vector<Term>* terms = nullptr;  // taken so far (the search's outcome)
  bool taken(const effects::Effect* e) const {
    return std::find(used.begin(), used.end(), e) != used.end();
  }
};

// A variant's columns beyond `current`; with Settings::leave_out_spanned, without those the
// model already spans (the constant part of direction-dependent friction once an offset is in):
// they add nothing the data can tell.
std::vector<int> columns_of(const Search& s, const Variant& var, const std::vector<int>& current) {
  if (!s.st.leave_out_spanned) return var.idx;
  std::vector<int> kept;
  for (int c : var.idx) {
    const auto others = with(current, kept);
    if (others.empty() ||
        stats::partial_r2(s.g, {}, {c}, Eigen::VectorXd::Ones(1), others) < rules::kSpannedR2)
      kept.push_back(c);
  }
  return kept;
}

// Keeps the implausible fit that removes the most held-out error in this step.
void note_implausible(const Search& s, Outcome& out, const Variant& var, const effects::Params& prm,
                      std::vector<double> ho) {
  const double after = total(ho);
  if (!(after < total(s.cur_ho))) return;
  if (out.implausible && total(out.implausible->ho) <= after) return;
  out.implausible = ImplausibleFit{&var, prm, std::move(ho), s.cur_ho};
}

// Which variants a search step weighs: those whose period the fitted samples see (a repeating
// law's shape is resolved there: Effect::resolved_at), or the others.
enum class Seen { resolved, unresolved };

// The effect's variant with the least held-out error among those with plausible parameters.
std::optional<Trial> best_variant(const Search& s, const effects::Effect* e, Outcome& out,
                                  Seen seen = Seen::resolved) {
  std::optional<Trial> best;
  for (const auto& var : s.cand.variants) {
    if (var.effect != e || e->resolved_at(var.shape, s.st.scales) != (seen == Seen::resolved))
      continue;
    std::vector<int> cols = columns_of(s, var, s.current);
    if (cols.empty()) continue;
    const auto idx = with(s.current, cols);
    const Fit full = stats::solve(s.g, idx, -1);
    const auto prm = s.rules.parameters(var, cols, full);
    if (!prm) continue;
    auto ho = stats::heldout(s.g, idx);
    if (!effects::plausible(*e, *prm,
                            s.st.scales)) {  // a term must make physical sense to explain anything
      if (seen == Seen::resolved) note_implausible(s, out, var, *prm, std::move(ho));
      continue;
    }
    if (best && total(ho) >= total(best->ho)) continue;
    const auto k = static_cast<Eigen::Index>(cols.size());
    best = Trial{&var, std::move(cols), full.theta.tail(k), std::move(ho), 0, 0, 0, 0, *prm};
  }
  return best;
}

// Whether the trial's fitted contribution carries Settings::acting_share of segment f's error, or
// of the floor's error there where that is larger (Rules::floor_n): a load-cell delay's column
// in unloaded moves is the load cell's noise, 0.01 N against a 0.022 N error, both below what
// the recording resolves; it predicts nothing there (and would count those segments worse, at
// 0.024 N).
bool acts_in(const Search& s, const Trial& tr, std::size_t f, double err, double floor_n) {
  if (s.st.acting_share == 0) return true;
  const double floor_err = floor_n * floor_n * static_cast<double>(s.g.n[f]);
  const auto k = static_cast<Eigen::Index>(tr.idx.size());
  Eigen::MatrixXd xx(k, k);
  for (Eigen::Index r = 0; r < k; ++r)
    for (Eigen::Index c = 0; c < k; ++c)
      xx(r, c) =
          s.g.xx[f](tr.idx[static_cast<std::size_t>(r)], tr.idx[static_cast<std::size_t>(c)]);
  return tr.w.dot(xx * tr.w) >= s.st.acting_share * std::max(err, floor_err);
}

// Consistency over the segments where the term acts (elsewhere it predicts nothing and tells
// nothing, as a drift early in a recording): t of the relative gain per segment (so an effect
// that grows counts in early segments too) or of the error removed (segments weighed by what is at
// stake), the larger; the worst segment and the total gain.
void score(const Search& s, Trial& tr, const std::vector<double>& cur) {
  std::vector<double> d, rel;
  tr.improved = 0;
  const double floor_n = s.rules.floor_n(*s.terms);  // the same for every segment
  for (std::size_t f = 0; f < cur.size(); ++f) {
    if (!(cur[f] > 0) || !acts_in(s, tr, f, cur[f], floor_n)) continue;
    d.push_back(cur[f] - tr.ho[f]);
    rel.push_back(d.back() / cur[f]);
    tr.improved += d.back() > 0;
  }
  tr.t = std::max(stats::t_statistic(rel), stats::t_statistic(d));
  tr.worst = rel.empty() ? 0.0 : 100.0 * *std::min_element(rel.begin(), rel.end());
  tr.gain = 100.0 * (total(cur) - total(tr.ho)) / total(cur);
}

// Root-mean-square force a trial explains on top of the model with held-out error `cur`.
double explained_n(const Search& s, const std::vector<double>& cur, const Trial& tr) {
  return std::sqrt(std::max(0.0, total(cur) - total(tr.ho)) / s.n_used);
}

// Whether the force the trial explains on top of the model with held-out error `cur` is one the
// recording resolves (Rules::resolved), measured where its law acts (`where`: a law with compact
// support, as an end zone, changes the force only there), beside the terms `model`.
bool resolved_where(const Search& s, const std::vector<double>& cur, const Trial& tr,
                    const Acting& where, const std::vector<Term>& model) {
  return s.rules.resolved(tr, explained_n(s, cur, tr) / std::sqrt(where.share), where, model);
}

// Significant: a real share of the held-out error, consistent over the segments, and a force the
// recording resolves where the trial acts (resolved_where); a localized effect (its gain
// rules::kLocalizedGainFactor times the minimum, no segment worse beyond
// rules::kLocalizedWorstSegmentPct) counts as consistent.
bool significant(const Search& s, const std::vector<double>& cur, const Trial& tr,
                 const Acting& where) {
  const bool consistent =
      tr.t >= s.st.min_t || (tr.gain >= rules::kLocalizedGainFactor * s.st.min_gain_pct &&
                             tr.worst > rules::kLocalizedWorstSegmentPct);
  return tr.gain >= s.st.min_gain_pct && consistent && resolved_where(s, cur, tr, where, *s.terms);
}

// Which of significant()'s rules a trial fails, with its figures: the left-out table's "why"
// must be the rule that failed, not a gain and t that both pass.
std::string why_not_significant(const Search& s, const std::vector<double>& cur, const Trial& tr,
                                const Acting& where) {
  char b[240];
  if (tr.gain < s.st.min_gain_pct) {
    std::snprintf(b, sizeof b, "held-out gain %.2f %% below %.3g %%", tr.gain + 0.0,
                  s.st.min_gain_pct);
  } else if (!(tr.t >= s.st.min_t || (tr.gain >= rules::kLocalizedGainFactor * s.st.min_gain_pct &&
                                      tr.worst > rules::kLocalizedWorstSegmentPct))) {
    std::snprintf(b, sizeof b,
                  "not consistent over the segments: t = %.2f below %.3g, worst segment %.0f %%",
                  tr.t, s.st.min_t, tr.worst);
  } else {
    const std::string unit(s.st.drive_unit);
    std::snprintf(b, sizeof b,
                  "the force it explains, %.3f %s RMS where it acts, is not one the recording "
                  "resolves (it must beat %.3f %s)",
                  explained_n(s, cur, tr) / std::sqrt(where.share), unit.c_str(),
                  s.rules.floor_n(*s.terms), unit.c_str());
  }
  return std::string(kBelowSignificance) + ": " + b;
}

// Every effect not taken yet, each at its best variant and scored.
std::vector<Trial> trials_of(const Search& s, Outcome& out) {
  std::vector<Trial> trials;
  for (const auto* e : effects::library()) {
    if (s.taken(e)) continue;
    auto best = best_variant(s, e, out);
    if (!best) continue;
    score(s, *best, s.cur_ho);
    trials.push_back(std::move(*best));
  }
  return trials;
}

// The trial the rule names next, starting from the best one: a simpler trial (fewer columns)
// goes first when the data cannot prefer the richer one: it reaches Settings::parsimony of the
// richer one's gain and lies inside its span (kNestedR2), or the richer one explains no more
// force than it by what the recording resolves (Rules::resolved: a spring's free rest position
// taking a calibration's few hundredths of a newton beside a gain error). The richer one is
// tested next, in the library's order (simpler effects first), and so on down. If the simpler
// one is not significant, neither is what the richer one adds to it: the search stops.
std::size_t preferred(const Search& s, const std::vector<Trial>& trials, std::size_t best) {
  std::size_t pick = best;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    const Trial &a = trials[k], &p = trials[pick];
    if (a.idx.size() >= p.idx.size() || !(a.gain > 0)) continue;
    const bool as_good = a.gain >= s.st.parsimony * p.gain ||
                         !resolved_where(s, a.ho, p, s.rules.acting(p), *s.terms);
    if (as_good && stats::partial_r2(s.g, s.current, a.idx, a.w, p.idx) > kNestedR2) pick = k;
  }
  return pick;
}

// Identifiability: other effects whose columns reproduce the taken term's contribution.
std::vector<AlternativeFit> alternatives_of(const Search& s, const Trial& tr) {
  std::vector<AlternativeFit> out;
  for (const auto* e : effects::library()) {
    if (e == tr.var->effect || s.taken(e)) continue;
    const auto [var, r2] = best_reproducing(s.g, s.cand, e, s.current, tr.idx, tr.w);
    if (!var || r2 < kAlternativeR2) continue;
    const auto cols = columns_of(s, *var, s.current);
    const auto prm = s.rules.parameters(*var, cols, stats::solve(s.g, with(s.current, cols), -1));
    out.push_back({var, prm, r2, prm && effects::plausible(*e, *prm, s.st.scales)});
  }
  return out;
}

// Takes trials[pick], acting on `share` of the samples, as the next term (preferred to
// trials[best] if they differ).
void take(Search& s, Outcome& out, const std::vector<Trial>& trials, std::size_t pick,
          std::size_t best, double share) {
  const Trial& tr = trials[pick];
  Term term{tr,
            explained_n(s, s.cur_ho, tr),
            share,
            total(s.cur_ho),
            total(tr.ho),
            pick != best ? trials[best].var->effect : nullptr,
            alternatives_of(s, tr)};
  s.current.insert(s.current.end(), tr.idx.begin(), tr.idx.end());
  s.used.push_back(tr.var->effect);
  s.cur_ho = tr.ho;
  out.terms.push_back(std::move(term));
  out.steps.push_back({'+', tr.var->effect, s.current, s.cur_ho});
  out.implausible.reset();  // judged against what the next step leaves
}

// The terms' columns again, in order, each without what the model before it spans.
std::vector<int> rebuild(const Search& s, const std::vector<int>& start, std::vector<Term>& terms) {
  std::vector<int> current = start;
  for (auto& t : terms) {
    t.trial.idx = columns_of(s, *t.trial.var, current);
    current.insert(current.end(), t.trial.idx.begin(), t.trial.idx.end());
  }
  return current;
}

struct Weakest {
  std::size_t k;
  Trial trial;
  double explained_n;
};

// The term the others, their columns restored, leave least to add, if what it adds last is no
// longer a real share of the held-out error or a force the recording resolves. Consistency over
// the segments is not asked again: taken last beside a term it is collinear with (a coupling
// gain error beside a gain drift), a term that removes most of the error can still have a
// segment where the pair trade places, and the forward test already asked it.
std::optional<Weakest> weakest_term(const Search& s, const std::vector<int>& start,
                                    const std::vector<Term>& terms) {
  std::optional<Weakest> out;
  const Fit all = stats::solve(s.g, s.current, -1);
  auto off = static_cast<Eigen::Index>(start.size());
  for (std::size_t k = 0; k < terms.size(); ++k) {
    Trial tr = terms[k].trial;
    const auto n = static_cast<Eigen::Index>(tr.idx.size());
    tr.w = all.theta.segment(off, n);
    off += n;
    tr.ho = s.cur_ho;
    auto others = terms;
    others.erase(others.begin() + static_cast<std::ptrdiff_t>(k));
    const auto without = stats::heldout(s.g, rebuild(s, start, others));
    score(s, tr, without);
    const double expl = explained_n(s, without, tr);
    const bool adds =
        tr.gain >= s.st.min_gain_pct && resolved_where(s, without, tr, s.rules.acting(tr), others);
    if (adds || (out && out->trial.t <= tr.t)) continue;  // the least consistent goes first
    out = Weakest{k, std::move(tr), expl};
  }
  return out;
}

// Backward check: a term taken early may be explained by those taken after it (an offset once
// direction-dependent friction is in, whose own constant columns were left out while the offset
// spanned them). Each term is tested again as if added last; the weakest that adds too little is
// dropped, the others' columns restored, and the check repeats.
void backward_check(Search& s, const std::vector<int>& start, Outcome& out) {
  while (auto weak = weakest_term(s, start, out.terms)) {
    out.terms.erase(out.terms.begin() + static_cast<std::ptrdiff_t>(weak->k));
    s.current = rebuild(s, start, out.terms);
    s.cur_ho = stats::heldout(s.g, s.current);
    out.steps.push_back({'-', weak->trial.var->effect, s.current, s.cur_ho});
    out.dropped.emplace_back(std::move(weak->trial), weak->explained_n);
  }
}

// A repeating law whose period the fitted samples do not see (an angle ripple over less than a
// screw turn) is not named for what it explains alone: there it can pass for a gain or a
// friction level. But when it explains more than the step's pick by a force the recording
// resolves, and the pick adds nothing significant beside it, the pick is the part of it the data
// show, and the law takes its place (in force control and held-screw pushes an angle ripple
// seen over part of a turn read as direction-dependent friction, 30 % of the held-out error,
// where the ripple explains 99 %). Returns the law's trial on the model as it is, if so.
std::optional<Trial> unseen_period_instead(const Search& s, Outcome& out, const Trial& pick) {
  std::optional<Trial> u;
  for (const auto* e : effects::library()) {
    if (s.taken(e)) continue;
    auto v = best_variant(s, e, out, Seen::unresolved);
    if (v && total(v->ho) < total(pick.ho) && (!u || total(v->ho) < total(u->ho))) u = std::move(v);
  }
  if (!u) return std::nullopt;
  score(s, *u, s.cur_ho);
  if (!resolved_where(s, pick.ho, *u, s.rules.acting(*u), *s.terms)) return std::nullopt;
  // The pick's effect beside it, on a copy of the search with the law in (and an outcome of
  // its own: an implausible fit there is not this step's).
  Search with_law = s;
  with_law.current = with(s.current, u->idx);
  with_law.cur_ho = u->ho;
  Outcome scratch;
  auto beside = best_variant(with_law, pick.var->effect, scratch);
  if (!beside) return u;
  score(with_law, *beside, with_law.cur_ho);
  if (significant(with_law, with_law.cur_ho, *beside, s.rules.acting(*beside))) return std::nullopt;
  return u;
}

// The forward search from s's model, then the backward check.
Outcome search(Search& s, const std::vector<int>& start,
               const std::function<void(double)>& progress) {
  Outcome out;
  out.start_ho = s.cur_ho;
  s.terms = &out.terms;
  for (int step = 0; step < s.st.max_terms; ++step) {
    if (progress) progress(static_cast<double>(step) / s.st.max_terms);
    auto trials = trials_of(s, out);
    if (trials.empty()) break;
    const auto best = static_cast<std::size_t>(
        std::min_element(trials.begin(), trials.end(),
                         [](const Trial& a, const Trial& b) { return total(a.ho) < total(b.ho); }) -
        trials.begin());
    std::size_t pick = preferred(s, trials, best);
    if (auto u = unseen_period_instead(s, out, trials[pick])) {
      trials.push_back(std::move(*u));
      pick = trials.size() - 1;
    }
    const Acting where = s.rules.acting(trials[pick]);  // once per step: a pass over samples
    if (!significant(s, s.cur_ho, trials[pick], where)) {
      out.stopped_at = trials[pick];
      out.stopped_explained_n = explained_n(s, s.cur_ho, trials[pick]);
      out.stopped_reason = why_not_significant(s, s.cur_ho, trials[pick], where);
      break;
    }
    take(s, out, trials, pick, best, where.share);
  }
  backward_check(s, start, out);
  out.current = s.current;
  out.ho = s.cur_ho;
  return out;
}

// A value with a least count (a play of at least one count of the phase) must reach it less its
// standard error over the held-out segments, and a magnitude must be beyond zero by it, as a
// finding's force must beat the stated minimum by its own error: at 1.06 counts ± 0.12 a play
// on the third actuator took the place of the load-cell delay that made the recording.
bool beyond_its_error(const Search& s, const Trial& tr, const std::vector<int>& before,
                      const effects::Params& prm) {
  std::vector<stats::Named> without_each;
  for (const auto& f : stats::leave_one_out(s.g, with(before, tr.idx)))
    if (auto p = s.rules.parameters(*tr.var, tr.idx, f)) without_each.push_back(*p);
  return effects::beyond_its_error(*tr.var->effect, prm, stats::jackknife_se(without_each),
                                   s.st.scales);
}

// Its own force where it acts, less that force's jackknife standard error over the held-out
// segments, still reaches the stated minimum (Rules::minimum_n): an offset of 0.081 ± 0.012 N in
// the final fit against a calibration known to 0.070 N is one the calibration makes as well,
// and so is a spring that takes its place.
bool beyond_minimum_by_its_error(const Search& s, const Trial& tr, const std::vector<int>& before,
                                 const std::vector<Term>& others) {
  const double minimum_n = s.rules.minimum_n(others);
  if (!(minimum_n > 0)) return true;
  const auto n = static_cast<Eigen::Index>(tr.idx.size());
  const auto own_n = [&](const Fit& fit) {
    Trial at = tr;
    at.w = fit.theta.tail(n);
    return s.rules.acting(at).own_rms_n;
  };
  const auto all = with(before, tr.idx);
  std::vector<stats::Named> without_each;
  for (const auto& f : stats::leave_one_out(s.g, all)) without_each.push_back({{"own", own_n(f)}});
  const auto se = stats::jackknife_se(without_each);
  const double own = own_n(stats::solve(s.g, all, -1));
  return own - (se.contains("own") ? se.at("own") : 0.0) >= minimum_n;
}

// Why a term taken is not a finding in the final fit beside the others (nullptr: it is one).
const char* refusal(const Search& s, const Trial& tr, const std::vector<int>& before,
                    const effects::Params& prm, const std::vector<Term>& others) {
  if (!effects::plausible(*tr.var->effect, prm, s.st.scales))
    return "outside its physical range in the final fit beside the terms taken after it";
  if (!beyond_its_error(s, tr, before, prm))
    return "in the final fit its value is within its standard error of zero or of one count";
  if (!beyond_minimum_by_its_error(s, tr, before, others))
    return "in the final fit its own force is within its standard error of the stated minimum";
  return nullptr;
}

// The first term whose parameters leave its unit's physical range once the others are fitted
// beside it (collinear columns trading places: on moves against high friction the coupling force
// is the friction, so a gain taken first and the friction levels taken after it share it), or
// that its own error no longer sets apart (refusal), with its parameters there and why. A unit
// that gives no value there is not refused.
std::optional<std::pair<Trial, const char*>> refused_in_final_fit(const Search& s,
                                                                  const std::vector<int>& start,
                                                                  const std::vector<Term>& terms) {
  for (std::size_t k = 0; k < terms.size(); ++k) {
    auto others = terms;
    others.erase(others.begin() + static_cast<std::ptrdiff_t>(k));
    const auto before = rebuild(s, start, others);
    Trial tr = terms[k].trial;
    tr.idx = columns_of(s, *tr.var, before);
    const auto prm =
        s.rules.parameters(*tr.var, tr.idx, stats::solve(s.g, with(before, tr.idx), -1));
    if (!prm) continue;
    const char* why = refusal(s, tr, before, *prm, others);
    if (!why) continue;
    tr.params = *prm;
    return std::pair{std::move(tr), why};
  }
  return std::nullopt;
}

Found found_of(const Trial& tr, double explained_n, int folds) {
  Found f;
  f.id = std::string(tr.var->effect->id());
  f.effect = tr.var->effect;
  f.shape = tr.var->shape;
  f.idx = tr.idx;
  f.params = tr.params;
  f.gain_pct = tr.gain;
  f.t_stat = tr.t;
  f.worst_pct = tr.worst;
  f.explained_n = explained_n;
  f.segments_improved = tr.improved;
  f.segments = folds;
  return f;
}

Found found_of(const Term& term, int folds) {
  Found f = found_of(term.trial, term.explained_n, folds);
  f.acting_share = term.acting_share;
  f.heldout_before = term.before;
  f.heldout_after = term.after;
  f.over = term.over;
  for (const auto& a : term.alternatives)
    f.alternatives.push_back(
        {std::string(a.var->effect->id()), a.params, 100.0 * a.r2, a.plausible});
  return f;
}

// x rounded to 1/per, with no sign on a zero: "0.00", never "-0.00" for −4.7e-08.
double unsigned_zero(double x, double per) { return std::round(x * per) / per + 0.0; }

// A term the backward check dropped, with what it adds last.
Rejected dropped_of(const Trial& tr, double explained_n) {
  char why[160];
  std::snprintf(why, sizeof why,
                "dropped by the backward check: with the other terms in, it adds a held-out "
                "gain of %.2f %% at t = %.2f",
                unsigned_zero(tr.gain, 100.0), unsigned_zero(tr.t, 100.0));
  return rejected_of(found_of(tr, explained_n, 0), why);
}

// A term refused in the final fit, with its parameters there (as it was taken: gain, t).
Rejected refused_of(const Trial& tr, const char* why, int folds) {
  Rejected r = rejected_of(found_of(tr, 0, folds), why);
  r.worst_segment_pct.reset(), r.explained_rms_n.reset();
  r.parameters = parameters_of(tr.params);
  return r;
}

}  // namespace

Rejected rejected_of(const Found& f, std::string reason) {
  return Rejected{f.id,          f.gain_pct,        f.t_stat,    f.worst_pct,
                  f.explained_n, std::move(reason), std::nullopt};
}

Rejected best_left_out(const Found& f, const std::string& reason) {
  Rejected r = rejected_of(f, reason.empty() ? std::string(kBelowSignificance) : reason);
  if (!f.params.empty()) r.parameters = parameters_of(f.params);
  return r;
}

Parameters parameters_of(const effects::Params& p) {
  Parameters out;
  for (const auto& [k, v] : p) out.push_back({k, v, false});
  return out;
}

namespace {
// The implausible fit and where the error it leaves is largest (the segment a user should look
// at first); after a stop, only if it would have stood out (its gain and force beyond what was
// left untaken) and explains more than the plausible candidate the stop left untaken (that one,
// short of significance, is the better account of the misfit, not an implausible one).
std::optional<Implausible> implausible_of(const Outcome& o, const Span& span) {
  if (!o.implausible) return std::nullopt;
  const auto& f = *o.implausible;
  const double before = total(f.cur_ho), after = total(f.ho);
  const double gain = 100.0 * (before - after) / before;
  const double explained_n = std::sqrt((before - after) / span.n_used);
  if (o.stopped_at &&
      (gain < span.min_gain_pct || explained_n < span.floor_n || o.stopped_at->gain >= gain))
    return std::nullopt;
  const auto worst =
      static_cast<std::size_t>(std::max_element(f.ho.begin(), f.ho.end()) - f.ho.begin());
  const double seg = span.duration_s / static_cast<double>(f.ho.size());
  const double t0 = span.t0_s + seg * static_cast<double>(worst);
  return Implausible{std::string(f.var->effect->id()), f.params, gain, explained_n, t0, t0 + seg};
}

std::string params_text(const effects::Params& p) {
  std::ostringstream o;
  o.precision(3);
  for (const auto& [k, v] : p) o << (o.tellp() > 0 ? ", " : "") << k << " = " << v;
  return o.str();
}
}  // namespace

Unexplained unexplained_of(const Implausible& imp, std::string check) {
  Unexplained u;
  u.id = imp.id;
  u.parameters = parameters_of(imp.params);
  u.heldout_gain_pct = imp.gain_pct;
  u.explained_rms_n = imp.explained_n;
  std::ostringstream where;
  where.precision(3);
  where << "the missing force follows the law of " << imp.id
        << ", most left in t = " << imp.worst_t0_s << " .. " << imp.worst_t1_s << " s";
  u.where = where.str();
  u.check = std::move(check);
  u.message = "no library effect explains this plausibly: " + imp.id + " would need " +
              params_text(imp.params) + ", outside its physical range";
  return u;
}

Result result_of(const Outcome& o, int folds, const Span& span) {
  Result r;
  r.implausible = implausible_of(o, span);
  r.current = o.current;
  r.start_heldout_sse = total(o.start_ho);
  const double final_sse = total(o.ho);
  for (const auto& term : o.terms) {
    r.terms.push_back(found_of(term, folds));
    if (r.start_heldout_sse > 0)
      r.terms.back().improvement_pct = 100.0 * (term.left_out - final_sse) / r.start_heldout_sse;
  }
  for (const auto& st : o.steps)
    r.steps.push_back(
        {std::string(1, st.sign) + " " + std::string(st.effect->id()), st.current, total(st.ho)});
  for (const auto& [tr, explained] : o.dropped) r.dropped.push_back(dropped_of(tr, explained));
  for (const auto& [tr, why] : o.refused) r.refused.push_back(refused_of(tr, why, folds));
  if (o.stopped_at) r.stopped_at = found_of(*o.stopped_at, o.stopped_explained_n, folds);
  r.stopped_reason = o.stopped_reason;
  return r;
}

std::string describe(const Settings& st) {
  std::ostringstream o;
  o << "forward, by held-out error on contiguous time segments; a term must cut the held-out "
       "mean square error by >= "
    << st.min_gain_pct << " % with t >= " << st.min_t
    << " over the segments (or >= " << rules::kLocalizedGainFactor
    << "x that gain with no segment worse)";
  return o.str();
}

namespace {
// Each kept term's left_out: the final model's held-out error without its columns.
void set_left_out(const stats::Grams& g, Outcome& out) {
  for (auto& term : out.terms) {
    std::vector<int> without;
    for (int c : out.current)
      if (std::find(term.trial.idx.begin(), term.trial.idx.end(), c) == term.trial.idx.end())
        without.push_back(c);
    term.left_out = total(stats::heldout(g, without));
  }
}
}  // namespace

Outcome select(const stats::Grams& g, const Candidates& cand, const Rules& rules,
               const Settings& st, const std::vector<int>& start,
               const std::vector<const effects::Effect*>& excluded,
               const std::function<void(double)>& progress) {
  std::vector<const effects::Effect*> out_of = excluded;
  std::vector<std::pair<Trial, const char*>> refused;
  for (;;) {  // each pass refuses one more effect, so this ends within the library's size
    Search s{g, cand, rules, st, 0, start, stats::heldout(g, start), out_of};
    for (auto c : g.n) s.n_used += static_cast<double>(c);
    Outcome out = search(s, start, progress);
    auto bad = refused_in_final_fit(s, start, out.terms);
    if (!bad) {
      out.refused = std::move(refused);
      set_left_out(g, out);
      return out;
    }
    out_of.push_back(bad->first.var->effect);
    refused.push_back(std::move(*bad));
  }
}

}  // namespace maglead::analysis::selection
