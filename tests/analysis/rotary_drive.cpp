// Writes the generated rotary drive (rotary_drive.hpp) as a recording, for the command-line test
// (rotary_cli.py): rotary_drive OUT.csv [VISCOUS_N_M_S_PER_RAD].
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "rotary_drive.hpp"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: rotary_drive OUT.csv [VISCOUS_N_M_S_PER_RAD]\n");
    return 2;
  }
  maglead::test::RotaryDrive d;
  if (argc > 2) d.viscous_n_m_s_per_rad = std::atof(argv[2]);
  try {
    maglead::write_recording(argv[1], maglead::test::rotary_recording(d));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rotary_drive: %s\n", e.what());
    return 1;
  }
  return 0;
}
