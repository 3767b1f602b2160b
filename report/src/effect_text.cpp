#include "effect_text.hpp"

#include <array>

#include "maglead/analysis/results.hpp"
#include "maglead/effects/effect.hpp"
#include "maglead/report/html.hpp"

namespace maglead::report {
namespace {

// The unit is the end of a parameter's name (docs/effects.md); longest suffixes first.
struct UnitSuffix {
  const char* suffix;
  const char* unit;
};
constexpr std::array<UnitSuffix, 9> kUnitSuffixes{{{"_n_s_per_m", "N·s/m"},
                                                   {"_n_per_m", "N/m"},
                                                   {"_per_min", "1/min"},
                                                   {"_m_s", "m/s"},
                                                   {"_rad", "rad"},
                                                   {"_kg", "kg"},
                                                   {"_n", "N"},
                                                   {"_m", "m"},
                                                   {"_s", "s"}}};

std::string unit_of(const std::string& name) {
  for (const auto& [suffix, unit] : kUnitSuffixes) {
    const std::string s = suffix;
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0)
      return unit;
  }
  return "";
}

// The library's meaning without a trailing "[unit]" (the unit is printed with the value).
std::string meaning_of(const std::string& effect_id, const std::string& name) {
  const auto* e = effects::find(effect_id);
  if (!e) return "";
  for (const auto& p : e->params()) {
    if (p.name != name) continue;
    std::string m = p.meaning;
    if (const auto bracket = m.find(" ["); bracket != std::string::npos) m.erase(bracket);
    return m;
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

std::string effect_law(const std::string& id) {
  const auto* e = effects::find(id);
  return e ? std::string(e->law()) : std::string();
}

std::string parameter_html(const std::string& effect_id, const std::string& name, double value,
                           double standard_error) {
  const std::string unit = unit_of(name), meaning = meaning_of(effect_id, name);
  std::string shown = analysis::value_with_error(value, standard_error);
  if (shown.empty()) shown = number(value, 3);
  if (shown.front() == '-') shown.replace(0, 1, "−");
  std::string h = "<code>" + escape_html(name) + "</code> = " + escape_html(shown);
  if (!unit.empty()) h += " " + escape_html(unit);
  if (!meaning.empty()) h += " <span class=\"meaning\">(" + escape_html(meaning) + ")</span>";
  return h;
}

}  // namespace maglead::report
