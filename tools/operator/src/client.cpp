#include "maglead/operator/client.hpp"

#include <modbus/modbus.h>

#include <arpa/inet.h>
#include <netdb.h>
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <thread>

#include "maglead/physics/estimator.hpp"

namespace maglead::op {

namespace reg = maglead::registers;
using Kind = ClientError::Kind;

namespace {

modbus_t* ctx_of(void* p) { return static_cast<modbus_t*>(p); }

std::string fmt(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

std::string ipv4_text(std::uint32_t ip) {
  return std::to_string(ip >> 24) + "." + std::to_string((ip >> 16) & 255) + "." +
         std::to_string((ip >> 8) & 255) + "." + std::to_string(ip & 255);
}

}  // namespace

// ------------------------------------------------------------------------------- basics

std::string Endpoint::describe() const {
  if (!serial.empty())
    return serial + " " + std::to_string(baud) + " " + std::to_string(data_bits) + parity +
           std::to_string(stop_bits) + " unit " + std::to_string(unit);
  const bool v6 = host.find(':') != std::string::npos;
  return (v6 ? "[" + host + "]" : host) + ":" + std::to_string(port) + " unit " +
         std::to_string(unit);
}

int ClientError::exit_code() const {
  switch (kind_) {
    case Kind::refused_locally:
      return 2;
    case Kind::connection:
    case Kind::no_reply:
    case Kind::protocol:
      return 3;
    case Kind::exception:
    case Kind::rejected:
      return 4;
    case Kind::interrupted:
      return 130;
  }
  return 3;
}

std::optional<double> Values::get(std::string_view name) const {
  for (std::size_t i = 0; i < regs.size(); ++i)
    if (regs[i]->name == name) return si[i];
  return std::nullopt;
}

double Values::at(std::string_view name) const {
  if (auto v = get(name)) return *v;
  throw ClientError(Kind::protocol, "internal: register '" + std::string(name) + "' was not read");
}

std::vector<Block> read_blocks(reg::Table table) {
  std::vector<const reg::Register*> regs;
  for (const auto& r : reg::table())
    if (r.table == table) regs.push_back(&r);
  std::sort(regs.begin(), regs.end(), [](auto* a, auto* b) { return a->address < b->address; });
  std::vector<Block> blocks;
  for (const auto* r : regs) {
    const auto n = static_cast<std::uint16_t>(reg::word_count(r->type));
    // A gap in the map is an exception 02 on the server: start a new request there.
    if (!blocks.empty() && blocks.back().start + blocks.back().count == r->address &&
        blocks.back().count + n <= 125) {
      blocks.back().count = static_cast<std::uint16_t>(blocks.back().count + n);
    } else {
      blocks.push_back({table, r->address, n});
    }
  }
  return blocks;
}

// ------------------------------------------------------------------------------- client

Client::Client(const Endpoint& endpoint) : ep_(endpoint) {
  if (!ep_.serial.empty()) {
    ctx_ = modbus_new_rtu(ep_.serial.c_str(), ep_.baud, ep_.parity, ep_.data_bits, ep_.stop_bits);
  } else {
    // Host names and IPv6 addresses: resolve here (modbus_new_tcp takes dotted IPv4 only, and
    // turns "localhost" into 255.255.255.255), so a wrong name gets its own message.
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    const std::string service = std::to_string(ep_.port);
    const int gai = getaddrinfo(ep_.host.c_str(), service.c_str(), &hints, &found);
    if (gai != 0)
      throw ClientError(Kind::connection,
                        "cannot resolve host '" + ep_.host + "': " + gai_strerror(gai));
    freeaddrinfo(found);
    // Tries every address the name resolves to (e.g. ::1, then 127.0.0.1), in order.
    ctx_ = modbus_new_tcp_pi(ep_.host.c_str(), service.c_str());
  }
  if (!ctx_)
    throw ClientError(Kind::connection, "cannot set up a Modbus context for " + ep_.describe() +
                                            ": " + modbus_strerror(errno));
  auto* ctx = ctx_of(ctx_);
  if (modbus_set_slave(ctx, ep_.unit) != 0) {
    modbus_free(ctx);
    ctx_ = nullptr;
    throw ClientError(Kind::refused_locally,
                      "unit id " + std::to_string(ep_.unit) + " is not valid (0..247, TCP 255)");
  }
  const double t = std::max(ep_.timeout_s, 0.01);
  const auto sec = static_cast<std::uint32_t>(t);
  modbus_set_response_timeout(ctx, sec, static_cast<std::uint32_t>((t - sec) * 1e6));
  if (modbus_connect(ctx) != 0) {
    const int e = errno;
    modbus_free(ctx);
    ctx_ = nullptr;
    if (!ep_.serial.empty())
      throw ClientError(Kind::connection,
                        "cannot open serial line " + ep_.serial + ": " + std::strerror(e));
    throw ClientError(Kind::connection,
                      "cannot connect to " + ep_.host + ":" + std::to_string(ep_.port) + ": " +
                          (e == ECONNREFUSED ? std::string("connection refused (no controller "
                                                           "listening on that port?)")
                                             : std::string(modbus_strerror(e))));
  }
}

Client::~Client() {
  if (ctx_) {
    modbus_close(ctx_of(ctx_));
    modbus_free(ctx_of(ctx_));
  }
}

void Client::flush() {
  if (ctx_) modbus_flush(ctx_of(ctx_));
}

void Client::fail(const std::string& what) const {
  const int e = errno;
  const std::string where = ep_.describe();
  const char* exc = nullptr;
  switch (e) {
    case EMBXILFUN:
      exc = "01 illegal function (a read-only controller refuses every write)";
      break;
    case EMBXILADD:
      exc = "02 illegal data address (register not in this controller's map, or read-only)";
      break;
    case EMBXILVAL:
      exc = "03 illegal data value (out of range or beyond its limits)";
      break;
    case EMBXSFAIL:
      exc =
          "04 refused (another client owns control, or a state change sent by broadcast; the "
          "reason is in "
          "write_refusal_reason)";
      break;
    case EMBXSBUSY:
      exc = "06 server busy (its command queue is full: try again)";
      break;
    case EMBXGPATH:
      exc = "0A gateway path unavailable";
      break;
    default:
      break;
  }
  if (exc)
    throw ClientError(Kind::exception,
                      what + ": controller at " + where + " answered with exception " + exc);
  switch (e) {
    case EMBXGTAR:
      throw ClientError(Kind::no_reply, what + ": " + ep_.host + ":" + std::to_string(ep_.port) +
                                            " does not serve unit " + std::to_string(ep_.unit) +
                                            " (exception 0B gateway target failed): check --unit");
    case EMBBADCRC:
    case EMBBADDATA:
    case EMBBADEXC:
    case EMBUNKEXC:
    case EMBMDATA:
    case EMBBADSLAVE:
      throw ClientError(Kind::protocol, what + ": malformed or mismatched reply from " + where +
                                            " (" + modbus_strerror(e) + ")");
    case ETIMEDOUT:
      if (!ep_.serial.empty())
        throw ClientError(Kind::no_reply,
                          what + ": no reply from unit " + std::to_string(ep_.unit) + " on " +
                              ep_.serial + " within " + fmt(ep_.timeout_s) +
                              " s: wrong --unit, --baud or --parity, or the controller is off");
      throw ClientError(Kind::no_reply,
                        what + ": no reply from " + where + " within " + fmt(ep_.timeout_s) + " s");
    case ECONNRESET:
    case EPIPE:
    case ENOTCONN:
    case EBADF:
      throw ClientError(Kind::connection, what + ": connection to " + where + " dropped");
    default:
      throw ClientError(Kind::connection, what + ": " + where + ": " + modbus_strerror(e));
  }
}

void Client::check_identity() {
  const auto w = read_words(reg::Table::input_register, 0, 3);
  if (w[0] != reg::kDeviceType)
    throw ClientError(
        Kind::protocol, ep_.describe() + " is not a maglead controller (device type 0x" + [&] {
          char b[8];
          std::snprintf(b, sizeof b, "%04X", w[0]);
          return std::string(b);
        }() + ", expected 0x4D4C)");
  if (w[2] != reg::kMapVersion)
    throw ClientError(Kind::protocol, ep_.describe() + " speaks register map version " +
                                          std::to_string(w[2]) + ", this tool knows version " +
                                          std::to_string(reg::kMapVersion));
}

std::vector<std::uint16_t> Client::read_words(reg::Table table, std::uint16_t start,
                                              std::uint16_t count) {
  std::vector<std::uint16_t> words(count);
  int rc = -1;
  if (table == reg::Table::input_register)
    rc = modbus_read_input_registers(ctx_of(ctx_), start, count, words.data());
  else if (table == reg::Table::holding_register)
    rc = modbus_read_registers(ctx_of(ctx_), start, count, words.data());
  else
    throw ClientError(Kind::protocol, "internal: read_words needs a register table");
  if (rc != count) {
    if (rc >= 0) errno = EMBMDATA;
    fail("reading " + std::string(reg::to_string(table)) + "s " + std::to_string(start) + ".." +
         std::to_string(start + count - 1));
  }
  return words;
}

Values Client::read_range(reg::Table table, std::uint16_t start, std::uint16_t count) {
  const auto words = read_words(table, start, count);
  Values v;
  for (const auto& r : reg::table()) {
    if (r.table != table || r.address < start ||
        r.address + reg::word_count(r.type) > start + count)
      continue;
    const std::uint16_t* w = words.data() + (r.address - start);
    v.regs.push_back(&r);
    v.si.push_back(reg::decode(r, w));
    v.raw.push_back(reg::word_count(r.type) == 2 ? (static_cast<std::uint32_t>(w[0]) << 16) | w[1]
                                                 : w[0]);
  }
  return v;
}

Values Client::read_tables(const std::vector<reg::Table>& tables) {
  Values all;
  for (auto t : tables)
    for (const auto& b : read_blocks(t)) {
      Values part = read_range(t, b.start, b.count);
      all.regs.insert(all.regs.end(), part.regs.begin(), part.regs.end());
      all.si.insert(all.si.end(), part.si.begin(), part.si.end());
      all.raw.insert(all.raw.end(), part.raw.begin(), part.raw.end());
    }
  return all;
}

/// Exception 04 on a write: the controller says why in write_refusal_reason and who owns control
/// in control_owner_ipv4 (reads are never refused), so the message can say what to do.
void Client::refused_write(const std::string& what) {
  std::string why = "another client owns control, or a state change sent by broadcast";
  try {
    const auto* owner = reg::find("control_owner_ipv4");
    const auto* reason = reg::find("write_refusal_reason");
    const Values v = read_range(reg::Table::input_register, owner->address, 2);
    const Values r = read_range(reg::Table::input_register, reason->address, 1);
    const double code = r.at("write_refusal_reason");
    const auto ip = static_cast<std::uint32_t>(v.at("control_owner_ipv4"));
    why = code_name(reg::refusals(), code) + ": " + code_meaning(reg::refusals(), code);
    if (ip != 0)
      why += " (owner " + ipv4_text(ip) +
             "; that client must release it: Ctrl-C on its 'maglead set' or 'maglead enable', or "
             "enable cleared in its control word; control is free again once its connection "
             "ends)";
  } catch (const ClientError&) {
    // The reason could not be read: the generic text stands.
  }
  throw ClientError(Kind::exception, what + ": controller at " + ep_.describe() +
                                         " refused it (exception 04): " + why);
}

/// Exception 03 on a write: the controller says why in write_refusal_reason. A value outside its
/// register's range is named with that range (the one the controller's decoded value failed,
/// checked as the server checks it), so the message blames the register that was refused, not
/// the setpoint beside it in the same request.
void Client::refused_value(const std::string& what, const std::vector<WrittenValue>& written) {
  std::string why = "out of range or beyond its limits";
  try {
    const auto* reason = reg::find("write_refusal_reason");
    const double code =
        read_range(reg::Table::input_register, reason->address, 1).at("write_refusal_reason");
    why = code_name(reg::refusals(), code) + ": " + code_meaning(reg::refusals(), code);
    if (code == static_cast<double>(reg::Refusal::out_of_range)) {
      std::string named;
      for (const auto& [r, v] : written) {
        std::uint16_t w[2] = {0, 0};
        reg::encode(*r, v, w);
        if (reg::in_range(*r, reg::decode(*r, w))) continue;
        const std::string unit = r->unit.empty() ? "" : " " + std::string(r->unit);
        named += "; " + si_name(*r) + " " + fmt(v) + unit + " is outside " + fmt(r->min) + " .. " +
                 fmt(r->max) + unit;
      }
      why += named.empty() ? " (every value written is inside the range this tool knows)" : named;
    }
  } catch (const ClientError&) {
    // The reason could not be read: the generic text stands.
  }
  throw ClientError(Kind::exception, what + ": controller at " + ep_.describe() +
                                         " refused it (exception 03 illegal data value): " + why);
}

void Client::write(const std::vector<std::pair<std::string, double>>& values) {
  // Check everything first: a refused value must leave the controller untouched.
  std::vector<WrittenValue> items;
  for (const auto& [name, v] : values) {
    const auto* r = reg::find(name);
    if (!r) throw ClientError(Kind::refused_locally, "no register named '" + name + "'");
    if (r->table != reg::Table::holding_register || r->access != reg::Access::read_write)
      throw ClientError(Kind::refused_locally, "'" + name + "' is not a writable holding register");
    if (auto why = check_register(*r, v)) throw ClientError(Kind::refused_locally, *why);
    items.push_back({r, v});
  }
  std::size_t i = 0;
  while (i < items.size()) {
    std::vector<std::uint16_t> words;
    const std::uint16_t start = items[i].r->address;
    std::string names;
    std::size_t j = i;
    for (; j < items.size(); ++j) {
      if (items[j].r->address != start + words.size()) break;
      std::uint16_t w[2];
      reg::encode(*items[j].r, items[j].v, w);
      words.insert(words.end(), w, w + reg::word_count(items[j].r->type));
      names += (names.empty() ? "" : ", ") + si_name(*items[j].r);
    }
    const int n = static_cast<int>(words.size());
    if (modbus_write_registers(ctx_of(ctx_), start, n, words.data()) != n) {
      if (errno == EMBXSFAIL) refused_write("writing " + names);
      if (errno == EMBXILVAL)
        refused_value("writing " + names, {items.begin() + static_cast<std::ptrdiff_t>(i),
                                           items.begin() + static_cast<std::ptrdiff_t>(j)});
      fail("writing " + names);
    }
    i = j;
  }
}

// ------------------------------------------------------------------------------- values, units

double parse_quantity(const std::string& text, std::string_view si_unit) {
  struct U {
    std::string_view si, name;
    double factor;
  };
  static constexpr U kUnits[] = {
      {"N", "N", 1},         {"N", "mN", 1e-3},        {"N", "kN", 1e3},
      {"m", "m", 1},         {"m", "mm", 1e-3},        {"m", "um", 1e-6},
      {"m", "µm", 1e-6},     {"m/s", "m/s", 1},        {"m/s", "mm/s", 1e-3},
      {"m/s", "um/s", 1e-6}, {"m/s^2", "m/s^2", 1},    {"m/s^2", "mm/s^2", 1e-3},
      {"m/s^2", "m/s2", 1},  {"m/s^2", "mm/s2", 1e-3}, {"s", "s", 1},
      {"s", "ms", 1e-3},     {"s", "min", 60},         {"s", "h", 3600},
  };
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    throw ClientError(Kind::refused_locally, "'" + text + "' is not a number");
  }
  std::string unit = text.substr(used);
  unit.erase(std::remove(unit.begin(), unit.end(), ' '), unit.end());
  if (unit.empty()) {
    if (!std::isfinite(v))
      throw ClientError(Kind::refused_locally, "'" + text + "' is not a finite number");
    return v;  // a bare number is in the SI unit
  }
  // A decimal comma ("1,5"): the tools read a decimal point only.
  if (unit.size() > 1 && unit[0] == ',' && std::isdigit(static_cast<unsigned char>(unit[1]))) {
    std::string point = text;
    point[point.find(',')] = '.';
    throw ClientError(Kind::refused_locally,
                      "'" + text + "': use a decimal point, not a comma: '" + point + "'");
  }
  // "m" is metres in every other quantity, so a time typed as "2m" is refused, not guessed.
  if (si_unit == "s" && unit == "m")
    throw ClientError(Kind::refused_locally,
                      "'" + text + "' is metres; for minutes type " + text.substr(0, used) + "min");
  std::string accepted;
  for (const auto& u : kUnits) {
    if (u.si != si_unit) continue;
    if (u.name == unit) return v * u.factor;
    accepted += (accepted.empty() ? "" : ", ") + std::string(u.name);
  }
  throw ClientError(Kind::refused_locally,
                    "'" + text + "': unit '" + unit + "' is not one of " +
                        (accepted.empty() ? std::string(si_unit) : accepted));
}

std::string code_name(std::span<const reg::Code> codes, double value) {
  for (const auto& c : codes)
    if (c.value == value) return std::string(c.name);
  return "unknown (" + fmt(value) + ")";
}

std::string code_meaning(std::span<const reg::Code> codes, double value) {
  for (const auto& c : codes)
    if (c.value == value) return std::string(c.description);
  return "not in this tool's register map";
}

std::string si_name(const reg::Register& r) {
  std::string n(r.name);
  if (r.type == reg::Type::f32 && n.ends_with("_f32")) {
    // A float32-only figure (twin_drift_statistic_f32) goes by its SI name; a float32 copy of an
    // integer register keeps the suffix, so the two names stay apart.
    const std::string base = n.substr(0, n.size() - 4);
    const bool copy = std::any_of(reg::table().begin(), reg::table().end(), [&](const auto& x) {
      return x.type != reg::Type::f32 && si_name(x) == base;
    });
    return copy ? n : base;
  }
  if (r.scale == 1.0) return n;
  // Raw suffix -> SI suffix, longest first (_um_s2 before _um_s before _um).
  static const std::pair<std::string_view, std::string_view> kSuffixes[] = {
      {"_um_s2", "_m_s2"}, {"_um_s", "_m_s"}, {"_um", "_m"}, {"_urad", "_rad"},
      {"_mn", "_n"},       {"_ms", "_s"},     {"_us", "_s"}};
  for (const auto& [raw, si] : kSuffixes)
    if (n.ends_with(raw)) return n.substr(0, n.size() - raw.size()) + std::string(si);
  return n;
}

const reg::Register* find_by_any_name(std::string_view name) {
  if (const auto* r = reg::find(name)) return r;
  for (const auto& r : reg::table())
    if (si_name(r) == name) return &r;
  return nullptr;
}

int si_decimals(const reg::Register& r) {
  if (r.type == reg::Type::f32 || r.scale >= 1.0) return 0;
  return static_cast<int>(std::lround(-std::log10(r.scale)));
}

double si_rounded(const reg::Register& r, double v) {
  if (!std::isfinite(v)) return v;
  char b[64];
  if (r.type == reg::Type::f32)
    std::snprintf(b, sizeof b, "%.7g", v);
  else
    std::snprintf(b, sizeof b, "%.*f", si_decimals(r), v);
  return std::strtod(b, nullptr);
}

std::string si_text(const reg::Register& r, double v) {
  char b[64];
  // %.17g of the rounded value prints the shortest decimal only by luck; %g with enough digits
  // for the resolution, then trailing zeros trimmed, does it by construction.
  if (r.type == reg::Type::f32)
    std::snprintf(b, sizeof b, "%.7g", v);
  else
    std::snprintf(b, sizeof b, "%.*f", si_decimals(r), v);
  std::string s = b;
  if (s.find('.') != std::string::npos && s.find('e') == std::string::npos) {
    s.erase(s.find_last_not_of('0') + 1);
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

bool has_load_cell(const Values& v) { return !std::isnan(v.at("load_cell_force_n_f32")); }

std::vector<std::string> command_bits(std::uint16_t command_status) {
  std::vector<std::string> out;
  for (const auto& b : reg::command_bits())
    if ((command_status >> b.value) & 1u) out.emplace_back(b.name);
  return out;
}

std::vector<std::string> status_bits(std::uint16_t status_word) {
  std::vector<std::string> out;
  for (const auto& r : reg::table())
    if (r.table == reg::Table::discrete_input && ((status_word >> r.address) & 1u))
      out.emplace_back(r.name);
  return out;
}

namespace {
/// The smallest non-zero value a register stores: its scale; for float32, the smallest
/// subnormal (a value below it underflows to 0).
double resolution_si(const reg::Register& r) {
  return r.type == reg::Type::f32 ? std::numeric_limits<float>::denorm_min() * r.scale : r.scale;
}

/// A non-zero value the register's resolution rounds to 0, refused with what to type.
std::string below_resolution_text(const reg::Register& r, double v) {
  const std::string unit = r.unit.empty() ? "" : " " + std::string(r.unit);
  const double step = resolution_si(r);
  const std::string step_text = r.type == reg::Type::f32 ? fmt(step) : si_text(r, step);
  // The table says what 0 means where it is a switch ("0 = off"): the watchdog.
  const bool zero_is_off = r.description.find("0 = off") != std::string_view::npos;
  return si_name(r) + " " + fmt(v) + unit + " is below the register's resolution " + step_text +
         unit + "; write 0" + (zero_is_off ? " to switch it off" : "") +
         (v < 0 ? " or at most -" : " or at least ") + step_text + unit;
}
}  // namespace

std::optional<std::string> check_register(const reg::Register& r, double v) {
  if (!reg::in_range(r, v))
    return si_name(r) + " = " + fmt(v) + (r.unit.empty() ? "" : " ") + std::string(r.unit) +
           " is outside its range " + fmt(r.min) + " .. " + fmt(r.max) +
           (r.unit.empty() ? "" : " ") + std::string(r.unit) +
           " (the register map: docs/registers.md, maglead registers)";
  // What the register would store, not what was typed: a non-zero request rounded to 0 writes a
  // different meaning (watchdog 0 is off, mode_command 0 is idle, force 0 N), never a smaller
  // value of the same one. Every write of the tools passes here (Client::write).
  std::uint16_t words[2] = {0, 0};
  reg::encode(r, v, words);
  if (v != 0.0 && reg::decode(r, words) == 0.0) return below_resolution_text(r, v);
  return std::nullopt;
}

namespace {
/// Whether v lies in [lo, hi] as reported in float32: a limit typed exactly (0.04 m) must pass
/// although its float32 (0.0399999991) is a little less; 1e-6 is above float32's 6e-8 rounding.
bool within_reported(double v, double lo, double hi) {
  constexpr double kFloat32Slack = 1e-6;
  return v >= lo - std::abs(lo) * kFloat32Slack && v <= hi + std::abs(hi) * kFloat32Slack;
}
}  // namespace

std::optional<ReportedLimits> read_reported_limits(Client& client) {
  const auto* first = reg::find("force_limit_push_n_f32");
  try {
    const auto v = client.read_range(reg::Table::input_register, first->address, 8);
    return ReportedLimits{v.at("force_limit_pull_n_f32"), v.at("force_limit_push_n_f32"),
                          v.at("stroke_min_m_f32"), v.at("stroke_max_m_f32")};
  } catch (const ClientError& e) {
    if (e.kind() != ClientError::Kind::exception) throw;
    return std::nullopt;
  }
}

std::optional<std::string> check_force(const Limits& limits, double force_n) {
  if (const auto& r = limits.reported) {
    if (!within_reported(force_n, r->force_pull_n, r->force_push_n))
      return "force " + fmt(force_n) + " N is beyond the safe limit " +
             fmt(force_n > 0 ? r->force_push_n : r->force_pull_n) + " N; allowed " +
             force_limit_text(limits);
    return check_register(*reg::find("force_setpoint_mn"), force_n);
  }
  // The server's own check first: the calibrated inverse refuses beyond safe_fraction × peak,
  // a limit well inside the register's range, so it is the one worth saying.
  const auto inv =
      phase_for_output_force(limits.calibration, force_n, limits.actuator.safe_force_fraction);
  if (inv.status != InverseStatus::ok)
    return "force " + fmt(force_n) + " N is beyond the safe limit " + fmt(inv.limit_n) +
           " N; allowed " + force_limit_text(limits);
  return check_register(*reg::find("force_setpoint_mn"), force_n);
}

std::string force_limit_text(const Limits& limits) {
  if (const auto& r = limits.reported)
    return fmt(r->force_pull_n) + " .. " + fmt(r->force_push_n) +
           " N (the controller's limits, force_limit_pull_n_f32 / force_limit_push_n_f32)";
  const auto& cal = limits.calibration;
  const double f = limits.actuator.safe_force_fraction;
  return fmt(f * cal.peak_pull_n) + " .. " + fmt(f * cal.peak_push_n) + " N (safe_force_fraction " +
         fmt(f) + " in " + limits.actuator_source + " x calibration peaks " + fmt(cal.peak_pull_n) +
         " / " + fmt(cal.peak_push_n) + " N in " + limits.calibration_source + ")";
}

std::string position_limit_text(const Limits& limits) {
  if (const auto& r = limits.reported)
    return fmt(r->stroke_min_m * 1e3) + " .. " + fmt(r->stroke_max_m * 1e3) +
           " mm (the controller's stroke, stroke_min_m_f32 / stroke_max_m_f32)";
  const auto& a = limits.actuator;
  return fmt(a.stroke_min_m * 1e3) + " .. " + fmt(a.stroke_max_m * 1e3) +
         " mm (stroke_min_m, stroke_max_m in " + limits.actuator_source + ")";
}

std::optional<std::string> check_position(const Limits& limits, double position_m) {
  // The stroke first: it is the configured limit, usually inside the register's range.
  const auto& a = limits.actuator;
  const auto& r = limits.reported;
  if (r ? !within_reported(position_m, r->stroke_min_m, r->stroke_max_m)
        : !(position_m >= a.stroke_min_m && position_m <= a.stroke_max_m))
    return "position " + fmt(position_m * 1e3) + " mm is outside the stroke " +
           position_limit_text(limits);
  return check_register(*reg::find("position_setpoint_um"), position_m);
}

// ------------------------------------------------------------------------------- commands

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// The loop's command-side state: one read of input registers 10..53 (one control cycle).
struct Status {
  std::uint16_t status_word = 0, alarm = 0, drive_state = 0, command_status = 0, reject = 0;
  std::uint32_t cycle = 0;
  bool bit(int b) const { return (command_status >> b) & 1u; }
};

Status read_status(Client& c) {
  const auto* first = reg::find("status_word");
  const auto* last = reg::find("loop_cycle_count");
  const auto v = c.read_range(reg::Table::input_register, first->address,
                              static_cast<std::uint16_t>(last->address + 2 - first->address));
  Status s;
  s.status_word = static_cast<std::uint16_t>(v.at("status_word"));
  s.alarm = static_cast<std::uint16_t>(v.at("alarm_code"));
  s.drive_state = static_cast<std::uint16_t>(v.at("drive_state"));
  s.command_status = static_cast<std::uint16_t>(v.at("command_status"));
  s.reject = static_cast<std::uint16_t>(v.at("command_reject_reason"));
  s.cycle = static_cast<std::uint32_t>(v.at("loop_cycle_count"));
  return s;
}

struct Image {
  std::uint16_t control_word = 0;
  double watchdog_s = 0.0;
};
Image read_image(Client& c) {
  const auto v = c.read_range(reg::Table::holding_register, reg::find("control_word")->address, 4);
  return {static_cast<std::uint16_t>(v.at("control_word")), v.at("watchdog_ms")};
}

void write_cw(Client& c, std::uint16_t cw) { c.write({{"control_word", cw}}); }
constexpr std::uint16_t bit(int b) { return static_cast<std::uint16_t>(1u << b); }

/// Waits until the loop has run two cycles past `after` (our write was posted before the reply,
/// so by then it was applied), feeding the watchdog if one is set.
Status settle(Client& c, std::uint32_t after, const Image& im, const CommandOptions& o,
              const char* what) {
  const auto t0 = Clock::now();
  for (;;) {
    const Status s = read_status(c);
    if (static_cast<std::uint32_t>(s.cycle - after) >= 2u) return s;
    if (since(t0) > o.ack_timeout_s)
      throw ClientError(Kind::no_reply, std::string(what) +
                                            ": the controller's loop did not run within " +
                                            fmt(o.ack_timeout_s) + " s");
    if (im.watchdog_s > 0) c.write({{"heartbeat", 0}});
    std::this_thread::sleep_for(std::chrono::duration<double>(o.poll_period_s));
  }
}

}  // namespace

std::string drive_limit_reached_text(double load_n, std::optional<double> limit_n) {
  // Rounded towards 0 N: the figure said must be one the drive can reach.
  const double try_n = std::trunc(load_n * 10.0) / 10.0;
  char b[320];
  std::snprintf(b, sizeof b,
                "the coupling reached its safe limit%s before the force (force_limited, "
                "force_reached_reason 9 drive_limit): friction takes the rest of the drive, so "
                "the load gets %.2f N (load_force_est_n, the controller's estimate there); ask "
                "for no more than that: 'maglead set force %.1fN'",
                limit_n ? (" " + fmt(*limit_n) + " N").c_str() : "", load_n, try_n);
  return b;
}

namespace {
/// The coupling at its safe limit short of the force, with the limit the controller reports.
std::string read_drive_limit_reached_text(Client& c, const Values& loop) {
  const double load_n = loop.at("load_force_est_mn");
  const auto limits = read_reported_limits(c);
  std::optional<double> limit_n;
  if (limits) limit_n = load_n < 0 ? limits->force_pull_n : limits->force_push_n;
  return drive_limit_reached_text(load_n, limit_n);
}

/// force_limited for good: the stroke window ended before the force (stroke_end), or the
/// coupling is at its safe limit and the loop gave up raising it (drive_limit while blocked);
/// then what to say. Another limit (the speed limit) passes and ends no command.
std::optional<std::string> limited_before_force(Client& c) {
  const auto* state = reg::find("force_loop_state");
  const auto* reason = reg::find("force_reached_reason");
  const auto v = c.read_range(reg::Table::input_register, state->address,
                              static_cast<std::uint16_t>(reason->address + 1 - state->address));
  const std::string why =
      code_name(reg::codes_of("force_reached_reason"), v.at("force_reached_reason"));
  if (why == "stroke_end")
    return "the stroke window ended before the force (force_limited, force_reached_reason 7 "
           "stroke_end): the nut is held short of the window's end; ask for less force or a "
           "stiffer "
           "load";
  if (why == "drive_limit" &&
      code_name(reg::codes_of("force_loop_state"), v.at("force_loop_state")) == "blocked")
    return read_drive_limit_reached_text(c, v);
  return std::nullopt;
}

/// Position mode stalled with the coupling at its safe limit (in_position_reason
/// coupling_limit): what to say, with where the nut stands.
std::optional<std::string> limited_before_position(Client& c) {
  const auto* why = reg::find("in_position_reason");
  const auto* pos = reg::find("nut_pos_um");
  const double reason = c.read_range(reg::Table::input_register, why->address, 1).at(why->name);
  if (code_name(reg::codes_of("in_position_reason"), reason) != "coupling_limit")
    return std::nullopt;
  const double nut_m = c.read_range(reg::Table::input_register, pos->address, 2).at(pos->name);
  char b[64];
  std::snprintf(b, sizeof b, "%.3f mm", nut_m * 1e3);
  return "the coupling reached its safe limit with the nut at " + std::string(b) +
         ", short of the target (force_limited, in_position_reason 4 coupling_limit): the load "
         "needs more force there than the safe limit (IR 140/142); ask for a target the load "
         "allows";
}

/// Why a force is not reached yet, from the controller's own registers: "force_loop_state 4
/// holding, force_reached_reason 4 bound_too_wide (the load-force bound is wider than the
/// tolerance): the load force is known only within -8.04 .. 8.03 N".
std::string force_not_reached_text(Client& c) {
  const auto read = [&](const char* name) {
    const auto* r = reg::find(name);
    return c
        .read_range(reg::Table::input_register, r->address,
                    static_cast<std::uint16_t>(reg::word_count(r->type)))
        .at(name);
  };
  const double state = read("force_loop_state"), why = read("force_reached_reason");
  const auto codes = reg::codes_of("force_reached_reason");
  char bound[96];
  std::snprintf(bound, sizeof bound, ": the load force is known only within %.2f .. %.2f N",
                read("load_force_lo_mn"), read("load_force_hi_mn"));
  return "force_loop_state " + fmt(state) + " " +
         code_name(reg::codes_of("force_loop_state"), state) + ", force_reached_reason " +
         fmt(why) + " " + code_name(codes, why) + " (" + code_meaning(codes, why) + ")" +
         (code_name(codes, why) == "bound_too_wide" ? bound : "");
}

/// Why the nut is not in position yet, from the controller's own register: "in_position_reason 2
/// moving (…), nut at 20.512 mm".
std::string not_in_position_text(Client& c) {
  const auto* why = reg::find("in_position_reason");
  const auto* pos = reg::find("nut_pos_um");
  const double reason = c.read_range(reg::Table::input_register, why->address, 1).at(why->name);
  const double nut_m = c.read_range(reg::Table::input_register, pos->address, 2).at(pos->name);
  const auto codes = reg::codes_of("in_position_reason");
  char b[64];
  std::snprintf(b, sizeof b, ", nut at %.3f mm", nut_m * 1e3);
  return "in_position_reason " + fmt(reason) + " " + code_name(codes, reason) + " (" +
         code_meaning(codes, reason) + ")" + b;
}

/// A slip leaves φ a lead (or more) away from the stable branch, and the controller refuses a
/// plain reset while it is (still_faulty): the resync takes the nut's new lead as zero first.
bool slipped(double alarm) {
  return alarm == static_cast<double>(reg::Alarm::step_out) ||
         alarm == static_cast<double>(reg::Alarm::phase_jump);
}

/// The step_out status bit: a stroke_limit (or any) fault the nut slipped into needs the resync
/// as much as a step_out alarm does.
bool stepped_out(std::uint16_t status_word) { return (status_word >> reg::kStepOut) & 1u; }

/// reset_command for the drive as it is now: its alarm and its step_out status bit. A nut still
/// moving just after the latch may be slipping yet, its step_out bit a few cycles behind the
/// alarm: wait for the bit or a standstill, at most kSettle_s.
/// The status read again every heartbeat period while `waiting` holds, at most `most_s`.
template <class Pred>
Status read_status_while(Client& c, Pred waiting, double most_s) {
  const auto t0 = Clock::now();
  Status s = read_status(c);
  while (waiting(s) && since(t0) < most_s) {
    std::this_thread::sleep_for(std::chrono::duration<double>(kHeartbeatPeriod_s));
    s = read_status(c);
  }
  return s;
}

bool moving(const Status& s) { return ((s.status_word >> reg::kMoving) & 1u) != 0; }

std::string reset_command_now(Client& c, double alarm) {
  constexpr double kSettle_s = 0.5;
  const Status s = read_status_while(
      c, [](const Status& x) { return !stepped_out(x.status_word) && moving(x); }, kSettle_s);
  return reset_command(alarm, stepped_out(s.status_word));
}

/// After a slip the nut may still be sliding over the screw: a resync would take a passing lead
/// and the controller refuses a reset until the phase stands. Wait, as a person would, until the
/// nut stands (the moving bit clear: no encoder edge for a while), at most kSlipEnd_s; then the
/// controller's answer decides.
void wait_for_slip_to_end(Client& c) {
  // A slip's slide ends within tens of ms and the moving bit clears 0.2 s after the nut's last
  // encoder edge: 1 s covers both with margin, and a person does not wait on a nut held sliding.
  constexpr double kSlipEnd_s = 1.0;
  read_status_while(
      c,
      [](const Status& x) {
        return x.drive_state == static_cast<std::uint16_t>(reg::DriveState::fault) &&
               (slipped(x.alarm) || stepped_out(x.status_word)) && moving(x);
      },
      kSlipEnd_s);
}

/// What to type when a fault latched again while its reset was confirming.
std::string returned_fault_advice(const Status& s) {
  if (slipped(s.alarm) || stepped_out(s.status_word))
    return "the nut slipped again (still sliding, or a load beyond the coupling's peak): wait "
           "until it stands with that load taken off, then run 'maglead reset --resync'";
  return "its cause persists: remove it (the alarm codes: docs/registers.md, 'alarm_code'), then "
         "run 'maglead reset' again";
}

}  // namespace

std::string reset_command(double alarm, bool step_out_bit) {
  return slipped(alarm) || step_out_bit ? "maglead reset --resync" : "maglead reset";
}

std::optional<std::string> other_owner(Client& c) {
  const auto* owner = reg::find("control_owner");
  const Values v = c.read_range(reg::Table::input_register, owner->address, 3);  // IR 17-19
  const double id = v.at("control_owner");
  constexpr double kRtuMaster = 65535;  // over RTU the one master is this client
  if (id == 0 || (id == kRtuMaster && !c.endpoint().serial.empty())) return std::nullopt;
  const auto ip = static_cast<std::uint32_t>(v.at("control_owner_ipv4"));
  return id == kRtuMaster ? "the RTU master"
         : ip != 0        ? "the client at " + ipv4_text(ip)
                          : "TCP connection " + fmt(id);
}

std::string reset_step(double alarm, double drive_fault_cause, const std::string& command,
                       const char* tail) {
  std::string run = "run '" + command + "'" + tail;
  if (alarm != static_cast<double>(reg::Alarm::drive_fault)) return run;
  const std::string cause = code_name(reg::codes_of("drive_fault_cause"), drive_fault_cause);
  if (cause == "drive_restarted")
    return "restart 'maglead serve' (a drive that restarted is configured only at start; a "
           "reset is refused)";
  if (cause == "drive_silent" || cause == "process_data_lost" || cause == "bus_off")
    return "once the drive answers again (its power and fault display, then 'ip -details "
           "-statistics link show can0' and 'candump can0'; a reset is refused until then), " +
           run;
  return run;
}

namespace {
/// reset_step with the drive fault's cause read from the controller.
std::string reset_step_read(Client& c, double alarm, const std::string& command, const char* tail) {
  const double cause =
      alarm != static_cast<double>(reg::Alarm::drive_fault)
          ? 0.0
          : c.read_range(reg::Table::input_register, reg::find("drive_fault_cause")->address, 1)
                .at("drive_fault_cause");
  return reset_step(alarm, cause, command, tail);
}
}  // namespace

std::string reset_advice(Client& c, double alarm) {
  const auto who = other_owner(c);
  if (!who) return reset_step_read(c, alarm, reset_command_now(c, alarm), " first");
  return "another client owns control (" + *who +
         ", IR 17-19), and the controller takes a reset from it only: it must clear the fault "
         "itself (a fault_reset edge in its control word, then enable 0 -> 1 again before its "
         "next execute), or release control (enable cleared) or close its connection, after "
         "which '" +
         reset_command_now(c, alarm) + "' works";
}

namespace {

/// The alarm by name and meaning; a drive fault with its cause (IR 68) and the drive's own code
/// (IR 69), which say what to check: a silent drive is not cleared by a reset.
std::string alarm_text(Client& c, double alarm) {
  std::string s = fmt(alarm) + " " + code_name(reg::alarm_codes(), alarm) + ": " +
                  code_meaning(reg::alarm_codes(), alarm);
  if (alarm != static_cast<double>(reg::Alarm::drive_fault)) return s;
  const auto* cause = reg::find("drive_fault_cause");
  const Values v = c.read_range(reg::Table::input_register, cause->address, 2);
  const double why = v.at("drive_fault_cause"), code = v.at("drive_error_code");
  if (why == 0) return s;
  const auto codes = reg::codes_of("drive_fault_cause");
  s += "; drive_fault_cause " + fmt(why) + " " + code_name(codes, why) + " (" +
       code_meaning(codes, why) + ")";
  if (code != 0) {
    char b[48];
    std::snprintf(b, sizeof b, "; drive_error_code 0x%04X", static_cast<unsigned>(code));
    s += b;
  }
  return s + "; what to check: docs/cia402.md, 'When a fault stays'";
}

/// The time a watchdog_s takes in words, at its resolution ("0.02 s").
std::string seconds_text(double s) { return si_text(*reg::find("watchdog_ms"), s) + " s"; }

}  // namespace

void check_watchdog(Client& c, const std::string& what) {
  const double w = read_image(c).watchdog_s;
  if (w <= 0 || w >= kShortestWatchdog_s) return;
  throw ClientError(Kind::refused_locally,
                    what + ": refused, nothing sent: watchdog_s " + seconds_text(w) +
                        " is shorter than this tool can feed (it sends the heartbeat every " +
                        seconds_text(kHeartbeatPeriod_s) + " and needs watchdog_s " +
                        seconds_text(kShortestWatchdog_s) + " or more): type 'maglead set " +
                        "watchdog_s " + si_text(*reg::find("watchdog_ms"), kShortestWatchdog_s) +
                        "' first (or 0 to switch it off), or use a PLC that feeds it faster");
}

std::string release_after_fault(Client& c, double alarm) {
  const auto* owner = reg::find("control_owner");
  const double id = c.read_range(reg::Table::input_register, owner->address, 1).at("control_owner");
  if (id != 0) {
    try {  // ours when the controller takes the write; another owner's answers exception 04
      const Image im = read_image(c);
      write_cw(c, static_cast<std::uint16_t>(im.control_word &
                                             ~(bit(reg::kEnable) | bit(reg::kExecute))));
      return "control released (enable cleared; the drive stays in fault): run '" +
             reset_command_now(c, alarm) + "'";
    } catch (const ClientError& e) {
      if (e.kind() != Kind::exception) throw;
    }
  }
  return reset_advice(c, alarm);
}

namespace {

[[noreturn]] void rejected(const char* what, const Status& s) {
  throw ClientError(Kind::rejected, std::string(what) + " rejected by the controller: " +
                                        code_name(reg::reject_codes(), s.reject) + " (" +
                                        code_meaning(reg::reject_codes(), s.reject) + ")");
}

}  // namespace

CommandResult execute(Client& c, reg::Mode mode,
                      const std::vector<std::pair<std::string, double>>& setpoints,
                      const CommandOptions& o) {
  const auto t0 = Clock::now();
  if (o.claim) {
    check_watchdog(c, "execute");
    // Take control the documented way: a previous owner's connection that ended left an
    // owner_lost fault (its reaction has run); clear it, then claim with an enable edge.
    const Status st = read_status(c);
    const bool fault = st.drive_state == static_cast<std::uint16_t>(reg::DriveState::fault);
    if (fault && st.alarm == static_cast<std::uint16_t>(reg::Alarm::owner_lost))
      reset(c, false, o);
    else if (fault)  // any other fault is the operator's to look at and reset
      throw ClientError(Kind::rejected, "execute: the drive is in fault (alarm " +
                                            alarm_text(c, st.alarm) + "); " +
                                            reset_advice(c, st.alarm));
    if (read_status(c).drive_state == static_cast<std::uint16_t>(reg::DriveState::ready))
      enable(c, o);
  }
  const Image im = read_image(c);
  std::uint16_t cw = im.control_word;
  if (!setpoints.empty()) c.write(setpoints);
  // A rising edge needs the bit low first (a previous client may have left it high).
  if (cw & bit(reg::kExecute))
    write_cw(c, cw = static_cast<std::uint16_t>(cw & ~bit(reg::kExecute)));
  cw = static_cast<std::uint16_t>(cw & ~(bit(reg::kFaultReset) | bit(reg::kResync)));
  // The mode and the edge in one request: the loop applies both in the same cycle.
  c.write({{"control_word", cw | bit(reg::kExecute)}, {"mode_command", static_cast<double>(mode)}});
  const Status before = read_status(c);
  Status s = settle(c, before.cycle, im, o, "execute");
  write_cw(c, cw);  // drop execute again: the handshake's falling edge
  if (s.bit(reg::kRejected) && !s.bit(reg::kExecuteAck)) rejected("execute", s);
  if (!s.bit(reg::kExecuteAck) && !s.bit(reg::kExecuteDone))
    throw ClientError(Kind::protocol,
                      "execute: the controller neither acknowledged nor rejected the edge");
  CommandResult r;
  if (!o.wait_done || mode == reg::Mode::idle) {
    r.elapsed_s = since(t0);
    return r;
  }
  for (;;) {
    if (s.bit(reg::kExecuteDone)) {
      r.done = true;
      break;
    }
    if (s.drive_state == static_cast<std::uint16_t>(reg::DriveState::fault))
      throw ClientError(Kind::rejected,
                        "execute: the drive faulted before reaching the target (alarm " +
                            alarm_text(c, s.alarm) + "); " + release_after_fault(c, s.alarm));
    if (s.drive_state != static_cast<std::uint16_t>(reg::DriveState::enabled))
      throw ClientError(Kind::rejected,
                        "execute: the drive was disabled before reaching the target");
    if (o.stop && o.stop()) break;
    if ((s.status_word >> reg::kForceLimited) & 1u)
      if (auto why =
              mode == reg::Mode::force ? limited_before_force(c) : limited_before_position(c))
        throw ClientError(Kind::rejected, "execute: " + *why);
    if (since(t0) > o.done_timeout_s)  // the controller answers: it is its answer, not the line
      throw ClientError(
          Kind::rejected,
          "execute: acknowledged, but " +
              std::string(mode == reg::Mode::force ? "force not reached" : "not in position") +
              " within " + fmt(o.done_timeout_s) + " s: " +
              (mode == reg::Mode::force ? force_not_reached_text(c) : not_in_position_text(c)));
    if (im.watchdog_s > 0) c.write({{"heartbeat", 0}});
    if (o.waiting) o.waiting(c);
    std::this_thread::sleep_for(std::chrono::duration<double>(o.poll_period_s));
    s = read_status(c);
  }
  r.elapsed_s = since(t0);
  return r;
}

namespace {
/// A fault seen after our enable edge: a watchdog or stroke_limit alarm latches only in an
/// enabled drive, so it enabled first and then faulted; control released, and what to type.
[[noreturn]] void enable_faulted(Client& c, double alarm) {
  const bool was_enabled = alarm == static_cast<double>(reg::Alarm::watchdog) ||
                           alarm == static_cast<double>(reg::Alarm::stroke_limit);
  throw ClientError(Kind::rejected,
                    std::string(was_enabled ? "enable: the drive enabled, then faulted"
                                            : "enable: the drive faulted instead of enabling") +
                        " (alarm " + alarm_text(c, alarm) + "); " + release_after_fault(c, alarm));
}
}  // namespace

void enable(Client& c, const CommandOptions& o) {
  check_watchdog(c, "enable");
  const Image im = read_image(c);
  Status s = read_status(c);
  using DS = reg::DriveState;
  // Enabled already: ours only if the controller takes a write from us (the same control word,
  // no edge); another client's control is refused with exception 04, naming it.
  if (s.drive_state == static_cast<std::uint16_t>(DS::enabled)) {
    write_cw(c, im.control_word);
    return;
  }
  // The controller ignores an enable edge outside "ready" without a reason code: say why here.
  if (s.drive_state == static_cast<std::uint16_t>(DS::fault))
    throw ClientError(Kind::rejected, "enable: the drive is in fault (alarm " +
                                          alarm_text(c, s.alarm) + "); " +
                                          reset_advice(c, s.alarm));
  if (s.drive_state != static_cast<std::uint16_t>(DS::ready))
    throw ClientError(Kind::rejected, "enable: the drive is not ready (" +
                                          code_meaning(reg::drive_states(), s.drive_state) + ")");
  std::uint16_t cw = static_cast<std::uint16_t>(
      im.control_word & ~(bit(reg::kExecute) | bit(reg::kFaultReset) | bit(reg::kResync)));
  if (im.control_word & bit(reg::kEnable))
    write_cw(c, static_cast<std::uint16_t>(cw & ~bit(reg::kEnable)));
  write_cw(c, cw | bit(reg::kEnable));
  const auto t0 = Clock::now();
  for (;;) {
    s = read_status(c);
    if (s.drive_state == static_cast<std::uint16_t>(DS::enabled)) return;
    if (s.drive_state == static_cast<std::uint16_t>(DS::fault)) enable_faulted(c, s.alarm);
    if (since(t0) > o.ack_timeout_s)
      throw ClientError(Kind::rejected,
                        "enable: the drive did not enable within " + fmt(o.ack_timeout_s) +
                            " s (state " + code_name(reg::drive_states(), s.drive_state) +
                            (s.alarm ? ", alarm " + alarm_text(c, s.alarm) : std::string()) + ")");
    if (im.watchdog_s > 0) c.write({{"heartbeat", 0}});
    std::this_thread::sleep_for(std::chrono::duration<double>(o.poll_period_s));
  }
}

void disable(Client& c, const CommandOptions& o) {
  const Image im = read_image(c);
  write_cw(c,
           static_cast<std::uint16_t>(im.control_word & ~(bit(reg::kEnable) | bit(reg::kExecute))));
  const auto t0 = Clock::now();
  for (;;) {
    const Status s = read_status(c);
    if (s.drive_state != static_cast<std::uint16_t>(reg::DriveState::enabled)) return;
    if (since(t0) > o.ack_timeout_s)
      throw ClientError(Kind::no_reply,
                        "disable: the drive is still enabled after " + fmt(o.ack_timeout_s) + " s");
    std::this_thread::sleep_for(std::chrono::duration<double>(o.poll_period_s));
  }
}

std::string disable_and_say(Client& c) {
  // Nothing enabled and no fault: nothing to disable, nothing written.
  if (const Status s0 = read_status(c);
      s0.drive_state != static_cast<std::uint16_t>(reg::DriveState::enabled) &&
      s0.drive_state != static_cast<std::uint16_t>(reg::DriveState::fault))
    return "the drive was not enabled: nothing to disable (drive_state " +
           code_name(reg::drive_states(), s0.drive_state) + ")";
  disable(c, {});
  const Status s = read_status(c);
  if (s.drive_state == static_cast<std::uint16_t>(reg::DriveState::fault))
    return "enable cleared; the drive stays in fault (alarm " + alarm_text(c, s.alarm) + "): " +
           reset_step_read(c, s.alarm, reset_command(s.alarm, stepped_out(s.status_word)),
                           " to clear it");
  return "drive disabled: enable cleared, control released (drive_state " +
         code_name(reg::drive_states(), s.drive_state) + ")";
}

void reset(Client& c, bool resync_first, const CommandOptions& o) {
  // A fault under another client's control takes a reset from that owner only: say what it must
  // do before writing (the write would be refused, exception 04, with the generic not_owner text).
  if (const Status s0 = read_status(c);
      s0.drive_state == static_cast<std::uint16_t>(reg::DriveState::fault)) {
    const std::string advice = reset_advice(c, s0.alarm);
    if (advice.starts_with("another client"))
      throw ClientError(Kind::exception,
                        "fault reset refused, nothing sent (not_owner): the drive is in fault "
                        "(alarm " +
                            alarm_text(c, s0.alarm) + "); " + advice);
  }
  wait_for_slip_to_end(c);
  const Image im = read_image(c);
  std::uint16_t cw = static_cast<std::uint16_t>(im.control_word & ~bit(reg::kExecute));
  const auto edge = [&](int b, int ack, int done, const char* what) {
    if (cw & bit(b)) write_cw(c, cw = static_cast<std::uint16_t>(cw & ~bit(b)));
    write_cw(c, cw | bit(b));
    const Status before = read_status(c);
    Status s = settle(c, before.cycle, im, o, what);
    write_cw(c, cw);
    if (s.bit(reg::kRejected) && !s.bit(ack)) {
      // still_faulty after a slip: the command that works for this alarm, not a hint to decode.
      if (s.reject == static_cast<std::uint16_t>(reg::Reject::still_faulty) && !resync_first &&
          (slipped(s.alarm) || stepped_out(s.status_word)))
        throw ClientError(Kind::rejected, std::string(what) + " rejected by the controller: " +
                                              code_name(reg::reject_codes(), s.reject) +
                                              " (alarm " + alarm_text(c, s.alarm) + "): run '" +
                                              reset_command(s.alarm, true) + "'");
      // Refused after a resync: the nut was still slipping when the resync took its lead, or a
      // load beyond the coupling's peak keeps the phase off the band.
      if (s.reject == static_cast<std::uint16_t>(reg::Reject::still_faulty) && resync_first)
        throw ClientError(Kind::rejected,
                          std::string(what) + " rejected by the controller: " +
                              code_name(reg::reject_codes(), s.reject) + " (alarm " +
                              alarm_text(c, s.alarm) +
                              "): the nut has not stood still on the phase's stable band: it "
                              "is still slipping, or a load beyond the coupling's peak holds it "
                              "off the band; wait until it stands with that load taken off, "
                              "then run 'maglead reset --resync' again");
      rejected(what, s);
    }
    if (!s.bit(ack))
      throw ClientError(Kind::protocol,
                        std::string(what) + ": no acknowledgement from the controller");
    // Acknowledged: done once the controller has seen the fault stay away (a drive's own reset
    // takes some cycles); a fault that latched again meanwhile is the answer instead.
    const auto t0 = Clock::now();
    while (!s.bit(done)) {
      if (s.bit(reg::kRejected))
        throw ClientError(Kind::rejected, std::string(what) + " rejected by the controller: " +
                                              code_name(reg::reject_codes(), s.reject) + " (" +
                                              code_meaning(reg::reject_codes(), s.reject) +
                                              "): alarm " + alarm_text(c, s.alarm) + ": " +
                                              returned_fault_advice(s));
      if (since(t0) > o.ack_timeout_s)
        throw ClientError(Kind::no_reply, std::string(what) + ": acknowledged, not done within " +
                                              fmt(o.ack_timeout_s) + " s");
      std::this_thread::sleep_for(std::chrono::duration<double>(o.poll_period_s));
      s = read_status(c);
    }
  };
  if (resync_first) edge(reg::kResync, reg::kResyncAck, reg::kResyncDone, "resync");
  edge(reg::kFaultReset, reg::kResetAck, reg::kResetDone, "fault reset");
}

std::string reset_and_say(Client& c, bool resync_first) {
  // A reset of a healthy drive resets nothing, a resync without a step-out resyncs nothing: say
  // so, send nothing (the controller's own not_stepped_out stays for raw Modbus clients).
  const Status s0 = read_status(c);
  const std::string state = "(drive_state " + code_name(reg::drive_states(), s0.drive_state) + ")";
  if (s0.drive_state != static_cast<std::uint16_t>(reg::DriveState::fault)) {
    if (!resync_first) return "no fault to reset " + state;
    if (!stepped_out(s0.status_word)) return "no step-out to resync and no fault to reset " + state;
  }
  reset(c, resync_first, {});
  return std::string(resync_first ? "resync and " : "") +
         "fault reset done; enable again to resume ('maglead enable', or 'maglead set ...')";
}

}  // namespace maglead::op

namespace maglead::op {

void hold(Client& c, double seconds, const CommandOptions& o, const std::function<bool()>& stop) {
  const Image im = read_image(c);
  const auto t0 = Clock::now();
  while (since(t0) < seconds && !(stop && stop())) {
    const Status s = read_status(c);
    if (s.drive_state == static_cast<std::uint16_t>(reg::DriveState::fault))
      throw ClientError(Kind::rejected, "hold: the drive faulted (alarm " + alarm_text(c, s.alarm) +
                                            "); " + release_after_fault(c, s.alarm));
    if (s.drive_state != static_cast<std::uint16_t>(reg::DriveState::enabled))
      throw ClientError(Kind::rejected, "hold: the drive was disabled");
    if (im.watchdog_s > 0) c.write({{"heartbeat", 0}});
    std::this_thread::sleep_for(
        std::chrono::duration<double>(std::max(o.poll_period_s, kHeartbeatPeriod_s)));
  }
}

}  // namespace maglead::op
