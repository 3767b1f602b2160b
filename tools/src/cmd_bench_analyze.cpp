// maglead bench analyze: the whole analysis on a one-hour 1 kHz recording (3.6 M samples), timed
// stage by stage, with peak memory. Generates the recording with the simulated plant unless one
// is given (generation is timed apart: it is not part of the analysis). Then `maglead analyze` as
// a user runs it, a process of its own, timed whole with its peak memory, and set beside pandas'
// read_csv of the same file, measured in the same run.
#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.hpp"
#include "cli_common.hpp"
#include "large_blocks.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/reading.hpp"
#include "maglead/plant/scenario.hpp"
#include "maglead/report/analysis_page.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::cli {
namespace {

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

/// Reads the file once, untimed, so that both CSV readers find it in the page cache.
void warm_page_cache(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return;  // read_recording says why
  std::vector<char> buf(std::size_t{1} << 20);
  while (std::fread(buf.data(), 1, buf.size(), f) == buf.size()) {
  }
  std::fclose(f);
}

std::string shell_quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// pandas.read_csv of the file in a Python child process: wall and CPU seconds of the call alone
/// (not the interpreter's start or the import), or why there is no figure.
struct PandasRead {
  std::optional<double> wall_s, cpu_s;
  std::string version, python;
  std::size_t rows = 0;
  std::string why_not;
};

PandasRead pandas_read_csv(const std::string& path) {
  // Debian's python first: python3-pandas (tools/setup.sh) installs there, and the python3
  // first on PATH may be another one.
  static const char* const kScript =
      "import sys, time\n"
      "try:\n"
      "    import pandas\n"
      "except Exception as e:\n"
      "    print(\"unavailable\", type(e).__name__ + \":\", e)\n"
      "    sys.exit(0)\n"
      "w, c = time.perf_counter(), time.process_time()\n"
      "df = pandas.read_csv(sys.argv[1], comment=\"#\")\n"
      "w, c = time.perf_counter() - w, time.process_time() - c\n"
      "print(\"ok\", pandas.__version__, repr(w), repr(c), len(df))\n";
  PandasRead r;
  for (const char* python : {"/usr/bin/python3", "python3"}) {
    const std::string cmd =
        shell_quoted(python) + " -c " + shell_quoted(kScript) + " " + shell_quoted(path) + " 2>&1";
    std::FILE* p = popen(cmd.c_str(), "r");
    if (!p) {
      r.why_not += std::string(r.why_not.empty() ? "" : "; ") + "cannot start " + python;
      continue;
    }
    std::string out;
    char buf[4096];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
    pclose(p);
    std::istringstream in(out);
    std::string word;
    in >> word;
    double wall = 0, cpu = 0;
    if (word == "ok" && in >> r.version >> wall >> cpu >> r.rows) {
      r.wall_s = wall;
      r.cpu_s = cpu;
      r.python = python;
      return r;
    }
    while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
    if (const auto nl = out.rfind('\n'); nl != std::string::npos) out = out.substr(nl + 1);
    r.why_not += std::string(r.why_not.empty() ? "" : "; ") + python + ": " +
                 (word == "unavailable" ? out.substr(12) : out);
  }
  return r;
}

/// `maglead analyze` on the file as a child process: wall seconds from spawn to exit and the
/// child's own peak resident set (wait4), or nullopt when it could not run or failed.
struct ProcessRun {
  double wall_s = 0, peak_mb = 0;
};
std::optional<ProcessRun> time_analyze_process(const std::string& path, const std::string& out,
                                               const std::string& config) {
  std::error_code ec;
  const std::string exe = std::filesystem::read_symlink("/proc/self/exe", ec).string();
  if (ec) return std::nullopt;
  std::vector<std::string> args = {exe,     "analyze", "--recording", path,
                                   "--out", out,       "--config",    config};
  std::vector<char*> argv;
  argv.reserve(args.size() + 1);
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);  // its report: not ours
  posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, exe.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (spawned != 0) return std::nullopt;
  int status = 0;
  rusage u{};
  if (wait4(pid, &status, 0, &u) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    return std::nullopt;
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return ProcessRun{wall, static_cast<double>(u.ru_maxrss) / 1024.0};
}

/// The whole process against the aims: within 0.8x pandas' read_csv of the same file
/// (the analysis should cost less than a common reader's mere parse) and 300 MB at its peak
/// (a 3.6 M-sample hour fits a small industrial PC beside the controller).
constexpr double kWholeProcessOverPandas = 0.8;
constexpr double kPeakMemoryAimMb = 300.0;
/// The aims are an hour's at 1 kHz; a shorter recording (--quick) is timed, not judged.
constexpr std::size_t kAimSamples = 3'600'000;

/// "met" / "missed" for an hour's recording, else why it is not judged.
std::string verdict(bool met, std::size_t rows) {
  if (rows < kAimSamples) return "not judged: the aim is for an hour at 1 kHz";
  return met ? "met" : "missed";
}

struct BenchAnalyzeOptions {
  std::string recording, out, config = default_config_dir();
  bool quick = false;
};

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point a) {
  return std::chrono::duration<double>(Clock::now() - a).count();
}

/// The default recording: position moves with a spring, a position ripple and an offset
/// concealed, an hour (two minutes with --quick).
std::string generate_recording(const BenchAnalyzeOptions& o, const ActuatorParams& act,
                               const std::filesystem::path& dir) {
  std::string path = (dir / (o.quick ? "bench_2min.csv" : "bench_1h.csv")).string();
  ScenarioOptions opt;
  opt.scenario = "position-moves";
  opt.duration_s = o.quick ? 120.0 : 3600.0;
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
              path.c_str(), opt.duration_s, seconds_since(t0));
  return path;
}

struct ReadTime {
  double wall_s = 0, cpu_s = 0;
  std::size_t rows = 0;
};

/// After the analysis, so that neither disturbs the other's figures.
void compare_with_pandas(const std::string& path, const ReadTime& ours,
                         const std::optional<ProcessRun>& whole) {
  std::printf("\n  reading the CSV, same file, same run (page cache warm for both):\n");
  std::printf("    %-28s %7.2f s wall %7.2f s CPU\n", "maglead read_recording", ours.wall_s,
              ours.cpu_s);
  std::fflush(stdout);
  const PandasRead pd = pandas_read_csv(path);
  if (!pd.wall_s) {
    std::printf(
        "    pandas read_csv: reference unavailable (%s); install python3-pandas: "
        "bash tools/setup.sh\n",
        pd.why_not.c_str());
    return;
  }
  const std::string label = "pandas " + pd.version + " read_csv";
  std::printf("    %-28s %7.2f s wall %7.2f s CPU   (%s, comment='#')\n", label.c_str(), *pd.wall_s,
              *pd.cpu_s, pd.python.c_str());
  std::printf("    %-28s %7.2f        %7.2f         (target <= 1: %s)\n", "maglead / pandas",
              ours.wall_s / *pd.wall_s, ours.cpu_s / *pd.cpu_s,
              ours.wall_s <= *pd.wall_s ? "met" : "missed");
  if (pd.rows != ours.rows)
    std::printf("    ** pandas read %zu rows, maglead %zu **\n", pd.rows, ours.rows);
  if (!whole) return;
  std::printf("    %-28s %7.2f         (target <= %.1f: %s)\n", "maglead analyze / pandas",
              whole->wall_s / *pd.wall_s, kWholeProcessOverPandas,
              verdict(whole->wall_s <= kWholeProcessOverPandas * *pd.wall_s, ours.rows).c_str());
}

void run_bench_analyze(const BenchAnalyzeOptions& o) {
  const auto tmp = std::filesystem::temp_directory_path() / "maglead_bench_analyze";
  std::filesystem::create_directories(tmp);
  const ActuatorParams act = load_actuator_or_default(o.config);
  const std::string path = o.recording.empty() ? generate_recording(o, act, tmp) : o.recording;
  const std::string out = o.out.empty() ? (tmp / "out").string() : o.out;
  const std::string model_path = config_file(o.config, "model.toml");
  const bool has_model = std::filesystem::exists(model_path);
  if (has_model) twin::check_model_format(model_path);
  const auto model =
      has_model ? analysis::load_model(model_path) : analysis::actuator_model_from_config(act);
  const auto cal = load_calibration(config_file(o.config, "calibration.toml"));

  warm_page_cache(path);
  const auto t_all = Clock::now();
  const double c_read0 = thread_cpu_s();
  const Recording rec = read_recording(path, {}, analysis::columns_read);  // as analyze reads
  const ReadTime read{seconds_since(t_all), thread_cpu_s() - c_read0, rec.rows()};
  analysis::AnalysisOptions aopt;
  std::string last;
  aopt.progress = [&](const std::string& stage, double) {
    if (stage != last) note("  " + stage + " (" + std::to_string(seconds_since(t_all)) + " s)");
    last = stage;
  };
  auto t0 = Clock::now();
  const auto result = analysis::analyze_recording(rec, model, cal, act, aopt);
  const double t_an = seconds_since(t0);
  t0 = Clock::now();
  report::write_analysis_outputs(result, out);
  const double t_out = seconds_since(t0), total = seconds_since(t_all);
  const auto& J = result.findings;
  std::printf("maglead bench analyze: %zu samples (%.0f s at 1 kHz)\n", rec.rows(),
              static_cast<double>(rec.rows()) / 1000.0);
  std::printf(
      "  read recording   %7.2f s\n  analysis         %7.2f s\n  report + plots   %7.2f s\n",
      read.wall_s, t_an, t_out);
  std::printf("  total            %7.2f s   (target <= 5 s for one hour)\n", total);
  std::printf("  peak memory      %7.0f MB (max resident set size)\n", peak_rss_mb());
  std::printf("  found:");
  for (const auto& e : J.effects) std::printf(" %s", e.id.c_str());
  std::printf("%s\n  held-out RMS %.4f N -> %.4f N; report in %s\n",
              J.effects.empty() ? " nothing" : "", J.validation.front().heldout_rms_n,
              J.validation.back().heldout_rms_n, out.c_str());
  std::fflush(stdout);
  const auto whole = time_analyze_process(path, out + "_process", o.config);
  if (whole)
    std::printf(
        "\n  maglead analyze, the whole process: %.2f s wall, peak memory %.0f MB "
        "(target <= %.0f MB: %s)\n",
        whole->wall_s, whole->peak_mb, kPeakMemoryAimMb,
        verdict(whole->peak_mb <= kPeakMemoryAimMb, rec.rows()).c_str());
  else
    std::printf("\n  maglead analyze as a process: did not run to the end (run it by hand)\n");
  compare_with_pandas(path, read, whole);
}

void add_bench_analyze(CLI::App& app) {
  auto* cmd = bench_command(app)->add_subcommand(
      "analyze",
      "Time maglead analyze on a one-hour 1 kHz recording (aim: at most 5 s), with "
      "peak memory, and the CSV read beside pandas' read_csv of the same file");
  auto o = std::make_shared<BenchAnalyzeOptions>();
  cmd->add_option("--recording", o->recording,
                  "Recording to analyse (default: generate position-moves with a spring, a "
                  "position ripple and an offset concealed)");
  cmd->add_flag("--quick", o->quick, "Two simulated minutes instead of an hour (CI)");
  cmd->add_option("-o,--out", o->out, "Output directory (default: a temporary one)");
  add_config_option(cmd, o->config);
  cmd->callback([o] {
    maglead::cli::advise_large_blocks_to_huge_pages();  // reads whole recordings
    run_bench_analyze(*o);
  });
}

MAGLEAD_COMMAND(95, add_bench_analyze);

}  // namespace
}  // namespace maglead::cli
