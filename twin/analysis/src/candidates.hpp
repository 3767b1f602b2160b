#pragma once
// The candidate columns both analyses fit (internal to twin/analysis): every effect unit's
// columns once, grouped by effect and shape value, in the library's order.
#include <Eigen/Dense>
#include <string>
#include <utility>
#include <vector>

#include "maglead/effects/effect.hpp"
#include "statistics.hpp"

namespace maglead::analysis {

/// Which of a unit's fitted forms: the nut's sliding balance (the actuator) or a force-driven
/// axis's drive force (effects::Effect::axis_columns and the rest).
enum class Form { nut, axis };

/// One of a unit's columns at one shape value.
struct Column {
  const effects::Effect* effect;
  double shape;
  int index;  // within the unit's columns
};

/// One effect at one shape value: its columns' positions in the Gram matrices.
struct Variant {
  const effects::Effect* effect;
  double shape;
  std::vector<int> idx;
};

struct Candidates {
  std::vector<Column> cols;
  std::vector<Variant> variants;
  /// The effect's first variant, or nullptr.
  const Variant* of(const effects::Effect* e) const;
};

/// Every selectable unit with columns in `form` (on an axis: only laws that exist there), but
/// those whose ids `exclude` lists.
Candidates candidate_columns(Form form, const std::vector<std::string>& exclude);

/// The unit's own regressors of columns `cols` at state `s` in `form`, one per column (a unit
/// with several columns is asked once per run of them).
void unit_row(Form form, const std::vector<Column>& cols, const effects::State& s, double* row);

/// `start` less the fitted contribution Σ θ_j x_j of columns `cols` at state `s` (x: unit_row),
/// column by column: the corrected residual (or prediction) at one sample, for every path.
double less_fitted(Form form, const std::vector<Column>& cols, const effects::State& s,
                   const Eigen::VectorXd& theta, double start);

/// A term the model file already has, at its values: part of the baseline.
struct BaselineTerm {
  const effects::Effect* effect;
  effects::Params params;
};

/// What the baseline leaves unexplained at state `s`, from M p̈ = F_m − C v − F_c sign(v) + F_ext
/// + Σ terms: M a + C v + F_c sign(v) − F_m − F_ext − Σ terms, with the totals M, C, F_c the
/// state's (the model file's). One law for both paths: on a force-driven axis the drive force is
/// what the motion needs, and the coupling and load (zero in its state) drop out.
double missing_force(const effects::State& s, const std::vector<BaselineTerm>& terms);

/// Gram positions `current` followed by `more`.
std::vector<int> with(const std::vector<int>& current, const std::vector<int>& more);

/// The variant of effect `e` that best reproduces the contribution `w` of columns `idx` beyond
/// `current` (identifiability: the data cannot tell the two apart), and that share (partial
/// R²); nullptr and 0 when no variant reproduces any of it.
std::pair<const Variant*, double> best_reproducing(const stats::Grams& g, const Candidates& cand,
                                                   const effects::Effect* e,
                                                   const std::vector<int>& current,
                                                   const std::vector<int>& idx,
                                                   const Eigen::VectorXd& w);

}  // namespace maglead::analysis
