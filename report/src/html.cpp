#include "maglead/report/html.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace maglead::report {

std::string escape_html(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string base64(std::string_view in) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  const auto byte = [&](std::size_t i) {
    return i < in.size() ? static_cast<unsigned char>(in[i]) : 0u;
  };
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const unsigned v = (byte(i) << 16) | (byte(i + 1) << 8) | byte(i + 2);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < in.size() ? kAlphabet[(v >> 6) & 63] : '=';
    out += i + 2 < in.size() ? kAlphabet[v & 63] : '=';
  }
  return out;
}

std::string data_url_of_png_bytes(const std::string& png_bytes) {
  return "data:image/png;base64," + base64(png_bytes);
}

std::string number(double value, int significant) {
  if (!std::isfinite(value)) return "–";
  char buf[64];
  // %g would write 2000 N/m as "2e+03": whole numbers of that size print in full.
  if (std::abs(value) >= 1e3 && std::abs(value) < 1e9)
    std::snprintf(buf, sizeof buf, "%.0f", value);
  else
    std::snprintf(buf, sizeof buf, "%.*g", significant, value);
  std::string s = buf;
  if (s.front() == '-') s.replace(0, 1, "−");
  return s;
}

std::string fixed(double value, int decimals) {
  if (!std::isfinite(value)) return "–";
  char buf[64];
  // + 0.0: a value that rounds to zero prints "0.00", never "−0.00".
  const double scale = std::pow(10.0, decimals);
  std::snprintf(buf, sizeof buf, "%.*f", decimals, std::round(value * scale) / scale + 0.0);
  std::string s = buf;
  if (s.front() == '-') s.replace(0, 1, "−");
  return s;
}

}  // namespace maglead::report
