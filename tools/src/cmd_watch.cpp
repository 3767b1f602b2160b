// maglead watch: a live view of a controller. On a terminal: a full screen (ANSI escape codes,
// no curses) laid out for the terminal's size (80x24 and down to 60x20): drive state, status bits
// and alarm spelled out, values in SI units, and a force trend (setpoint, estimate and load cell
// against a time axis). When stdout is not a terminal, or with --once: plain lines, no escape
// codes. When the connection drops it shows "reconnecting" and carries on once the controller
// answers again. q or Ctrl-C quits and the terminal is restored.
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdarg>
#include <cstdio>
#include <deque>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "operator_cli.hpp"

namespace maglead::cli {
namespace {

namespace reg = maglead::registers;
using Clock = std::chrono::steady_clock;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

volatile std::sig_atomic_t g_quit = 0;
void on_quit(int) { g_quit = 1; }

/// Raw keyboard and the alternate screen while alive; everything restored on destruction.
class Terminal {
 public:
  Terminal() {
    tty_in_ = isatty(STDIN_FILENO) != 0;
    if (tty_in_ && tcgetattr(STDIN_FILENO, &saved_) == 0) {
      termios raw = saved_;
      raw.c_lflag &= static_cast<tcflag_t>(
          ~(ICANON | ECHO));  // keys at once, not echoed; ISIG kept for Ctrl-C
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

 private:
  termios saved_{};
  bool tty_in_ = false, restore_ = false;
};

/// Waits up to timeout for a key on a terminal stdin; true when q was pressed (or on a signal).
bool wait_for_quit(double timeout_s) {
  const auto until = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (!g_quit) {
    const double left = std::chrono::duration<double>(until - Clock::now()).count();
    if (left <= 0) return false;
    const int ms = std::max(1, static_cast<int>(std::min(left, 0.05) * 1e3));
    if (isatty(STDIN_FILENO)) {
      pollfd p{STDIN_FILENO, POLLIN, 0};
      if (poll(&p, 1, ms) > 0 && (p.revents & POLLIN)) {
        char buf[16];
        const auto n = read(STDIN_FILENO, buf, sizeof buf);
        for (ssize_t i = 0; i < n; ++i)
          if (buf[i] == 'q' || buf[i] == 'Q') return true;
      }
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    }
  }
  return true;
}

/// One trend sample: force setpoint (NaN outside force mode), estimate and load cell [N].
struct Sample {
  double t_s, set_n, est_n, load_n;
};

struct Screen {
  int width = 80, height = 24;
};

Screen screen_size() {
  winsize ws{};
  Screen s;
  if (ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0 && ws.ws_row > 0) {
    s.width = ws.ws_col;
    s.height = ws.ws_row;
  }
  return s;
}

/// The columns `s` takes; UTF-8 (µm): a continuation byte takes none.
int columns_of(const std::string& s) {
  return static_cast<int>(std::count_if(
      s.begin(), s.end(), [](char c) { return (static_cast<unsigned char>(c) & 0xC0U) != 0x80U; }));
}

/// `s` cut to `width` columns, a UTF-8 character never cut in two.
std::string fit(std::string s, int width) {
  if (width <= 0) return {};
  int columns = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if ((static_cast<unsigned char>(s[i]) & 0xC0U) == 0x80U) continue;
    if (columns == width) {
      s.resize(i);
      break;
    }
    ++columns;
  }
  return s;
}

std::string printf_str(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string printf_str(const char* format, ...) {
  char b[512];
  va_list ap;
  va_start(ap, format);
  std::vsnprintf(b, sizeof b, format, ap);
  va_end(ap);
  return b;
}

/// Words of `text` over lines of at most `width` columns: a line breaks between words, never
/// inside one (a word longer than a line, such as an address, gets a line of its own and is cut
/// only if it is wider than the screen).
std::vector<std::string> wrap(const std::string& text, int width, const std::string& indent = "") {
  std::vector<std::string> lines;
  std::string line;
  std::size_t i = 0;
  while (i < text.size()) {
    const std::size_t end = std::min(text.find(' ', i), text.size());
    const std::string word = text.substr(i, end - i);
    i = end + 1;
    if (word.empty()) continue;
    const std::string next = line.empty() ? word : line + " " + word;
    if (static_cast<int>(next.size()) <= width || line.empty() ||
        static_cast<int>(line.size()) <= static_cast<int>(indent.size())) {
      line = next;
    } else {
      lines.push_back(fit(line, width));
      line = indent + word;
    }
  }
  if (!line.empty()) lines.push_back(fit(line, width));
  return lines;
}

/// The names of the status bits that are set, `sep` between them. force_limited carries its
/// reason's code name (force_limited(stroke_end)): the stroke end, the speed limit and the
/// drive's limit are different situations; in position mode the reason is in_position_reason's.
std::string set_bits_text(const op::Values& v, const char* sep) {
  std::string s;
  const bool force_mode = v.at("active_mode") == static_cast<double>(reg::Mode::force);
  const char* reason = force_mode ? "force_reached_reason" : "in_position_reason";
  for (const auto& n : op::status_bits(static_cast<std::uint16_t>(v.at("status_word")))) {
    s += (s.empty() ? "" : sep) + n;
    if (n == "force_limited") s += "(" + op::code_name(reg::codes_of(reason), v.at(reason)) + ")";
  }
  return s;
}

/// What of the controller's targets applies now: a position target only while enabled in position
/// mode (a reference move reads position too), a force setpoint only while enabled in force mode.
/// The controller keeps its last target through a mode change or a disable: shown then, it read
/// as one being held.
struct Applies {
  bool position, force;
};
Applies targets_that_apply(const op::Values& v) {
  const bool enabled = v.at("drive_state") == static_cast<double>(reg::DriveState::enabled);
  const double mode = v.at("active_mode");
  return {enabled && mode == static_cast<double>(reg::Mode::position),
          enabled && mode == static_cast<double>(reg::Mode::force)};
}

/// Everything one refresh shows.
struct View {
  std::string endpoint;
  bool connected = true;
  std::string problem;      // why the connection is down
  double down_since_s = 0;  // when it went down (watch time)
  double now_s = 0;
  std::optional<op::Values> v;  // the latest values read (kept while reconnecting)
};

/// The trend: force against watch time over the last `window_s`, in `rows` x `cols` cells with
/// a y axis (7 columns) and a time axis (2 rows) below.
std::vector<std::string> trend(const std::deque<Sample>& samples, double now_s, double window_s,
                               int rows, int width) {
  const int cols = width - 8;
  std::vector<std::string> out;
  if (cols < 10 || rows < 3) return out;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& s : samples)
    for (double x : {s.set_n, s.est_n, s.load_n})
      if (std::isfinite(x)) lo = std::min(lo, x), hi = std::max(hi, x);
  if (!std::isfinite(lo)) lo = -1, hi = 1;
  if (hi - lo < 1.0) {  // at least 1 N of span, centred
    const double mid = 0.5 * (hi + lo);
    lo = mid - 0.5, hi = mid + 0.5;
  }
  const double pad = 0.05 * (hi - lo);
  lo -= pad, hi += pad;
  std::vector<std::string> grid(static_cast<std::size_t>(rows),
                                std::string(static_cast<std::size_t>(cols), ' '));
  const auto plot = [&](double t, double value, char mark) {
    if (!std::isfinite(value)) return;
    const int c = static_cast<int>(std::floor((t - (now_s - window_s)) / window_s * cols));
    if (c < 0 || c >= cols) return;
    const int r = std::clamp(static_cast<int>(std::lround((hi - value) / (hi - lo) * (rows - 1))),
                             0, rows - 1);
    char& cell = grid[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)];
    // Where two curves share a cell, say so: the estimate on the load cell is the good case.
    cell = cell == ' ' || cell == mark ? mark : '#';
  };
  for (const auto& s : samples) plot(s.t_s, s.set_n, '-');
  for (const auto& s : samples) plot(s.t_s, s.load_n, 'o');
  for (const auto& s : samples) plot(s.t_s, s.est_n, '*');
  for (int r = 0; r < rows; ++r) {
    std::string label(7, ' ');
    if (r == 0 || r == rows - 1 || r == rows / 2) {
      const double y = hi - (hi - lo) * r / (rows - 1);
      label = printf_str("%7.1f", y).substr(0, 7);
    }
    out.push_back(label + "|" + grid[static_cast<std::size_t>(r)]);
  }
  out.push_back("       +" + std::string(static_cast<std::size_t>(cols), '-'));
  // Time labels: the window's start, its middle and now.
  std::string axis(static_cast<std::size_t>(width), ' ');
  const auto put = [&](int at, const std::string& text) {
    at = std::clamp(at, 0, width - static_cast<int>(text.size()));
    axis.replace(static_cast<std::size_t>(at), text.size(), text);
  };
  put(8, printf_str("-%.0fs", window_s));
  put(8 + cols / 2 - 2, printf_str("-%.0fs", window_s / 2));
  put(width - 3, "now");
  out.push_back(axis);
  return out;
}

/// The values in two columns of half the width each; a label is shortened before a value is,
/// and a value too wide for its column gets a line of its own.
void value_rows(const op::Values& v, int w, std::vector<std::string>& L) {
  const auto at = [&](const char* name) { return v.at(name); };
  const int half = w / 2;
  struct Cell {
    std::string label, short_label, value;
    std::string in(int width) const {
      for (const auto* l : {&label, &short_label}) {
        std::string s = printf_str("%-*s %s", l == &label ? 11 : 0, l->c_str(), value.c_str());
        if (columns_of(s) <= width) return s;
      }
      return {};
    }
  };
  const auto cell = [](const char* label, const char* short_label, const std::string& value) {
    return Cell{label, short_label, value};
  };
  const auto pair = [&](const Cell& a, const Cell& b) {
    std::string left = a.in(half - 1);
    const std::string right = b.in(w - half);
    if (left.empty() || right.empty()) {
      L.push_back(fit(a.in(w).empty() ? a.short_label + " " + a.value : a.in(w), w));
      L.push_back(fit(b.in(w).empty() ? b.short_label + " " + b.value : b.in(w), w));
      return;
    }
    left.append(static_cast<std::size_t>(half - columns_of(left)), ' ');
    L.push_back(left + right);
  };
  const bool twin = !(at("twin_pred_nut_pos_um") == 0 && at("twin_pred_force_mn") == 0 &&
                      at("twin_residual_pos_um") == 0 && at("twin_dynamic_force_mn") == 0);
  const Applies applies = targets_that_apply(v);
  pair(cell("position", "pos", printf_str("%.3f mm", at("nut_pos_um") * 1e3)),
       cell("velocity", "vel", printf_str("%.3f mm/s", at("nut_vel_um_s") * 1e3)));
  // The load observer's output force and the interval it is sure of (no load cell needed).
  pair(cell("estimate", "est",
            // The bound rounded outward: the estimate never shows outside its own interval.
            printf_str("%.2f N in [%.1f, %.1f]", at("load_force_est_mn"),
                       std::floor(at("load_force_lo_mn") * 10.0) / 10.0,
                       std::ceil(at("load_force_hi_mn") * 10.0) / 10.0)),
       op::has_load_cell(v)
           ? cell("load cell", "cell", printf_str("%.2f N", at("load_cell_force_mn")))
           : cell("load cell:", "cell:", "none on this backend"));
  pair(
      cell("setpoint", "set",
           applies.force ? printf_str("%.2f N", at("active_force_setpoint_mn")) : std::string("-")),
      cell("target", "tgt",
           applies.position ? printf_str("%.3f mm", at("active_target_pos_um") * 1e3)
                            : std::string("-")));
  pair(cell("phase", "phi", printf_str("%.4f rad", at("phase_urad"))),
       cell("twin", "twin",
            // The residual is measured minus predicted position, in µm as serve says µs.
            twin ? printf_str("%.2f N, residual %.1f µm", at("twin_dynamic_force_mn"),
                              at("twin_residual_pos_um") * 1e6)
                 : std::string("not running")));
}

/// The alarm's name; a drive fault with its cause beside it, as force_limited(stroke_end):
/// "drive_fault(drive_silent)".
std::string alarm_name(const op::Values& v) {
  const double alarm = v.at("alarm_code");
  std::string s = op::code_name(reg::alarm_codes(), alarm);
  if (alarm == static_cast<double>(reg::Alarm::drive_fault) && v.at("drive_fault_cause") != 0)
    s += "(" + op::code_name(reg::codes_of("drive_fault_cause"), v.at("drive_fault_cause")) + ")";
  return s;
}

/// The alarm in full: its meaning, a drive fault's cause (IR 68: a silent drive is not cleared by
/// a reset), and the command that clears it from a terminal (a PLC's wording alone is not the
/// tool's).
std::string alarm_line(const op::Values& v, double alarm) {
  std::string s = "alarm: " + op::code_meaning(reg::alarm_codes(), alarm);
  if (alarm == static_cast<double>(reg::Alarm::drive_fault)) {
    const double why = v.at("drive_fault_cause");
    const auto codes = reg::codes_of("drive_fault_cause");
    s += printf_str("; drive_fault_cause %.0f %s (%s)", why, op::code_name(codes, why).c_str(),
                    op::code_meaning(codes, why).c_str());
  }
  const auto status = static_cast<std::uint16_t>(v.at("status_word"));
  return s + "; from a terminal: " +
         op::reset_step(alarm, v.at("drive_fault_cause"),
                        op::reset_command(alarm, ((status >> reg::kStepOut) & 1u) != 0));
}

/// The full screen for a terminal of `scr` size: each line at most scr.width columns, at most
/// scr.height lines. Styles (bold, reverse) are whole-line prefixes.
std::vector<std::string> render(const View& view, const std::deque<Sample>& samples,
                                double window_s, Screen scr, bool* reverse_title) {
  const int w = scr.width;
  std::vector<std::string> L;
  *reverse_title = !view.connected;
  if (view.connected) {
    L.push_back(fit("maglead watch  " + view.endpoint + "  connected  (q quits)", w));
  } else {  // the whole reason, wrapped: a port number or an errno text is never cut
    const auto lines = wrap(printf_str("RECONNECTING to %s for %.0f s: %s", view.endpoint.c_str(),
                                       view.now_s - view.down_since_s, view.problem.c_str()),
                            w, "  ");
    L.insert(L.end(), lines.begin(),
             lines.begin() + std::min<std::ptrdiff_t>(3, std::ssize(lines)));
  }
  if (!view.v) {
    L.push_back("no values read yet");
    return L;
  }
  const op::Values& v = *view.v;
  const auto at = [&](const char* name) { return v.at(name); };
  const double alarm = at("alarm_code");
  // The drive fault's cause beside the alarm where it fits (the alarm line below has it too).
  const auto state_line = [&](const std::string& alarm_shown) {
    return printf_str("drive %s   mode %s   alarm %s%s",
                      op::code_name(reg::drive_states(), at("drive_state")).c_str(),
                      op::code_name(reg::modes(), at("active_mode")).c_str(), alarm_shown.c_str(),
                      view.connected ? "" : "   (values from before the drop)");
  };
  std::string top = state_line(alarm_name(v));
  if (std::ssize(top) > w) top = state_line(op::code_name(reg::alarm_codes(), alarm));
  L.push_back(fit(top, w));
  // Status bits by name (monochrome terminals too), wrapped; two rows kept so the layout is
  // steady.
  const std::string set_bits = set_bits_text(v, " ");
  auto bits = wrap("status " + (set_bits.empty() ? "(no bits set)" : set_bits), w, "       ");
  bits.resize(std::max<std::size_t>(bits.size(), 2));
  L.insert(L.end(), bits.begin(), bits.end());
  // The alarm in full (what to type is at its end), then the last rejection, wrapped: a fault's
  // way out is never hidden behind the command that ran into it.
  const double rej = at("command_reject_reason");
  auto why = wrap(alarm != 0 ? alarm_line(v, alarm) : std::string(), w, "  ");
  if (rej != 0) {
    const auto rejected = wrap("last command rejected: " + op::code_name(reg::reject_codes(), rej) +
                                   " (" + op::code_meaning(reg::reject_codes(), rej) + ")",
                               w, "  ");
    why.insert(why.end(), rejected.begin(), rejected.end());
  }
  if (why.empty()) L.emplace_back();
  L.insert(L.end(), why.begin(), why.end());
  value_rows(v, w, L);
  // The trend takes what is left: legend, chart rows, two axis rows.
  const int rows = scr.height - static_cast<int>(L.size()) - 3;
  if (rows >= 3) {
    const char* cell = op::has_load_cell(v) ? "o load cell" : "(no load cell)";
    std::string legend =
        printf_str("force [N] over %.0f s: * estimate %s - setpoint # same", window_s, cell);
    if (static_cast<int>(legend.size()) > w)
      legend = printf_str("force [N], %.0f s: * estimate %s - setpoint # same", window_s, cell);
    L.push_back(fit(legend, w));
    for (auto& line : trend(samples, view.now_s, window_s, rows, w)) L.push_back(fit(line, w));
  }
  if (static_cast<int>(L.size()) > scr.height) L.resize(static_cast<std::size_t>(scr.height));
  return L;
}

/// One plain line (no escape codes): watch time, connection, state and the trend's values.
std::string plain_line(const View& view) {
  std::string s = printf_str("t_s=%.2f ", view.now_s);
  if (!view.connected) return s + "reconnecting to " + view.endpoint + ": " + view.problem;
  const op::Values& v = *view.v;
  s += "drive=" + op::code_name(reg::drive_states(), v.at("drive_state")) +
       " mode=" + op::code_name(reg::modes(), v.at("active_mode")) + " alarm=" + alarm_name(v);
  const Applies applies = targets_that_apply(v);
  for (const char* name :
       {"nut_pos_um", "load_force_est_mn", "load_cell_force_mn", "active_force_setpoint_mn"}) {
    const auto* r = reg::find(name);
    const bool none = (name == std::string("load_cell_force_mn") && !op::has_load_cell(v)) ||
                      (name == std::string("active_force_setpoint_mn") && !applies.force);
    s += " " + op::si_name(*r) + "=" + (none ? "none" : op::si_text(*r, v.at(name)));
  }
  const std::string bits = set_bits_text(v, ",");
  return s + " status=" + (bits.empty() ? "none" : bits);
}

struct WatchOptions {
  double rate_hz = 10.0;
  int count = 0;
  std::string window = "30s";
  bool once = false;
};

/// Draws the view at the top left, every row cleared to its end; no newline after the last row:
/// nothing scrolls.
void draw_full_screen(const View& view, const std::deque<Sample>& samples, double window_s) {
  bool reverse = false;
  const auto lines = render(view, samples, window_s, screen_size(), &reverse);
  std::string s = "\x1b[H";
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (i == 0) s += reverse ? "\x1b[7m" : "\x1b[1m";
    s += lines[i];
    if (i == 0) s += "\x1b[0m";
    s += "\x1b[K";
    if (i + 1 < lines.size()) s += "\n";
  }
  s += "\x1b[J";
  std::fputs(s.c_str(), stdout);
  std::fflush(stdout);
}

void print_plain(const std::string& line) {
  std::printf("%s\n", line.c_str());
  std::fflush(stdout);
}

/// One watch session: the connection (made again when the controller comes back), the view and
/// the trend's samples.
class Watcher {
 public:
  Watcher(const WatchOptions& o, const op::Endpoint& ep, std::unique_ptr<op::Client> client,
          bool full_screen)
      : o_(o),
        ep_(ep),
        client_(std::move(client)),
        full_screen_(full_screen),
        window_s_(parse_duration_s(o.window, "--window")) {
    view_.endpoint = ep.describe();
  }

  /// Until q, Ctrl-C, --count or --once; the read error that ends --once, if one did.
  std::optional<op::ClientError> run() {
    std::optional<Terminal> term;
    if (full_screen_) term.emplace();
    while (!g_quit) {
      view_.now_s = now_s();
      if (!client_) reconnect();
      if (client_ && !poll() && o_.once) return error_;
      if (full_screen_)
        draw_full_screen(view_, samples_, window_s_);
      else if (view_.connected)
        print_plain(plain_line(view_));
      ++frames_;
      if (o_.once || (o_.count > 0 && frames_ >= o_.count)) break;
      if (wait_for_quit(view_.connected ? 1.0 / o_.rate_hz : 0.5)) break;
    }
    return std::nullopt;
  }

  int frames() const { return frames_; }
  int reconnects() const { return reconnects_; }
  const View& view() const { return view_; }

 private:
  double now_s() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }

  void reconnect() {
    try {
      client_ = std::make_unique<op::Client>(ep_);
      client_->check_identity();
      view_.connected = true;
      ++reconnects_;
      if (!full_screen_) {
        std::printf("t_s=%.2f reconnected to %s\n", now_s(), view_.endpoint.c_str());
        std::fflush(stdout);
      }
    } catch (const op::ClientError& e) {
      client_.reset();
      view_.problem = e.what();
    }
  }

  /// Reads the tables into the view and the trend; false (error_ set) when the read failed.
  bool poll() {
    try {
      view_.v = client_->read_tables({reg::Table::input_register, reg::Table::holding_register});
      const op::Values& v = *view_.v;
      samples_.push_back(
          {view_.now_s, targets_that_apply(v).force ? v.at("active_force_setpoint_mn") : kNaN,
           v.at("load_force_est_mn"), op::has_load_cell(v) ? v.at("load_cell_force_mn") : kNaN});
      while (!samples_.empty() && samples_.front().t_s < view_.now_s - window_s_)
        samples_.pop_front();
      return true;
    } catch (const op::ClientError& e) {
      error_ = e;
      if (o_.once) return false;
      client_.reset();
      view_.connected = false;
      view_.down_since_s = view_.now_s;
      view_.problem = e.what();
      if (!full_screen_) print_plain(plain_line(view_));
      return false;
    }
  }

  const WatchOptions& o_;
  op::Endpoint ep_;
  std::unique_ptr<op::Client> client_;
  bool full_screen_;
  double window_s_;
  Clock::time_point t0_ = Clock::now();
  std::deque<Sample> samples_;
  View view_;
  int frames_ = 0, reconnects_ = 0;
  std::optional<op::ClientError> error_;
};

void run_watch(const WatchOptions& o, const ConnectionOptions& conn) {
  parse_duration_s(o.window, "--window");  // a bad window is refused before anything is opened
  const op::Endpoint ep = endpoint_of(conn);
  // Connect before taking the screen: a wrong address stays visible as one line, exit 3.
  auto client = std::make_unique<op::Client>(ep);
  client->check_identity();
  const bool full_screen = !o.once && isatty(STDOUT_FILENO) != 0;
  g_quit = 0;
  std::signal(SIGINT, on_quit);
  std::signal(SIGTERM, on_quit);
  Watcher w(o, ep, std::move(client), full_screen);
  const auto error = w.run();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (error) throw *error;
  if (full_screen)
    std::printf("maglead watch: %d refreshes from %s, %d reconnect%s\n", w.frames(),
                w.view().endpoint.c_str(), w.reconnects(), w.reconnects() == 1 ? "" : "s");
}

void add_watch(CLI::App& app) {
  auto* cmd = app.add_subcommand("watch",
                                 "Live view of a controller: state, status bits, values and a "
                                 "force trend (setpoint, estimate, "
                                 "load cell over time); reconnects when the controller restarts; "
                                 "plain lines when stdout is not "
                                 "a terminal (q or Ctrl-C quits)");
  auto conn = add_connection_options(cmd);
  auto o = std::make_shared<WatchOptions>();
  cmd->add_option("--rate", o->rate_hz, "Refreshes per second [Hz], 0.5 .. 50")
      ->check(number_in({0.5, 50.0, "Hz", "refreshes per second", "--rate 10"}))
      ->capture_default_str();
  cmd->add_option("--count", o->count, "Quit after this many refreshes (0: until q or Ctrl-C)")
      ->capture_default_str();
  cmd->add_option("--window", o->window, "Time span of the trend (e.g. 30s, 2min)")
      ->capture_default_str();
  cmd->add_flag("--once", o->once,
                "Print one plain line and exit (exit 3 when the controller cannot be read)");
  cmd->callback([o, conn] { run_operator("watch", [&] { run_watch(*o, *conn); }); });
}

MAGLEAD_COMMAND(85, add_watch);

}  // namespace
}  // namespace maglead::cli
