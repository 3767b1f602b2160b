// maglead watch: a live full-screen view of a controller (ANSI escape codes, no curses):
// values by name in SI units, status bits and alarm spelled out, a force/position trend.
// q or Ctrl-C quits and the terminal is restored, also when the connection drops.
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <deque>
#include <optional>
#include <string>
#include <thread>

#include "operator_cli.hpp"

namespace maglead::cli {
namespace {

namespace reg = maglead::registers;
using Clock = std::chrono::steady_clock;

volatile std::sig_atomic_t g_quit = 0;
void on_quit(int) { g_quit = 1; }

/// Raw keyboard and the alternate screen while alive; everything restored on destruction.
class Terminal {
 public:
  Terminal() {
    tty_in_ = isatty(STDIN_FILENO) != 0;
    if (tty_in_ && tcgetattr(STDIN_FILENO, &saved_) == 0) {
      termios raw = saved_;
      raw.c_lflag &= static_cast<tcflag_t>(~(ICANON | ECHO));  // keys at once, not echoed; ISIG kept for Ctrl-C
      raw.c_cc[VMIN] = 0;
      raw.c_cc[VTIME] = 0;
      restore_ = tcsetattr(STDIN_FILENO, TCSANOW, &raw) == 0;
    }
    std::fputs("\x1b[?1049h\x1b[?25l", stdout);  // alternate screen, hide cursor
    std::fflush(stdout);
  }
  ~Terminal() {
    std::fputs("\x1b[0m\x1b[?25h\x1b[?1049l", stdout);
    std::fflush(stdout);
    if (restore_) tcsetattr(STDIN_FILENO, TCSANOW, &saved_);
  }
  Terminal(const Terminal&) = delete;
  Terminal& operator=(const Terminal&) = delete;
  /// Waits up to timeout for a key; true when q was pressed.
  bool wait_for_quit(double timeout_s) const {
    pollfd p{STDIN_FILENO, POLLIN, 0};
    const int ms = static_cast<int>(timeout_s * 1e3);
    if (!tty_in_) {
      std::this_thread::sleep_for(std::chrono::milliseconds(ms));
      return false;
    }
    if (poll(&p, 1, ms) > 0 && (p.revents & POLLIN)) {
      char buf[16];
      const auto n = read(STDIN_FILENO, buf, sizeof buf);
      for (ssize_t i = 0; i < n; ++i)
        if (buf[i] == 'q' || buf[i] == 'Q') return true;
    }
    return false;
  }

 private:
  termios saved_{};
  bool tty_in_ = false, restore_ = false;
};

/// One row of block characters scaled to [lo, hi].
std::string sparkline(const std::deque<double>& v, double lo, double hi) {
  static const char* const kBlocks[] = {"▁", "▂", "▃", "▄", "▅", "▆", "▇", "█"};
  std::string s;
  for (double x : v) {
    const double f = hi > lo ? (x - lo) / (hi - lo) : 0.5;
    s += kBlocks[std::clamp(static_cast<int>(std::lround(f * 7.0)), 0, 7)];
  }
  return s;
}

void add_watch(CLI::App& app) {
  auto* cmd = app.add_subcommand("watch", "Live full-screen view of a controller: values, status bits, alarm, "
                                          "force/position trend (q or Ctrl-C quits)");
  auto conn = add_connection_options(cmd);
  struct Opts {
    double rate_hz = 10.0;
    int count = 0;
    int trend = 60;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--rate", o->rate_hz, "Refreshes per second")->check(CLI::Range(0.5, 50.0))->capture_default_str();
  cmd->add_option("--count", o->count, "Quit after this many refreshes (0: until q or Ctrl-C)")->capture_default_str();
  cmd->add_option("--trend", o->trend, "Trend length in samples")->check(CLI::Range(10, 200))->capture_default_str();
  cmd->callback([o, conn] {
    run_operator("watch", [&] {
      op::Client client(endpoint_of(*conn));  // connect before taking the screen: errors stay visible
      client.check_identity();
      std::signal(SIGINT, on_quit);
      std::signal(SIGTERM, on_quit);
      std::deque<double> force_n, pos_mm;
      int frames = 0;
      std::optional<op::ClientError> error;
      {
        Terminal term;
        while (!g_quit) {
          op::Values v;
          try {
            v = client.read_tables({reg::Table::input_register, reg::Table::holding_register});
          } catch (const op::ClientError& e) {
            error = e;
            break;  // the terminal is restored first, then the one-line error
          }
          const double f = v.at("force_est_mn"), p = v.at("nut_pos_um") * 1e3;
          force_n.push_back(f);
          pos_mm.push_back(p);
          while (static_cast<int>(force_n.size()) > o->trend) force_n.pop_front(), pos_mm.pop_front();
          const auto [fmin, fmax] = std::minmax_element(force_n.begin(), force_n.end());
          const auto [pmin, pmax] = std::minmax_element(pos_mm.begin(), pos_mm.end());
          const auto sw = static_cast<std::uint16_t>(v.at("status_word"));
          const double alarm = v.at("alarm_code");
          std::string s = "\x1b[H\x1b[2J";
          char b[256];
          std::snprintf(b, sizeof b, "\x1b[1mmaglead watch\x1b[0m  %s   (q or Ctrl-C quits)\n\n",
                        client.endpoint().describe().c_str());
          s += b;
          std::snprintf(b, sizeof b, "drive  %-9s  mode %-9s  owner %-5.0f  step-outs %.0f  cycles %.0f\n",
                        op::code_name(reg::drive_states(), v.at("drive_state")).c_str(),
                        op::code_name(reg::modes(), v.at("active_mode")).c_str(), v.at("control_owner"),
                        v.at("step_out_count"), v.at("loop_cycle_count"));
          s += b;
          s += "status ";
          int shown_bits = 0;
          for (const auto& r : reg::table()) {
            if (r.table != reg::Table::discrete_input) continue;
            if (shown_bits++ == 7) s += "\n       ";  // two rows fit an 80-column terminal
            const bool on = (sw >> r.address) & 1u;
            const bool bad = r.name == "fault" || r.name == "step_out" || r.name == "drift_warning" ||
                             r.name == "watchdog_expired" || r.name == "step_out_warning" || r.name == "stroke_limit";
            s += on ? (bad ? "\x1b[1;31m" : "\x1b[1;32m") : "\x1b[2m";
            s += (on ? "\u25CF " : "\u25CB ") + std::string(r.name) + "\x1b[0m  ";  // ● set, ○ clear
          }
          s += "\n";
          if (alarm != 0)
            s += "\x1b[1;31malarm  " + op::code_name(reg::alarm_codes(), alarm) + ": " +
                 op::code_meaning(reg::alarm_codes(), alarm) + "\x1b[0m\n";
          else
            s += "alarm  none\n";
          const double rej = v.at("command_reject_reason");
          if (rej != 0)
            s += "last command rejected: " + op::code_name(reg::reject_codes(), rej) + " (" +
                 op::code_meaning(reg::reject_codes(), rej) + ")\n";
          s += "\n";
          const auto line = [&](const char* label, double value, const char* unit) {
            std::snprintf(b, sizeof b, "  %-30s %12.4f %s\n", label, value, unit);
            s += b;
          };
          line("nut position", v.at("nut_pos_um") * 1e3, "mm");
          line("nut velocity", v.at("nut_vel_um_s") * 1e3, "mm/s");
          line("screw angle", v.at("screw_angle_urad"), "rad");
          line("phase", v.at("phase_urad"), "rad");
          line("output force estimate", v.at("force_est_mn"), "N");
          line("load cell (output force)", v.at("load_cell_force_mn"), "N");
          line("force setpoint held", v.at("active_force_setpoint_mn"), "N");
          line("target position", v.at("active_target_pos_um") * 1e3, "mm");
          line("profile position", v.at("profile_pos_um") * 1e3, "mm");
          // The registers read 0 without a twin: say so rather than show zeros as predictions.
          if (v.at("twin_pred_nut_pos_um") == 0 && v.at("twin_pred_force_mn") == 0 &&
              v.at("twin_residual_pos_um") == 0 && v.at("twin_dynamic_force_mn") == 0) {
            s += "  twin                           not running on this controller\n";
          } else {
            line("twin: predicted position", v.at("twin_pred_nut_pos_um") * 1e3, "mm");
            line("twin: position residual", v.at("twin_residual_pos_um") * 1e6, "um");
            line("twin: force residual", v.at("twin_residual_force_mn"), "N");
            line("twin: dynamic force estimate", v.at("twin_dynamic_force_mn"), "N");
          }
          line("watchdog", v.at("watchdog_ms"), "s");
          std::snprintf(b, sizeof b, "\nforce    [%8.2f .. %8.2f N ] %s\n", *fmin, *fmax,
                        sparkline(force_n, *fmin, *fmax).c_str());
          s += b;
          std::snprintf(b, sizeof b, "position [%8.3f .. %8.3f mm] %s\n", *pmin, *pmax,
                        sparkline(pos_mm, *pmin, *pmax).c_str());
          s += b;
          std::fputs(s.c_str(), stdout);
          std::fflush(stdout);
          ++frames;
          if (o->count > 0 && frames >= o->count) break;
          if (term.wait_for_quit(1.0 / o->rate_hz)) break;
        }
      }
      std::signal(SIGINT, SIG_DFL);
      std::signal(SIGTERM, SIG_DFL);
      if (error) throw *error;
      std::printf("maglead watch: %d refreshes from %s\n", frames, client.endpoint().describe().c_str());
    });
  });
}

MAGLEAD_COMMAND(85, add_watch);

}  // namespace
}  // namespace maglead::cli
