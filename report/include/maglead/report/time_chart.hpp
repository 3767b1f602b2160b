#pragma once
// Interactive time plots for the HTML report, drawn in the browser by dygraphs (inlined): zoom
// by dragging, pan with shift-drag, values on hover, double-click to reset; every chart of a
// page follows the others' time window.
#include <cstddef>
#include <string>
#include <vector>

namespace maglead::report {

struct TimeSeries {
  std::string label;      // with its unit in the chart's y label
  std::vector<double> y;  // one value per sample of the chart's time axis; NaN = gap
};

struct TimeBand {
  double start_s = 0, end_s = 0;  // shaded (drift windows)
};

struct TimeChart {
  std::string id;  // unique on the page: [a-z0-9_]
  std::string title, caption, y_label;
  const std::vector<double>* t_s = nullptr;
  std::size_t first = 0;  // first sample drawn
  std::vector<TimeSeries> series;
  std::vector<TimeBand> bands;
  std::vector<double> markers_s;  // vertical lines (step-outs)
};

/// The page head's part: dygraphs' CSS and JavaScript and the page's chart helper.
std::string time_chart_head();

/// A chart's figure (title, legend box, plot box) and the script that draws it. Long recordings
/// are reduced to at most max_points rows: per bucket of samples its minimum and maximum, in
/// the order they occurred, so a one-sample spike still shows and an hour stays openable.
std::string time_chart_html(const TimeChart& chart, std::size_t max_points = 30000);

/// After the last chart: ties the charts' time axes together.
std::string time_chart_tail();

/// The downsampling itself (sample indices to draw, ascending), for tests and the JSON.
std::vector<std::size_t> envelope_rows(const std::vector<double>& t_s, std::size_t first,
                                       const std::vector<std::vector<double>>& series,
                                       std::size_t max_points);

}  // namespace maglead::report
