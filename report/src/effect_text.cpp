#include "effect_text.hpp"

#include "maglead/analysis/results.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "maglead/effects/effect.hpp"
#include "maglead/report/html.hpp"

namespace maglead::report {
namespace {

// The library's meaning without a trailing "[unit]" (the unit is printed with the value), in
// the kind's words.
std::string meaning_of(const std::string& effect_id, const std::string& name,
                       const effects::AxisKind& kind) {
  const auto* e = effects::find(effect_id);
  if (!e) return "";
  for (const auto& p : e->params()) {
    // A rotary axis names the parameter in its own units (effects/axis_kind.hpp).
    if (p.name != name && effects::rotary_axis().name_of(p.name) != name) continue;
    std::string m = p.meaning;
    if (const auto bracket = m.find(" ["); bracket != std::string::npos) m.erase(bracket);
    return kind.words(m);
  }
  return "";
}

}  // namespace

std::string effect_title(const std::string& id) {
  std::string t = id;
  for (char& c : t)
    if (c == '_') c = ' ';
  return t;
}

std::string effect_law(const std::string& id, const effects::AxisKind* axis) {
  const auto* e = effects::find(id);
  if (!e) return "";
  return axis ? axis->law(*e) : std::string(e->law());
}

std::string parameter_html(const std::string& effect_id, const std::string& name, double value,
                           double standard_error, const effects::AxisKind& kind) {
  const std::string unit = analysis::unit_of_parameter(name),
                    meaning = meaning_of(effect_id, name, kind);
  std::string shown = analysis::value_with_error(value, standard_error);
  if (shown.empty()) shown = number(value, 3);
  if (shown.front() == '-') shown.replace(0, 1, "−");
  std::string h = "<code>" + escape_html(name) + "</code> = " + escape_html(shown);
  if (!unit.empty()) h += " " + escape_html(unit);
  if (!meaning.empty()) h += " <span class=\"meaning\">(" + escape_html(meaning) + ")</span>";
  return h;
}

}  // namespace maglead::report
