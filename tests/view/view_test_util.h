#pragma once
// The live view's tests (tests/view/): a raw WebSocket client over a TCP socket (RFC 6455
// handshake, unmasked server frames), and a small HTTP GET.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace felt::testing_view {

/// A TCP connection to 127.0.0.1:`port` with `timeout_ms` on reads (-1 when it fails) and, when
/// `receive_buffer` > 0, that SO_RCVBUF (set before connecting, so the window starts small).
inline int ConnectLocal(uint16_t port, int timeout_ms = 5000, int receive_buffer = 0) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  if (receive_buffer > 0) {
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof(receive_buffer));
  }
  timeval tv{timeout_ms / 1000, (timeout_ms % 1000) * 1000};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

/// Writes all of `text`; false on error.
inline bool SendAll(int fd, const std::string& text) {
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = send(fd, text.data() + done, text.size() - done, MSG_NOSIGNAL);
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

/// Reads exactly `n` bytes into `out`; false on error, timeout or end of stream.
inline bool RecvExactly(int fd, size_t n, std::vector<uint8_t>* out) {
  out->resize(n);
  size_t done = 0;
  while (done < n) {
    const ssize_t r = recv(fd, out->data() + done, n - done, 0);
    if (r <= 0) return false;
    done += static_cast<size_t>(r);
  }
  return true;
}

/// Reads up to the end of the HTTP head ("\r\n\r\n"), byte by byte ("" on error).
inline std::string RecvHead(int fd) {
  std::string head;
  char c = 0;
  while (head.size() < 16384 && recv(fd, &c, 1, 0) == 1) {
    head.push_back(c);
    if (head.size() >= 4 && head.compare(head.size() - 4, 4, "\r\n\r\n") == 0) return head;
  }
  return "";
}

/// Connects and upgrades to a WebSocket on `path` (SO_RCVBUF `receive_buffer` when > 0); returns
/// the socket (-1 when refused).
inline int ConnectWebSocket(uint16_t port, const std::string& path = "/ws", int receive_buffer = 0) {
  const int fd = ConnectLocal(port, 5000, receive_buffer);
  if (fd < 0) return -1;
  const std::string request =
      "GET " + path +
      " HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n"
      "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
      "Sec-WebSocket-Version: 13\r\n\r\n";
  if (!SendAll(fd, request) || RecvHead(fd).find(" 101 ") == std::string::npos) {
    close(fd);
    return -1;
  }
  return fd;
}

/// One WebSocket message from the server: its opcode (1 text, 2 binary) and payload.
struct WsMessage {
  int opcode = -1;  ///< -1: nothing read (error or timeout)
  std::vector<uint8_t> payload;
};

/// Reads the next data message (skipping ping/pong frames; a server's frames are not masked).
inline WsMessage RecvMessage(int fd) {
  for (;;) {
    WsMessage m;
    std::vector<uint8_t> head;
    if (!RecvExactly(fd, 2, &head)) return m;
    const int opcode = head[0] & 0x0F;
    uint64_t length = head[1] & 0x7F;
    std::vector<uint8_t> ext;
    if (length == 126) {
      if (!RecvExactly(fd, 2, &ext)) return m;
      length = (uint64_t{ext[0]} << 8) | ext[1];
    } else if (length == 127) {
      if (!RecvExactly(fd, 8, &ext)) return m;
      length = 0;
      for (int i = 0; i < 8; ++i) length = (length << 8) | ext[static_cast<size_t>(i)];
    }
    if (!RecvExactly(fd, length, &m.payload)) return m;
    if (opcode == 0x9 || opcode == 0xA) continue;  // ping, pong
    m.opcode = opcode;
    return m;
  }
}

/// GET `path` from 127.0.0.1:`port`: the whole response, head and body ("" on error).
inline std::string HttpGet(uint16_t port, const std::string& path) {
  const int fd = ConnectLocal(port);
  if (fd < 0) return "";
  std::string response;
  if (SendAll(fd, "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")) {
    char buffer[65536];
    ssize_t n = 0;
    while ((n = recv(fd, buffer, sizeof(buffer), 0)) > 0) {
      response.append(buffer, static_cast<size_t>(n));
    }
  }
  close(fd);
  return response;
}

}  // namespace felt::testing_view
