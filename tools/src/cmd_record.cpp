// maglead record: poll a controller at a fixed rate and write an mls-recording/1 that
// `analyze`, `estimate` and `report` read. Time is the controller's own (cycle counter / loop
// rate), so the network's jitter does not enter the time axis.
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <limits>
#include <thread>

#include "maglead/recording/recording.hpp"
#include "operator_cli.hpp"

namespace maglead::cli {
namespace {

namespace reg = maglead::registers;
using op::ClientError;
using Clock = std::chrono::steady_clock;

volatile std::sig_atomic_t g_interrupted = 0;
void on_interrupt(int) { g_interrupted = 1; }

void add_record(CLI::App& app) {
  auto* cmd = app.add_subcommand("record",
                                 "Poll a controller at a fixed rate and write an mls-recording/1 "
                                 "(angles, position, force estimate, setpoints, load cell, twin)");
  auto conn = add_connection_options(cmd);
  struct Opts {
    std::string duration, out, load_cell = "auto";
    double rate_hz = 100.0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--duration", o->duration, "How long to record (e.g. 60s, 2min)")->required();
  cmd->add_option("--out", o->out,
                  "Recording to write (CSV). Each row is written to the file whole as soon as it "
                  "is polled (so flushed well within 100 ms) and the file is synced to disk at "
                  "least every second: a crash or SIGKILL loses no row already polled, a power "
                  "cut at most the last second, and neither tears an earlier row (readers drop a "
                  "torn last line with a warning)")
      ->required();
  cmd->add_option("--rate", o->rate_hz, "Polls per second")
      ->check(CLI::Range(1.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--load-cell", o->load_cell,
                  "Log load_force_n: auto (if the controller reports a non-zero load cell at "
                  "start), yes, no")
      ->check(CLI::IsMember({"auto", "yes", "no"}))
      ->capture_default_str();
  cmd->callback([o, conn] {
    run_operator("record", [&] {
      const double duration_s = parse_duration_s(o->duration);
      op::Client client(endpoint_of(*conn));
      client.check_identity();
      const double loop_hz = client.read_range(reg::Table::input_register, 3, 1).at("loop_rate_hz");
      if (!(loop_hz > 0))
        throw ClientError(ClientError::Kind::protocol, "controller reports a loop rate of 0 Hz");
      // One request covers status through the cycle counter: every row is one control cycle.
      const auto* first = reg::find("status_word");
      const auto* last = reg::find("loop_cycle_count");
      const auto start = first->address;
      const auto count = static_cast<std::uint16_t>(last->address + 2 - start);
      auto poll = [&] { return client.read_range(reg::Table::input_register, start, count); };

      const auto probe = poll();
      const bool load_cell = o->load_cell == "yes" ||
                             (o->load_cell == "auto" && probe.at("load_cell_force_mn") != 0.0);

      std::vector<std::string> names = {"t_s",         "screw_angle_rad", "nut_pos_m",
                                        "nut_vel_m_s", "phase_rad",       "out_force_est_n",
                                        "force_set_n", "pos_set_m",       "profile_pos_m"};
      if (load_cell) names.push_back("load_force_n");
      for (const char* n :
           {"twin_pred_nut_pos_m", "twin_pred_out_force_n", "twin_residual_pos_m",
            "twin_residual_force_n", "twin_dynamic_out_force_est_n", "status_word", "alarm_code",
            "drive_state", "active_mode", "step_out_count", "loop_cycle_count"})
        names.emplace_back(n);
      char rate_text[32], loop_text[32];
      std::snprintf(rate_text, sizeof rate_text, "%g", o->rate_hz);
      std::snprintf(loop_text, sizeof loop_text, "%g", loop_hz);
      RecordingWriter out(
          o->out,
          {{"sample_rate_hz", rate_text},
           {"source", "maglead record from " + client.endpoint().describe()},
           {"system", "magnetic lead-screw actuator"},
           {"controller_loop_rate_hz", loop_text},
           {"time_base", "controller cycle counter / loop rate (t_s of the sampled cycle)"},
           {"load_force_sign", "force on the nut from the load (= -output force of the register)"},
           {"twin_columns", "empty while the controller runs no twin (all twin registers 0)"}},
          names);

      std::signal(SIGINT, on_interrupt);
      std::signal(SIGTERM, on_interrupt);
      const double nan = std::numeric_limits<double>::quiet_NaN();
      const double period_s = 1.0 / o->rate_hz;
      std::size_t rows = 0, timeouts = 0, late = 0, repeated = 0, consecutive_failures = 0;
      std::uint64_t cycles = 0;
      std::uint32_t last_cycle = 0;
      bool have_first = false;
      std::vector<double> row(names.size());
      Progress bar("record " + o->out);
      const auto t0 = Clock::now();
      std::uint64_t k = 0;
      std::string lost;
      while (!g_interrupted) {
        const auto deadline =
            t0 + std::chrono::duration_cast<Clock::duration>(
                     std::chrono::duration<double>(static_cast<double>(k) * period_s));
        if (static_cast<double>(k) * period_s >= duration_s) break;
        std::this_thread::sleep_until(deadline);
        // Behind by whole periods (a slow reply): those polls are missed, not made up later.
        const double behind_s = std::chrono::duration<double>(Clock::now() - deadline).count();
        if (behind_s >= period_s) {
          const auto skip = static_cast<std::uint64_t>(behind_s / period_s);
          late += skip;
          k += skip;
          continue;
        }
        ++k;
        op::Values v;
        try {
          v = poll();
          consecutive_failures = 0;
        } catch (const ClientError& e) {
          if (e.kind() == ClientError::Kind::connection) {
            lost = e.what();
            break;
          }
          ++timeouts;
          client.flush();
          // Over 2 s without a reply (and more than 3 polls) means the controller is gone.
          if (static_cast<double>(++consecutive_failures) * period_s > 2.0 &&
              consecutive_failures > 3) {
            lost = e.what();
            break;
          }
          continue;
        }
        const auto cycle = static_cast<std::uint32_t>(v.at("loop_cycle_count"));
        if (!have_first) {
          last_cycle = cycle;
          have_first = true;
        } else if (cycle == last_cycle) {
          ++repeated;  // polled faster than the loop publishes: same cycle again
          continue;
        } else {
          cycles += static_cast<std::uint32_t>(cycle - last_cycle);  // wraps like the counter
          last_cycle = cycle;
        }
        const double mode = v.at("active_mode");
        const bool twin =
            v.at("twin_pred_nut_pos_um") != 0.0 || v.at("twin_pred_force_mn") != 0.0 ||
            v.at("twin_residual_pos_um") != 0.0 || v.at("twin_residual_force_mn") != 0.0 ||
            v.at("twin_dynamic_force_mn") != 0.0;
        // Each value at its register's resolution: 0.026, never 0.026000000000000002.
        const auto si = [&](const char* name) {
          return op::si_rounded(*reg::find(name), v.at(name));
        };
        std::size_t c = 0;
        row[c++] = static_cast<double>(cycles) / loop_hz;
        row[c++] = si("screw_angle_urad");
        row[c++] = si("nut_pos_um");
        row[c++] = si("nut_vel_um_s");
        row[c++] = si("phase_urad");
        row[c++] = si("force_est_mn");
        row[c++] =
            mode == static_cast<double>(reg::Mode::force) ? si("active_force_setpoint_mn") : nan;
        row[c++] =
            mode == static_cast<double>(reg::Mode::position) ? si("active_target_pos_um") : nan;
        row[c++] = si("profile_pos_um");
        if (load_cell)
          row[c++] = -si("load_cell_force_mn");  // register: output force; column: load force
        row[c++] = twin ? si("twin_pred_nut_pos_um") : nan;
        row[c++] = twin ? si("twin_pred_force_mn") : nan;
        row[c++] = twin ? si("twin_residual_pos_um") : nan;
        row[c++] = twin ? si("twin_residual_force_mn") : nan;
        row[c++] = twin ? si("twin_dynamic_force_mn") : nan;
        row[c++] = v.at("status_word");
        row[c++] = v.at("alarm_code");
        row[c++] = v.at("drive_state");
        row[c++] = mode;
        row[c++] = v.at("step_out_count");
        row[c++] = v.at("loop_cycle_count");  // the controller's own: ties a row to its cycle
        out.write_row(row.data(), row.size());
        ++rows;
        bar(std::min(1.0, static_cast<double>(k) * period_s / duration_s));
      }
      bar.done();
      out.close();
      std::signal(SIGINT, SIG_DFL);
      std::signal(SIGTERM, SIG_DFL);
      const double span_s = static_cast<double>(cycles) / loop_hz;
      const std::size_t attempts = static_cast<std::size_t>(k);
      std::printf(
          "recorded %zu samples over %.2f s of controller time from %s at %g Hz requested (%.1f Hz "
          "achieved)%s\n",
          rows, span_s, client.endpoint().describe().c_str(), o->rate_hz,
          span_s > 0 && rows > 1 ? static_cast<double>(rows - 1) / span_s : 0.0,
          g_interrupted ? ", interrupted" : "");
      std::printf(
          "dropped polls: %zu of %zu (%zu without reply, %zu missed while behind); repeated cycles "
          "skipped: %zu\n",
          timeouts + late, attempts, timeouts, late, repeated);
      std::printf("wrote %s\n", o->out.c_str());
      if (!lost.empty())
        throw ClientError(
            ClientError::Kind::connection,
            "stopped after " + std::to_string(rows) + " samples (kept in " + o->out + "): " + lost);
    });
  });
}

MAGLEAD_COMMAND(86, add_record);

}  // namespace
}  // namespace maglead::cli
