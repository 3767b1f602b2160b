#pragma once
// Plugs the digital twin (twin::TwinMonitor) into the control loop's TwinHook.
#include <memory>

#include "maglead/controller/controller.hpp"

namespace maglead::twin {
class TwinMonitor;
struct TwinMonitorConfig;
}  // namespace maglead::twin

namespace maglead::controller {

class TwinMonitorHook final : public TwinHook {
 public:
  /// Builds the monitor (allocates; before the loop starts). Throws on a bad model.
  explicit TwinMonitorHook(const twin::TwinMonitorConfig& config);
  ~TwinMonitorHook() override;
  void clear_warnings() noexcept override;
  void step(const TwinInputs& in, TwinOutputs& out) noexcept override;
  void resync(double t_s, double screw_angle_rad, double nut_pos_m) noexcept override;

 private:
  std::unique_ptr<twin::TwinMonitor> monitor_;
  bool ok_ = true;  // false once a re-sync failed: the twin then reports itself unhealthy
};

}  // namespace maglead::controller
