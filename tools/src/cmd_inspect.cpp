// maglead inspect: read a recording as analyze, report and estimate do and say what it holds, so
// a file left by a crash or copied from a bench can be checked before anything else reads it.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cli_common.hpp"
#include "maglead/analysis/analysis.hpp"

namespace maglead::cli {
namespace {

/// Values a column holds (missing ones left out) and their range.
struct ColumnSummary {
  std::size_t present = 0;
  double lo = INFINITY, hi = -INFINITY;
};

ColumnSummary summarise(const std::vector<double>& v) {
  ColumnSummary s;
  for (const double x : v)
    if (!std::isnan(x)) ++s.present, s.lo = std::min(s.lo, x), s.hi = std::max(s.hi, x);
  return s;
}

void add_inspect(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "inspect",
      "Read a recording (mls-recording/1) as analyze does and print its rows, time span and "
      "columns; an axis's (a '# axis:' line, or an axis's columns) has its kind and columns "
      "checked as analyze checks them. Exit 0 when the readers will take it (a dropped torn "
      "last line is a warning), exit 2 with the reason and what to fix when not (e.g. fewer "
      "than 2 data rows, t_ms for t_s, angle_deg for angle_rad, a rotary file without "
      "'# axis: rotary')");
  struct Opts {
    std::string recording, config = default_config_dir();
  };
  auto o = std::make_shared<Opts>();
  add_recording_option(cmd, o->recording, "mls-recording/1 CSV");
  add_config_option(cmd, o->config, "the actuator's stroke");
  cmd->callback([o] {
    const std::string* path = &o->recording;
    const Recording rec =
        read_actuator_recording(*path, load_actuator_or_default(o->config), o->config);
    analysis::check_axis_columns(rec);  // analyze's own check: the same refusal, the same fix
    std::printf("%s: %zu rows, %zu columns", path->c_str(), rec.rows(), rec.names.size());
    if (rec.has("t_s") && rec.rows() > 0)
      std::printf(", t_s %g .. %g s", rec.column("t_s").front(), rec.column("t_s").back());
    std::printf("%s\n", rec.warnings.empty() ? "" : " (see the warnings)");
    for (std::size_t c = 0; c < rec.names.size(); ++c) {
      const ColumnSummary s = summarise(rec.columns[c]);
      if (s.present == 0)
        std::printf("  %-30s empty\n", rec.names[c].c_str());
      else
        std::printf("  %-30s %g .. %g (%zu values)\n", rec.names[c].c_str(), s.lo, s.hi, s.present);
    }
  });
}

MAGLEAD_COMMAND(50, add_inspect);

}  // namespace
}  // namespace maglead::cli
