// The axis kinds (maglead/effects/axis_kind.hpp): columns, units and parameter names.
#include "maglead/effects/axis_kind.hpp"

#include <array>
#include <cctype>
#include <utility>

#include "maglead/effects/effect.hpp"

namespace maglead::effects {
namespace {

bool ends_with(std::string_view s, std::string_view end) {
  return s.size() > end.size() && s.substr(s.size() - end.size()) == end;
}

// A rotary axis's name of a unit parameter: a quantity that is another one on a shaft (a mass is
// an inertia, a force a torque) by its whole name, else the unit in the name's suffix (longest
// first), so `offset_n` is `offset_n_m` and `phase_rad` stays itself.
std::string rotary_name(std::string_view n) {
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 4> kQuantities{{
      {"nut_mass_kg", "inertia_kg_m2"},
      {"rest_position_m", "rest_angle_rad"},
      {"stribeck_velocity_m_s", "stribeck_speed_rad_s"},
      {"force_n", "torque_n_m"},
  }};
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 6> kUnits{{
      {"_n_s_per_m", "_n_m_s_per_rad"},
      {"_n_per_m", "_n_m_per_rad"},
      {"_m_s", "_rad_s"},
      {"_n", "_n_m"},
      {"_kg", "_kg_m2"},
      {"_m", "_rad"},
  }};
  for (const auto& [from, to] : kQuantities)
    if (n == from) return std::string(to);
  for (const auto& [from, to] : kUnits)
    if (ends_with(n, from))
      return std::string(n.substr(0, n.size() - from.size())) + std::string(to);
  return std::string(n);
}

// A shaft's word or symbol for the nut's: whole words, and a law's symbols before a subscript
// (F_c is τ_c). Words with units in them (`nut_mass_kg`) are names, renamed by name_of.
std::string_view rotary_word(std::string_view w) {
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 11> kWords{
      {{"force", "torque"},
       {"forces", "torques"},
       {"Force", "Torque"},
       {"nut", "shaft"},
       {"slides", "turns"},
       {"mass", "inertia"},
       {"position", "angle"},
       {"F", "τ"},
       {"M", "J"},
       {"v", "ω"},
       {"p", "θ"}}};
  for (const auto& [from, to] : kWords)
    if (w == from) return to;
  return w;
}

bool word_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_'; }

}  // namespace

std::string AxisKind::words(std::string_view text) const {
  if (name != "rotary") return std::string(text);
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    if (!word_char(text[i])) {
      out += text[i++];
      continue;
    }
    std::size_t end = i;
    while (end < text.size() && word_char(text[end])) ++end;
    const std::string_view word = text.substr(i, end - i);
    const std::size_t sub = word.find('_');
    // A one-letter symbol with a subscript (F_c, v_s) is the symbol's; other words with '_' are
    // names.
    if (sub == 1)
      out += std::string(rotary_word(word.substr(0, 1))) + std::string(word.substr(1));
    else
      out += sub == std::string_view::npos ? rotary_word(word) : word;
    i = end;
  }
  return out;
}

std::string AxisKind::law(const Effect& e) const { return words(e.axis_law()); }

std::string AxisKind::name_of(std::string_view unit_name) const {
  return name == "rotary" ? rotary_name(unit_name) : std::string(unit_name);
}

std::string AxisKind::unit_name_of(std::string_view kind_name) const {
  for (const Effect* e : library())
    for (const auto& p : e->params())
      if (name_of(p.name) == kind_name) return p.name;
  return "";
}

const AxisKind& linear_axis() {
  static const AxisKind k{.name = "linear",
                          .system = "axis",
                          .position = "pos_m",
                          .drive = "drive_force_n",
                          .drive_unit = "N",
                          .quantity = "force",
                          .motion = "position",
                          .map_unit = "mm",
                          .map_rate_unit = "mm/s",
                          .map_scale = 1e3,
                          .setpoints = {"force_set_n", "pos_set_m", "ref_pos_m"},
                          .not_offered = {}};
  return k;
}

const AxisKind& rotary_axis() {
  // A ripple's period and a Stribeck velocity are scanned over a lead screw's millimetres and
  // millimetres per second, and a spring's rest position is bounded in metres: read as radians
  // those grids are not a shaft's (a cogging period, a Stribeck speed in rad/s), so these units
  // wait until their rotary shapes and ranges are stated.
  static const AxisKind k{.name = "rotary",
                          .system = "rotary",
                          .position = "angle_rad",
                          .drive = "drive_torque_n_m",
                          .drive_unit = "N·m",
                          .quantity = "torque",
                          .motion = "angle",
                          .map_unit = "rad",
                          .map_rate_unit = "rad/s",
                          .map_scale = 1.0,
                          .setpoints = {"torque_set_n_m", "ref_angle_rad"},
                          .not_offered = {"position_ripple", "stribeck_friction", "spring"}};
  return k;
}

const AxisKind* axis_kind(std::string_view name) {
  if (name.empty() || name == "linear") return &linear_axis();
  if (name == "rotary") return &rotary_axis();
  return nullptr;
}

const AxisKind* axis_kind_of_system(std::string_view system) {
  if (system == "axis") return &linear_axis();
  if (system == "rotary") return &rotary_axis();
  return nullptr;
}

std::string_view drive_unit_of_system(std::string_view system) {
  const AxisKind* k = axis_kind_of_system(system);
  return k ? k->drive_unit : linear_axis().drive_unit;
}

}  // namespace maglead::effects
