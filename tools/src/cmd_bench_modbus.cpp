// maglead bench modbus: Modbus TCP throughput and latency of `maglead serve`'s composition (the
// 1 kHz loop with the digital twin on its thread, by default), beside a plain libmodbus server
// serving the same mapping, measured in the same run; and the loop's overruns and lateness
// during each case.
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.hpp"
#include "cli_common.hpp"
#include "maglead/recording/error_stats.hpp"
#include "maglead/registers/registers.hpp"
#include "maglead/runtime/service.hpp"

namespace maglead::cli {
namespace {

using Clock = std::chrono::steady_clock;

/// The reference: libmodbus's own server loop (select over all sockets, modbus_receive,
/// modbus_reply) on a mapping that covers the same addresses.
class ReferenceServer {
 public:
  ReferenceServer() {
    ctx_ = modbus_new_tcp("127.0.0.1", 0);
    mapping_ = modbus_mapping_new_start_address(0, 8, 0, 16, 0, 1100, 0, 128);
    if (!ctx_ || !mapping_) throw std::runtime_error("reference server: out of memory");
    listen_fd_ = modbus_tcp_listen(ctx_, 64);
    if (listen_fd_ < 0)
      throw std::runtime_error(std::string("reference server: ") + modbus_strerror(errno));
    sockaddr_in sa{};
    socklen_t sl = sizeof sa;
    getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&sa), &sl);
    port_ = ntohs(sa.sin_port);
    // Same values a client would see from maglead where it matters for decoding.
    mapping_->tab_input_registers[0] = registers::kDeviceType;
    for (int i = 1000; i < 1100; ++i) mapping_->tab_registers[i] = 0;
    thread_ = std::thread([this] { run(); });
  }
  ~ReferenceServer() {
    stop_ = true;
    thread_.join();
    close(listen_fd_);
    modbus_mapping_free(mapping_);
    modbus_free(ctx_);
  }
  int port() const { return port_; }

 private:
  void run() {
    fd_set all;
    FD_ZERO(&all);
    FD_SET(listen_fd_, &all);
    int maxfd = listen_fd_;
    std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    while (!stop_) {
      fd_set rd = all;
      timeval tv{0, 50'000};
      if (select(maxfd + 1, &rd, nullptr, nullptr, &tv) <= 0) continue;
      for (int fd = 0; fd <= maxfd; ++fd) {
        if (!FD_ISSET(fd, &rd)) continue;
        if (fd == listen_fd_) {
          const int c = accept(listen_fd_, nullptr, nullptr);
          if (c >= 0 && c < FD_SETSIZE) {
            FD_SET(c, &all);
            maxfd = std::max(maxfd, c);
          } else if (c >= 0) {
            close(c);
          }
          continue;
        }
        modbus_set_socket(ctx_, fd);
        const int rc = modbus_receive(ctx_, query);
        if (rc > 0) {
          modbus_reply(ctx_, query, rc, mapping_);
        } else if (rc == -1) {
          close(fd);
          FD_CLR(fd, &all);
        }
      }
    }
    for (int fd = 0; fd <= maxfd; ++fd)
      if (fd != listen_fd_ && FD_ISSET(fd, &all)) close(fd);
  }
  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  int listen_fd_ = -1, port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

enum class Work { read_holding, read_input, write_multiple };
const char* work_name(Work w) {
  switch (w) {
    case Work::read_holding:
      return "FC3 read 16";
    case Work::read_input:
      return "FC4 read 16";
    case Work::write_multiple:
      return "FC16 write 16";
  }
  return "?";
}

struct Result {
  double rps = 0, p50_us = 0, p99_us = 0, max_us = 0;
  std::size_t errors = 0;    // a wrong answer, an exception other than 06, a broken connection
  std::size_t busy = 0;      // exception 06: the loop's command queue was full, nothing applied
  std::size_t timeouts = 0;  // no answer within the client's 1 s: a latency, not a wrong answer
  std::map<int, std::size_t> errors_by_errno;
};

/// Exception 06 is a defined answer to more writes than the loop takes per cycle, not a fault.
bool is_busy_reply(int err) { return err == EMBXSBUSY; }

/// The 16 setpoint registers 1004..1019 (i32 then f32 forms), all valid, force alternating.
std::vector<std::uint16_t> setpoint_words(double force_n) {
  std::vector<std::uint16_t> w;
  const auto put = [&](const char* name, double v) {
    const auto* r = registers::find(name);
    std::uint16_t words[2];
    registers::encode(*r, v, words);
    w.push_back(words[0]);
    w.push_back(words[1]);
  };
  put("force_setpoint_mn", force_n);
  put("position_setpoint_um", 0.02);
  put("velocity_limit_um_s", 0.01);
  put("accel_limit_um_s2", 0.1);
  put("force_setpoint_n_f32", force_n);
  put("position_setpoint_m_f32", 0.02);
  put("velocity_limit_m_s_f32", 0.01);
  put("accel_limit_m_s2_f32", 0.1);
  return w;
}

/// One client's share of a case: its latencies and its failures by errno.
struct ClientTally {
  std::vector<double> latency_us;
  std::map<int, std::size_t> errors_by_errno;
};

/// libmodbus leaves a late answer in the socket, so every later answer would be the one before
/// (a client desynchronised for good): after a timeout or a broken connection, a client
/// reconnects, as a PLC does.
bool reconnect(modbus_t* ctx) {
  modbus_close(ctx);
  return modbus_connect(ctx) == 0;
}

int one_request(modbus_t* ctx, Work work, std::size_t k, const std::vector<std::uint16_t>& a,
                const std::vector<std::uint16_t>& b) {
  std::uint16_t regs[16];
  switch (work) {
    case Work::read_holding:
      return modbus_read_registers(ctx, 10, 16, regs);
    case Work::read_input:
      return modbus_read_input_registers(ctx, 10, 16, regs);
    case Work::write_multiple:
      return modbus_write_registers(ctx, 1004, 16, (k & 1 ? a : b).data());
  }
  return -1;
}

void run_client(int port, Work work, double seconds, std::atomic<int>& ready,
                const std::atomic<bool>& go, ClientTally& tally) {
  const auto words_a = setpoint_words(1.0), words_b = setpoint_words(2.0);
  tally.latency_us.reserve(200000);
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
  modbus_set_slave(ctx, 1);
  modbus_set_response_timeout(ctx, 1, 0);
  bool ok = modbus_connect(ctx) == 0;
  if (!ok) tally.errors_by_errno[errno]++;
  ready++;
  while (!go.load()) std::this_thread::yield();
  const auto end = Clock::now() + std::chrono::duration<double>(seconds);
  std::size_t failures = 0;
  for (std::size_t k = 0; ok && Clock::now() < end; ++k) {
    const auto t0 = Clock::now();
    const int rc = one_request(ctx, work, k, words_a, words_b);
    const auto t1 = Clock::now();
    if (rc >= 0) {
      tally.latency_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      continue;
    }
    const int err = errno;
    tally.errors_by_errno[err]++;
    if (is_busy_reply(err)) continue;
    // A server that keeps failing is not measured further: 100 failures are enough to say so.
    constexpr std::size_t kMaxFailures = 100;
    ok = ++failures <= kMaxFailures && reconnect(ctx);
  }
  modbus_close(ctx);
  modbus_free(ctx);
}

Result measure(int port, Work work, int clients, double seconds) {
  std::vector<ClientTally> tallies(static_cast<std::size_t>(clients));
  std::atomic<int> ready{0};
  std::atomic<bool> go{false};
  std::vector<std::thread> threads;
  threads.reserve(static_cast<std::size_t>(clients));
  for (auto& tally : tallies)
    threads.emplace_back([&] { run_client(port, work, seconds, ready, go, tally); });
  while (ready.load() < clients) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const auto t0 = Clock::now();
  go = true;
  for (auto& t : threads) t.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
  std::vector<double> all;
  Result r;
  for (const auto& tally : tallies) {
    all.insert(all.end(), tally.latency_us.begin(), tally.latency_us.end());
    for (const auto& [err, n] : tally.errors_by_errno) {
      r.errors_by_errno[err] += n;
      (is_busy_reply(err) ? r.busy : err == ETIMEDOUT ? r.timeouts : r.errors) += n;
    }
  }
  r.rps = static_cast<double>(all.size()) / elapsed;
  r.max_us = all.empty() ? 0.0 : *std::max_element(all.begin(), all.end());
  r.p50_us = percentile(all, 0.50);
  r.p99_us = percentile(all, 0.99);
  return r;
}

/// What the loop did during one case: overruns (controller's count, register 50) and its
/// lateness distribution (start after deadline, from the runner's cycle log).
struct LoopDuring {
  std::uint64_t overruns = 0, twin_lagging = 0;
  double late_p99_us = 0, late_max_us = 0;
};

class LoopWatch {
 public:
  explicit LoopWatch(runtime::Service& service) : service_(service) {
    overruns0_ = service_.controller().snapshot().overrun_count;
    lagging0_ = twin_lagging();
    service_.loop().begin_period_log();
  }
  LoopDuring end() {
    auto log = service_.loop().end_cycle_log();
    LoopDuring d;
    d.overruns = service_.controller().snapshot().overrun_count - overruns0_;
    d.twin_lagging = twin_lagging() - lagging0_;
    for (double& l : log.late_s) l *= 1e6;
    if (!log.late_s.empty())
      d.late_max_us = *std::max_element(log.late_s.begin(), log.late_s.end());
    d.late_p99_us = percentile(log.late_s, 0.99);
    return d;
  }

 private:
  std::uint64_t twin_lagging() const {
    return service_.twin() ? service_.twin()->stats().lagging_cycles : 0;
  }
  runtime::Service& service_;
  std::uint64_t overruns0_ = 0, lagging0_ = 0;
};

runtime::ServiceConfig bench_service(const std::string& config_dir, bool twin) {
  runtime::ServiceConfig sc;
  sc.controller.actuator = load_actuator_or_default(config_dir);
  sc.controller.calibration = load_calibration(config_file(config_dir, "calibration.toml"));
  sc.backend.simulated.spring_n_per_m = 0.0;  // a free nut, at rest: the network is the load here
  sc.twin = twin;
  if (twin) sc.twin_config = twin::load_monitor_config(config_dir);
  sc.network.tcp.port = 0;
  sc.network.tcp.max_connections = 64;
  sc.network.realtime = controller::RealtimePolicy::attempt;
  return sc;
}

void print_row(const char* work, const char* clients, const char* server, const Result& r,
               const char* ratio, const LoopDuring& d) {
  std::printf("%-14s %7s  %-9s %9.0f %8.1f %8.1f %9.1f %6s  %8llu %8.1f %8.1f %6llu\n", work,
              clients, server, r.rps, r.p50_us, r.p99_us, r.max_us, ratio,
              static_cast<unsigned long long>(d.overruns), d.late_p99_us, d.late_max_us,
              static_cast<unsigned long long>(d.twin_lagging));
}

struct Targets {
  bool throughput_ok = true, latency_ok = true, loop_ok = true;
  std::size_t errors = 0, busy = 0, timeouts = 0;
  std::vector<std::string> error_lines;  // which case, which server, how many of which error
};

void note_errors(Targets& t, const std::string& where, const Result& r) {
  t.errors += r.errors;
  t.busy += r.busy;
  t.timeouts += r.timeouts;
  for (const auto& [err, n] : r.errors_by_errno)
    t.error_lines.push_back(where + ": " + std::to_string(n) + " x " + modbus_strerror(err));
}

/// Every case against both servers, one row each; whether the 16-client targets were met.
Targets run_cases(runtime::Service& service, ReferenceServer& reference, double seconds) {
  const int port = service.tcp_port();
  std::printf("%-14s %7s  %-9s %9s %8s %8s %9s %6s  %8s %8s %8s %6s\n", "case", "clients", "server",
              "req/s", "p50 us", "p99 us", "max us", "ratio", "overruns", "late p99", "late max",
              "twin lag");
  Targets t;
  for (Work work : {Work::read_holding, Work::read_input, Work::write_multiple}) {
    for (int clients : {1, 16}) {
      // The loop and the twin run during both, so both servers share the machine with them.
      LoopWatch ref_watch(service);
      const Result ref = measure(reference.port(), work, clients, seconds);
      const LoopDuring ref_loop = ref_watch.end();
      LoopWatch watch(service);
      const Result ours = measure(port, work, clients, seconds);
      const LoopDuring d = watch.end();
      const double ratio = ref.rps > 0 ? ours.rps / ref.rps : 0.0;
      char ratio_text[16];
      std::snprintf(ratio_text, sizeof ratio_text, "%.0f%%", 100.0 * ratio);
      const std::string n = std::to_string(clients);
      print_row(work_name(work), n.c_str(), "maglead", ours, ratio_text, d);
      print_row("", "", "reference", ref, "", ref_loop);
      const std::string where =
          std::string(work_name(work)) + ", " + n + (clients == 1 ? " client, " : " clients, ");
      note_errors(t, where + "maglead", ours);
      note_errors(t, where + "reference", ref);
      if (clients == 16) {
        t.throughput_ok = t.throughput_ok && ratio >= 1.0;
        t.latency_ok = t.latency_ok && ours.p99_us < 1000.0;
        t.loop_ok = t.loop_ok && d.overruns == 0 && d.late_p99_us < 200.0;
      }
    }
  }
  return t;
}

void add_bench_modbus(CLI::App& app) {
  auto* cmd = bench_command(app)->add_subcommand(
      "modbus",
      "Modbus TCP requests/s and latency of the controller's server, with the 1 kHz loop and the "
      "digital twin running, beside a plain libmodbus server; the loop's overruns and lateness "
      "during each case");
  struct Opts {
    bool quick = false, no_twin = false;
    int twin_priority = runtime::ServiceConfig{}.twin_fifo_priority;
    double seconds = 2.0;
    std::string config = default_config_dir();
  };
  auto o = std::make_shared<Opts>();
  cmd->add_flag("--quick", o->quick, "Short run (0.4 s per case) for a smoke test");
  cmd->add_option("--seconds", o->seconds, "Seconds per case")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
  add_config_option(cmd, o->config);
  cmd->add_flag("--no-twin", o->no_twin, "Run the loop without the digital twin");
  cmd->add_option("--twin-priority", o->twin_priority,
                  "The twin thread's SCHED_FIFO priority (0: SCHED_OTHER)")
      ->check(CLI::Range(0, 49))
      ->capture_default_str();
  cmd->callback([o] {
    const double seconds = o->quick ? 0.4 : o->seconds;
    runtime::ServiceConfig sc = bench_service(o->config, !o->no_twin);
    sc.twin_fifo_priority = o->twin_priority;
    runtime::Service service(sc);
    service.start();
    ReferenceServer reference;

    std::printf(
        "maglead bench modbus: %.1f s per case, %u CPUs, loop %.0f Hz on the simulated actuator, "
        "%s\n",
        seconds, std::thread::hardware_concurrency(),
        service.controller().config().actuator.sample_rate_hz,
        service.twin() ? "digital twin on its own thread" : "no twin");
    const auto& grant = service.loop().realtime_grant();
    std::printf(
        "loop: %s, %s%s\n",
        grant.fifo ? "SCHED_FIFO" : "normal scheduling (no real-time priority granted)",
        grant.pinned ? ("pinned to CPU " + std::to_string(grant.cpu)).c_str() : "not pinned",
        service.refused().empty() ? "" : ("; not granted: " + service.refused()).c_str());
    {
      LoopWatch watch(service);
      std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
      const LoopDuring idle = watch.end();
      std::printf("no network load: %llu overruns, lateness p99 %.1f µs, max %.1f µs\n\n",
                  static_cast<unsigned long long>(idle.overruns), idle.late_p99_us,
                  idle.late_max_us);
    }
    const Targets t = run_cases(service, reference, seconds);
    service.stop();
    std::printf(
        "\ncolumns overruns/late/twin lag: the loop during that case (cycles started > 1 period "
        "late; "
        "start after deadline [us]; cycles with twin_lagging)\n");
    std::printf(
        "targets: with 16 clients, throughput >= reference: %s; p99 < 1 ms: %s; "
        "loop 0 overruns and lateness p99 < 200 µs: %s; request errors: %zu\n",
        t.throughput_ok ? "met" : "NOT met", t.latency_ok ? "met" : "NOT met",
        t.loop_ok ? "met" : "NOT met", t.errors);
    if (t.busy > 0)
      std::printf(
          "busy replies (exception 06: writes came faster than the loop takes %d a cycle; "
          "nothing applied, a client retries): %zu\n",
          controller::Controller::kCommandsPerCycle, t.busy);
    if (t.timeouts > 0)
      std::printf(
          "answers later than the clients' 1 s timeout (a latency; the client reconnects): "
          "%zu\n",
          t.timeouts);
    for (const auto& line : t.error_lines) std::printf("  %s\n", line.c_str());
  });
}

MAGLEAD_COMMAND(90, add_bench_modbus);

}  // namespace
}  // namespace maglead::cli
