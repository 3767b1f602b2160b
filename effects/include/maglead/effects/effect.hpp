#pragma once
// The effect library (docs/effects.md): one unit per physical effect a baseline model may lack.
// Each unit states its parameters with units and plausible ranges, its law (the force it adds to
// the nut's balance M p̈ = F_m − C v − F_f + F_ext, as the twin and the analysis apply it), and
// its regressors: the same law linear in a few coefficients once a shape value (a period, a zone,
// a velocity scale) is fixed, which is how the analysis fits it. Adding an effect is one file in
// effects/src plus its test; the registry lists it.
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace maglead::effects {

/// What a plausible range is stated in: absolute units, or the actuator's own scales, so that
/// no one actuator's size sits in a range (a friction beyond the force the drive produces would
/// never let it move, whatever that force is).
enum class Scale {
  absolute,
  force,            // multiples of Scales::force_n
  force_per_speed,  // multiples of Scales::force_n / Scales::speed_m_s (a viscous coefficient)
};

struct ParamSpec {
  std::string name;  // spec name, unit in the name (offset_n, delay_s)
  std::string meaning;
  double min, max;  // plausible range in units of `per`: a fit outside it is not this physics
  Scale per = Scale::absolute;
  // Below this many counts of the phase (Scales::phase_count_rad) a value is what the encoders'
  // rounding holds where the nut and screw stand still, not this physics (0: no such bound).
  double least_counts = 0;
};

/// The scales of the actuator a fit is judged on (from its configuration and recording).
struct Scales {
  double force_n = 0;    // the largest force the drive produces (the calibrated peak, an axis's
                         // largest drive force)
  double speed_m_s = 0;  // the largest speed the recording reaches
  // What the fitted samples cover (max − min of the nut's position and the screw's angle): a
  // law that repeats over more than that is not seen to repeat (0: not known, not applied).
  double travel_m = 0, turn_rad = 0;
  // One count of the phase φ: the coarser encoder's count (0: not known, not applied).
  double phase_count_rad = 0;
  // The recording's sample rate and the frequency at which the nut rings on its coupling (the
  // coupling's stiffness over the model's mass; 0: not known, not applied).
  double sample_rate_hz = 0, ring_hz = 0;
};

// Transparent comparison: the twin looks parameters up by name inside the 1 kHz cycle, and a
// lookup must not build a std::string (an allocation for names past the small-string buffer).
using Params = std::map<std::string, double, std::less<>>;

/// One instant of the actuator as the twin or the analysis sees it (SI units).
struct State {
  double t_s = 0;  // time since the start of the recording
  double p_m = 0, v_m_s = 0, a_m_s2 = 0;
  double jerk_m_s3 = 0;  // d³p/dt³ (0 where the caller cannot know it: see NutModel::state)
  double theta_rad = 0, phi_rad = 0, phi_rate_rad_s = 0;
  double coupling_n = 0;                 // F_m(φ): calibrated magnetic force on the nut along +p
  double coupling_slope_n_per_rad = 0;   // dF_m/dφ
  double load_n = 0, load_rate_n_s = 0;  // F_ext as the load cell reads it, and its rate
  double stroke_min_m = 0, stroke_max_m = 0.04, lead_m = 0.006;
  // The baseline model's own values: friction and mass effects are stated as totals and act
  // as the difference from these.
  double coulomb_n = 7.5, viscous_n_s_per_m = 2.0, nut_mass_kg = 0.12;
};

/// Evidence an effect reports in the time domain (events: step-outs, disturbance pulses).
struct Event {
  double t_s = 0, duration_s = 0, value = 0;  // value: leads slipped or force [N]
};

class Effect {
 public:
  virtual ~Effect() = default;
  virtual std::string_view id() const = 0;
  virtual std::string_view law() const = 0;  // one line, as in docs/effects.md
  virtual std::vector<ParamSpec> params() const = 0;

  /// The law: force added to the nut's balance along +p [N] (sliding; stuck is the friction
  /// units' break-away below). Exact where cheap, else first order in the small parameter.
  virtual double force_n(const Params& p, const State& s) const = 0;
  /// Extra break-away friction for motion in direction `dir` (+1/−1) over the kinetic level [N].
  virtual double breakaway_extra_n(const Params&, const State& /*model*/, double /*dir*/) const {
    return 0.0;
  }

  // ---- how the analysis fits it: force_n = Σ c_k x_k(s) for a fixed shape value
  /// Shape values to scan (an empty list: one shape, no value).
  virtual std::vector<double> shapes() const { return {}; }
  /// Whether samples spanning `scales` can tell this shape's law from others at all (a ripple
  /// whose period exceeds the travel seen is any smooth function of position there). A law not
  /// resolved is not named; it may still be listed as an alternative the data cannot rule out.
  virtual bool resolved_at(double /*shape*/, const Scales& /*scales*/) const { return true; }
  /// Why a recording at `scales` cannot judge this law at all (it is then not offered, and the
  /// reason is said); nothing when it can.
  virtual std::optional<std::string> unjudged_at(const Scales& /*scales*/) const {
    return std::nullopt;
  }
  virtual int columns() const = 0;
  virtual void regressors(double shape, const State& s, double* x) const = 0;
  /// Physical parameters from the coefficients; nullopt when they make no physical sense.
  virtual std::optional<Params> parameters(double shape, const double* c,
                                           const State& model) const = 0;
  /// Friction laws act only while sliding and against the motion (the twin's stick/slip logic
  /// treats them apart from the forces that drive the nut).
  virtual bool friction() const { return false; }
  /// False for effects the analysis only names as an alternative (identifiability).
  virtual bool selectable() const { return true; }

  // ---- the same law on a force-driven axis (a drive's force from measured motion, EMPS-like):
  // no magnetic coupling and no load cell, but every sample, sliding or slow, is in the fit.
  /// False where the law needs the coupling, the screw angle or the load cell.
  virtual bool on_axis() const { return true; }
  /// The law as an axis reads it: an axis has no load cell, so a law that speaks of one says it
  /// here without it.
  virtual std::string_view axis_law() const { return law(); }
  /// The axis fits the law in these columns: by default the nut's, a unit overrides them where
  /// the drive's force resolves more of its law (viscous friction per direction).
  virtual int axis_columns() const { return columns(); }
  virtual void axis_regressors(double shape, const State& s, double* x) const {
    regressors(shape, s, x);
  }
  virtual std::optional<Params> axis_parameters(double shape, const double* c,
                                                const State& model) const {
    return parameters(shape, c, model);
  }
};

/// The most regressor columns a unit may have (columns() and axis_columns()): the analysis asks
/// a unit for its row in a buffer of this size, once per sample, with no allocation.
inline constexpr int kMaxColumns = 8;
/// Throws std::logic_error naming the unit when it has more columns than kMaxColumns.
void check_columns(const Effect& e);
/// Every effect, in the order the analysis prefers among explanations it cannot tell apart; each
/// passed check_columns when the library was first asked for.
const std::vector<const Effect*>& library();
/// nullptr if unknown.
const Effect* find(std::string_view id);
/// Throws std::invalid_argument naming the effect and parameter when a required one is absent
/// or outside its range.
void check(const Effect& e, const Params& p);
/// True when every value lies inside its documented plausible range, a range in the actuator's
/// scales taken in `scales` (a scale not known, 0: that bound is not applied).
bool plausible(const Effect& e, const Params& p, const Scales& scales);
/// Whether a value with a least count (ParamSpec::least_counts) still reaches it less its
/// standard error `se` (a parameter without an error is judged as it is), and a magnitude (a
/// range starting at zero: a stiffness, a delay, a friction level) is beyond zero by its error:
/// a spring of 8.6 ± 9.0 N/m is no spring.
bool beyond_its_error(const Effect& e, const Params& p, const Params& se, const Scales& scales);

double sgn(double x);

}  // namespace maglead::effects
