// maglead bench analyze: the whole analysis on a one-hour 1 kHz recording (3.6 M samples), timed
// stage by stage, with peak memory. Generates the recording with the simulated plant unless one
// is given (generation is timed apart: it is not part of the analysis).
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "bench_common.hpp"
#include "cli_common.hpp"
#include "maglead/twin/model.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/plant/scenario.hpp"

namespace maglead::cli {
namespace {

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

void add_bench_analyze(CLI::App& app) {
  auto* cmd = bench_command(app)->add_subcommand(
      "analyze", "Time maglead analyze on a one-hour 1 kHz recording (aim: under 30 s), with "
                 "peak memory");
  struct Opts {
    std::string recording, out, config = default_config_dir();
    bool quick = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--recording", o->recording,
                  "Recording to analyse (default: generate position-moves with a spring, a "
                  "position ripple and an offset concealed)");
  cmd->add_flag("--quick", o->quick, "Two simulated minutes instead of an hour (CI)");
  cmd->add_option("--out", o->out, "Output directory (default: a temporary one)");
  cmd->add_option("--config", o->config, "Configuration directory")->capture_default_str();
  cmd->callback([o] {
    using Clock = std::chrono::steady_clock;
    auto secs = [](Clock::time_point a) {
      return std::chrono::duration<double>(Clock::now() - a).count();
    };
    const auto tmp = std::filesystem::temp_directory_path() / "maglead_bench_analyze";
    std::filesystem::create_directories(tmp);
    const ActuatorParams act = load_actuator_or_default(o->config);
    std::string path = o->recording;
    if (path.empty()) {
      path = (tmp / (o->quick ? "bench_2min.csv" : "bench_1h.csv")).string();
      ScenarioOptions opt;
      opt.scenario = "position-moves";
      opt.duration_s = o->quick ? 120.0 : 3600.0;
      opt.seed = 11;
      opt.plant.actuator = act;
      set_plant_effect(opt.plant.effects, "spring", 300.0);
      set_plant_effect(opt.plant.effects, "position_ripple", 1.0);
      set_plant_effect(opt.plant.effects, "offset", 1.0);
      Progress progress("generate");
      opt.progress = [&](double f) { progress(f); };
      const auto t0 = Clock::now();
      run_scenario(opt, path);
      progress.done();
      std::printf("generated %s (%.0f s simulated) in %.1f s (not part of the analysis)\n",
                  path.c_str(), opt.duration_s, secs(t0));
    }
    const std::string out = o->out.empty() ? (tmp / "out").string() : o->out;
    const bool has_model = std::filesystem::exists(config_file(o->config, "model.toml"));
    if (has_model) twin::check_model_format(config_file(o->config, "model.toml"));
    const auto model = has_model ? analysis::load_model(config_file(o->config, "model.toml"))
                           : analysis::actuator_model_from_config(act);
    const auto cal = load_calibration(config_file(o->config, "calibration.toml"));

    const auto t_all = Clock::now();
    auto t0 = Clock::now();
    const Recording rec = read_recording(path);
    const double t_read = secs(t0);
    analysis::AnalysisOptions aopt;
    std::string last;
    aopt.progress = [&](const std::string& stage, double) {
      if (stage != last) note("  " + stage + " (" + std::to_string(secs(t_all)) + " s)");
      last = stage;
    };
    t0 = Clock::now();
    const auto result = analysis::analyze_recording(rec, model, cal, act, aopt);
    const double t_an = secs(t0);
    t0 = Clock::now();
    analysis::write_outputs(result, out);
    const double t_out = secs(t0);
    const double total = secs(t_all);
    const auto& J = result.json;
    std::printf("maglead bench analyze: %zu samples (%.0f s at 1 kHz)\n", rec.rows(),
                static_cast<double>(rec.rows()) / 1000.0);
    std::printf("  read recording   %7.2f s\n  analysis         %7.2f s\n  report + plots   %7.2f s\n",
                t_read, t_an, t_out);
    std::printf("  total            %7.2f s   (target < 30 s for one hour)\n", total);
    std::printf("  peak memory      %7.0f MB (max resident set size)\n", peak_rss_mb());
    std::printf("  found:");
    for (const auto& e : J["effects"]) std::printf(" %s", e["id"].get<std::string>().c_str());
    std::printf("%s\n  held-out RMS %.4f N -> %.4f N; report in %s\n",
                J["effects"].empty() ? " nothing" : "",
                J["validation"].front()["heldout_rms"].get<double>(),
                J["validation"].back()["heldout_rms"].get<double>(), out.c_str());
  });
}

MAGLEAD_COMMAND(95, add_bench_analyze);

}  // namespace
}  // namespace maglead::cli
