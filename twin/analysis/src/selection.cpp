// The one forward selection of the analysis (see selection.hpp): held-out segments decide, the
// effect units give the columns and parameters, and Rules/Settings say what differs.
#include "selection.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace maglead::analysis::selection {
namespace {

using stats::Fit;
using stats::total;

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
    if (others.empty() || stats::partial_r2(s.g, {}, {c}, Eigen::VectorXd::Ones(1), others) < 0.999)
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

// The effect's variant with the least held-out error among those with plausible parameters.
std::optional<Trial> best_variant(const Search& s, const effects::Effect* e, Outcome& out) {
  std::optional<Trial> best;
  for (const auto& var : s.cand.variants) {
    if (var.effect != e) continue;
    std::vector<int> cols = columns_of(s, var, s.current);
    if (cols.empty()) continue;
    const auto idx = with(s.current, cols);
    const Fit full = stats::solve(s.g, idx, -1);
    const auto prm = s.rules.parameters(var, cols, full);
    if (!prm) continue;
    auto ho = stats::heldout(s.g, idx);
    if (!effects::plausible(*e, *prm)) {  // a term must make physical sense to explain anything
      note_implausible(s, out, var, *prm, std::move(ho));
      continue;
    }
    if (best && total(ho) >= total(best->ho)) continue;
    const auto k = static_cast<Eigen::Index>(cols.size());
    best = Trial{&var, std::move(cols), full.theta.tail(k), std::move(ho), 0, 0, 0, 0, *prm};
  }
  return best;
}

// Whether the trial's fitted contribution carries Settings::acting_share of segment f's error.
bool acts_in(const Search& s, const Trial& tr, std::size_t f, double err) {
  if (s.st.acting_share == 0) return true;
  const auto k = static_cast<Eigen::Index>(tr.idx.size());
  Eigen::MatrixXd xx(k, k);
  for (Eigen::Index r = 0; r < k; ++r)
    for (Eigen::Index c = 0; c < k; ++c)
      xx(r, c) =
          s.g.xx[f](tr.idx[static_cast<std::size_t>(r)], tr.idx[static_cast<std::size_t>(c)]);
  return tr.w.dot(xx * tr.w) >= s.st.acting_share * err;
}

// Consistency over the segments where the term acts (elsewhere it predicts nothing and tells
// nothing, as a drift early in a recording): t of the relative gain per segment (so an effect
// that grows counts in early segments too) and, with Settings::t_of_removed, of the error removed
// (segments weighed by what is at stake); the worst segment and the total gain.
void score(const Search& s, Trial& tr, const std::vector<double>& cur) {
  std::vector<double> d, rel;
  tr.improved = 0;
  for (std::size_t f = 0; f < cur.size(); ++f) {
    if (!(cur[f] > 0) || !acts_in(s, tr, f, cur[f])) continue;
    d.push_back(cur[f] - tr.ho[f]);
    rel.push_back(d.back() / cur[f]);
    tr.improved += d.back() > 0;
  }
  tr.t = stats::t_statistic(rel);
  if (s.st.t_of_removed) tr.t = std::max(tr.t, stats::t_statistic(d));
  tr.worst = rel.empty() ? 0.0 : 100.0 * *std::min_element(rel.begin(), rel.end());
  tr.gain = 100.0 * (total(cur) - total(tr.ho)) / total(cur);
}

// Root-mean-square force a trial explains on top of the model with held-out error `cur`.
double explained_n(const Search& s, const std::vector<double>& cur, const Trial& tr) {
  return std::sqrt(std::max(0.0, total(cur) - total(tr.ho)) / s.n_used);
}

// Significant: a real share of the held-out error, consistent over the segments, and a force the
// recording resolves. With Settings::localized, an effect that improves only the segments where
// it occurs counts as consistent when its total gain is large and no segment gets worse.
bool significant(const Search& s, const std::vector<double>& cur, const Trial& tr) {
  const bool consistent =
      tr.t >= s.st.min_t ||
      (s.st.localized && tr.gain >= 10.0 * s.st.min_gain_pct && tr.worst > -1.0);
  return tr.gain >= s.st.min_gain_pct && consistent &&
         s.rules.resolved(tr, explained_n(s, cur, tr));
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

// The trial the rule names next given the best one: a simpler trial (fewer columns) reaching
// Settings::parsimony of the best gain, and with Settings::nested_r2 lying inside the best's
// span, goes first (the data cannot prefer the richer one; it is tested next); the one with the
// largest gain among those. If the simpler one is not significant, neither is what the richer
// one adds to it: the search stops.
std::size_t preferred(const Search& s, const std::vector<Trial>& trials, std::size_t best) {
  const Trial& b = trials[best];
  std::optional<std::size_t> pick;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    const Trial& a = trials[k];
    if (k == best || a.idx.size() >= b.idx.size() || a.gain < s.st.parsimony * b.gain) continue;
    if (pick && trials[*pick].gain >= a.gain) continue;
    if (s.st.nested_r2 > 0 &&
        stats::partial_r2(s.g, s.current, a.idx, a.w, b.idx) <= s.st.nested_r2)
      continue;
    pick = k;
  }
  return pick.value_or(best);
}

// Identifiability: other effects whose columns reproduce the taken term's contribution.
std::vector<Alternative> alternatives_of(const Search& s, const Trial& tr) {
  std::vector<Alternative> out;
  for (const auto* e : effects::library()) {
    if (e == tr.var->effect || s.taken(e)) continue;
    const auto [var, r2] = best_reproducing(s.g, s.cand, e, s.current, tr.idx, tr.w);
    if (!var || r2 < s.st.alternative_r2) continue;
    const auto cols = columns_of(s, *var, s.current);
    const auto prm = s.rules.parameters(*var, cols, stats::solve(s.g, with(s.current, cols), -1));
    out.push_back({var, prm, r2, prm && effects::plausible(*e, *prm)});
  }
  return out;
}

// Takes trials[pick] as the next term (preferred to trials[best] if they differ).
void take(Search& s, Outcome& out, const std::vector<Trial>& trials, std::size_t pick,
          std::size_t best) {
  const Trial& tr = trials[pick];
  Term term{tr,
            explained_n(s, s.cur_ho, tr),
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

// The term the others, their columns restored, leave least to add, if it no longer passes the
// selection's own test once they are all in (the held-out t and gain it adds last).
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
    if (significant(s, without, tr) || (out && out->trial.t <= tr.t)) continue;
    const double expl = explained_n(s, without, tr);
    out = Weakest{k, std::move(tr), expl};
  }
  return out;
}

// Backward check: a term taken early may be explained by those taken after it (an offset once
// direction-dependent friction is in, whose own constant columns were left out while the offset
// spanned them). Each term is tested again as if added last; the weakest that fails the forward
// test is dropped, the others' columns restored, and the check repeats.
void backward_check(Search& s, const std::vector<int>& start, Outcome& out) {
  while (auto weak = weakest_term(s, start, out.terms)) {
    out.terms.erase(out.terms.begin() + static_cast<std::ptrdiff_t>(weak->k));
    s.current = rebuild(s, start, out.terms);
    s.cur_ho = stats::heldout(s.g, s.current);
    out.steps.push_back({'-', weak->trial.var->effect, s.current, s.cur_ho});
    out.dropped.emplace_back(std::move(weak->trial), weak->explained_n);
  }
}

}  // namespace

Outcome select(const stats::Grams& g, const Candidates& cand, const Rules& rules,
               const Settings& st, const std::vector<int>& start,
               const std::vector<const effects::Effect*>& excluded,
               const std::function<void(double)>& progress) {
  Search s{g, cand, rules, st, 0, start, stats::heldout(g, start), excluded};
  for (auto c : g.n) s.n_used += static_cast<double>(c);
  Outcome out;
  out.start_ho = s.cur_ho;
  for (int step = 0; step < st.max_terms; ++step) {
    if (progress) progress(static_cast<double>(step) / st.max_terms);
    const auto trials = trials_of(s, out);
    if (trials.empty()) break;
    const auto best = static_cast<std::size_t>(
        std::min_element(trials.begin(), trials.end(),
                         [](const Trial& a, const Trial& b) { return total(a.ho) < total(b.ho); }) -
        trials.begin());
    const std::size_t pick = preferred(s, trials, best);
    if (!significant(s, s.cur_ho, trials[pick])) {
      out.stopped_at = trials[pick];
      out.stopped_explained_n = explained_n(s, s.cur_ho, trials[pick]);
      break;
    }
    take(s, out, trials, pick, best);
  }
  if (st.backward) backward_check(s, start, out);
  out.current = s.current;
  out.ho = s.cur_ho;
  return out;
}

}  // namespace maglead::analysis::selection
