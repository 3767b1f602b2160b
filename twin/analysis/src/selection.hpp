#pragma once
// The one forward selection both analyses run (internal to twin/analysis): every remaining
// candidate effect's best variant scored on held-out time segments, the next term picked by the
// rule, taken or the search stopped, then a backward check. What differs between an axis and an
// actuator is only what `Rules` and `Settings` say.
#include <Eigen/Dense>
#include <cstddef>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "candidates.hpp"
#include "maglead/analysis/results.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/effects/effect.hpp"
#include "statistics.hpp"

namespace maglead::analysis::selection {

/// One effect tried as the next term, at its best variant.
struct Trial {
  const Variant* var = nullptr;
  std::vector<int> idx;    // its columns in the fit (after those already in)
  Eigen::VectorXd w;       // their coefficients in the fit with them
  std::vector<double> ho;  // held-out error per segment with it
  double gain = 0, t = 0;  // held-out gain [%] and its consistency over the segments
  double worst = 0;        // the worst counted segment's relative gain [%]
  int improved = 0;        // segments it improves
  effects::Params params;
};

struct Term;

/// Where a trial's fitted law acts, as the Rules see it (one pass over the samples).
struct Acting {
  double share = 1.0;  // of the samples where its law is not zero
  double own_rms_n = std::numeric_limits<double>::infinity();  // its own law's RMS there
};

/// What an axis and an actuator decide differently (the rest is Settings).
class Rules {
 public:
  virtual ~Rules() = default;
  /// The variant's physical parameters from `fit`, the model with its columns `cols` last;
  /// none: the unit gives no value there.
  virtual std::optional<effects::Params> parameters(const Variant& var,
                                                    const std::vector<int>& cols,
                                                    const stats::Fit& fit) const = 0;
  /// Whether the RMS force a trial explains, measured where its law acts (`where`), and its own
  /// law's force there are ones the recording resolves and a user acts on, beside the terms
  /// `model` holds (as taken).
  virtual bool resolved(const Trial& tr, double explained_n, const Acting& where,
                        const std::vector<Term>& model) const = 0;
  /// Where the trial's fitted law acts (default: everywhere, its own force not asked).
  virtual Acting acting(const Trial& /*tr*/) const { return {}; }
  /// The RMS force the recording resolves beside the terms `model` holds: errors below it are
  /// the floor's (default: none).
  virtual double floor_n(const std::vector<Term>& /*model*/) const { return 0.0; }
  /// The smallest own force of a term a user acts on beside the terms `model` holds (the
  /// calibration's accuracy; default: none asked).
  virtual double minimum_n(const std::vector<Term>& /*model*/) const { return 0.0; }
};

struct Settings {
  int max_terms = rules::kMaxTerms;
  double min_gain_pct = rules::kMinHeldOutGainPct;  // held-out error a term must remove …
  double min_t = rules::kMinT;                      // … consistently over the segments
  // Segments where the term's fitted contribution carries less than this share of the error are
  // not counted (it predicts nothing there); 0: every segment counts.
  double acting_share = 0;
  double parsimony =
      rules::kAxisParsimony;       // a simpler term reaching this share of the best gain goes first
  bool leave_out_spanned = false;  // a variant's columns the model already spans are left out
  effects::Scales scales{};        // the actuator's, that the units' plausible ranges are in
  std::string_view drive_unit = "N";  // the residual's, in the reasons' texts ("N·m": rotary)
};

/// Another effect that reproduces a taken term's contribution, as the selection fits it.
struct AlternativeFit {
  const Variant* var;
  std::optional<effects::Params> params;
  double r2;
  bool plausible;
};

struct Term {
  Trial trial;  // as taken; trial.idx: its columns in the final model
  double explained_n = 0;
  double acting_share = 1;                // Rules::acting
  double before = 0, after = 0;           // total held-out error before and after it was taken
  const effects::Effect* over = nullptr;  // the richer best trial it was preferred to, if any
  std::vector<AlternativeFit> alternatives;
  double left_out = 0;  // total held-out error of the final model without it (set by select)
};

/// A step of the selection: a term taken (+) or dropped (−) and the model it leaves.
struct OutcomeStep {
  char sign;
  const effects::Effect* effect;
  std::vector<int> current;
  std::vector<double> ho;
};

/// The implausible fit that would remove most held-out error in the last step tried.
struct ImplausibleFit {
  const Variant* var;
  effects::Params params;
  std::vector<double> ho, cur_ho;
};

struct Outcome {
  std::vector<int> current;  // the final model's columns: the start's, then each term's
  std::vector<double> start_ho, ho;
  std::vector<Term> terms;  // the terms kept, in the order taken
  std::vector<OutcomeStep> steps;
  std::optional<Trial> stopped_at;  // the trial the rule named next, below the threshold
  std::string stopped_reason;       // which rule it failed, with its figures
  double stopped_explained_n = 0;
  std::vector<std::pair<Trial, double>> dropped;  // by the backward check, with explained_n
  // Taken, then refused in the final fit (its params there), with why.
  std::vector<std::pair<Trial, const char*>> refused;
  std::optional<ImplausibleFit> implausible;
};

/// A term as every path reports it: the one result type of the analysis. result_of builds it
/// from the Outcome; a path that names a term otherwise (the actuator's Stribeck friction from its
/// stuck episodes) fills the same type, and a new path plugs in by reading these.
/// Another effect the data cannot tell from a found term; every one, plausible or not (a path
/// that lists only the plausible filters where it renders the findings' Alternative).
struct FoundAlternative {
  std::string id;
  std::optional<effects::Params> params;
  double explains_pct = 0;
  bool plausible = false;
};

struct Found {
  /// Stribeck friction named from the releases, not by the selection (optional extras).
  struct FromReleases {
    bool velocity_determined = true;                 // did slow sliding pin down v_s?
    std::pair<double, double> velocity_range_m_s{};  // the v_s the sliding data allow
    std::size_t stops_left_out = 0;                  // hidden stops the sliding fit left out
  };
  std::string id;
  const effects::Effect* effect = nullptr;
  double shape = 0;
  std::vector<int> idx;                     // its columns in the final model (none: not selected)
  effects::Params params;                   // as selected; a path sets the final fit's
  effects::Params standard_errors{};        // jackknife over the held-out segments' fits
  effects::Params calibration_errors{};     // most a calibration error moves each (see finish)
  bool plausible = true;                    // params inside the unit's physical range
  double acting_share = 1;                  // samples where its law is not zero (Rules)
  double gain_pct = 0, t_stat = 0;          // held-out gain and its consistency over the segments
  double worst_pct = 0;                     // the worst counted segment's relative gain
  double explained_n = 0;                   // RMS force it explains on top of the model before it
  int segments_improved = 0, segments = 0;  // held-out segments (from releases: the releases)
  double heldout_before = 0, heldout_after = 0;  // total held-out error before and after it
  // The share of the baseline's held-out squared error the final model loses without it [%]
  // (its part in the final model, whatever was taken before it or dropped after).
  double improvement_pct = 0;
  const effects::Effect* over = nullptr;  // the richer best trial it was preferred to, if any
  std::vector<FoundAlternative> alternatives;
  std::optional<FromReleases> from_releases;
};

/// The implausible fit that would remove most error, as both paths report it: "no library effect
/// explains this plausibly", with where most error is left.
struct Implausible {
  std::string id;
  effects::Params params;
  double gain_pct = 0, explained_n = 0;
  double worst_t0_s = 0, worst_t1_s = 0;  // the held-out segment with the most error left
};

/// What a path says about its recording for that report.
struct Span {
  double n_used = 0;                // samples in the fit
  double t0_s = 0, duration_s = 0;  // the recording's time span
  double floor_n = 0;               // the RMS force a term must explain to count
  double min_gain_pct = 0;          // the held-out gain a term must bring
};

/// A step of the selection as the paths' validation reports it.
struct HeldOutStep {
  std::string model;  // "+ id" taken, "- id" dropped by the backward check
  std::vector<int> current;
  double heldout_sse = 0;  // of the model it leaves
};

/// The selection's result as both paths read it.
struct Result {
  std::vector<int> current;  // the final model's columns: the start's, then each term's
  double start_heldout_sse = 0;
  std::vector<Found> terms;  // the terms kept, in the order taken
  std::vector<HeldOutStep> steps;
  std::vector<Rejected> dropped;    // by the backward check
  std::vector<Rejected> refused;    // outside their range or within their error in the final fit
  std::optional<Found> stopped_at;  // the next term the rule named, below the threshold
  std::string stopped_reason;       // kBelowSignificance: the rule it failed, with its figures
  std::optional<Implausible> implausible;
};

/// Parameters by name in the findings' form (the same for every path).
Parameters parameters_of(const effects::Params& p);

/// The Outcome as a Result over `folds` held-out segments of `span`.
Result result_of(const Outcome& o, int folds, const Span& span);

/// The implausible fit as the findings say it; `check`: what a user should look at.
Unexplained unexplained_of(const Implausible& imp, std::string check);

/// A term not selected, with the RMS force it explains and why.
Rejected rejected_of(const Found& f, std::string reason);
/// The best candidate left out (the term the rule named next, below the threshold) as both
/// paths' findings list it: its held-out gain, t, worst segment, the force it would explain, why
/// it was left out and its parameters where the unit gives them.
Rejected best_left_out(const Found& f, const std::string& reason);

/// The rule in words, for the report's method.
std::string describe(const Settings& st);

/// Runs the selection on `g` from the model with columns `start`; effects in `excluded` are not
/// candidates. A term whose parameters leave its unit's physical range in the final fit is
/// refused and the rest chosen again without it. `progress` (may be empty) gets the share of
/// the terms tried.
Outcome select(const stats::Grams& g, const Candidates& cand, const Rules& rules,
               const Settings& st, const std::vector<int>& start,
               const std::vector<const effects::Effect*>& excluded,
               const std::function<void(double)>& progress);

}  // namespace maglead::analysis::selection
