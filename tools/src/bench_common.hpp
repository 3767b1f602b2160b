#pragma once
// The `bench` parent subcommand, shared by every `maglead bench NAME`: whichever registers first
// creates it, the others find it. And what every benchmark times with.
#include <time.h>  // NOLINT(modernize-deprecated-headers): POSIX clock_gettime

#include <CLI/CLI.hpp>

namespace maglead::cli {

inline CLI::App* bench_command(CLI::App& app) {
  for (auto* sub : app.get_subcommands([](CLI::App*) { return true; }))
    if (sub->get_name() == "bench") return sub;
  auto* bench = app.add_subcommand("bench", "Benchmarks (printed side by side with a reference)");
  bench->require_subcommand(1);
  return bench;
}

/// CPU time of this thread: on a shared, loaded machine wall time measures the neighbours too.
inline double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace maglead::cli
