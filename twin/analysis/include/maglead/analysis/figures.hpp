#pragma once
// What the analysis has to show, as data: curves over an axis and mean values over a grid.
// Drawing them (PNG, HTML) is the report library's job (report/), not the analysis's.
#include <string>
#include <vector>

namespace maglead::analysis {

struct Curve {
  std::string label;
  std::vector<double> x, y;
};

/// Curves sharing one pair of axes; labels carry their unit in brackets.
struct Chart {
  std::string title, x_label, y_label;
  std::vector<Curve> curves;
};

/// A value averaged over cells of a grid, row-major ny × nx; NaN where no data fell.
struct Grid {
  std::string title, x_label, y_label, value_label;
  double x_min = 0, x_max = 1, y_min = 0, y_max = 1;
  int nx = 0, ny = 0;
  std::vector<double> values;
};

/// One figure of the analysis: stacked charts, or a grid map.
struct Figure {
  std::string caption;
  std::vector<Chart> charts;
  bool is_grid = false;
  Grid grid;
};

}  // namespace maglead::analysis
