#include "maglead/modbus/modbus_tcp.hpp"

#include "maglead/modbus/framing.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <unordered_map>

namespace maglead::modbus {
namespace {

// A client that does not read its replies is dropped once this much waits for it beyond the
// kernel's send buffer (kSendBuffer, which the kernel doubles): a few hundred replies, not the
// megabytes an autotuned loopback buffer would take while the others wait.
constexpr std::size_t kMaxPendingOut = std::size_t{16} * 1024;
constexpr int kSendBuffer = 32 * 1024;
// Reads per connection per wake-up: one client's stream of requests cannot starve the others.
constexpr int kReadsPerWake = 4;

double mono_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string sys_error(const std::string& what) { return what + ": " + std::strerror(errno); }

}  // namespace

std::pair<std::uint32_t, std::uint32_t> parse_ipv4_cidr(const std::string& text) {
  const auto slash = text.find('/');
  const std::string addr = text.substr(0, slash);
  in_addr a{};
  if (inet_pton(AF_INET, addr.c_str(), &a) != 1)
    throw std::invalid_argument("allow-list entry '" + text +
                                "' is not an IPv4 address or a.b.c.d/len");
  int len = 32;
  if (slash != std::string::npos) {
    try {
      std::size_t used = 0;
      len = std::stoi(text.substr(slash + 1), &used);
      if (used != text.size() - slash - 1) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      len = -1;
    }
    if (len < 0 || len > 32)
      throw std::invalid_argument("allow-list entry '" + text + "': prefix length must be 0..32");
  }
  const std::uint32_t mask = len == 0 ? 0u : ~0u << (32 - len);
  return {ntohl(a.s_addr) & mask, mask};
}

struct TcpServer::Conn {
  int fd = -1;
  std::uint16_t id = 0;
  std::uint32_t ipv4 = 0;
  std::uint8_t in[kMaxTcpAdu * 2];
  std::size_t in_len = 0;
  double frame_started_s = 0.0;  // when the bytes of an incomplete frame began
  double last_activity_s = 0.0;
  // Order of last activity among all connections: last_activity_s is the wake-up's clock, the
  // same for every connection accepted or read in one wake-up, so "idle longest" needs this.
  std::uint64_t activity_order = 0;
  std::string out;
  bool read_closed = false;  // the peer shut down its sending side: answer what came, then close
};

TcpServer::TcpServer(ModbusCore& core, TcpOptions options)
    : core_(core), options_(std::move(options)) {
  for (const auto& a : options_.allow) allow_.push_back(parse_ipv4_cidr(a));
  if (options_.max_connections < 1)
    throw std::invalid_argument("max connections must be at least 1");
  if (options_.port < 0 || options_.port > 65535)
    throw std::invalid_argument("port must be 0..65535");
  if (!(options_.frame_timeout_s > 0))
    throw std::invalid_argument("frame timeout must be positive");
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_port = htons(static_cast<std::uint16_t>(options_.port));
  if (inet_pton(AF_INET, options_.bind_address.c_str(), &sa.sin_addr) != 1)
    throw std::invalid_argument("bind address '" + options_.bind_address +
                                "' is not an IPv4 address");
  listen_fd_ = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (listen_fd_ < 0) throw std::runtime_error(sys_error("socket"));
  const int one = 1;
  setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (bind(listen_fd_, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
    const bool in_use = errno == EADDRINUSE;
    std::string msg =
        sys_error("bind " + options_.bind_address + ":" + std::to_string(options_.port));
    if (in_use)  // most often a second `maglead serve`: say how to run one beside it
      msg +=
          " (another program, perhaps another 'maglead serve', listens there: stop it, or "
          "give this one another port: --port " +
          std::to_string(options_.port + 1) + ")";
    close(listen_fd_);
    throw std::runtime_error(msg);
  }
  if (listen(listen_fd_, 64) != 0) {
    close(listen_fd_);
    throw std::runtime_error(sys_error("listen"));
  }
  socklen_t sl = sizeof sa;
  getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&sa), &sl);
  port_ = ntohs(sa.sin_port);
  epoll_fd_ = epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (epoll_fd_ < 0 || wake_fd_ < 0) throw std::runtime_error(sys_error("epoll/eventfd"));
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.fd = listen_fd_;
  epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, listen_fd_, &ev);
  ev.data.fd = wake_fd_;
  epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &ev);
}

TcpServer::~TcpServer() {
  stop();
  for (int fd : {listen_fd_, epoll_fd_, wake_fd_})
    if (fd >= 0) close(fd);
}

void TcpServer::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { run(); });
}

void TcpServer::stop() {
  if (!running_.exchange(false)) return;
  const std::uint64_t one = 1;
  [[maybe_unused]] auto w = write(wake_fd_, &one, sizeof one);
  if (thread_.joinable()) thread_.join();
}

// The network thread's state: the open connections and what it does with them. Lives on the
// network thread's stack, so nothing here is shared with the loop (it talks to core_ only).
struct TcpServer::Loop {
  explicit Loop(TcpServer& s) : server(s) {}
  TcpServer& server;
  std::unordered_map<int, std::unique_ptr<Conn>> conns;
  std::uint16_t next_id = 1;
  std::uint64_t activity_count = 0;

  void run();
  void drop(Conn& c);
  bool flush(Conn& c);
  bool serve(Conn& c, double now);
  void accept_all(double now);
  bool allowed(std::uint32_t ip) const;
  bool make_room();
  std::uint16_t free_id();
  bool read(Conn& c, double now);
  void on_event(const epoll_event& ev, double now);
  void expire(double now);
  void close_all();
};

void TcpServer::run() { Loop(*this).run(); }

void TcpServer::Loop::run() {
  epoll_event events[64];
  while (server.running_.load(std::memory_order_relaxed)) {
    const int n = epoll_wait(server.epoll_fd_, events, 64, 50);
    const double now = mono_s();
    for (int i = 0; i < n; ++i) on_event(events[i], now);
    expire(now);
  }
  close_all();
}

void TcpServer::Loop::drop(Conn& c) {
  epoll_ctl(server.epoll_fd_, EPOLL_CTL_DEL, c.fd, nullptr);
  close(c.fd);
  server.core_.client_closed(c.id);
  conns.erase(c.fd);
  server.connections_.store(conns.size());
}

// Sends what waits; false: the connection must go.
bool TcpServer::Loop::flush(Conn& c) {
  while (!c.out.empty()) {
    const ssize_t n = send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      c.out.erase(0, static_cast<std::size_t>(n));
    } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      break;
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      return false;
    }
  }
  if (c.read_closed && c.out.empty()) return false;  // every answer is out: close
  epoll_event ev{};
  ev.events = (c.read_closed ? 0u : static_cast<std::uint32_t>(EPOLLIN | EPOLLRDHUP)) |
              (c.out.empty() ? 0u : static_cast<std::uint32_t>(EPOLLOUT));
  ev.data.fd = c.fd;
  epoll_ctl(server.epoll_fd_, EPOLL_CTL_MOD, c.fd, &ev);
  return c.out.size() <= kMaxPendingOut;
}

// Frames every complete ADU in the buffer; false: the stream is broken, close it.
bool TcpServer::Loop::serve(Conn& c, double now) {
  std::size_t off = 0;
  std::uint8_t resp[kMaxTcpAdu];
  for (;;) {
    const TcpFrame f = frame_tcp(c.in + off, c.in_len - off);
    if (f.status == FrameStatus::error) return false;
    if (f.status == FrameStatus::need_more) break;
    std::size_t n = 0;
    if (f.unit_id == server.options_.unit_id || f.unit_id == 0xFF) {
      n = server.core_.handle(ClientInfo{c.id, c.ipv4, false}, f.pdu, f.pdu_size, resp + kMbapSize);
    } else {
      n = ModbusCore::exception(f.pdu[0], Exception::gateway_target_failed, resp + kMbapSize);
    }
    if (n > 0) {
      std::memcpy(resp, c.in + off, 4);  // transaction id, protocol id
      resp[4] = static_cast<std::uint8_t>((n + 1) >> 8);
      resp[5] = static_cast<std::uint8_t>((n + 1) & 0xFF);
      resp[6] = f.unit_id;
      c.out.append(reinterpret_cast<const char*>(resp), kMbapSize + n);
    }
    off += f.size;
  }
  if (off > 0) {
    std::memmove(c.in, c.in + off, c.in_len - off);
    c.in_len -= off;
  }
  c.frame_started_s =
      c.in_len > 0 ? (off > 0 || c.frame_started_s == 0.0 ? now : c.frame_started_s) : 0.0;
  return true;
}

bool TcpServer::Loop::allowed(std::uint32_t ip) const {
  bool ok = server.allow_.empty();
  for (const auto& [net, mask] : server.allow_) ok = ok || (ip & mask) == net;
  return ok;
}

// At the cap, the connection idle longest makes room (never the owner's, nor one with a request
// or a reply under way): idle connections cannot lock the PLC out. False: every one is busy.
bool TcpServer::Loop::make_room() {
  Conn* oldest = nullptr;
  const std::uint16_t owner = server.core_.owner();
  for (auto& [f, other] : conns) {
    if (other->id == owner || other->in_len > 0 || !other->out.empty() || other->read_closed)
      continue;
    if (!oldest || other->activity_order < oldest->activity_order) oldest = other.get();
  }
  if (!oldest) return false;
  drop(*oldest);
  return true;
}

// Connection numbers stay unique among open connections.
std::uint16_t TcpServer::Loop::free_id() {
  const auto taken = [&](std::uint16_t id) {
    for (const auto& [f, other] : conns)
      if (other->id == id) return true;
    return false;
  };
  std::uint16_t id = 0;
  do {
    id = next_id;
    next_id = static_cast<std::uint16_t>(next_id >= 0xFFFE ? 1 : next_id + 1);
  } while (taken(id));
  return id;
}

void TcpServer::Loop::accept_all(double now) {
  for (;;) {
    sockaddr_in peer{};
    socklen_t pl = sizeof peer;
    const int cfd = accept4(server.listen_fd_, reinterpret_cast<sockaddr*>(&peer), &pl,
                            SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (cfd < 0) break;
    const std::uint32_t ip = ntohl(peer.sin_addr.s_addr);
    const bool at_cap = conns.size() >= static_cast<std::size_t>(server.options_.max_connections);
    if (!allowed(ip) || (at_cap && !make_room())) {
      close(cfd);  // refused: not on the allow-list, or every connection is busy
      continue;
    }
    const int one = 1;
    setsockopt(cfd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    setsockopt(cfd, SOL_SOCKET, SO_SNDBUF, &kSendBuffer, sizeof kSendBuffer);
    auto c = std::make_unique<Conn>();
    c->fd = cfd;
    c->ipv4 = ip;
    c->last_activity_s = now;
    c->activity_order = ++activity_count;
    c->id = free_id();
    epoll_event ev{};
    ev.events = EPOLLIN | EPOLLRDHUP;
    ev.data.fd = cfd;
    epoll_ctl(server.epoll_fd_, EPOLL_CTL_ADD, cfd, &ev);
    conns.emplace(cfd, std::move(c));
    server.connections_.store(conns.size());
  }
}

// Reads what came (a few times at most) and answers it; false: the connection must go.
bool TcpServer::Loop::read(Conn& c, double now) {
  for (int reads = 0; reads < kReadsPerWake; ++reads) {
    const ssize_t r = recv(c.fd, c.in + c.in_len, sizeof c.in - c.in_len, 0);
    if (r > 0) {
      c.in_len += static_cast<std::size_t>(r);
      c.last_activity_s = now;
      c.activity_order = ++activity_count;
      if (!serve(c, now)) return false;
      if (c.out.size() > kMaxPendingOut) return true;
    } else if (r == 0) {
      // The peer shut down its sending side (or closed): every complete request read has been
      // answered into c.out; send that, then close. An incomplete frame is dropped: it can
      // never complete.
      c.read_closed = true;
      c.in_len = 0;
      return true;
    } else {
      if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return false;
      if (errno != EINTR) return true;
    }
  }
  return true;
}

void TcpServer::Loop::on_event(const epoll_event& ev, double now) {
  const int fd = ev.data.fd;
  if (fd == server.wake_fd_) return;
  if (fd == server.listen_fd_) {
    accept_all(now);
    return;
  }
  auto it = conns.find(fd);
  if (it == conns.end()) return;
  Conn& c = *it->second;
  bool ok = true;
  if ((ev.events & (EPOLLIN | EPOLLRDHUP)) && !c.read_closed) ok = read(c, now);
  if (ok && (ev.events & EPOLLERR)) ok = false;
  // Both directions gone: nobody can read a reply.
  if (ok && (ev.events & EPOLLHUP) && !(ev.events & EPOLLIN)) ok = false;
  if (ok) ok = flush(c);
  if (!ok) drop(c);
}

// Deadlines: a frame left incomplete, or a connection idle too long, is closed.
void TcpServer::Loop::expire(double now) {
  const TcpOptions& o = server.options_;
  std::vector<Conn*> expired;
  for (auto& [fd, c] : conns) {
    const bool frame_stalled = c->in_len > 0 && now - c->frame_started_s > o.frame_timeout_s;
    const bool idle = o.idle_timeout_s > 0 && now - c->last_activity_s > o.idle_timeout_s;
    const bool half_closed = c->read_closed && now - c->last_activity_s > o.frame_timeout_s;
    if (frame_stalled || idle || half_closed) expired.push_back(c.get());
  }
  for (Conn* c : expired) drop(*c);
}

void TcpServer::Loop::close_all() {
  for (auto& [fd, c] : conns) {
    close(fd);
    server.core_.client_closed(c->id);
  }
  conns.clear();
  server.connections_.store(0);
}

}  // namespace maglead::modbus
