// maglead record: poll a controller at a fixed rate and write an mls-recording/1 that
// `analyze`, `estimate` and `report` read. Time is the controller's own (cycle counter / loop
// rate), so the network's jitter does not enter the time axis.
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <optional>
#include <thread>

#include "maglead/recording/recording.hpp"
#include "operator_cli.hpp"

namespace maglead::cli {
namespace {

namespace reg = maglead::registers;
using op::ClientError;
using Clock = std::chrono::steady_clock;

volatile std::sig_atomic_t g_interrupted = 0;
void on_interrupt(int signal_number) { g_interrupted = signal_number; }

struct RecordOptions {
  std::string duration, out, load_cell = "auto";
  double rate_hz = 100.0;
};

std::vector<std::string> column_names(bool load_cell) {
  std::vector<std::string> names = {"t_s",         "screw_angle_rad", "nut_pos_m",
                                    "nut_vel_m_s", "phase_rad",       "out_force_est_n",
                                    "force_set_n", "pos_set_m",       "profile_pos_m"};
  if (load_cell) names.emplace_back("load_force_n");
  for (const char* n :
       {"twin_pred_nut_pos_m", "twin_pred_out_force_n", "twin_residual_pos_m",
        "twin_residual_force_n", "twin_dynamic_out_force_est_n", "status_word", "alarm_code",
        "drive_state", "active_mode", "step_out_count", "loop_cycle_count"})
    names.emplace_back(n);
  return names;
}

std::vector<std::pair<std::string, std::string>> header(const RecordOptions& o,
                                                        const op::Client& client, double loop_hz,
                                                        bool load_cell) {
  char rate_text[32], loop_text[32];
  std::snprintf(rate_text, sizeof rate_text, "%g", o.rate_hz);
  std::snprintf(loop_text, sizeof loop_text, "%g", loop_hz);
  std::vector<std::pair<std::string, std::string>> h = {
      {"sample_rate_hz", rate_text},
      {"source", "maglead record from " + client.endpoint().describe()},
      {"system", "magnetic lead-screw actuator"},
      {"controller_loop_rate_hz", loop_text},
      {"time_base", "controller cycle counter / loop rate (t_s of the sampled cycle)"}};
  if (load_cell)  // said of the column only where there is one
    h.emplace_back("load_force_sign",
                   "force on the nut from the load (= -output force of the register)");
  h.emplace_back("twin_columns", "empty while the controller runs no twin (all twin registers 0)");
  return h;
}

/// One polled cycle in the columns of column_names(), each value at its register's resolution
/// (0.026, never 0.026000000000000002).
void fill_row(const op::Values& v, double t_s, bool load_cell, std::vector<double>& row) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double mode = v.at("active_mode");
  const auto si = [&](const char* name) { return op::si_rounded(*reg::find(name), v.at(name)); };
  const bool twin = v.at("twin_pred_nut_pos_um") != 0.0 || v.at("twin_pred_force_mn") != 0.0 ||
                    v.at("twin_residual_pos_um") != 0.0 || v.at("twin_residual_force_mn") != 0.0 ||
                    v.at("twin_dynamic_force_mn") != 0.0;
  std::size_t c = 0;
  row[c++] = t_s;
  row[c++] = si("screw_angle_urad");
  row[c++] = si("nut_pos_um");
  row[c++] = si("nut_vel_um_s");
  row[c++] = si("phase_urad");
  row[c++] = si("force_est_mn");
  row[c++] = mode == static_cast<double>(reg::Mode::force) ? si("active_force_setpoint_mn") : nan;
  row[c++] = mode == static_cast<double>(reg::Mode::position) ? si("active_target_pos_um") : nan;
  row[c++] = si("profile_pos_um");
  if (load_cell) row[c++] = -si("load_cell_force_mn");  // register: output force; column: load
  for (const char* n : {"twin_pred_nut_pos_um", "twin_pred_force_mn", "twin_residual_pos_um",
                        "twin_residual_force_mn", "twin_dynamic_force_mn"})
    row[c++] = twin ? si(n) : nan;
  for (const char* n : {"status_word", "alarm_code", "drive_state", "active_mode", "step_out_count",
                        "loop_cycle_count"})  // the counter ties a row to its cycle
    row[c++] = v.at(n);
}

/// What a recording run did, for the summary.
struct Tally {
  std::size_t rows = 0, timeouts = 0, late = 0, repeated = 0, consecutive_failures = 0;
  std::size_t gap_rows = 0, gaps = 0;  // what readers fill (rows_missing_between)
  std::uint64_t attempts = 0, cycles = 0;
  std::string lost;  // why the controller was given up, if it was
};

/// Counts controller cycles between polls; a poll of the cycle already seen is not a new row.
struct CycleCounter {
  bool have_first = false;
  std::uint32_t last = 0;
  double loop_hz = 1.0, period_s = 1.0;  // the controller's loop; the rows' period
  bool advance(std::uint32_t cycle, Tally& t) {
    if (have_first && cycle == last) {
      ++t.repeated;  // polled faster than the loop publishes: same cycle again
      return false;
    }
    if (have_first) {
      const std::uint32_t steps = cycle - last;  // wraps as the counter does
      t.cycles += steps;
      const long missing = rows_missing_between(steps / loop_hz, period_s);
      t.gap_rows += static_cast<std::size_t>(missing);
      t.gaps += missing > 0 ? 1u : 0u;
    }
    have_first = true;
    last = cycle;
    return true;
  }
};

/// One poll; nullopt when it failed and the run goes on (t.lost set when it must stop).
std::optional<op::Values> poll_once(op::Client& client, std::uint16_t start, std::uint16_t count,
                                    double period_s, Tally& t) {
  try {
    auto v = client.read_range(reg::Table::input_register, start, count);
    t.consecutive_failures = 0;
    return v;
  } catch (const ClientError& e) {
    if (e.kind() == ClientError::Kind::connection) {
      t.lost = e.what();
      return std::nullopt;
    }
    ++t.timeouts;
    client.flush();
    // Over 2 s without a reply (and more than 3 polls) means the controller is gone.
    if (static_cast<double>(++t.consecutive_failures) * period_s > 2.0 &&
        t.consecutive_failures > 3)
      t.lost = e.what();
    return std::nullopt;
  }
}

/// Polls at the requested rate until the duration is up, an interrupt or the controller is lost.
Tally record_rows(const RecordOptions& o, op::Client& client, double loop_hz, bool load_cell,
                  RecordingWriter& out, std::size_t columns) {
  // One request covers status through the cycle counter: every row is one control cycle.
  const auto start = reg::find("status_word")->address;
  const auto count = static_cast<std::uint16_t>(reg::find("loop_cycle_count")->address + 2 - start);
  const double duration_s = parse_duration_s(o.duration, "--duration"), period_s = 1.0 / o.rate_hz;
  Tally t;
  CycleCounter counter{.loop_hz = loop_hz, .period_s = period_s};
  std::vector<double> row(columns);
  Progress bar("record " + o.out);
  const auto t0 = Clock::now();
  std::uint64_t& k = t.attempts;
  while (!g_interrupted && t.lost.empty()) {
    if (static_cast<double>(k) * period_s >= duration_s) break;
    const auto deadline =
        t0 + std::chrono::duration_cast<Clock::duration>(
                 std::chrono::duration<double>(static_cast<double>(k) * period_s));
    std::this_thread::sleep_until(deadline);
    // Behind by whole periods (a slow reply): those polls are missed, not made up later.
    const double behind_s = std::chrono::duration<double>(Clock::now() - deadline).count();
    if (behind_s >= period_s) {
      const auto skip = static_cast<std::uint64_t>(behind_s / period_s);
      t.late += skip;
      k += skip;
      continue;
    }
    ++k;
    const auto v = poll_once(client, start, count, period_s, t);
    if (!v || !counter.advance(static_cast<std::uint32_t>(v->at("loop_cycle_count")), t)) continue;
    fill_row(*v, static_cast<double>(t.cycles) / loop_hz, load_cell, row);
    out.write_row(row.data(), row.size());
    ++t.rows;
    bar(std::min(1.0, static_cast<double>(k) * period_s / duration_s));
  }
  bar.done();
  return t;
}

void print_summary(const RecordOptions& o, const op::Client& client, double loop_hz, const Tally& t,
                   const std::string& replacing) {
  const double span_s = static_cast<double>(t.cycles) / loop_hz;
  char b[512];
  std::snprintf(b, sizeof b,
                "recorded %zu samples over %.2f s of controller time from %s at %g Hz requested "
                "(%.1f Hz achieved)%s",
                t.rows, span_s, client.endpoint().describe().c_str(), o.rate_hz,
                span_s > 0 && t.rows > 1 ? static_cast<double>(t.rows - 1) / span_s : 0.0,
                g_interrupted ? ", interrupted" : "");
  print_line(b);
  std::snprintf(b, sizeof b,
                "dropped polls: %zu of %zu (%zu without reply, %zu missed while behind); repeated "
                "cycles skipped: %zu",
                t.timeouts + t.late, static_cast<std::size_t>(t.attempts), t.timeouts, t.late,
                t.repeated);
  print_line(b);
  if (t.gaps > 0) {  // late replies: the rows' cycles lie further apart than a period
    std::snprintf(b, sizeof b,
                  "gaps: %zu rows missing in %zu places (readers fill short gaps by interpolation "
                  "and say so)",
                  t.gap_rows, t.gaps);
    print_line(b);
  }
  print_line("wrote " + o.out + replacing);
}

/// Gaps too many or too long make the readers refuse the file: said now, by the reader's own
/// rule, not when the analysis is run on it.
void warn_if_readers_refuse(const RecordOptions& o, const Tally& t) {
  if (t.gaps == 0 || t.rows == 0) return;
  try {
    (void)read_recording(o.out);
  } catch (const RecordingError& e) {
    std::fflush(stdout);  // after the summary, as it was printed
    std::fprintf(stderr, "%s\n",
                 error_text("warning: the readers (analyze, inspect, …) refuse this recording as "
                            "it is: " +
                            std::string(e.what()) +
                            "; record again at a lower --rate (the polls fell behind)")
                     .c_str());
  }
}

void run_record(const RecordOptions& o, const ConnectionOptions& conn) {
  // A bad duration is refused before anything is opened.
  parse_duration_s(o.duration, "--duration");
  op::Client client(endpoint_of(conn));
  client.check_identity();
  const double loop_hz = client.read_range(reg::Table::input_register, 3, 1).at("loop_rate_hz");
  if (!(loop_hz > 0))
    throw ClientError(ClientError::Kind::protocol, "controller reports a loop rate of 0 Hz");
  // The float32 copy says whether there is one (the integer register reads 0 without one, as it
  // may with one at no load).
  const bool present = op::has_load_cell(client.read_range(
      reg::Table::input_register, reg::find("load_cell_force_n_f32")->address, 2));
  const bool load_cell = o.load_cell == "yes" || (o.load_cell == "auto" && present);
  if (o.load_cell == "yes" && !present)
    throw ClientError(ClientError::Kind::refused_locally,
                      "--load-cell yes: the controller has no load cell (load_cell_force_n_f32 "
                      "reads NaN, e.g. the CiA 402 backend); record without it: --load-cell no");
  const auto names = column_names(load_cell);
  const std::string replacing = replacing_note(o.out);
  RecordingWriter out(o.out, header(o, client, loop_hz, load_cell), names);
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
  const Tally t = record_rows(o, client, loop_hz, load_cell, out, names.size());
  out.close();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  // The progress bar's own newline has left the "^C" behind already when it was drawn.
  if (g_interrupted && !show_progress()) fresh_line_after_interrupt(g_interrupted);
  print_summary(o, client, loop_hz, t, replacing);
  warn_if_readers_refuse(o, t);
  // Stopped before its duration: the file is whole and readable, but shorter than asked.
  if (g_interrupted && t.lost.empty())
    throw ClientError(ClientError::Kind::interrupted,
                      "interrupted before --duration " + o.duration +
                          " was up: " + std::to_string(t.rows) + " samples kept in " + o.out +
                          " (whole and readable)");
  if (!t.lost.empty())
    throw ClientError(
        ClientError::Kind::connection,
        "stopped after " + std::to_string(t.rows) + " samples (kept in " + o.out + "): " + t.lost);
}

void add_record(CLI::App& app) {
  auto* cmd = app.add_subcommand("record",
                                 "Poll a controller at a fixed rate and write an mls-recording/1 "
                                 "(angles, position, force estimate, setpoints, load cell, twin)");
  auto conn = add_connection_options(cmd);
  auto o = std::make_shared<RecordOptions>();
  cmd->add_option("--duration", o->duration, "How long to record (e.g. 60s, 2min)")->required();
  cmd->add_option("-o,--out", o->out,
                  "Recording to write (CSV). Each row is written to the file whole as soon as it "
                  "is polled (so flushed well within 100 ms) and the file is synced to disk at "
                  "least every second: a crash or SIGKILL loses no row already polled, a power "
                  "cut at most the last second, and neither tears an earlier row (readers drop a "
                  "torn last line with a warning)")
      ->required();
  cmd->add_option("--rate", o->rate_hz, "Polls per second [Hz], 1 .. 1000")
      ->check(number_in({1.0, 1000.0, "Hz", "the loop runs at 1 kHz", "--rate 100"}))
      ->capture_default_str();
  cmd->add_option("--load-cell", o->load_cell,
                  "Log load_force_n: auto (if the controller has a load cell: the simulated "
                  "actuator has one, the CiA 402 backend none), yes, no")
      ->check(CLI::IsMember({"auto", "yes", "no"}))
      ->capture_default_str();
  cmd->callback([o, conn] { run_operator("record", [&] { run_record(*o, *conn); }); });
}

MAGLEAD_COMMAND(86, add_record);

}  // namespace
}  // namespace maglead::cli
