#include "maglead/canopen/sdo_client.hpp"

#include <algorithm>
#include <array>
#include <cstdio>

#include "maglead/canopen/protocol.hpp"

namespace maglead::canopen {
namespace {

// Command specifiers (byte 0, bits 7..5) and the codes the client aborts with (CiA 301).
constexpr std::uint8_t ccs_download_segment = 0x00, ccs_initiate_download = 0x20,
                       ccs_initiate_upload = 0x40, ccs_upload_segment = 0x60, cs_abort = 0x80;
constexpr std::uint8_t scs_upload_segment = 0x00, scs_download_segment = 0x20,
                       scs_initiate_upload = 0x40, scs_initiate_download = 0x60;
constexpr std::uint32_t abort_toggle = 0x05030000, abort_timeout = 0x05040000,
                        abort_command = 0x05040001, abort_memory = 0x05040005,
                        abort_general = 0x08000000;
constexpr std::uint8_t toggle_bit = 0x10, last_segment_bit = 0x01;

std::uint8_t command_of(const CanFrame& f) { return f.data[0] & 0xE0; }
std::uint16_t index_of(const CanFrame& f) {
  return static_cast<std::uint16_t>(get_le(f.data.data() + 1, 2));
}

struct AbortText {
  std::uint32_t code;
  const char* text;
};
constexpr std::array<AbortText, 30> abort_texts{{
    {0x05030000, "toggle bit not alternated"},
    {0x05040000, "SDO protocol timed out"},
    {0x05040001, "client/server command specifier not valid or unknown"},
    {0x05040002, "invalid block size"},
    {0x05040003, "invalid sequence number"},
    {0x05040004, "CRC error"},
    {0x05040005, "out of memory"},
    {0x06010000, "unsupported access to an object"},
    {0x06010001, "attempt to read a write only object"},
    {0x06010002, "attempt to write a read only object"},
    {0x06020000, "object does not exist in the object dictionary"},
    {0x06040041, "object cannot be mapped to the PDO"},
    {0x06040042, "the number and length of the objects to be mapped would exceed PDO length"},
    {0x06040043, "general parameter incompatibility reason"},
    {0x06040047, "general internal incompatibility in the device"},
    {0x06060000, "access failed due to a hardware error"},
    {0x06070010, "data type does not match, length of service parameter does not match"},
    {0x06070012, "data type does not match, length of service parameter too high"},
    {0x06070013, "data type does not match, length of service parameter too low"},
    {0x06090011, "sub-index does not exist"},
    {0x06090030, "invalid value for parameter"},
    {0x06090031, "value of parameter written too high"},
    {0x06090032, "value of parameter written too low"},
    {0x06090036, "maximum value is less than minimum value"},
    {0x060A0023, "resource not available: SDO connection"},
    {0x08000000, "general error"},
    {0x08000020, "data cannot be transferred or stored to the application"},
    {0x08000021, "data cannot be transferred or stored because of local control"},
    {0x08000022, "data cannot be transferred or stored because of the present device state"},
    {0x08000024, "no data available"},
}};

}  // namespace

const char* sdo_abort_text(std::uint32_t abort_code) noexcept {
  for (const auto& a : abort_texts)
    if (a.code == abort_code) return a.text;
  return "unknown abort code";
}

std::string describe_sdo(const SdoResult& result, bool upload, std::uint16_t index,
                         std::uint8_t sub) {
  std::array<char, 64> head{};
  std::snprintf(head.data(), head.size(), "SDO %s 0x%04X:%02X", upload ? "upload" : "download",
                index, sub);
  std::array<char, 16> code{};
  std::snprintf(code.data(), code.size(), "0x%08X", result.abort_code);
  const std::string detail = std::string(code.data()) + " " + sdo_abort_text(result.abort_code);
  switch (result.status) {
    case SdoStatus::ok:
      return std::string(head.data()) + ": ok";
    case SdoStatus::aborted_by_server:
      return std::string(head.data()) + ": aborted by the drive: " + detail;
    case SdoStatus::bus_error:
      return std::string(head.data()) + ": the request could not be sent on the bus";
    case SdoStatus::timeout:
    case SdoStatus::toggle_error:
    case SdoStatus::protocol_error:
    case SdoStatus::too_large:
      break;
  }
  return std::string(head.data()) + ": aborted by the master: " + detail;
}

SdoClient::SdoClient(CanBus& bus, std::uint8_t node_id, double timeout_s)
    : bus_(bus), node_id_(node_id), timeout_s_(timeout_s) {}

CanFrame SdoClient::request(std::uint8_t command, std::uint16_t index,
                            std::uint8_t sub) const noexcept {
  CanFrame f;
  f.id = cob_sdo_rx + node_id_;
  f.len = 8;
  f.data[0] = command;
  put_le(f.data.data() + 1, 2, index);
  f.data[3] = sub;
  return f;
}

SdoResult SdoClient::fail(SdoStatus status, std::uint32_t code, std::uint16_t index,
                          std::uint8_t sub) {
  CanFrame abort = request(cs_abort, index, sub);
  put_le(abort.data.data() + 4, 4, code);
  (void)bus_.send(abort);  // best effort: the server times out by itself otherwise
  return {status, code};
}

SdoResult SdoClient::exchange(const CanFrame& req, std::uint16_t index, std::uint8_t sub,
                              CanFrame& response) {
  if (bus_.send(req) != CanStatus::ok) return {SdoStatus::bus_error, 0};
  const double deadline_s = bus_.now_s() + timeout_s_;
  for (;;) {
    const CanStatus status = bus_.receive(response, deadline_s);
    if (status == CanStatus::timeout) return fail(SdoStatus::timeout, abort_timeout, index, sub);
    if (status != CanStatus::ok) continue;  // error frames: the deadline still bounds the wait
    if (response.id == cob_sdo_tx + node_id_ && response.len == 8) break;
    if (other_) other_(response);
  }
  if (command_of(response) == cs_abort)
    return {SdoStatus::aborted_by_server, get_le(response.data.data() + 4, 4)};
  return {};
}

SdoResult SdoClient::segment(const CanFrame& seg, std::uint8_t expected_command,
                             std::uint16_t index, std::uint8_t sub, CanFrame& response) {
  if (const SdoResult r = exchange(seg, index, sub, response); !r.ok()) return r;
  if (command_of(response) != expected_command)
    return fail(SdoStatus::protocol_error, abort_command, index, sub);
  // The answer carries the request's toggle bit; anything else is a lost or repeated segment.
  if ((response.data[0] & toggle_bit) != (seg.data[0] & toggle_bit))
    return fail(SdoStatus::toggle_error, abort_toggle, index, sub);
  return {};
}

SdoResult SdoClient::download(std::uint16_t index, std::uint8_t sub,
                              std::span<const std::uint8_t> data) {
  // Expedited carries 1..4 bytes; an empty value goes as one empty segment.
  const bool expedited = !data.empty() && data.size() <= 4;
  // Expedited: e=1, s=1 and n = 4 - size; segmented: s=1 and the size in bytes 4..7.
  const auto command = static_cast<std::uint8_t>(
      ccs_initiate_download | 0x01 |
      (expedited ? 0x02 | static_cast<std::uint8_t>((4 - data.size()) << 2) : 0));
  CanFrame req = request(command, index, sub);
  if (expedited)
    std::copy(data.begin(), data.end(), req.data.begin() + 4);
  else
    put_le(req.data.data() + 4, 4, static_cast<std::uint32_t>(data.size()));
  CanFrame response;
  if (const SdoResult r = exchange(req, index, sub, response); !r.ok()) return r;
  if (command_of(response) != scs_initiate_download || index_of(response) != index ||
      response.data[3] != sub)
    return fail(SdoStatus::protocol_error, abort_command, index, sub);
  return expedited ? SdoResult{} : download_segments(index, sub, data);
}

SdoResult SdoClient::download_segments(std::uint16_t index, std::uint8_t sub,
                                       std::span<const std::uint8_t> data) {
  std::uint8_t toggle = 0;
  std::size_t at = 0;
  do {
    const std::size_t n = std::min<std::size_t>(7, data.size() - at);
    const bool last = at + n == data.size();
    CanFrame seg =
        request(static_cast<std::uint8_t>(ccs_download_segment | toggle | ((7 - n) << 1) |
                                          (last ? last_segment_bit : 0)),
                0, 0);
    std::copy_n(data.begin() + static_cast<std::ptrdiff_t>(at), n, seg.data.begin() + 1);
    CanFrame response;
    if (const SdoResult r = segment(seg, scs_download_segment, index, sub, response); !r.ok())
      return r;
    toggle ^= toggle_bit;
    at += n;
  } while (at < data.size());
  return {};
}

SdoResult SdoClient::upload(std::uint16_t index, std::uint8_t sub,
                            std::vector<std::uint8_t>& data) {
  data.clear();
  CanFrame response;
  if (const SdoResult r = exchange(request(ccs_initiate_upload, index, sub), index, sub, response);
      !r.ok())
    return r;
  if (command_of(response) != scs_initiate_upload || index_of(response) != index ||
      response.data[3] != sub)
    return fail(SdoStatus::protocol_error, abort_command, index, sub);
  const std::uint8_t flags = response.data[0];
  const bool expedited = (flags & 0x02) != 0, size_given = (flags & 0x01) != 0;
  if (expedited) {
    // Without s the server leaves the size open: CiA 301 says take all four bytes.
    const std::size_t n = size_given ? 4U - ((flags >> 2) & 0x03U) : 4U;
    data.assign(response.data.begin() + 4, response.data.begin() + 4 + static_cast<long>(n));
    return {};
  }
  const std::size_t size = size_given ? get_le(response.data.data() + 4, 4) : 0;
  if (size > max_upload_bytes) return fail(SdoStatus::too_large, abort_memory, index, sub);
  return upload_segments(index, sub, size, data);
}

SdoResult SdoClient::upload_segments(std::uint16_t index, std::uint8_t sub, std::size_t size,
                                     std::vector<std::uint8_t>& data) {
  std::uint8_t toggle = 0;
  for (;;) {
    const CanFrame seg = request(static_cast<std::uint8_t>(ccs_upload_segment | toggle), 0, 0);
    CanFrame response;
    if (const SdoResult r = segment(seg, scs_upload_segment, index, sub, response); !r.ok())
      return r;
    const std::size_t n = 7U - ((response.data[0] >> 1) & 0x07U);
    if (data.size() + n > max_upload_bytes)
      return fail(SdoStatus::too_large, abort_memory, index, sub);
    data.insert(data.end(), response.data.begin() + 1,
                response.data.begin() + 1 + static_cast<long>(n));
    if ((response.data[0] & last_segment_bit) != 0) break;
    toggle ^= toggle_bit;
  }
  // A size announced at the start that the segments do not add up to is a broken transfer.
  if (size != 0 && data.size() != size)
    return fail(SdoStatus::protocol_error, abort_general, index, sub);
  return {};
}

}  // namespace maglead::canopen
