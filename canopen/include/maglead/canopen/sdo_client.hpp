#pragma once
// The SDO client (CiA 301 §7.2.4): expedited and segmented upload and download to one server,
// each exchange bounded by a timeout, the toggle bit checked, aborts both ways with their codes.
// Used at start-up (configuration and identity), not in the cycle: it waits for each answer and
// its uploads allocate.
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "maglead/canopen/can_bus.hpp"

namespace maglead::canopen {

enum class SdoStatus : std::uint8_t {
  ok,
  aborted_by_server,  // the drive sent an abort: abort_code says why
  timeout,            // no answer in time (the client aborted with 0x05040000)
  toggle_error,       // a segment with the wrong toggle bit (the client aborted with 0x05030000)
  protocol_error,     // an answer that does not fit the request (the client aborted)
  too_large,          // an upload longer than the client takes (the client aborted)
  bus_error,          // the request could not be sent
};

struct SdoResult {
  SdoStatus status = SdoStatus::ok;
  std::uint32_t abort_code = 0;  // the code sent or received; 0 when ok
  bool ok() const noexcept { return status == SdoStatus::ok; }
};

/// CiA 301's text of an SDO abort code (table 22), "unknown abort code" otherwise.
const char* sdo_abort_text(std::uint32_t abort_code) noexcept;
/// "SDO upload 0x6060:00: aborted by the drive: 0x06020000 object does not exist ..."
std::string describe_sdo(const SdoResult& result, bool upload, std::uint16_t index,
                         std::uint8_t sub);

class SdoClient {
 public:
  // Uploads longer than this are refused: the objects read here are a few bytes to a name.
  static constexpr std::size_t max_upload_bytes = 1024;

  SdoClient(CanBus& bus, std::uint8_t node_id, double timeout_s);
  SdoResult download(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data);
  SdoResult upload(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t>& data);
  /// Frames that arrive during an exchange but are not its answer (heartbeats, EMCY) go here.
  void on_other_frame(std::function<void(const CanFrame&)> handler) { other_ = std::move(handler); }

 private:
  /// Sends a request and waits for the server's answer; a timeout aborts index:sub.
  SdoResult exchange(const CanFrame& request, std::uint16_t index, std::uint8_t sub,
                     CanFrame& response);
  /// One segment out and its answer in, the command and the toggle bit checked.
  SdoResult segment(const CanFrame& seg, std::uint8_t expected_command, std::uint16_t index,
                    std::uint8_t sub, CanFrame& response);
  SdoResult fail(SdoStatus status, std::uint32_t code, std::uint16_t index, std::uint8_t sub);
  SdoResult download_segments(std::uint16_t index, std::uint8_t sub,
                              std::span<const std::uint8_t> data);
  SdoResult upload_segments(std::uint16_t index, std::uint8_t sub, std::size_t size,
                            std::vector<std::uint8_t>& data);
  CanFrame request(std::uint8_t command, std::uint16_t index, std::uint8_t sub) const noexcept;

  CanBus& bus_;
  std::uint8_t node_id_;
  double timeout_s_;
  std::function<void(const CanFrame&)> other_;
};

}  // namespace maglead::canopen
