#include "maglead/report/plot.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string_view>
#include <utility>
#include <vector>

#include "image_encode.hpp"
#include "maglead/fileio/atomic_file.hpp"

namespace maglead::plot {
namespace {

const cv::Scalar kPalette[] = {{180, 119, 31}, {14, 127, 255},  {44, 160, 44},
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
  cv::putText(img, ascii_label(s), at, kFont, scale, kInk, thick, cv::LINE_AA);
}

int text_width_px(const std::string& s, double scale) {
  int base = 0;
  return cv::getTextSize(ascii_label(s), kFont, scale, 1, &base).width;
}

/// The legend's column: as wide as the panel's longest label (up to a third of the width).
int legend_width_px(const Panel& p, int width_px) {
  int widest = 0;
  for (const auto& s : p.series) widest = std::max(widest, text_width_px(s.label, 0.4));
  return std::clamp(widest + 50, 60, width_px / 3);
}

/// What stacked panels share so their axes line up: the legend column, and the x range when
/// they plot the same x (NaN: each panel its own).
struct PanelFrame {
  int right_px = 60;
  double x0 = std::numeric_limits<double>::quiet_NaN(), x1 = x0;
};

void draw_panel(cv::Mat& img, const Panel& p, cv::Rect area, const PanelFrame& frame) {
  // The title and the y label each have a line of their own above the plot.
  const int left = 80, right = frame.right_px, top = 48, bottom = 45;
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
  if (std::isfinite(frame.x0) && std::isfinite(frame.x1)) x0 = frame.x0, x1 = frame.x1;
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
    text(img, fmt(std::abs(x) < 1e-9 * xs ? 0.0 : x), {X - 12, plot.y + plot.height + 18}, 0.4);
  }
  for (double y = std::ceil(y0 / ys) * ys; y <= y1; y += ys) {
    const int Y = static_cast<int>(py(y));
    cv::line(img, {plot.x, Y}, {plot.x + plot.width, Y}, kGrid);
    text(img, fmt(std::abs(y) < 1e-9 * ys ? 0.0 : y), {area.x + 10, Y + 4}, 0.4);
  }
  if (y0 < 0 && y1 > 0) {
    const int Y = static_cast<int>(py(0));
    cv::line(img, {plot.x, Y}, {plot.x + plot.width, Y}, {160, 160, 160});
  }
  cv::rectangle(img, plot, kInk);
  text(img, p.title, {plot.x, area.y + 20}, 0.55, 1);
  text(img, p.x_label, {plot.x + plot.width / 2 - 30, plot.y + plot.height + 38}, 0.45);
  text(img, p.y_label, {area.x + 4, plot.y - 8}, 0.4);

  std::size_t ci = 0;
  for (const auto& s : p.series) {
    const cv::Scalar col = kPalette[ci % std::size(kPalette)];
    // Decimate to about two points per pixel column: plots of hours of 1 kHz data stay fast.
    const std::size_t n = std::min(s.x.size(), s.y.size());
    const std::size_t stride =
        std::max<std::size_t>(1, n / (2 * static_cast<std::size_t>(plot.width)));
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
  static const double stops[][3] = {
      {68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  f = std::clamp(f, 0.0, 1.0) * 4.0;
  const int i = std::min(3, static_cast<int>(f));
  const double u = f - i;
  cv::Vec3b c;
  for (int k = 0; k < 3; ++k)
    c[2 - k] = static_cast<uchar>(stops[i][k] + u * (stops[i + 1][k] - stops[i][k]));
  return c;
}

cv::Scalar diverging(double f) {  // blue → light grey → red (coolwarm): the sign stays readable
  static const double stops[][3] = {{59, 76, 192}, {221, 221, 221}, {180, 4, 38}};
  f = std::clamp(f, 0.0, 1.0) * 2.0;
  const int i = std::min(1, static_cast<int>(f));
  const double u = f - i;
  return cv::Scalar(stops[i][2] + u * (stops[i + 1][2] - stops[i][2]),
                    stops[i][1] + u * (stops[i + 1][1] - stops[i][1]),
                    stops[i][0] + u * (stops[i + 1][0] - stops[i][0]));
}

// Values of both signs get a diverging scale symmetric about zero; one-signed values the ramp.
struct ColourScale {
  double lo = 0, hi = 1;
  bool diverging = false;
  cv::Scalar colour(double v) const {
    const double f = (v - lo) / (hi - lo);
    return diverging ? ::maglead::plot::diverging(f) : cv::Scalar(colormap(f));
  }
};

ColourScale colour_scale(const std::vector<double>& values) {
  ColourScale s{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                false};
  for (double v : values)
    if (std::isfinite(v)) s.lo = std::min(s.lo, v), s.hi = std::max(s.hi, v);
  if (!std::isfinite(s.lo)) return {0.0, 1.0, false};
  if (s.lo < 0 && s.hi > 0) {
    const double m = std::max(-s.lo, s.hi);
    return {-m, m, true};
  }
  if (s.hi <= s.lo) s.hi = s.lo + 1;
  return s;
}

// A JPEG's quality: OpenCV's default, where a figure's lines and text show no artefacts.
constexpr int kJpegQuality = 95;

void write_png(const std::string& path, const cv::Mat& img) {
  // Encoded in memory, then written atomically: a report never holds half a figure.
  const std::string ext = image_extension(path);
  const BgrImage pixels{img.ptr<unsigned char>(0), img.cols, img.rows, img.step[0]};
  std::string bytes;
  try {
    bytes = ext == ".png" ? encode_png(pixels) : encode_jpeg(pixels, kJpegQuality);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(path + ": cannot write the image: " + e.what());
  }
  write_file_atomically(path, bytes);
}

}  // namespace

std::string ascii_label(const std::string& s) {
  // Longer spellings first where one starts another ("⁻¹" before "⁻").
  static constexpr std::pair<std::string_view, std::string_view> kSpelling[] = {
      {"·", "*"},      {"⋅", "*"},      {"×", "x"},      {"²", "^2"},  {"³", "^3"},
      {"⁻¹", "^-1"},   {"⁻", "^-"},     {"¹", "^1"},     {"µ", "u"},   {"μ", "u"},
      {"−", "-"},      {"–", "-"},      {"—", "-"},      {"±", "+/-"}, {"°", "deg"},
      {"θ", "theta"},  {"ω", "omega"},  {"τ", "tau"},    {"π", "pi"},  {"Δ", "d"},
      {"α", "alpha"},  {"σ", "sigma"},  {"φ", "phi"},    {"ε", "eps"}, {"Ω", "Ohm"},
      {"≈", "~"},      {"≤", "<="},     {"≥", ">="},     {"→", "->"},  {"…", "..."},
      {"\u00a0", " "}, {"\u2009", " "}, {"\u202f", " "}, {"’", "'"},   {"‘", "'"}};
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    if (static_cast<unsigned char>(s[i]) < 0x80) {
      out += s[i++];
      continue;
    }
    const std::string_view rest = std::string_view(s).substr(i);
    const auto* known = std::find_if(std::begin(kSpelling), std::end(kSpelling),
                                     [&](const auto& k) { return rest.starts_with(k.first); });
    if (known != std::end(kSpelling)) {
      out += known->second;
      i += known->first.size();
      continue;
    }
    out += '_';  // a character without a spelling here: its lead and continuation bytes
    ++i;
    while (i < s.size() && (static_cast<unsigned char>(s[i]) & 0xC0) == 0x80) ++i;
  }
  return out;
}

/// The image format the file's name asks for; the bytes always match the name.
std::string image_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") return ext;
  throw std::runtime_error(path + ": cannot write an image named '" + ext +
                           "': give the file a .png (or .jpg) name");
}

namespace {
cv::Mat panels_image(const std::vector<Panel>& panels, int width_px, int panel_height_px) {
  const int n = static_cast<int>(std::max<std::size_t>(1, panels.size()));
  cv::Mat img(n * panel_height_px, width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  // Stacked panels line up: one legend column, and one x range where they share the x axis.
  PanelFrame frame;
  bool same_x = true;
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0;
  for (const auto& p : panels) {
    frame.right_px = std::max(frame.right_px, legend_width_px(p, width_px));
    same_x = same_x && p.x_label == panels.front().x_label;
    for (const auto& s : p.series)
      for (double x : s.x)
        if (std::isfinite(x)) x0 = std::min(x0, x), x1 = std::max(x1, x);
  }
  if (same_x && x1 > x0) frame.x0 = x0, frame.x1 = x1;
  for (int i = 0; i < static_cast<int>(panels.size()); ++i)
    draw_panel(img, panels[static_cast<std::size_t>(i)],
               {0, i * panel_height_px, width_px, panel_height_px}, frame);
  return img;
}

cv::Mat heatmap_image(const HeatMap& m, int width_px, int height_px) {
  cv::Mat img(height_px, width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  // Room above the plot for the title (if any) and, on its own line, the y label: never one
  // over the other. The colour bar's label is right-aligned so it stays inside the image.
  const int top = m.title.empty() ? 34 : 60;
  const cv::Rect plot(80, top, width_px - 200, height_px - top - 56);
  const ColourScale scale = colour_scale(m.values);
  for (int r = 0; r < m.ny; ++r)
    for (int c = 0; c < m.nx; ++c) {
      const double v = m.values[static_cast<std::size_t>(r) * static_cast<std::size_t>(m.nx) +
                                static_cast<std::size_t>(c)];
      const int xa = plot.x + c * plot.width / m.nx, xb = plot.x + (c + 1) * plot.width / m.nx;
      const int ya = plot.y + plot.height - (r + 1) * plot.height / m.ny;
      const int yb = plot.y + plot.height - r * plot.height / m.ny;
      if (std::isfinite(v))
        cv::rectangle(img, cv::Point(xa, ya), cv::Point(xb, yb), scale.colour(v), cv::FILLED);
    }
  cv::rectangle(img, plot, kInk);
  if (!m.title.empty()) text(img, m.title, {plot.x, 24}, 0.55);
  text(img, m.y_label, {8, plot.y - 10}, 0.45);
  text(img, m.x_label, {plot.x + plot.width / 2 - 50, plot.y + plot.height + 44}, 0.45);
  const double sx = tick_step(m.x_max - m.x_min, 6), sy = tick_step(m.y_max - m.y_min, 6);
  for (double x = std::ceil(m.x_min / sx) * sx; x <= m.x_max + 1e-9 * sx; x += sx) {
    const int px = plot.x + static_cast<int>((x - m.x_min) / (m.x_max - m.x_min) * plot.width);
    cv::line(img, {px, plot.y + plot.height}, {px, plot.y + plot.height + 5}, kInk);
    text(img, fmt(std::abs(x) < 1e-9 * sx ? 0.0 : x), {px - 14, plot.y + plot.height + 20}, 0.4);
  }
  for (double y = std::ceil(m.y_min / sy) * sy; y <= m.y_max + 1e-9 * sy; y += sy) {
    const int py =
        plot.y + plot.height - static_cast<int>((y - m.y_min) / (m.y_max - m.y_min) * plot.height);
    cv::line(img, {plot.x - 5, py}, {plot.x, py}, kInk);
    text(img, fmt(std::abs(y) < 1e-9 * sy ? 0.0 : y), {plot.x - 52, py + 4}, 0.4);
  }
  const cv::Rect bar(plot.x + plot.width + 24, plot.y, 18, plot.height);
  for (int y = 0; y < bar.height; ++y)
    cv::line(img, {bar.x, bar.y + y}, {bar.x + bar.width, bar.y + y},
             scale.colour(scale.hi - (scale.hi - scale.lo) * y / bar.height));
  cv::rectangle(img, bar, kInk);
  text(img, fmt(scale.hi), {bar.x + bar.width + 5, bar.y + 10}, 0.4);
  text(img, fmt(scale.lo), {bar.x + bar.width + 5, bar.y + bar.height}, 0.4);
  if (scale.diverging) text(img, "0", {bar.x + bar.width + 5, bar.y + bar.height / 2 + 4}, 0.4);
  const int label_w = text_width_px(m.value_label, 0.45);
  text(img, m.value_label, {std::min(bar.x, width_px - label_w - 6), plot.y - 10}, 0.45);
  return img;
}

std::string png_of(const cv::Mat& img) {
  return encode_png(BgrImage{img.ptr<unsigned char>(0), img.cols, img.rows, img.step[0]});
}
}  // namespace

void save_panels_png(const std::string& path, const std::vector<Panel>& panels, int width_px,
                     int panel_height_px) {
  write_png(path, panels_image(panels, width_px, panel_height_px));
}
std::string panels_png(const std::vector<Panel>& panels, int width_px, int panel_height_px) {
  return png_of(panels_image(panels, width_px, panel_height_px));
}
std::string heatmap_png(const HeatMap& m, int width_px, int height_px) {
  return png_of(heatmap_image(m, width_px, height_px));
}

}  // namespace maglead::plot
