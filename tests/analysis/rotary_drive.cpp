// Writes the generated rotary drive (rotary_drive.hpp) as a recording, for the command-line test
// (rotary_cli.py) and for trying the rotary analysis (docs/analysis.md, a rotary axis):
// rotary_drive OUT.csv [VISCOUS_N_M_S_PER_RAD].
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string_view>

#include "rotary_drive.hpp"

namespace {

constexpr const char* kUsage =
    "usage: rotary_drive OUT.csv [VISCOUS_N_M_S_PER_RAD]\n"
    "Writes a generated servo drive (40 s at 1 kHz, '# axis: rotary'; columns t_s, angle_rad,\n"
    "drive_torque_n_m, ref_angle_rad) with viscous friction VISCOUS (default 0.002 N*m*s/rad),\n"
    "for maglead analyze with a rotary model.\n";

// The viscous coefficient, or a negative value when the argument is no number of that unit.
double viscous_of(const char* text) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  return (end == text || *end != '\0' || !(v >= 0.0)) ? -1.0 : v;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string_view first = argc > 1 ? argv[1] : "";
  if (first == "-h" || first == "--help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  // An option (a name starting with '-') would be written as a file of that name.
  if (argc < 2 || argc > 3 || first.empty() || first.front() == '-') {
    std::fputs(kUsage, stderr);
    return 2;
  }
  maglead::test::RotaryDrive d;
  if (argc > 2 && (d.viscous_n_m_s_per_rad = viscous_of(argv[2])) < 0.0) {
    std::fprintf(stderr, "rotary_drive: VISCOUS '%s' is no coefficient >= 0\n%s", argv[2], kUsage);
    return 2;
  }
  try {
    maglead::write_recording(argv[1], maglead::test::rotary_recording(d));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rotary_drive: %s\n", e.what());
    return 1;
  }
  return 0;
}
