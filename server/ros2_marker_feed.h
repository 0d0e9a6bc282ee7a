#pragma once
// The cloth and the proxies as ROS 2 markers at up to 30 Hz (issue 24): a thread of its own reads
// an observer tap of the server (server/view_tap.h: the loops copy the cloth each frame and the
// devices each tick into preallocated triple-buffer slots, one atomic exchange each, never waiting
// on this thread), builds one visualization_msgs/MarkerArray (ros2/markers.h) and publishes it
// through the transport (ServerTransport::PublishMarkers) on absolute deadlines at
// Ros2MarkerSettings::rate_hz. The haptic tick and the sim frame never allocate, lock, log or
// block for it; without the feed (Felt's profile, or ros2_markers = false) no tap exists and the
// loops copy nothing.
//
// Stamp: the wall clock (ROS time) when the array is built. Frame: Ros2MarkerSettings::frame_id,
// positions in Felt's world frame or, with Ros2MarkerSettings::device, in that device's frame.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

#include "base/non_copyable.h"
#include "ros2/markers.h"
#include "server/server.h"
#include "transport/server_transport.h"

namespace felt {

/// The marker feed of one server and its transport. Construction is set-up (allocates; takes an
/// observer tap, so before Server::Start); Start() launches the thread, Stop() joins it.
class Ros2MarkerFeed : NonCopyable {
 public:
  /// `server` and `transport` must outlive the feed; `settings` as validated by the transport
  /// (rate_hz > 0; device "" or a device id of the server's spec). Throws std::logic_error when
  /// the server is running, std::invalid_argument for a device the server does not have.
  Ros2MarkerFeed(Server* server, transport::ServerTransport* transport,
                 const transport::Ros2MarkerSettings& settings);
  /// Stops and joins the thread.
  ~Ros2MarkerFeed();

  /// Starts the publishing thread (once).
  void Start();
  /// Stops and joins it (idempotent).
  void Stop();

  /// One publication: takes the newest cloth and devices from the tap, fills, stamps with
  /// `wall_ns` [ns since 1970] and publishes. What the thread runs each period; public for tests
  /// (then not while the thread runs). Returns PublishMarkers' result.
  bool PublishOnce(int64_t wall_ns);

  /// The array as last built (the feed's thread, or a test after PublishOnce).
  const ros2::MarkerArray& markers() const { return markers_; }
  /// Publications that succeeded. Any thread.
  uint64_t published() const { return published_.load(std::memory_order_relaxed); }

 private:
  void Run();

  Server* server_;
  transport::ServerTransport* transport_;
  ViewTap* tap_;
  double period_s_;
  ros2::MarkerStyle style_;
  ros2::MarkerMap map_;
  std::vector<double> radius_m_;  // [devices] proxy radii, world m
  ros2::MarkerArray markers_;
  std::atomic<uint64_t> published_{0};
  std::atomic<bool> stop_{false};
  std::mutex mutex_;  // the thread's sleep only
  std::condition_variable wake_;
  std::thread thread_;
};

}  // namespace felt
