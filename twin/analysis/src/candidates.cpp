// The candidate columns both analyses fit: one list from the effect library.
#include "candidates.hpp"

#include <algorithm>

namespace maglead::analysis {

double missing_force(const effects::State& s, const std::vector<BaselineTerm>& terms) {
  // The order of the sums is kept as the actuator had it (its output is compared bit for bit).
  double r = s.nut_mass_kg * s.a_m_s2 - s.coupling_n + s.viscous_n_s_per_m * s.v_m_s +
             s.coulomb_n * effects::sgn(s.v_m_s) - s.load_n;
  for (const auto& term : terms) r -= term.effect->force_n(term.params, s);
  return r;
}

const Variant* Candidates::of(const effects::Effect* e) const {
  for (const auto& v : variants)
    if (v.effect == e) return &v;
  return nullptr;
}

Candidates candidate_columns(Form form, const std::vector<std::string>& exclude) {
  Candidates out;
  for (const effects::Effect* e : effects::library()) {
    const int columns = form == Form::axis ? e->axis_columns() : e->columns();
    if (!e->selectable() || columns == 0 || (form == Form::axis && !e->on_axis())) continue;
    if (std::find(exclude.begin(), exclude.end(), e->id()) != exclude.end()) continue;
    auto shapes = e->shapes();
    if (shapes.empty()) shapes.push_back(0.0);
    for (double sh : shapes) {
      Variant v{e, sh, {}};
      for (int k = 0; k < columns; ++k) {
        v.idx.push_back(static_cast<int>(out.cols.size()));
        out.cols.push_back({e, sh, k});
      }
      out.variants.push_back(v);
    }
  }
  return out;
}

namespace {

// Asks the unit for its regressors at `s` unless `last` already asked it (same unit and shape).
void ask(Form form, const Column& c, const Column*& last, const effects::State& s, double* buf) {
  if (last && last->effect == c.effect && last->shape == c.shape) return;
  if (form == Form::axis)
    c.effect->axis_regressors(c.shape, s, buf);
  else
    c.effect->regressors(c.shape, s, buf);
  last = &c;
}

}  // namespace

void unit_row(Form form, const std::vector<Column>& cols, const effects::State& s, double* row) {
  double buf[effects::kMaxColumns];
  const Column* last = nullptr;
  for (std::size_t j = 0; j < cols.size(); ++j) {
    ask(form, cols[j], last, s, buf);
    row[j] = buf[cols[j].index];
  }
}

double less_fitted(Form form, const std::vector<Column>& cols, const effects::State& s,
                   const Eigen::VectorXd& theta, double start) {
  double buf[effects::kMaxColumns];
  const Column* last = nullptr;
  for (std::size_t j = 0; j < cols.size(); ++j) {
    ask(form, cols[j], last, s, buf);
    start -= theta[static_cast<Eigen::Index>(j)] * buf[cols[j].index];
  }
  return start;
}

std::vector<int> with(const std::vector<int>& current, const std::vector<int>& more) {
  std::vector<int> idx = current;
  idx.insert(idx.end(), more.begin(), more.end());
  return idx;
}

std::pair<const Variant*, double> best_reproducing(const stats::Grams& g, const Candidates& cand,
                                                   const effects::Effect* e,
                                                   const std::vector<int>& current,
                                                   const std::vector<int>& idx,
                                                   const Eigen::VectorXd& w) {
  double best_r2 = 0;
  const Variant* best = nullptr;
  for (const auto& var : cand.variants) {
    if (var.effect != e) continue;
    const double r2 = stats::partial_r2(g, current, idx, w, var.idx);
    if (r2 > best_r2) best_r2 = r2, best = &var;
  }
  return {best, best_r2};
}

}  // namespace maglead::analysis
