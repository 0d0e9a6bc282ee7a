#pragma once
// The live view (issue 25, docs/view.md): an HTTP + WebSocket server (civetweb, Debian's
// libcivetweb-dev) that serves a three.js page and streams the cloth, the devices and the loops'
// timing of a running Server at up to 60 Hz.
//
// Threads (none of them a loop's): civetweb's workers answer HTTP and hold each WebSocket; one
// view thread reads the server's ViewTap (server/view_tap.h, the tap's only reader) and its
// lock-free statistics, builds one binary frame and offers it to every client; one sender thread
// per client writes the newest frame it was offered. Each client has a one-frame slot: a frame
// not yet taken when the next is offered is replaced (counted as dropped), so a slow or stalled
// browser holds at most two frames (the slot and the one being written) and never slows the
// loops, which only ever write their tap.
//
// Wire format (little-endian): on connect one text message, the static scene as JSON (StaticJson);
// then binary frames of kViewHeaderBytes of header, float32 positions [3 n], float32 device
// blocks [kViewDeviceFloats per device] and float32 statistics [kViewStatsFloats] (docs/view.md).
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "base/non_copyable.h"
#include "server/server.h"

namespace felt {

/// "FELV" read as a little-endian uint32: the first 4 bytes of every binary frame.
inline constexpr uint32_t kViewMagic = 0x564C4546;
/// The binary frame format's version.
inline constexpr uint16_t kViewVersion = 1;
/// Header bytes before the positions (a multiple of 8: the float arrays stay aligned).
inline constexpr uint32_t kViewHeaderBytes = 48;
/// Floats per device block: goal[3] proxy[3] force[3] |force| contacts fresh, then per contact
/// (kMaxConstraintPlanes of them) point[3] normal[3] triangle pad.
inline constexpr uint32_t kViewDeviceFloats = 36;
/// Floats of statistics: haptic lateness p99 and max [us], sim frame p50 and max [ms] over the
/// last window, haptic ticks/s, sim frames/s, two reserved.
inline constexpr uint32_t kViewStatsFloats = 8;

/// Bytes of one binary frame for `particles` particles and `devices` devices.
size_t ViewFrameBytes(int32_t particles, uint32_t devices);

/// How the view serves.
struct ViewOptions {
  uint16_t port = 0;               ///< TCP port; 0 picks a free one (see ViewServer::port)
  std::string bind = "127.0.0.1";  ///< address to listen on ("0.0.0.0": every interface)
  double rate_hz = 60.0;           ///< frames per second at most, > 0
  std::string www_dir;             ///< the page's files ("" = this source tree's view/www)
  std::string three_dir = "/usr/share/javascript/three";  ///< Debian's libjs-three
  /// civetweb's request_timeout_ms (ms); a WebSocket write to a client that stops reading was
  /// not seen to give up within 3 s (docs/view.md): it ends when the peer reads or goes, or the
  /// view stops.
  int send_timeout_ms = 2000;
  int max_clients = 8;         ///< WebSocket clients at once (each holds a civetweb worker)
};

/// The view's counters (any thread).
struct ViewStats {
  uint64_t frames_built = 0;      ///< frames built by the view thread
  uint64_t frames_sent = 0;       ///< frames written to clients (all clients)
  uint64_t frames_dropped = 0;    ///< frames replaced in a client's slot before it was taken
  uint64_t bytes_sent = 0;        ///< bytes written to clients (all clients, frames and JSON)
  uint64_t clients = 0;           ///< clients connected now
  uint64_t clients_total = 0;     ///< clients ever accepted
  uint64_t clients_given_up = 0;  ///< clients whose write failed or timed out
  uint64_t queued_bytes = 0;      ///< bytes held for clients now (slots + frames being written)
  uint64_t max_queued_bytes = 0;  ///< the most queued_bytes seen
};

/// The static scene as the page receives it on connect (JSON): cloth size, triangles, rest
/// spacing, obstacles, devices (id, proxy radius), rates and the frame layout. Allocates.
std::string StaticJson(const Server& server);

/// The live view of one Server. Construction starts serving (the server may be running or not);
/// destruction stops the view thread and the HTTP server, closing every client.
class ViewServer : NonCopyable {
 public:
  /// Serves `server` (which must outlive this) with `options`: enables its ViewTap (so construct
  /// before server->Start(), or while the caller drives its loops) and starts the HTTP server and
  /// the view thread. Throws std::runtime_error when the address cannot be bound or a file of the
  /// page is missing (naming it), std::invalid_argument for a bad option.
  ViewServer(Server* server, ViewOptions options);
  /// Stops the view thread and the HTTP server.
  ~ViewServer();

  /// The TCP port it listens on.
  uint16_t port() const;
  /// "http://ADDR:PORT/" (ADDR the bind address; 0.0.0.0 shown as this host's name).
  std::string url() const;
  /// A copy of the counters.
  ViewStats stats() const;

  struct Impl;  ///< civetweb state, clients and threads (view_server.cc)

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace felt
