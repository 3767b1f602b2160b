// maglead: the command line of the magnetic lead-screw actuator controller and its twin.
#include <cstdio>
#include <exception>

#include "cli_common.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "maglead: force-estimating controller for a magnetic lead-screw actuator, with its "
      "simulated plant and digital twin.\nRun 'maglead COMMAND --help' for a command's options."};
  app.require_subcommand(1);
  app.fallthrough();
  maglead::cli::register_all(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "maglead: error: %s\n", e.what());
    return maglead::cli::kExitBadInput;
  }
  return 0;
}
