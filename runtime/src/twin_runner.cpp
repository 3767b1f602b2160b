#include "maglead/runtime/twin_runner.hpp"

#include <pthread.h>
#include <sched.h>
#include <ctime>

#include <cmath>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "maglead/twin/monitor.hpp"

namespace maglead::runtime {
namespace {

using controller::TwinReport;
using controller::TwinSample;

double finite_or_zero(double v) { return std::isfinite(v) ? v : 0.0; }

/// The drift flag's figures (free moves only), 0 where not yet estimated.
void drift_report(const twin::TwinOutputs& o, TwinReport& r) {
  const twin::DriftFigures& f = o.drift_now;
  r.drift_observability = static_cast<std::uint16_t>(o.drift_observability);
  r.drift_zero_load_n = finite_or_zero(f.zero_load_n);
  r.drift_zero_load_se_n = finite_or_zero(f.zero_load_se_n);
  r.drift_separable = f.separable;
  r.drift_rated_n = finite_or_zero(f.separable ? f.rated_n : f.rated_worst_n);
  r.drift_rated_se_n = finite_or_zero(f.separable ? f.rated_se_n : 0.0);
  r.drift_gain_change = finite_or_zero(f.gain_change);
  r.drift_friction_change_n = finite_or_zero(f.friction_change_n);
  r.drift_known_s = o.drift_known_s;
  r.drift_statistic = o.drift_statistic;
}

TwinReport report_of(const twin::TwinOutputs& o, bool reset_ok) {
  TwinReport r;
  r.pred_nut_pos_m = o.predicted_nut_pos_m;
  r.pred_force_n = o.predicted_output_force_n;
  r.residual_pos_m = o.residual_pos_m;
  r.residual_force_n = o.residual_force_n;
  r.dynamic_force_n = o.dynamic_output_force_est_n;
  r.healthy = reset_ok && o.healthy && o.solver_ok;
  r.drift_warning = o.drift_warning;
  r.step_out_warning = o.step_out_warning;
  r.drift_reason = static_cast<std::uint16_t>(o.drift_reason);
  r.health_reason =
      static_cast<std::uint16_t>(reset_ok ? o.health_reason : twin::HealthReason::solver);
  r.step_out_reason = static_cast<std::uint16_t>(o.step_out_reason);
  r.gain = std::isfinite(o.drift_gain_estimate) ? o.drift_gain_estimate : 0.0;
  r.gain_stderr = std::isfinite(o.drift_gain_stderr) ? o.drift_gain_stderr : 0.0;
  r.gain_reference = std::isfinite(o.drift_reference_gain) ? o.drift_reference_gain : 0.0;
  drift_report(o, r);
  return r;
}

void relaxed_max(std::atomic<std::uint64_t>& a, std::uint64_t v) {
  if (v > a.load(std::memory_order_relaxed)) a.store(v, std::memory_order_relaxed);
}
void relaxed_increment(std::atomic<std::uint64_t>& a) {
  a.store(a.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

}  // namespace

TwinRunner::TwinRunner(const twin::TwinMonitorConfig& config, TwinRunnerOptions options)
    : monitor_(std::make_unique<twin::TwinMonitor>(config)), options_(options) {}

TwinRunner::~TwinRunner() { stop(); }

void TwinRunner::start(const TwinPlacement& placement) {
  if (running_.exchange(true)) return;
  placed_.store(false);
  try {
    thread_ = std::thread([this, placement] {
      place(placement);
      placed_.store(true);
      placed_.notify_one();  // a member: it outlives start(), which may return before this call
      run();
    });
  } catch (const std::system_error& e) {
    running_.store(false);
    throw std::runtime_error(std::string("digital twin: cannot start its thread: ") + e.what());
  }
  placed_.wait(false);  // refused_ is written by the thread before this returns
}

void TwinRunner::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

void TwinRunner::place(const TwinPlacement& placement) {
  refused_.clear();
  const auto refuse = [this](const char* what, int err) {
    refused_ += std::string(refused_.empty() ? "" : ", ") + what + " (" + std::strerror(err) + ")";
  };
  cpu_set_t cpus;
  CPU_ZERO(&cpus);
  if (placement.avoid_cpu >= 0 && placement.avoid_cpu < CPU_SETSIZE &&
      pthread_getaffinity_np(pthread_self(), sizeof cpus, &cpus) == 0) {
    CPU_CLR(placement.avoid_cpu, &cpus);
    // With one core only, sharing it is the only choice: not a refusal.
    if (CPU_COUNT(&cpus) > 0) {
      if (const int err = pthread_setaffinity_np(pthread_self(), sizeof cpus, &cpus))
        refuse("twin off the loop's core", err);
    }
  }
  if (placement.fifo_priority > 0) {
    sched_param sp{};
    sp.sched_priority = placement.fifo_priority;
    if (const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp))
      refuse("twin SCHED_FIFO", err);
  }
}

void TwinRunner::run() {
  // Polls instead of being woken: the loop then makes no system call for the twin. Half a
  // cycle keeps results about a cycle behind, well inside the lag bound, and wakes the twin
  // (which preempts the network thread on its core) only twice per cycle.
  const timespec pause{0, 500'000};
  while (running_.load(std::memory_order_relaxed))
    if (drain() == 0) nanosleep(&pause, nullptr);
  drain();
}

void TwinRunner::step(const TwinSample& in, TwinReport& out) noexcept {
  if (has_pending_control_) has_pending_control_ = !queue_.push(pending_control_);
  // Samples after a lost resync would be read against the old state: they wait with it.
  const bool queued = !has_pending_control_ && queue_.push({Kind::sample, in});
  if (!queued) relaxed_increment(dropped_);
  results_.try_load(latest_);
  out = latest_;
  const std::uint64_t lag = in.cycle > out.cycle ? in.cycle - out.cycle : 0;
  relaxed_max(max_lag_, lag);
  out.lagging = !queued || lag > options_.max_lag_cycles;
  if (out.lagging) relaxed_increment(lagging_cycles_);
}

void TwinRunner::resync(double t_s, double screw_angle_rad, double nut_pos_m) noexcept {
  Message m{Kind::resync, {}};
  m.sample.t_s = t_s;
  m.sample.screw_angle_rad = screw_angle_rad;
  m.sample.nut_pos_m = nut_pos_m;
  push_control(m);
}

void TwinRunner::clear_warnings() noexcept { push_control({Kind::clear, {}}); }

void TwinRunner::push_control(const Message& m) noexcept {
  if (has_pending_control_) {
    if (pending_control_.kind == Kind::resync && m.kind == Kind::clear)
      return;  // the resync clears too
    has_pending_control_ = !queue_.push(pending_control_);
  }
  if (has_pending_control_ || !queue_.push(m)) {
    pending_control_ = m;  // keeps the latest; an older pending clear is superseded by a resync
    has_pending_control_ = true;
  }
}

std::size_t TwinRunner::drain() noexcept {
  std::size_t n = 0;
  Message m;
  while (queue_.pop(m)) {
    process(m);
    ++n;
  }
  return n;
}

void TwinRunner::process(const Message& m) noexcept {
  switch (m.kind) {
    case Kind::resync:
      try {
        monitor_->reset(m.sample.t_s, m.sample.screw_angle_rad, m.sample.nut_pos_m);
        reset_ok_ = true;
      } catch (...) {
        reset_ok_ = false;  // reset() should not throw; if it does, say so through healthy
      }
      return;
    case Kind::clear:
      monitor_->clear_drift();
      return;
    case Kind::sample: {
      const TwinSample& s = m.sample;
      // The twin takes the raw measurements: it keeps its own phase and step-out bookkeeping.
      TwinReport r = report_of(monitor_->step({s.t_s, s.screw_angle_rad, s.nut_pos_m,
                                               s.force_setpoint_n, s.load_force_n, s.free_move}),
                               reset_ok_);
      r.cycle = s.cycle;
      results_.store(r);
      return;
    }
  }
}

TwinRunnerStats TwinRunner::stats() const noexcept {
  return {dropped_.load(std::memory_order_relaxed), lagging_cycles_.load(std::memory_order_relaxed),
          max_lag_.load(std::memory_order_relaxed)};
}

}  // namespace maglead::runtime
