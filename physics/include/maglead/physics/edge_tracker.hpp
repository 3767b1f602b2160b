#pragma once
// EdgeTracker: where the nut is and how fast it goes, from a linear encoder's readings alone.
//
// A reading changes only when the nut crosses a count boundary (an edge). At an edge the nut is
// exactly on the boundary: the midpoint of the two readings, whatever the encoder's rounding
// convention (the calibration was made with the same encoder). Between edges it goes on at its
// last speed but stays inside the current count; a run of edges gives the speed from their
// spacing; when no edge comes for a few intervals it has stopped. No allocation.
#include <cstdint>

namespace maglead {

/// When a nut that was moving counts as stopped: the one rule the loop's observer and the twin
/// share.
struct StopRule {
  double intervals = 2;  // no edge for this many edge intervals: stopped …
  double min_s = 0.010;  // … and for at least this long
};

struct EdgeTrackerConfig {
  double count_m = 2.16e-5;  // one linear-encoder count
  StopRule stop;
};

enum class EdgeEvent : std::uint8_t {
  none = 0,
  edge = 1,     // an edge in the current run of motion
  started = 2,  // the first edge of a motion (the nut broke loose in the last interval)
  stopped = 3,  // no edge for long enough: the nut stands still
};

class EdgeTracker {
 public:
  /// Throws std::invalid_argument on a non-positive count or stop time.
  explicit EdgeTracker(const EdgeTrackerConfig& config);
  /// Start from a reading: stopped, at the reading itself.
  void reset(double t_s, double reading_m) noexcept;
  /// One sample (t_s after the previous one).
  EdgeEvent update(double t_s, double reading_m) noexcept;

  int direction() const noexcept { return dir_; }  // −1/+1 while moving, 0 stopped
  bool moving() const noexcept { return dir_ != 0; }
  double velocity_m_s() const noexcept { return moving() ? vel_m_s_ : 0.0; }
  double position_m() const noexcept { return pos_m_; }  // best estimate, inside the count
  int run_edges() const noexcept { return run_edges_; }  // edges in a row of this motion

 private:
  double cell_lo_m() const noexcept;
  void on_edge(double t_s, double h_s, long long count) noexcept;

  EdgeTrackerConfig cfg_;
  long long count_ = 0;
  double t_prev_s_ = 0.0;
  double edge_t_s_ = 0.0, edge_pos_m_ = 0.0, interval_s_ = 0.0;
  int edge_dir_ = 0, dir_ = 0, run_edges_ = 0;
  double vel_m_s_ = 0.0, pos_m_ = 0.0;
};

}  // namespace maglead
