#include "maglead/controller/reference_move.hpp"

namespace maglead::controller {

bool ReferenceMove::start(const ReferenceMoveConfig& c, double stroke_min_m,
                          double stroke_max_m) noexcept {
  active_ = c.window_min_m >= stroke_min_m && c.window_max_m <= stroke_max_m &&
            c.window_min_m < c.window_max_m && c.slow_m_s > 0 && c.fast_m_s > 0 && c.accel_m_s2 > 0;
  cfg_ = c;
  leg_ = 0;
  return active_;
}

bool ReferenceMove::next(Leg& leg) noexcept {
  if (!active_) return false;
  // Start of the window, then max / min at the slow speed, then max / min at the fast one.
  static constexpr int kLegs = 5;
  if (leg_ >= kLegs) {
    active_ = false;
    return false;
  }
  const bool to_max = leg_ % 2 == 1;
  leg.target_m = to_max ? cfg_.window_max_m : cfg_.window_min_m;
  leg.speed_m_s = leg_ < 3 ? cfg_.slow_m_s : cfg_.fast_m_s;
  ++leg_;
  return true;
}

}  // namespace maglead::controller
