#pragma once
// Modbus TCP server: one network thread, epoll over non-blocking sockets, MBAP framing per
// connection with a deadline for a started frame, an idle timeout, a connection cap (the
// connection idle longest makes room), a bounded output buffer per client and an IPv4
// allow-list, so a slow, half-open or broken client never delays the others. A half-closed
// connection gets every complete request it sent answered before it is closed.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "maglead/modbus/modbus_core.hpp"

namespace maglead::modbus {

struct TcpOptions {
  std::string bind_address = "127.0.0.1";
  int port = 1502;               // 0: any free port (see TcpServer::port())
  std::uint8_t unit_id = 1;      // also answered: 255 (the TCP "no unit" id)
  int max_connections = 32;      // at the cap, the connection idle longest makes room
  double frame_timeout_s = 1.0;  // a started frame must complete within this
  // Close a connection with no request for this long (0: never). Any polling client is far
  // inside it; a client gone without a FIN (cable pulled, crash behind NAT) is found, and an
  // owner that vanished loses control (its fault reaction) within a minute even without a
  // communication watchdog.
  double idle_timeout_s = 60.0;
  std::vector<std::string> allow;  // IPv4 "a.b.c.d" or "a.b.c.d/len"; empty: everyone
};

class TcpServer {
 public:
  /// Binds and listens; throws std::runtime_error (address in use, bad allow entry …).
  TcpServer(ModbusCore& core, TcpOptions options);
  ~TcpServer();
  TcpServer(const TcpServer&) = delete;
  TcpServer& operator=(const TcpServer&) = delete;

  int port() const { return port_; }
  void start();
  void stop();
  std::size_t connections() const { return connections_.load(); }

 private:
  struct Conn;
  struct Loop;  // the network thread's connections and their handling
  void run();
  ModbusCore& core_;
  TcpOptions options_;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> allow_;  // address, mask
  int listen_fd_ = -1, epoll_fd_ = -1, wake_fd_ = -1, port_ = 0;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<std::size_t> connections_{0};
};

/// Parses an allow-list entry; throws std::invalid_argument naming it.
std::pair<std::uint32_t, std::uint32_t> parse_ipv4_cidr(const std::string& text);

}  // namespace maglead::modbus
