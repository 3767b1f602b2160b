#include "maglead/physics/edge_tracker.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace maglead {

EdgeTracker::EdgeTracker(const EdgeTrackerConfig& config) : cfg_(config) {
  if (!(cfg_.count_m > 0) || !(cfg_.stop.intervals > 0) || !(cfg_.stop.min_s > 0))
    throw std::invalid_argument("edge tracker: count and stop times must be positive");
}

void EdgeTracker::reset(double t_s, double reading_m) noexcept {
  count_ = std::llround(reading_m / cfg_.count_m);
  pos_m_ = edge_pos_m_ = static_cast<double>(count_) * cfg_.count_m;
  t_prev_s_ = edge_t_s_ = t_s;
  interval_s_ = 0.0;
  edge_dir_ = dir_ = run_edges_ = 0;
  vel_m_s_ = 0.0;
}

double EdgeTracker::cell_lo_m() const noexcept {
  return (static_cast<double>(count_) - 0.5) * cfg_.count_m;
}

void EdgeTracker::on_edge(double t_s, double h_s, long long count) noexcept {
  const int dir = count > count_ ? 1 : -1;
  const double q = cfg_.count_m;
  const double e_pos = (static_cast<double>(count) - 0.5 * dir) * q;
  const double e_t = t_s - 0.5 * h_s;  // crossed somewhere within the sample: its middle
  const double gap = e_t - edge_t_s_;
  if (dir == edge_dir_ && dir_ != 0 && gap > 0) {
    ++run_edges_;
    interval_s_ = gap;
    vel_m_s_ = (e_pos - edge_pos_m_) / gap;
  } else {
    // First edge of a motion: the nut broke loose somewhere in the last interval.
    run_edges_ = 1;
    const double since = std::max(h_s, std::min(gap, cfg_.stop.min_s * 4));
    vel_m_s_ = dir * q / since;
    interval_s_ = since;
  }
  edge_t_s_ = e_t, edge_pos_m_ = e_pos, edge_dir_ = dir, count_ = count;
}

EdgeEvent EdgeTracker::update(double t_s, double reading_m) noexcept {
  const double h = std::max(t_s - t_prev_s_, 1e-9);
  t_prev_s_ = t_s;
  const long long k = std::llround(reading_m / cfg_.count_m);
  EdgeEvent ev = EdgeEvent::none;
  if (k != count_) {
    ev = dir_ == 0 || (k > count_ ? 1 : -1) != edge_dir_ ? EdgeEvent::started : EdgeEvent::edge;
    on_edge(t_s, h, k);
    dir_ = edge_dir_;
  } else if (dir_ != 0) {
    const double since = t_s - edge_t_s_;
    // No edge yet: the speed cannot exceed one count over the time since the last.
    const double bound = cfg_.count_m / std::max(since, h);
    if (std::abs(vel_m_s_) > bound) vel_m_s_ = edge_dir_ * bound;
    if (since > std::max(cfg_.stop.intervals * interval_s_, cfg_.stop.min_s)) {
      pos_m_ =
          std::clamp(edge_pos_m_ + vel_m_s_ * 0.5 * since, cell_lo_m(), cell_lo_m() + cfg_.count_m);
      dir_ = 0;
      return EdgeEvent::stopped;
    }
  }
  if (dir_ != 0)
    pos_m_ = std::clamp(edge_pos_m_ + vel_m_s_ * (t_s - edge_t_s_), cell_lo_m(),
                        cell_lo_m() + cfg_.count_m);
  return ev;
}

}  // namespace maglead
