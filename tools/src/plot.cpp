#include "maglead/tools/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace maglead::plot {
namespace {

const cv::Scalar kPalette[] = {{180, 119, 31}, {14, 127, 255}, {44, 160, 44},
                               {40, 39, 214},  {189, 103, 148}, {75, 86, 140}};
const cv::Scalar kInk{40, 40, 40}, kGrid{225, 225, 225};
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

/// "Nice" tick spacing: 1, 2 or 5 × 10^k giving about `want` ticks.
double tick_step(double span, int want) {
  const double raw = span / want;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / mag;
  return mag * (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10);
}

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = 0.45, int thick = 1) {
  cv::putText(img, s, at, kFont, scale, kInk, thick, cv::LINE_AA);
}

void draw_panel(cv::Mat& img, const Panel& p, cv::Rect area) {
  const int left = 80, right = 170, top = 30, bottom = 45;
  const cv::Rect plot(area.x + left, area.y + top, area.width - left - right,
                      area.height - top - bottom);
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const auto& s : p.series)
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x0 = std::min(x0, s.x[i]), x1 = std::max(x1, s.x[i]);
      y0 = std::min(y0, s.y[i]), y1 = std::max(y1, s.y[i]);
    }
  if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  if (x1 <= x0) x1 = x0 + 1;
  if (y1 <= y0) y1 = y0 + 1, y0 -= 1;
  const double pad = 0.05 * (y1 - y0);
  y0 -= pad, y1 += pad;
  auto px = [&](double x) { return plot.x + (x - x0) / (x1 - x0) * plot.width; };
  auto py = [&](double y) { return plot.y + plot.height - (y - y0) / (y1 - y0) * plot.height; };

  const double xs = tick_step(x1 - x0, 8), ys = tick_step(y1 - y0, 5);
  for (double x = std::ceil(x0 / xs) * xs; x <= x1; x += xs) {
    const int X = static_cast<int>(px(x));
    cv::line(img, {X, plot.y}, {X, plot.y + plot.height}, kGrid);
    text(img, fmt(x), {X - 12, plot.y + plot.height + 18}, 0.4);
  }
  for (double y = std::ceil(y0 / ys) * ys; y <= y1; y += ys) {
    const int Y = static_cast<int>(py(y));
    cv::line(img, {plot.x, Y}, {plot.x + plot.width, Y}, kGrid);
    text(img, fmt(y), {area.x + 10, Y + 4}, 0.4);
  }
  if (y0 < 0 && y1 > 0) {
    const int Y = static_cast<int>(py(0));
    cv::line(img, {plot.x, Y}, {plot.x + plot.width, Y}, {160, 160, 160});
  }
  cv::rectangle(img, plot, kInk);
  text(img, p.title, {plot.x, area.y + 20}, 0.55, 1);
  text(img, p.x_label, {plot.x + plot.width / 2 - 30, plot.y + plot.height + 38}, 0.45);
  text(img, p.y_label, {area.x + 4, area.y + 20}, 0.4);

  std::size_t ci = 0;
  for (const auto& s : p.series) {
    const cv::Scalar col = kPalette[ci % std::size(kPalette)];
    // Decimate to about two points per pixel column: plots of hours of 1 kHz data stay fast.
    const std::size_t n = std::min(s.x.size(), s.y.size());
    const std::size_t stride = std::max<std::size_t>(1, n / (2 * plot.width));
    std::vector<cv::Point> pts;
    auto flush = [&] {
      if (pts.size() > 1) cv::polylines(img, pts, false, col, 1, cv::LINE_AA);
      pts.clear();
    };
    for (std::size_t i = 0; i < n; i += stride) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) {
        flush();
        continue;
      }
      if (stride > 1) {  // keep the extremes of each bucket so spikes stay visible
        double lo = s.y[i], hi = s.y[i];
        for (std::size_t j = i; j < std::min(n, i + stride); ++j)
          if (std::isfinite(s.y[j])) lo = std::min(lo, s.y[j]), hi = std::max(hi, s.y[j]);
        pts.emplace_back(static_cast<int>(px(s.x[i])), static_cast<int>(py(lo)));
        pts.emplace_back(static_cast<int>(px(s.x[i])), static_cast<int>(py(hi)));
      } else {
        pts.emplace_back(static_cast<int>(px(s.x[i])), static_cast<int>(py(s.y[i])));
      }
    }
    flush();
    const int ly = plot.y + 15 + 20 * static_cast<int>(ci);
    cv::line(img, {plot.x + plot.width + 10, ly - 4}, {plot.x + plot.width + 30, ly - 4}, col, 2);
    text(img, s.label, {plot.x + plot.width + 35, ly}, 0.4);
    ++ci;
  }
}

cv::Vec3b colormap(double f) {  // perceptual-ish blue → yellow ramp (viridis-like)
  static const double stops[][3] = {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98},
                                    {253, 231, 37}};
  f = std::clamp(f, 0.0, 1.0) * 4.0;
  const int i = std::min(3, static_cast<int>(f));
  const double u = f - i;
  cv::Vec3b c;
  for (int k = 0; k < 3; ++k)
    c[2 - k] = static_cast<uchar>(stops[i][k] + u * (stops[i + 1][k] - stops[i][k]));
  return c;
}

void write_png(const std::string& path, const cv::Mat& img) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, img);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(path + ": cannot write PNG: " + e.what());
  }
  if (!ok) throw std::runtime_error(path + ": cannot write PNG");
}

}  // namespace

void save_panels_png(const std::string& path, const std::vector<Panel>& panels, int width_px,
                     int panel_height_px) {
  const int n = static_cast<int>(std::max<std::size_t>(1, panels.size()));
  cv::Mat img(n * panel_height_px, width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  for (int i = 0; i < static_cast<int>(panels.size()); ++i)
    draw_panel(img, panels[static_cast<std::size_t>(i)], {0, i * panel_height_px, width_px, panel_height_px});
  write_png(path, img);
}

void save_heatmap_png(const std::string& path, const HeatMap& m, int width_px, int height_px) {
  cv::Mat img(height_px, width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Rect plot(90, 40, width_px - 220, height_px - 100);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : m.values)
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  if (!std::isfinite(lo)) lo = 0, hi = 1;
  if (hi <= lo) hi = lo + 1;
  for (int r = 0; r < m.ny; ++r)
    for (int c = 0; c < m.nx; ++c) {
      const double v = m.values[static_cast<std::size_t>(r * m.nx + c)];
      const int xa = plot.x + c * plot.width / m.nx, xb = plot.x + (c + 1) * plot.width / m.nx;
      const int ya = plot.y + plot.height - (r + 1) * plot.height / m.ny;
      const int yb = plot.y + plot.height - r * plot.height / m.ny;
      const cv::Scalar col = std::isfinite(v) ? cv::Scalar(colormap((v - lo) / (hi - lo)))
                                              : cv::Scalar(235, 235, 235);
      cv::rectangle(img, cv::Point(xa, ya), cv::Point(xb, yb), col, cv::FILLED);
    }
  cv::rectangle(img, plot, kInk);
  text(img, m.title, {plot.x, 25}, 0.55);
  text(img, m.x_label, {plot.x + plot.width / 2 - 40, plot.y + plot.height + 40}, 0.45);
  text(img, m.y_label, {5, plot.y - 8}, 0.4);
  for (int i = 0; i <= 4; ++i) {
    const double fx = i / 4.0;
    text(img, fmt(m.x_min + fx * (m.x_max - m.x_min)),
         {plot.x + static_cast<int>(fx * plot.width) - 15, plot.y + plot.height + 18}, 0.4);
    text(img, fmt(m.y_min + fx * (m.y_max - m.y_min)),
         {10, plot.y + plot.height - static_cast<int>(fx * plot.height) + 4}, 0.4);
  }
  const cv::Rect bar(plot.x + plot.width + 20, plot.y, 20, plot.height);
  for (int y = 0; y < bar.height; ++y)
    cv::line(img, {bar.x, bar.y + y}, {bar.x + bar.width, bar.y + y},
             cv::Scalar(colormap(1.0 - static_cast<double>(y) / bar.height)));
  cv::rectangle(img, bar, kInk);
  text(img, fmt(hi), {bar.x + bar.width + 5, bar.y + 10}, 0.4);
  text(img, fmt(lo), {bar.x + bar.width + 5, bar.y + bar.height}, 0.4);
  text(img, m.value_label, {bar.x - 10, bar.y - 10}, 0.4);
  write_png(path, img);
}

}  // namespace maglead::plot
