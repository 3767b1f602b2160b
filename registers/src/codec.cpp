#include <bit>
#include <cmath>
#include <limits>

#include "maglead/registers/registers.hpp"

namespace maglead::registers {
namespace {

double saturate(double raw, double lo, double hi) {
  if (std::isnan(raw)) return 0.0;
  return raw < lo ? lo : (raw > hi ? hi : raw);
}

}  // namespace

void encode(const Register& reg, double value_si, std::uint16_t* words) {
  const double raw = value_si / reg.scale;
  switch (reg.type) {
    case Type::bit:
      words[0] = value_si != 0.0 && !std::isnan(value_si) ? 1 : 0;
      return;
    case Type::u16:
      words[0] = static_cast<std::uint16_t>(std::lround(saturate(raw, 0, 65535)));
      return;
    case Type::i16:
      words[0] = static_cast<std::uint16_t>(
          static_cast<std::int16_t>(std::lround(saturate(raw, -32768, 32767))));
      return;
    case Type::u32: {
      const auto v = static_cast<std::uint32_t>(std::llround(saturate(raw, 0, 4294967295.0)));
      words[0] = static_cast<std::uint16_t>(v >> 16);
      words[1] = static_cast<std::uint16_t>(v & 0xFFFF);
      return;
    }
    case Type::i32: {
      const auto v = static_cast<std::uint32_t>(
          static_cast<std::int32_t>(std::llround(saturate(raw, -2147483648.0, 2147483647.0))));
      words[0] = static_cast<std::uint16_t>(v >> 16);
      words[1] = static_cast<std::uint16_t>(v & 0xFFFF);
      return;
    }
    case Type::f32: {
      const auto v = std::bit_cast<std::uint32_t>(static_cast<float>(raw));
      words[0] = static_cast<std::uint16_t>(v >> 16);
      words[1] = static_cast<std::uint16_t>(v & 0xFFFF);
      return;
    }
  }
}

double decode(const Register& reg, const std::uint16_t* words) {
  const auto u32 = [&] { return (static_cast<std::uint32_t>(words[0]) << 16) | words[1]; };
  switch (reg.type) {
    case Type::bit:
      return words[0] ? 1.0 : 0.0;
    case Type::u16:
      return words[0] * reg.scale;
    case Type::i16:
      return static_cast<std::int16_t>(words[0]) * reg.scale;
    case Type::u32:
      return static_cast<double>(u32()) * reg.scale;
    case Type::i32:
      return static_cast<std::int32_t>(u32()) * reg.scale;
    case Type::f32:
      return static_cast<double>(std::bit_cast<float>(u32())) * reg.scale;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

bool in_range(const Register& reg, double value_si) {
  if (!std::isfinite(value_si)) return false;
  if (reg.type == Type::f32) {
    // Tolerate float32 rounding of the limits themselves (0.04 is not exact in float32).
    const double slack = 1e-6 * std::max(std::abs(reg.min), std::abs(reg.max));
    return value_si >= reg.min - slack && value_si <= reg.max + slack;
  }
  if (reg.type == Type::bit) return value_si >= reg.min && value_si <= reg.max;
  // A scaled integer is compared in its own units, rounded as encode rounds it: the documented
  // limit is the limit (10 µm/s decodes as 10 × 1e-6 = 9.999999999999999e-06, below 1e-05 in
  // doubles), and a client's SI value and the server's decoded one get the same answer.
  const double raw = std::round(value_si / reg.scale);
  return raw >= std::round(reg.min / reg.scale) && raw <= std::round(reg.max / reg.scale);
}

}  // namespace maglead::registers
