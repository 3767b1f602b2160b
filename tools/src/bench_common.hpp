#pragma once
// The `bench` parent subcommand, shared by every `maglead bench NAME`: whichever registers first
// creates it, the others find it.
#include <CLI/CLI.hpp>

namespace maglead::cli {

inline CLI::App* bench_command(CLI::App& app) {
  for (auto* sub : app.get_subcommands([](CLI::App*) { return true; }))
    if (sub->get_name() == "bench") return sub;
  auto* bench = app.add_subcommand("bench", "Benchmarks (printed side by side with a reference)");
  bench->require_subcommand(1);
  return bench;
}

}  // namespace maglead::cli
