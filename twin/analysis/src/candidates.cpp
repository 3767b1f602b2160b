// The candidate columns both analyses fit: one list from the effect library.
#include "candidates.hpp"

#include <algorithm>

namespace maglead::analysis {

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
