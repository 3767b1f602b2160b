// maglead bench twin: real-time factor of the twin's CVODE integration on a 1 kHz output grid,
// with SUNDIALS statistics, beside a fixed-step RK4 of the same hybrid model at equal accuracy
// (both measured against a tight-tolerance reference in the same run), and the cost of a whole
// TwinMonitor tick.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "bench_common.hpp"
#include "cli_common.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::cli {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kGrid_s = 1e-3;  // 1 kHz output grid

struct GridRun {
  std::vector<double> pos_m;
  double wall_s = 0, cpu_s = 0;
  twin::TwinStats stats;
  long rhs_evals = 0;
  bool ok = true;
};

template <class Integrator>
GridRun run_grid(Integrator& integ, const twin::InputSource& drive, double duration_s) {
  GridRun r;
  const auto n = static_cast<std::size_t>(std::llround(duration_s / kGrid_s));
  r.pos_m.resize(n);  // allocated before the clock starts
  const auto t0 = Clock::now();
  const double c0 = thread_cpu_s();
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k + 1) * kGrid_s;
    if constexpr (std::is_same_v<Integrator, twin::HybridTwin>) {
      r.ok &= integ.integrate_to(t, drive) == twin::TwinStatus::ok;
    } else {
      integ.integrate_to(t, drive);
    }
    r.pos_m[k] = integ.state().pos_m;
  }
  r.cpu_s = thread_cpu_s() - c0;
  r.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return r;
}

double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

void add_bench_twin(CLI::App& app) {
  auto* cmd = bench_command(app)->add_subcommand(
      "twin", "Digital twin: CVODE real-time factor and statistics beside fixed-step RK4 at equal "
              "accuracy, and the TwinMonitor's cost per control tick");
  struct Opts {
    bool quick = false;
    double duration_s = 120.0;
    std::uint64_t seed = 1;
    std::string config = default_config_dir();
  };
  auto o = std::make_shared<Opts>();
  cmd->add_flag("--quick", o->quick, "Short run for CI (10 s of simulated time)");
  cmd->add_option("--duration", o->duration_s, "Simulated seconds")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of the test drive")->capture_default_str();
  cmd->add_option("--config", o->config, "Configuration directory")->capture_default_str();
  cmd->callback([o] {
    const double T = o->quick ? 10.0 : o->duration_s;
    if (!(T > 0)) throw CLI::ValidationError("--duration", "must be positive");
    const twin::TwinMonitorConfig cfg = twin::load_monitor_config(o->config);
    const twin::NutModel model(cfg.actuator, cfg.calibration.periodic, cfg.model);
    const auto drive = twin::make_demo_drive(o->seed, T, cfg.actuator.lead_m);
    const twin::NutState s0{0.02, 0.0, twin::FrictionMode::stick};
    const double th0 = drive->screw_rad(0.0), f0 = drive->ext_force_n(0.0);

    std::printf("maglead bench twin: %.0f s of simulated time, 1 kHz output grid, single thread\n",
                T);
    std::printf("  drive: screw moves and hand-like pushes with knocks (seed %llu); model %s\n",
                static_cast<unsigned long long>(o->seed), cfg.model.source.c_str());

    // Reference: tight tolerances and a 0.1 ms cap.
    twin::IntegratorOptions ref_opt;
    ref_opt.rel_tol = 1e-11;
    ref_opt.abs_tol_pos_m = 1e-14;
    ref_opt.abs_tol_vel_m_s = 1e-12;
    ref_opt.max_step_s = 1e-4;
    ref_opt.max_internal_steps = 100000000;
    twin::HybridTwin ref(model, ref_opt);
    ref.reset(0.0, s0, th0, f0);
    const GridRun r_ref = run_grid(ref, *drive, T);

    twin::HybridTwin tw(model, cfg.integrator);
    tw.reset(0.0, s0, th0, f0);
    const GridRun r_cv = run_grid(tw, *drive, T);
    const twin::TwinStats st = tw.stats();
    const double err_cv = max_abs_diff(r_cv.pos_m, r_ref.pos_m);
    std::printf("\n  CVODE BDF (rtol %.0e, max step %.3g ms)%s\n", cfg.integrator.rel_tol,
                cfg.integrator.max_step_s * 1e3, r_cv.ok ? "" : "  ** solver reported failures **");
    std::printf("    real-time factor   %10.0f  (simulated s per thread-CPU s; target >= 500)\n",
                T / r_cv.cpu_s);
    std::printf("                       %10.0f  (per wall s, load average of this machine "
                "included)\n",
                T / r_cv.wall_s);
    std::printf("    max |p - p_ref|    %10.3g um\n", err_cv * 1e6);
    std::printf("    steps %ld, RHS evaluations %ld, Jacobian evaluations %ld\n", st.steps,
                st.rhs_evals, st.jac_evals);
    std::printf("    root events %ld (mode switches %ld, stable-branch edge crossings %ld), "
                "re-initialisations %ld\n",
                st.root_events, st.mode_switches, st.step_out_crossings, st.reinits);

    // RK4 at halving steps until it is as accurate as CVODE.
    std::printf("\n  fixed-step RK4 of the same hybrid model (events at step ends)\n");
    std::printf("    %10s %14s %14s %12s\n", "step [ms]", "max err [um]", "RHS evals", "RTF (CPU)");
    double rtf_equal = std::numeric_limits<double>::quiet_NaN(), h_equal = 0;
    for (double h = 1e-3; h >= 0.99e-6; h /= 2) {
      twin::Rk4Twin rk(model, h);
      rk.reset(0.0, s0);
      GridRun r = run_grid(rk, *drive, T);
      const double err = max_abs_diff(r.pos_m, r_ref.pos_m);
      std::printf("    %10.4f %14.3g %14ld %12.0f\n", h * 1e3, err * 1e6, rk.rhs_evals(), T / r.cpu_s);
      if (err <= err_cv) {
        rtf_equal = T / r.cpu_s;
        h_equal = h;
        break;
      }
    }
    if (std::isnan(rtf_equal))
      std::printf("    RK4 did not reach CVODE's accuracy down to 1 us steps\n");
    else
      std::printf("    at equal accuracy (step %.4g ms): RK4 real-time factor %.0f vs CVODE %.0f\n",
                  h_equal * 1e3, rtf_equal, T / r_cv.cpu_s);

    // The whole monitor per tick: quantized positions of the reference run as the measurement.
    twin::TwinMonitor mon(cfg);
    const auto n = r_ref.pos_m.size();
    const double q = cfg.actuator.linear_count_m;
    mon.reset(0.0, th0, std::floor(s0.pos_m / q) * q);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double c0 = thread_cpu_s();
    double sink = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double t = static_cast<double>(k + 1) * kGrid_s;
      sink += mon.step({t, drive->screw_rad(t), std::floor(r_ref.pos_m[k] / q) * q, nan})
                  .dynamic_output_force_est_n;
    }
    const double wall = thread_cpu_s() - c0;
    std::printf("\n  TwinMonitor (observer, twin, %g ms look-ahead every %d ticks, coupling-gain RLS)\n",
                cfg.lookahead_s * 1e3, cfg.lookahead_every_ticks);
    std::printf("    real-time factor   %10.0f  (%.1f us thread CPU per 1 ms tick)%s\n", T / wall,
                wall / static_cast<double>(n) * 1e6, std::isfinite(sink) ? "" : " (non-finite!)");
  });
}

MAGLEAD_COMMAND(96, add_bench_twin);

}  // namespace
}  // namespace maglead::cli
