#pragma once
// Line plots and heat maps drawn with OpenCV into PNG files, for people who would rather look
// than read.
#include <string>
#include <vector>

namespace maglead::plot {

/// Figure text as OpenCV's Hershey fonts can draw it (ASCII only; they draw '?' for anything
/// else): "N·m" → "N*m", "kg·m²" → "kg*m^2", "µm" → "um", "−" → "-", "θ" → "theta", "±" → "+/-";
/// a character without a spelling here becomes '_'. Every text of a figure is drawn through it.
std::string ascii_label(const std::string& s);

struct Series {
  std::string label;
  std::vector<double> x, y;
};

struct Panel {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<Series> series;  // drawn in order, colours from a fixed palette
};

/// Panels stacked vertically into one PNG. Throws std::runtime_error if it cannot be written.
/// The image format a file's name asks for (".png", ".jpg", ".jpeg"); throws std::runtime_error
/// saying what to name it otherwise. A tool checks its output name with it before any work.
std::string image_extension(const std::string& path);
void save_panels_png(const std::string& path, const std::vector<Panel>& panels, int width_px = 1200,
                     int panel_height_px = 320);
/// The same figure as PNG bytes, for a page that embeds it (nothing written beside the page).
std::string panels_png(const std::vector<Panel>& panels, int width_px = 1200,
                       int panel_height_px = 320);

struct HeatMap {
  std::string title, x_label, y_label, value_label;
  double x_min = 0, x_max = 1, y_min = 0, y_max = 1;
  int nx = 0, ny = 0;
  std::vector<double> values;  // row-major ny × nx, NaN = no data
};
/// A colour-mapped grid with axes and a colour bar.
std::string heatmap_png(const HeatMap& map, int width_px = 900, int height_px = 600);

}  // namespace maglead::plot
