// The analysis's first line: what was found, with its value beside the model's, or what is left
// unexplained, or why nothing could be judged. `analyze` prints it first and the report puts it
// at the top of the page.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/headline.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "maglead/effects/effect.hpp"

namespace maglead::analysis {
namespace {

std::string number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

// A finding's parameter name as the effect unit calls it: a rotary axis's findings carry its own
// (inertia_kg_m2 for nut_mass_kg), the model file holds the units' (effects/axis_kind.hpp).
std::string unit_name(const ModelFile& m, const std::string& name) {
  const effects::AxisKind* kind = effects::axis_kind_of_system(m.system);
  if (!kind || kind->name == "linear") return name;
  const std::string n = kind->unit_name_of(name);
  return n.empty() ? name : n;
}

/// The baseline's value of a parameter: its [model] value, or an enabled term's of the same id.
std::string model_value(const ModelFile& m, const std::string& id, const std::string& kind_name) {
  const std::string name = unit_name(m, kind_name);
  if (name == "nut_mass_kg") return number(m.nut_mass_kg);
  if (name == "viscous_n_s_per_m") return number(m.viscous_n_s_per_m);
  if (name == "coulomb_n") return number(m.coulomb_n);
  for (const auto& t : m.terms)
    if (t.enabled && t.id == id)
      for (const auto& [key, value] : t.parameters)
        if (key == name) return number(value);
  return "";
}

/// The effect's main parameter (the first its law names: an amplitude before its phase, a zone
/// before its depth), else the finding's first.
const Parameter& main_parameter(const EffectFinding& e, const ModelFile& baseline) {
  if (const auto* effect = effects::find(e.id); effect && !effect->params().empty()) {
    const std::string first = effect->params().front().name;
    for (const auto& p : e.parameters)
      if (unit_name(baseline, p.name) == first) return p;
  }
  return e.parameters.front();
}

/// "viscous friction 22.55 ± 0.12 N·s/m, calibration ± 3.6 N·s/m (model 2 N·s/m)".
std::string finding_text(const EffectFinding& e, const ModelFile& baseline) {
  std::string name = e.id;
  for (auto& ch : name)
    if (ch == '_') ch = ' ';
  if (e.parameters.empty()) return name;
  const Parameter& p = main_parameter(e, baseline);
  const std::string unit = unit_of_parameter(p.name);
  const std::string with_unit = unit.empty() ? "" : " " + unit;
  std::string value = value_with_error(p.value, parameter_value(e.standard_errors, p.name, 0.0));
  if (value.empty()) value = number(p.value);
  const double calibration = parameter_value(e.calibration_errors, p.name, 0.0);
  const std::string from_calibration =
      calibration > 0 ? ", calibration ± " + calibration_bound_text(p.name, calibration) : "";
  const std::string model = model_value(baseline, e.id, p.name);
  std::string s = name + " " + p.name + " " + value + with_unit + from_calibration +
                  (model.empty() ? " (not in the model)" : " (model " + model + with_unit + ")");
  if (e.note.rfind("left out of model_corrected.toml", 0) == 0)
    s += " [left out of the corrected model]";
  // A pair the data do not separate is said where it is read first, not only in the finding.
  std::string others;
  for (const auto& a : e.alternatives)
    if (a.plausible.value_or(true)) others += (others.empty() ? "" : " or ") + a.id;
  if (!others.empty()) s += ", or " + others + " (the data cannot tell them apart)";
  return s;
}

/// Laws the recording could not judge at all: "; not judged: mass_error (why)", so neither
/// "found" nor "nothing missing" is read as covering them.
std::string unjudged_suffix(const Findings& f) {
  std::string s;
  const std::string prefix = kNotJudged;
  for (const auto& r : f.not_selected)
    if (r.reason && r.reason->starts_with(prefix))
      s += (s.empty() ? "; " + prefix : std::string(", ")) + r.id + " (" +
           r.reason->substr(prefix.size()) + ")";
  return s;
}

/// Sliding laws judged on few samples or none (the note's first clause): neither "found" nor
/// "nothing missing" is read as covering them.
std::string sliding_caveat(const Findings& f) {
  if (f.sliding_note.empty()) return {};
  return (f.samples_used < rules::kMinSlidingSamples
              ? "; the sliding laws not judged: "
              : "; the sliding laws judged on few samples: ") +
         f.sliding_note.substr(0, f.sliding_note.find(':'));
}

/// No floor to judge the misfit against: the noise was not measurable and no logging step was
/// found to bound it (a floor of 0 would call any misfit force the model leaves out).
bool floor_unjudged(const Findings& f) { return f.noise_step_n && !(*f.noise_step_n > 0); }

std::string unjudged_misfit(const Findings& f, const effects::AxisKind& kind) {
  return "not judged: the load cell's noise floor could not be measured (no logging step "
         "found), so the misfit of " +
         number(f.final_fit.rms_n) + " " + std::string(kind.drive_unit) +
         " RMS cannot be judged against it";
}

/// A misfit above the floor beside the terms found, so "found" is not read as the whole story.
std::string misfit_beside(const Findings& f, const effects::AxisKind& kind) {
  if (floor_unjudged(f)) return "; " + unjudged_misfit(f, kind);
  if (!misfit_remains(f.final_fit.rms_n, f.noise_floor_n)) return {};
  const std::string unit(kind.drive_unit);
  return "; a misfit of " + number(f.final_fit.rms_n) + " " + unit + " RMS remains beside them (" +
         noise_floor_text(f, kind) + ")";
}

/// The headline without the laws left unjudged.
std::string conclusion_headline(const Findings& f, const ModelFile& baseline) {
  // A rotary axis's residual is a torque (effects/axis_kind.hpp).
  const effects::AxisKind* axis = effects::axis_kind_of_system(baseline.system);
  const effects::AxisKind& kind = axis ? *axis : effects::linear_axis();
  const auto found = [&](std::string s) {
    for (std::size_t k = 0; k < f.effects.size(); ++k)
      s += (k ? "; " : "") + finding_text(f.effects[k], baseline);
    return s;
  };
  const bool events_only = std::all_of(f.effects.begin(), f.effects.end(),
                                       [](const auto& e) { return e.evidence.events.has_value(); });
  // Terms fitted where the recording cannot tell their laws apart (one_way_unjudged): that leads.
  if (!events_only && f.conclusion.starts_with(kNotJudged))
    return f.conclusion + misfit_beside(f, kind) + sliding_caveat(f);
  if (!events_only) return found("found: ") + misfit_beside(f, kind) + sliding_caveat(f);
  // With events alone named, a force no library effect explains leads: events (pulses on a load
  // cell of the wrong sign, say) are no account of it.
  if (f.unexplained)
    return "not explained: " + f.unexplained->message +
           (f.effects.empty() ? std::string() : found("; events found beside it: "));
  // A misfit beside events is said as beside terms: a short pulse leaves little of its force in
  // the sliding residual, so what is left above the floor is force the events do not account for.
  if (!f.effects.empty()) return found("found: ") + misfit_beside(f, kind) + sliding_caveat(f);
  // The conclusion says why the model was not judged (too little sliding), with its counts.
  if (f.conclusion.starts_with(kNotJudged))
    return f.conclusion + "; no finding is not the same as no anomaly";
  const std::string unit(kind.drive_unit);
  if (floor_unjudged(f)) return unjudged_misfit(f, kind) + sliding_caveat(f);
  if (misfit_remains(f.final_fit.rms_n, f.noise_floor_n))
    return misfit_text(f, kind) + sliding_caveat(f);
  return "nothing missing: the model explains the recording to " + number(f.final_fit.rms_n) + " " +
         unit + " RMS (" + noise_floor_text(f, kind) + ")" + sliding_caveat(f);
}

}  // namespace

std::string headline_of(const Findings& f, const ModelFile& baseline) {
  return conclusion_headline(f, baseline) + unjudged_suffix(f);
}

}  // namespace maglead::analysis
