#include "maglead/report/time_chart.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "dygraphs_assets.hpp"
#include "maglead/report/html.hpp"

namespace maglead::report {
namespace {

// One place draws every chart: the legend goes into its own box above the plot (dygraphs'
// default floats it over the data), titles are HTML above the plot so axis labels never cover
// them, drift windows are shaded and step-outs drawn as red lines under the data.
constexpr const char* kChartScript = R"js(
window.maglead = {graphs: [],
// Tick values are round already: at most six digits, and thousands as k beyond 10 000 so a label
// fits its 56 px (dygraphs' own k/M labels would write 0.5 as "500m").
tick: function (v) {
  return Math.abs(v) >= 1e4 ? +(v / 1e3).toPrecision(4) + 'k' : String(+v.toPrecision(6));
},
chart: function (id, opts, data) {
  var bands = opts.bands || [], markers = opts.markers || [];
  var g = new Dygraph(document.getElementById('plot-' + id), data, {
    labels: opts.labels, xlabel: 'time [s]', ylabel: opts.ylabel,
    labelsDiv: document.getElementById('legend-' + id), legend: 'always',
    labelsSeparateLines: false, connectSeparatedPoints: false, strokeWidth: 1.2,
    axes: {y: {axisLabelWidth: 56, axisLabelFormatter: maglead.tick},
           x: {pixelsPerLabel: 60, axisLabelFormatter: maglead.tick}},
    xLabelHeight: 16, yLabelWidth: 16, rightGap: 12,
    colors: ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd'],
    underlayCallback: function (ctx, area, gr) {
      ctx.save();
      ctx.fillStyle = 'rgba(214, 39, 40, 0.12)';
      bands.forEach(function (b) {
        var x0 = gr.toDomXCoord(b[0]), x1 = gr.toDomXCoord(b[1]);
        ctx.fillRect(x0, area.y, Math.max(1, x1 - x0), area.h);
      });
      ctx.strokeStyle = 'rgba(214, 39, 40, 0.9)';
      markers.forEach(function (t) {
        var x = gr.toDomXCoord(t);
        ctx.beginPath(); ctx.moveTo(x, area.y); ctx.lineTo(x, area.y + area.h); ctx.stroke();
      });
      ctx.restore();
    }
  });
  window.maglead.graphs.push(g);
}};
)js";

void append_number(std::string& out, double v, int significant) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*g", significant, v);
  out += buf;
}

std::string js_string(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '<') {
      out += "\\u003c";  // never "</script>" inside a script
      continue;
    }
    out += c;
  }
  return out + "\"";
}

// Minimum then maximum of one series in [i0, i1), in the order they occurred; the bucket's
// first sample when the series has no finite value there.
std::pair<std::size_t, std::size_t> extremes(const std::vector<double>& y, std::size_t i0,
                                             std::size_t i1) {
  std::size_t lo = i0, hi = i0;
  bool any = false;
  for (std::size_t i = i0; i < i1; ++i) {
    if (!std::isfinite(y[i])) continue;
    if (!any || y[i] < y[lo]) lo = i;
    if (!any || y[i] > y[hi]) hi = i;
    any = true;
  }
  return {std::min(lo, hi), std::max(lo, hi)};
}

}  // namespace

std::vector<std::size_t> envelope_rows(const std::vector<double>& t, std::size_t first,
                                       const std::vector<std::vector<double>>& series,
                                       std::size_t max_points) {
  std::vector<std::size_t> rows;
  const std::size_t n = t.size();
  if (first >= n) return rows;
  if (n - first <= max_points) {
    for (std::size_t i = first; i < n; ++i) rows.push_back(i);
    return rows;
  }
  // Each bucket gives at most two rows per series: its extremes. With several series the rows
  // of one bucket are the union of their extremes.
  const std::size_t buckets =
      std::max<std::size_t>(1, max_points / (2 * std::max<std::size_t>(1, series.size())));
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t i0 = first + (n - first) * b / buckets,
                      i1 = first + (n - first) * (b + 1) / buckets;
    if (i0 >= i1) continue;
    const std::size_t before = rows.size();
    for (const auto& y : series) {
      const auto [a, c] = extremes(y, i0, i1);
      rows.push_back(a);
      rows.push_back(c);
    }
    std::sort(rows.begin() + static_cast<std::ptrdiff_t>(before), rows.end());
    rows.erase(std::unique(rows.begin() + static_cast<std::ptrdiff_t>(before), rows.end()),
               rows.end());
  }
  return rows;
}

std::string time_chart_head() {
  std::string h = "<style>\n";
  h += assets::dygraph_min_css;
  h += "\n</style>\n<script>\n";
  h += assets::dygraph_min_js;
  h += "\n</script>\n<script>\n";
  h += assets::extras_synchronizer_js;
  h += "\n</script>\n<script>";
  h += kChartScript;
  h += "</script>\n";
  return h;
}

std::string time_chart_html(const TimeChart& c, std::size_t max_points) {
  if (!c.t_s) throw std::invalid_argument("time chart " + c.id + " without a time axis");
  std::vector<std::vector<double>> ys;
  for (const auto& s : c.series) {
    if (s.y.size() != c.t_s->size())
      throw std::invalid_argument("time chart " + c.id + ": series length");
    ys.push_back(s.y);
  }
  std::string h = "<figure class=\"chart\" id=\"fig-" + c.id + "\">\n<figcaption><b>" +
                  escape_html(c.title) + ".</b> " + escape_html(c.caption) +
                  "</figcaption>\n<div class=\"legend\" id=\"legend-" + c.id +
                  "\"></div>\n<div class=\"plot\" id=\"plot-" + c.id +
                  "\"></div>\n</figure>\n<script>maglead.chart(\"" + c.id + "\", {labels: [\"t\"";
  for (const auto& s : c.series) h += ", " + js_string(s.label);
  h += "], ylabel: " + js_string(c.y_label) + ", bands: [";
  for (std::size_t k = 0; k < c.bands.size(); ++k) {
    h += k ? ",[" : "[";
    append_number(h, c.bands[k].start_s, 8);
    h += ",";
    append_number(h, c.bands[k].end_s, 8);
    h += "]";
  }
  h += "], markers: [";
  for (std::size_t k = 0; k < c.markers_s.size(); ++k) {
    if (k) h += ",";
    append_number(h, c.markers_s[k], 8);
  }
  h += "]}, [\n";
  const auto rows = envelope_rows(*c.t_s, c.first, ys, max_points);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    h += r ? ",[" : "[";
    append_number(h, (*c.t_s)[rows[r]], 8);
    for (const auto& y : ys) {
      h += ",";
      append_number(h, y[rows[r]], 5);
    }
    h += (r + 1) % 8 ? "]" : "]\n";
  }
  h += "]);</script>\n";
  return h;
}

std::string time_chart_tail() {
  return "<script>if (window.maglead.graphs.length > 1) Dygraph.synchronize(window.maglead.graphs, "
         "{selection: false, zoom: true, range: false});</script>\n";
}

}  // namespace maglead::report
