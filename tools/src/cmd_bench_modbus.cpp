// maglead bench modbus: Modbus TCP throughput and latency of `maglead serve`'s server while the
// 1 kHz loop runs, beside a plain libmodbus server serving the same mapping with no loop,
// measured in the same run; and the loop's period jitter meanwhile.
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
#include <memory>
#include <thread>
#include <vector>

#include "bench_common.hpp"
#include "cli_common.hpp"
#include "maglead/controller/controller.hpp"
#include "maglead/controller/loop_runner.hpp"
#include "maglead/controller/modbus_core.hpp"
#include "maglead/controller/modbus_tcp.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/registers/registers.hpp"

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
    if (listen_fd_ < 0) throw std::runtime_error(std::string("reference server: ") + modbus_strerror(errno));
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
    case Work::read_holding: return "FC3 read 16";
    case Work::read_input: return "FC4 read 16";
    case Work::write_multiple: return "FC16 write 16";
  }
  return "?";
}

struct Result {
  double rps = 0, p50_us = 0, p99_us = 0, max_us = 0;
  std::size_t errors = 0;
};

double percentile(std::vector<double>& v, double q) {
  if (v.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(std::clamp(q * static_cast<double>(v.size() - 1), 0.0,
                                                     static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

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

Result measure(int port, Work work, int clients, double seconds) {
  std::vector<std::vector<double>> lat(static_cast<std::size_t>(clients));
  std::vector<std::size_t> errors(static_cast<std::size_t>(clients), 0);
  std::atomic<int> ready{0};
  std::atomic<bool> go{false};
  const auto words_a = setpoint_words(1.0), words_b = setpoint_words(2.0);
  std::vector<std::thread> threads;
  for (int i = 0; i < clients; ++i) {
    threads.emplace_back([&, i] {
      auto& l = lat[static_cast<std::size_t>(i)];
      l.reserve(200000);
      modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
      modbus_set_slave(ctx, 1);
      modbus_set_response_timeout(ctx, 1, 0);
      const bool ok = modbus_connect(ctx) == 0;
      ready++;
      while (!go.load()) std::this_thread::yield();
      std::uint16_t regs[16];
      const auto end = Clock::now() + std::chrono::duration<double>(seconds);
      std::size_t k = 0;
      while (ok && Clock::now() < end) {
        const auto t0 = Clock::now();
        int rc = -1;
        switch (work) {
          case Work::read_holding: rc = modbus_read_registers(ctx, 10, 16, regs); break;
          case Work::read_input: rc = modbus_read_input_registers(ctx, 10, 16, regs); break;
          case Work::write_multiple:
            rc = modbus_write_registers(ctx, 1004, 16, (k++ & 1 ? words_a : words_b).data());
            break;
        }
        const auto t1 = Clock::now();
        if (rc < 0) {
          errors[static_cast<std::size_t>(i)]++;
          if (errors[static_cast<std::size_t>(i)] > 100) break;
        } else {
          l.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
        }
      }
      if (!ok) errors[static_cast<std::size_t>(i)]++;
      modbus_close(ctx);
      modbus_free(ctx);
    });
  }
  while (ready.load() < clients) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const auto t0 = Clock::now();
  go = true;
  for (auto& t : threads) t.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
  std::vector<double> all;
  Result r;
  for (std::size_t i = 0; i < lat.size(); ++i) {
    all.insert(all.end(), lat[i].begin(), lat[i].end());
    r.errors += errors[i];
  }
  r.rps = static_cast<double>(all.size()) / elapsed;
  r.max_us = all.empty() ? 0.0 : *std::max_element(all.begin(), all.end());
  r.p50_us = percentile(all, 0.50);
  r.p99_us = percentile(all, 0.99);
  return r;
}

struct Jitter {
  double p50_us = 0, p99_us = 0, max_us = 0;
  std::size_t cycles = 0;
};
Jitter jitter_of(std::vector<double> periods, double nominal_s) {
  Jitter j;
  j.cycles = periods.size();
  for (double& p : periods) p = std::abs(p - nominal_s) * 1e6;
  if (periods.empty()) return j;
  j.max_us = *std::max_element(periods.begin(), periods.end());
  j.p50_us = percentile(periods, 0.50);
  j.p99_us = percentile(periods, 0.99);
  return j;
}

void add_bench_modbus(CLI::App& app) {
  auto* cmd = bench_command(app)->add_subcommand(
      "modbus", "Modbus TCP requests/s and latency of the controller's server, with the 1 kHz loop "
                "running, beside a plain libmodbus server; and loop jitter meanwhile");
  struct Opts {
    bool quick = false;
    double seconds = 2.0;
    std::string config = default_config_dir();
  };
  auto o = std::make_shared<Opts>();
  cmd->add_flag("--quick", o->quick, "Short run (0.4 s per case) for a smoke test");
  cmd->add_option("--seconds", o->seconds, "Seconds per case")->check(CLI::Range(0.1, 600.0))->capture_default_str();
  cmd->add_option("--config", o->config, "Configuration directory")->capture_default_str();
  cmd->callback([o] {
    const double seconds = o->quick ? 0.4 : o->seconds;
    controller::ControllerConfig cfg;
    cfg.actuator = load_actuator_or_default(o->config);
    cfg.calibration = load_calibration(config_file(o->config, "calibration.toml"));
    PlantParams plant = paper_like_plant();
    plant.actuator = cfg.actuator;
    SimulatedActuator actuator(plant, 1, 0.02);
    controller::Controller ctl(cfg, actuator);
    controller::ModbusCore core(ctl, {});
    controller::TcpOptions tcp_opts;
    tcp_opts.port = 0;
    tcp_opts.max_connections = 64;
    controller::TcpServer server(core, tcp_opts);
    server.start();
    ReferenceServer reference;
    const double nominal = 1.0 / cfg.actuator.sample_rate_hz;

    std::printf("maglead bench modbus: %.1f s per case, %u CPUs, loop %.0f Hz on the simulated actuator\n",
                seconds, std::thread::hardware_concurrency(), cfg.actuator.sample_rate_hz);
    // Loop jitter with no network load, as a baseline.
    Jitter idle;
    {
      controller::LoopRunner loop(ctl);
      loop.set_realtime(controller::RealtimePolicy::attempt);
      loop.start();
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      loop.begin_period_log();
      std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
      idle = jitter_of(loop.end_period_log(), nominal);
      std::printf("loop: %s; idle jitter |period - %.0f us| p50 %.1f  p99 %.1f  max %.1f us (%zu cycles)\n\n",
                  loop.realtime() ? "SCHED_FIFO" : "normal scheduling (no real-time priority granted)",
                  nominal * 1e6, idle.p50_us, idle.p99_us, idle.max_us, idle.cycles);
      loop.stop();
    }
    std::printf("%-14s %7s  %-9s %9s %8s %8s %9s %6s  %s\n", "case", "clients", "server", "req/s", "p50 us",
                "p99 us", "max us", "ratio", "loop jitter p50/p99/max us");
    bool throughput_ok = true, latency_ok = true, jitter_ok = true;
    std::size_t total_errors = 0;
    for (Work work : {Work::read_holding, Work::read_input, Work::write_multiple}) {
      for (int clients : {1, 16}) {
        const Result ref = measure(reference.port(), work, clients, seconds);  // no loop running
        controller::LoopRunner loop(ctl);
        loop.set_realtime(controller::RealtimePolicy::attempt);
        loop.start();
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        loop.begin_period_log();
        const Result ours = measure(server.port(), work, clients, seconds);
        const Jitter j = jitter_of(loop.end_period_log(), nominal);
        loop.stop();
        const double ratio = ref.rps > 0 ? ours.rps / ref.rps : 0.0;
        std::printf("%-14s %7d  %-9s %9.0f %8.1f %8.1f %9.1f %5.0f%%  %.1f / %.1f / %.1f\n", work_name(work),
                    clients, "maglead", ours.rps, ours.p50_us, ours.p99_us, ours.max_us, 100.0 * ratio, j.p50_us,
                    j.p99_us, j.max_us);
        std::printf("%-14s %7s  %-9s %9.0f %8.1f %8.1f %9.1f %6s  %s\n", "", "", "reference", ref.rps, ref.p50_us,
                    ref.p99_us, ref.max_us, "", "(no loop)");
        total_errors += ours.errors + ref.errors;
        throughput_ok = throughput_ok && ratio >= 0.8;
        if (clients == 16) {
          latency_ok = latency_ok && ours.p99_us < 1000.0;
          jitter_ok = jitter_ok && j.p99_us < 200.0;
        }
      }
    }
    server.stop();
    std::printf("\ntargets: throughput >= 80%% of reference: %s; p99 < 1 ms with 16 clients: %s; "
                "loop jitter p99 < 200 us with 16 clients: %s; request errors: %zu\n",
                throughput_ok ? "met" : "NOT met", latency_ok ? "met" : "NOT met", jitter_ok ? "met" : "NOT met",
                total_errors);
  });
}

MAGLEAD_COMMAND(90, add_bench_modbus);

}  // namespace
}  // namespace maglead::cli
