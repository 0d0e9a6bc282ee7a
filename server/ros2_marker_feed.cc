#include "server/ros2_marker_feed.h"

#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <string>

#include "rt/clock.h"

namespace felt {

Ros2MarkerFeed::Ros2MarkerFeed(Server* server, transport::ServerTransport* transport,
                               const transport::Ros2MarkerSettings& settings)
    : server_(server),
      transport_(transport),
      tap_(server->AddObserverTap()),
      period_s_(1.0 / settings.rate_hz) {
  const ServerSpec& spec = server->spec();
  style_.frame_id = settings.frame_id;
  // Markers outlive three periods without an update, at least a second: RViz drops them soon
  // after Felt stops, never between two publications.
  const double lifetime_s = std::max(1.0, 3.0 * period_s_);
  style_.lifetime =
      ros2::Duration{static_cast<int32_t>(lifetime_s),
                     static_cast<uint32_t>((lifetime_s - static_cast<int32_t>(lifetime_s)) * 1e9)};
  for (const DeviceSpec& d : spec.devices) radius_m_.push_back(d.radius_m);
  // The map: identity (world), or the device's inverse workspace map p_D = R_WD^T (p_W -
  // offset_W) / scale (proxy/proxy_spec.h MapWorldToDevice), sizes / scale.
  if (!settings.device.empty()) {
    const DeviceSpec* device = nullptr;
    for (const DeviceSpec& d : spec.devices) {
      if (d.id == settings.device) device = &d;
    }
    if (device == nullptr) {
      throw std::invalid_argument("ros2_markers_device '" + settings.device +
                                  "': not a device of the server");
    }
    const Eigen::Matrix3d a = device->rotation_WD.transpose() / device->scale;
    const Vec3 b = -(a * device->offset_W_m);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) map_.linear[static_cast<size_t>(3 * r + c)] = a(r, c);
      map_.offset[static_cast<size_t>(r)] = b[r];
    }
    map_.size_scale = 1.0 / device->scale;
  }
  markers_ = ros2::MakeMarkerArray(server->model().triangles.size(), spec.devices.size(), style_);
}

Ros2MarkerFeed::~Ros2MarkerFeed() { Stop(); }

void Ros2MarkerFeed::Start() {
  if (thread_.joinable()) return;
  stop_.store(false);
  thread_ = std::thread([this] { Run(); });
}

void Ros2MarkerFeed::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_.store(true);
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool Ros2MarkerFeed::PublishOnce(int64_t wall_ns) {
  // The newest cloth and devices (or those already held when nothing newer was published).
  tap_->cloth.Acquire();
  tap_->devices.Acquire();
  const ViewCloth& cloth = tap_->cloth.read_slot();
  const ViewDevices& devices = tap_->devices.read_slot();
  ros2::FillClothMarker(cloth.xyz_m, server_->model().triangles, map_, &markers_.markers[0]);
  for (size_t i = 0; i < radius_m_.size(); ++i) {
    const ViewDevice& d = devices.devices[i];
    ros2::FillProxyMarker({d.proxy_W_m.x(), d.proxy_W_m.y(), d.proxy_W_m.z()}, radius_m_[i],
                          d.num_contacts > 0, map_, style_, &markers_.markers[1 + i]);
  }
  ros2::StampMarkers(ros2::TimeFromNs(wall_ns), &markers_);
  const bool ok = transport_->PublishMarkers(markers_);
  if (ok) published_.fetch_add(1, std::memory_order_relaxed);
  return ok;
}

void Ros2MarkerFeed::Run() {
  // Absolute deadlines on the steady clock; a late round skips the periods it missed.
  pthread_setname_np(pthread_self(), "felt-markers");
  using Clock = std::chrono::steady_clock;
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period_s_));
  auto next = Clock::now();
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stop_.load()) {
    lock.unlock();
    (void)PublishOnce(WallNowNs());
    lock.lock();
    next += period;
    const auto now = Clock::now();
    while (next <= now) next += period;
    wake_.wait_until(lock, next, [this] { return stop_.load(); });
  }
}

}  // namespace felt
