// maglead simulate: run the simulated actuator through a load scenario and record it.
#include <cstdio>
#include <memory>
#include <sstream>

#include "cli_common.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/plant/scenario.hpp"
#include "maglead/runtime/scenario_controller.hpp"

namespace maglead::cli {
namespace {

/// Which controller ran, in the printed line and the recording's `# controller:` line: two runs
/// that differ only in --controller must not look alike.
std::string controller_name(const std::string& controller, const std::string& scenario) {
  if (controller == "open-loop") return "open-loop, the paper's inverse";
  return scenario == "position-moves" ? "maglead, its position loop" : "maglead, its force loop";
}

void add_simulate(CLI::App& app) {
  const std::string effects_help =
      plant_effects_help("Extra plant physics, NAME=VALUE, repeatable:");
  std::string scenario_help = "Load scenario:";
  for (const auto& s : scenario_list()) scenario_help += "\n  " + s.name + "  " + s.description;

  auto* cmd = app.add_subcommand(
      "simulate", "Run the simulated actuator through a load scenario; write an mls-recording/1");
  struct Opts {
    std::string scenario, duration = "30s", out, config = default_config_dir(), calibration;
    std::string controller = "open-loop";
    std::uint64_t seed = 1;
    std::vector<std::string> effects;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--scenario", o->scenario, scenario_help)->required();
  cmd->add_option("--duration", o->duration, "Simulated time, e.g. 30s, 2min, 1h")
      ->capture_default_str();
  cmd->add_option("--seed", o->seed, "Random seed (hand profile, noise)")->capture_default_str();
  cmd->add_option("--effect", o->effects, effects_help);
  cmd->add_option("-o,--out", o->out, "Output recording (CSV)")->required();
  add_config_option(cmd, o->config);
  cmd->add_option("--calibration", o->calibration,
                  "Calibration for the logged force estimate (default: CONFIG/calibration.toml)");
  cmd->add_option("--controller", o->controller,
                  "What commands the screw: open-loop (the paper's inverse, the coupling at the "
                  "setpoint, the screw at the move's profile; every scenario, the default) or "
                  "maglead (maglead's own loop on the simulated clock, with CONFIG's [control] and "
                  "model.toml: the force loop and load observer on force-holds and force-steps, "
                  "the position loop and its profile on position-moves; each new setpoint or move "
                  "given with an execute edge as a PLC gives it)")
      ->check(CLI::IsMember({"open-loop", "maglead"}))
      ->capture_default_str();
  cmd->callback([o] {
    ScenarioOptions opt;
    opt.scenario = o->scenario;
    opt.duration_s = parse_duration_s(o->duration, "--duration");
    opt.seed = o->seed;
    opt.plant.actuator = load_actuator_or_default(o->config);
    apply_plant_effects("--effect", o->effects, opt.plant.effects);
    const std::string cal =
        o->calibration.empty() ? config_file(o->config, "calibration.toml") : o->calibration;
    opt.estimator_calibration = load_calibration(cal);
    opt.controller_name = controller_name(o->controller, o->scenario);
    std::unique_ptr<runtime::ScenarioController> loop;
    if (o->controller == "maglead") {
      if (!scenario_takes_controller(o->scenario))
        throw CLI::ValidationError("--controller",
                                   "maglead runs force-holds, force-steps and position-moves; '" +
                                       o->scenario +
                                       "' runs open loop only: leave out --controller, or use "
                                       "--scenario force-holds, force-steps or position-moves");
      controller::ControllerConfig cc = controller_config_of(o->config, cal, "", nullptr);
      cc.actuator = opt.plant.actuator;
      loop = std::make_unique<runtime::ScenarioController>(cc);
      opt.controller = [&loop](double t, const SensorSample& s, const ScenarioSetpoint& sp) {
        return loop->motor_angle_rad(t, s, sp);
      };
    }
    Progress progress("simulate " + o->scenario);
    opt.progress = [&](double f) { progress(f); };
    const std::string replacing = replacing_note(o->out);
    const auto summary = run_scenario(opt, o->out);
    progress.done();
    std::printf("wrote %s%s: %zu samples, %.1f s of %s (controller: %s)%s\n", o->out.c_str(),
                replacing.c_str(), summary.samples, opt.duration_s, o->scenario.c_str(),
                opt.controller_name.c_str(),
                summary.slips ? (", the nut stepped out " +
                                 std::to_string(std::abs(summary.slips)) + " lead(s)")
                                    .c_str()
                              : "");
  });
}

MAGLEAD_COMMAND(20, add_simulate);

}  // namespace
}  // namespace maglead::cli
