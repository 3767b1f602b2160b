#pragma once
// The reference move: a short back-and-forth at two speeds inside a configured window, with
// nothing touching the nut, so the twin knows the external force (zero) while it runs and can
// judge estimation drift without a load cell (README "Drift without a load cell").
namespace maglead::controller {

struct ReferenceMoveConfig {
  double window_min_m = 0.015, window_max_m = 0.025;  // inside the stroke, clear of its ends
  double slow_m_s = 0.010, fast_m_s = 0.040;          // the two speeds
  double accel_m_s2 = 1.0;
};

/// Legs: to the window's start and one back-and-forth at the slow speed, one at the fast speed.
class ReferenceMove {
 public:
  struct Leg {
    double target_m = 0.0, speed_m_s = 0.0;
  };
  /// False (and inactive) if the window is empty or leaves [stroke_min_m, stroke_max_m], or a
  /// speed or the acceleration is not positive.
  bool start(const ReferenceMoveConfig& c, double stroke_min_m, double stroke_max_m) noexcept;
  /// The next leg once the previous one has arrived; false when the move is over.
  bool next(Leg& leg) noexcept;
  bool active() const noexcept { return active_; }
  void cancel() noexcept { active_ = false; }
  double accel_m_s2() const noexcept { return cfg_.accel_m_s2; }

 private:
  ReferenceMoveConfig cfg_{};
  int leg_ = 0;
  bool active_ = false;
};

}  // namespace maglead::controller
