// The cloth and proxies as ROS 2 markers, end to end (issue 24): a server on the ROS 2 profile
// with its marker feed (server/ros2_marker_feed.h), driven by a participant that knows only the
// ROS 2 IDL types (a PoseStamped publisher pressing the cloth) and read by a MarkerArray
// subscriber with RViz's default QoS: the triangle count as built, points finite and equal to the
// cloth, the sphere at the proxy with its diameter, the rate at most the configured one. And the
// loops stay allocation-free with observer taps.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "ros2_types.h"
#include "rt/clock.h"
#include "server/ros2_marker_feed.h"
#include "server/server.h"
#include "server/transport_io.h"
#include "tests/alloc_counter.h"
#include "tests/server/server_test_util.h"
#include "tests/test_env.h"
#include "tests/transport/transport_test_util.h"
#include "transport/dds_config.h"
#include "transport/qos.h"
#include "transport/server_transport.h"

namespace felt {
namespace {

using transport::Entity;
using transport::Participant;
using transport::Qos;

// What the test keeps of each MarkerArray received.
struct ReceivedMarkers {
  int64_t receive_ns = 0;  // CLOCK_MONOTONIC at the take
  int64_t stamp_ns = 0;
  std::vector<std::array<double, 3>> points;  // the cloth's
  std::array<double, 3> sphere_m{};
  std::array<double, 3> sphere_scale_m{};
  bool sphere_contact_colour = false;
  bool shape_ok = false;  // two markers: a triangle list (ns felt_cloth, id 0), a sphere
  std::string frame_id;
};

// Takes every MarkerArray waiting on `reader` into `out`.
void TakeMarkerArrays(const Entity& reader, std::vector<ReceivedMarkers>* out) {
  for (;;) {
    void* ptrs[1] = {nullptr};
    dds_sample_info_t info{};
    if (dds_take(reader.get(), ptrs, &info, 1, 1) != 1) return;
    if (info.valid_data) {
      const auto* m = static_cast<const visualization_msgs_msg_dds__MarkerArray_*>(ptrs[0]);
      ReceivedMarkers r;
      r.receive_ns = MonotonicNowNs();
      if (m->markers._length == 2) {
        const visualization_msgs_msg_dds__Marker_& cloth = m->markers._buffer[0];
        const visualization_msgs_msg_dds__Marker_& sphere = m->markers._buffer[1];
        r.shape_ok = cloth.type == 11 && std::string(cloth.ns) == "felt_cloth" && cloth.id == 0 &&
                     sphere.type == 2 && std::string(sphere.ns) == "felt_proxy" && sphere.id == 0;
        r.stamp_ns = transport::Ros2StampNs(cloth.header.stamp.sec, cloth.header.stamp.nanosec);
        r.frame_id = cloth.header.frame_id;
        for (uint32_t i = 0; i < cloth.points._length; ++i) {
          const geometry_msgs_msg_dds__Point_& p = cloth.points._buffer[i];
          r.points.push_back({p.x, p.y, p.z});
        }
        r.sphere_m = {sphere.pose.position.x, sphere.pose.position.y, sphere.pose.position.z};
        r.sphere_scale_m = {sphere.scale.x, sphere.scale.y, sphere.scale.z};
        r.sphere_contact_colour = sphere.color.r > 0.5f && sphere.color.g < 0.5f;
      }
      out->push_back(std::move(r));
    }
    (void)dds_return_loan(reader.get(), ptrs, 1);
  }
}

TEST(ServerRos2Markers, ARos2SubscriberSeesTheClothAndTheProxyPressingIt) {
  using namespace ::felt::transport::testing;
  using transport::WaitUntil;
  const std::string ns = "/felt" + UniqueSuffix();
  constexpr double kRateHz = 20.0;
  transport::ServerTransportConfig config;
  config.dds = TestDds();
  config.topics = UniqueTopics();
  config.devices = {TestDevice("default")};
  config.devices[0].profile = transport::TransportProfile::kRos2;
  config.devices[0].ros2.pose = ns + "/measured_cp";
  config.devices[0].ros2.twist = "";
  config.devices[0].ros2.wrench = ns + "/servo_cf";
  config.ros2_markers.topic = ns + "/markers";
  config.ros2_markers.rate_hz = kRateHz;
  transport::ServerTransport dds(config);
  ASSERT_TRUE(dds.markers_enabled());
  TransportPointerSource source(&dds);
  TransportForceSink sink(&dds);
  ServerOptions options;
  options.apply_realtime = false;
  options.monitor_log = false;
  ServerSpec spec = testing_server::SmallCurtain();
  spec.haptic.safety.ramp_in_s = 0.05;
  Server server(spec, &source, &sink, options);
  Ros2MarkerFeed feed(&server, &dds, config.ros2_markers);

  // The ROS 2 side: a driver's pose publisher (ROS 2 default QoS) and RViz's marker subscription
  // (reliable, volatile, keep-last 5).
  Participant ros(AcquireDomain(TestDds()));
  const Entity pose_topic =
      CreateTopic(ros, &geometry_msgs_msg_dds__PoseStamped__desc, "rt" + ns + "/measured_cp");
  const Entity marker_topic =
      CreateTopic(ros, &visualization_msgs_msg_dds__MarkerArray__desc, "rt" + ns + "/markers");
  Qos qos(dds_create_qos());
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 10);
  const Entity pose_writer = CreateWriter(ros, pose_topic, qos.get(), "pose");
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 5);
  const Entity marker_reader = CreateReader(ros, marker_topic, qos.get(), nullptr, "rviz");
  ASSERT_TRUE(WaitUntil(
      [&] { return dds.MatchedPointerWriters() >= 1 && dds.MatchedMarkerReaders() >= 1; }, kWait));

  const int64_t wall_start_ns = WallNowNs();
  server.Start();
  feed.Start();
  // Press at ~1 kHz (PressPosition, device frame) for 1.5 s, taking the markers as they come.
  std::vector<ReceivedMarkers> got;
  geometry_msgs_msg_dds__PoseStamped_ pose{};
  char frame[] = "device";
  pose.header.frame_id = frame;
  pose.pose.orientation.w = 1.0;
  const int64_t start_ns = MonotonicNowNs();
  int64_t next_ns = start_ns;
  while (MonotonicNowNs() - start_ns < 1'500'000'000) {
    const double ms = static_cast<double>(MonotonicNowNs() - start_ns) * 1e-6;
    const Vec3 p = testing_server::PressPosition(ms);
    transport::Ros2StampOf(MonotonicNowNs(), &pose.header.stamp.sec, &pose.header.stamp.nanosec);
    pose.pose.position = {p.x(), p.y(), p.z()};
    (void)dds_write(pose_writer.get(), &pose);
    TakeMarkerArrays(marker_reader, &got);
    next_ns += 1'000'000;
    std::this_thread::sleep_until(std::chrono::steady_clock::time_point(
        std::chrono::nanoseconds(std::max(next_ns, MonotonicNowNs()))));
  }
  const int64_t end_ns = MonotonicNowNs();
  feed.Stop();
  server.Stop();
  TakeMarkerArrays(marker_reader, &got);

  // Every array: the shape as built, 3 points x 2 (W-1)(H-1) triangles, all finite; the sphere's
  // diameter; the frame; stamps from the wall clock of the run.
  const size_t triangles = 2u * (spec.sim.cloth.width - 1u) * (spec.sim.cloth.height - 1u);
  ASSERT_EQ(server.model().triangles.size(), triangles);
  ASSERT_FALSE(got.empty());
  const double diameter_m = 2.0 * spec.devices[0].radius_m;
  bool contact_seen = false;
  std::set<int64_t> stamps;
  for (const ReceivedMarkers& r : got) {
    ASSERT_TRUE(r.shape_ok);
    ASSERT_EQ(r.points.size(), 3u * triangles);
    for (const auto& p : r.points) {
      ASSERT_TRUE(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]));
    }
    EXPECT_EQ(r.sphere_scale_m[0], diameter_m);
    EXPECT_EQ(r.sphere_scale_m[2], diameter_m);
    EXPECT_EQ(r.frame_id, "world");
    EXPECT_GE(r.stamp_ns, wall_start_ns);
    EXPECT_LE(r.stamp_ns, WallNowNs());
    contact_seen = contact_seen || r.sphere_contact_colour;
    stamps.insert(r.stamp_ns);
  }
  EXPECT_TRUE(contact_seen) << "the proxy never showed contact in " << got.size() << " arrays";
  EXPECT_EQ(stamps.size(), got.size()) << "an array was received twice";
  // The rate: at most the configured one (loose: a 25 % margin and one for the edges), and
  // under no sanitizer at least a third of it.
  const double run_s = static_cast<double>(end_ns - start_ns) * 1e-9;
  const double rate_hz = static_cast<double>(got.size()) / run_s;
  EXPECT_LE(static_cast<double>(got.size()), 1.25 * kRateHz * run_s + 1.0) << rate_hz << " Hz";
  if (!felt::testing::Sanitized()) {
    EXPECT_GE(rate_hz, kRateHz / 3.0);
  }
  EXPECT_EQ(feed.published(), dds.Stats().markers_published);

  // One more array after the loops stopped: its points are the cloth's particles (float32, as
  // the tap holds them) triangle by triangle, its sphere the proxy's centre.
  const int64_t stamp_ns = WallNowNs();
  ASSERT_TRUE(feed.PublishOnce(stamp_ns));
  const size_t before = got.size();
  ASSERT_TRUE(WaitUntil(
      [&] {
        TakeMarkerArrays(marker_reader, &got);
        return got.size() > before && got.back().stamp_ns == stamp_ns;
      },
      kWait));
  const ReceivedMarkers& last = got.back();
  const ClothState& cloth = server.cloth();
  for (size_t t = 0; t < triangles; ++t) {
    for (size_t k = 0; k < 3; ++k) {
      const Vec3& x = cloth.x[static_cast<size_t>(server.model().triangles[t][k])];
      for (int a = 0; a < 3; ++a) {
        ASSERT_EQ(last.points[3 * t + k][static_cast<size_t>(a)],
                  static_cast<double>(static_cast<float>(x[a])))
            << "triangle " << t << " vertex " << k;
      }
    }
  }
  const Vec3& proxy = server.haptic().last_result(0).proxy_W_m;
  EXPECT_EQ(last.sphere_m[0], proxy.x());
  EXPECT_EQ(last.sphere_m[1], proxy.y());
  EXPECT_EQ(last.sphere_m[2], proxy.z());
  EXPECT_GT(server.Report()->contacts, 0u);
}

// ros2_markers_device: the markers in that device's frame, where its driver's pose is: the
// proxy's centre is WorldToDevice of the proxy, the cloth's points WorldToDevice of the
// particles, the sphere's diameter divided by the device's scale.
TEST(ServerRos2Markers, InADevicesFrameTheWorkspaceMapIsUndone) {
  using testing_server::Driver;
  DeviceSpec device = testing_server::DeviceAt("left", Vec3(0.05, -0.02, 0.1));
  device.scale = 2.5;
  device.rotation_WD = Eigen::AngleAxisd(0.7, Vec3(0.2, 1.0, -0.3).normalized()).toRotationMatrix();
  ServerSpec spec = testing_server::SmallCurtain({device});
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  ServerOptions options;
  options.apply_realtime = false;
  options.monitor_log = false;
  Server server(spec, &source, &sink, options);
  ViewTap* view = server.EnableViewTap();  // the same copies as the feed's tap, to compare with
  transport::ServerTransportConfig config;
  config.dds = transport::testing::TestDds();
  config.topics = transport::testing::UniqueTopics();
  config.devices = {transport::testing::TestDevice("left")};
  config.ros2_markers.enabled = false;  // the array is built; nothing is published
  config.ros2_markers.device = "left";
  transport::ServerTransport dds(config);
  Ros2MarkerFeed feed(&server, &dds, config.ros2_markers);
  Driver driver(&server, &source);
  for (int i = 0; i < 200; ++i) driver.Tick(1, testing_server::PressFeed());
  EXPECT_FALSE(feed.PublishOnce(WallNowNs()));  // markers off: not published
  const ros2::MarkerArray& a = feed.markers();
  const Vec3 proxy_D = WorldToDevice(device, server.haptic().last_result(0).proxy_W_m);
  EXPECT_NEAR(a.markers[1].pose.position.x, proxy_D.x(), 1e-12);
  EXPECT_NEAR(a.markers[1].pose.position.y, proxy_D.y(), 1e-12);
  EXPECT_NEAR(a.markers[1].pose.position.z, proxy_D.z(), 1e-12);
  EXPECT_NEAR(a.markers[1].scale.x, 2.0 * device.radius_m / 2.5, 1e-15);
  ASSERT_TRUE(view->cloth.Acquire());
  const std::vector<float>& xyz = view->cloth.read_slot().xyz_m;
  for (size_t t = 0; t < server.model().triangles.size(); ++t) {
    for (size_t k = 0; k < 3; ++k) {
      const size_t v = 3 * static_cast<size_t>(server.model().triangles[t][k]);
      const Vec3 x_D = WorldToDevice(device, Vec3(xyz[v], xyz[v + 1], xyz[v + 2]));
      const ros2::Vector3& p = a.markers[0].points[3 * t + k];
      ASSERT_NEAR(p.x, x_D.x(), 1e-12) << t;
      ASSERT_NEAR(p.y, x_D.y(), 1e-12) << t;
      ASSERT_NEAR(p.z, x_D.z(), 1e-12) << t;
    }
  }
}

TEST(ServerRos2Markers, TheLoopsFillObserverTapsWithoutAllocating) {
  using testing_server::Driver;
  ServerSpec spec = testing_server::SmallCurtain();
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  ServerOptions options;
  options.apply_realtime = false;
  options.monitor_log = false;
  Server server(spec, &source, &sink, options);
  ViewTap* view = server.EnableViewTap();
  ViewTap* markers = server.AddObserverTap();
  ASSERT_NE(view, markers);
  Driver driver(&server, &source);
  auto feed = testing_server::PressFeed();
  for (int i = 0; i < 300; ++i) driver.Tick(1, feed);
  uint64_t allocations = 0;
  int64_t now = driver.now_ns();
  for (int i = 0; i < 1000; ++i) {
    PointerInput in;
    in.seq = 100000 + static_cast<uint64_t>(i);
    in.receive_time_ns = now;
    in.p_D_m = testing_server::PressPosition(1000.0);
    source.Set(0, in);
    AllocationGuard guard;
    if (i % 16 == 0) server.SimFrame(1.0 / 60.0, now);
    server.HapticTick(now, 1e-3);
    allocations += guard.allocations();
    now += testing_server::kTickNs;
  }
  EXPECT_EQ(allocations, 0u);
  // Both observers see the same newest tick and frame.
  ASSERT_TRUE(view->devices.Acquire());
  ASSERT_TRUE(markers->devices.Acquire());
  EXPECT_EQ(view->devices.read_slot().tick, markers->devices.read_slot().tick);
  ASSERT_TRUE(markers->cloth.Acquire());
  EXPECT_EQ(markers->cloth.read_slot().frame, server.sim_frames());
  EXPECT_EQ(markers->cloth.read_slot().xyz_m[0], static_cast<float>(server.cloth().x[0][0]));
  // Taps are set-up: none after the threads start, and a bounded number.
  for (size_t i = 2; i < Server::kMaxObserverTaps; ++i) (void)server.AddObserverTap();
  EXPECT_THROW((void)server.AddObserverTap(), std::length_error);
}

}  // namespace
}  // namespace felt
