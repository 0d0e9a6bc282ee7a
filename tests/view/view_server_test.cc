// The live view's server (view/view_server.h): the page and three.js over HTTP, the static scene
// as JSON on connect, and binary frames that carry exactly the server's cloth and devices.
#include "view/view_server.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <memory>
#include <vector>
#include <nlohmann/json.hpp>

#include "server/server.h"
#include "tests/server/server_test_util.h"
#include "tests/view/view_test_util.h"
#include "transport/client_transport.h"

namespace felt {
namespace {

using testing_server::Driver;
using testing_server::PressFeed;
using testing_server::SmallCurtain;
using testing_view::ConnectWebSocket;
using testing_view::HttpGet;
using testing_view::RecvMessage;
using testing_view::WsMessage;

float ViewF32(const std::vector<uint8_t>& b, size_t offset) {
  float v = 0;
  std::memcpy(&v, b.data() + offset, 4);
  return v;
}
uint32_t ViewU32(const std::vector<uint8_t>& b, size_t offset) {
  uint32_t v = 0;
  std::memcpy(&v, b.data() + offset, 4);
  return v;
}

TEST(ViewServer, ServesThePageAndDebiansThreeJs) {
  ServerSpec spec = SmallCurtain();
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  Server server(spec, &source, &sink);
  ViewServer view(&server, ViewOptions{});
  ASSERT_GT(view.port(), 0);
  EXPECT_EQ(view.url(), "http://127.0.0.1:" + std::to_string(view.port()) + "/");
  const std::string page = HttpGet(view.port(), "/");
  EXPECT_NE(page.find("200 OK"), std::string::npos) << page.substr(0, 200);
  EXPECT_NE(page.find("<script src=\"three.min.js\">"), std::string::npos);
  const std::string three = HttpGet(view.port(), "/three.min.js");
  EXPECT_NE(three.find("200 OK"), std::string::npos);
  EXPECT_NE(three.find("REVISION=\"111\""), std::string::npos) << "Debian's r111 expected";
  EXPECT_NE(HttpGet(view.port(), "/OrbitControls.js").find("THREE.OrbitControls"),
            std::string::npos);
  EXPECT_NE(HttpGet(view.port(), "/etc/passwd").find("404"), std::string::npos);
}

TEST(ViewServer, MissingPageFilesAreNamed) {
  ServerSpec spec = SmallCurtain();
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  Server server(spec, &source, &sink);
  ViewOptions options;
  options.three_dir = "/nonexistent/three";
  try {
    ViewServer view(&server, options);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/three/three.min.js"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("libjs-three"), std::string::npos) << e.what();
  }
}

TEST(ViewServer, FramesCarryTheClothAndTheDevicesExactly) {
  ServerSpec spec = SmallCurtain();
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  Server server(spec, &source, &sink);
  ViewServer view(&server, ViewOptions{});
  // Press the cloth on a virtual clock (no loop threads), then hold still and look. A frame
  // carries the tap's newest tick and sim frame as the view thread last took them, which may be a
  // few ticks before the last (the thread took the tap, then the ticks ran on while it waited, and
  // the client's join made it send what it held: tick 394 of 400 once in 30 TSan runs on loaded
  // cores). So each tick's device and each frame's cloth are kept, and the frame is compared
  // with the ones it names, exactly.
  server.PublishInitialSnapshot(1'000'000'000'000);
  Driver driver(&server, &source);
  struct TickRecord {
    Vec3 goal, proxy, force;
    int32_t contacts = 0, first_triangle = -1;
  };
  std::vector<TickRecord> by_tick(1);  // by_tick[t]: after haptic tick t (counted from 1)
  std::vector<std::vector<Vec3>> cloth_by_frame(1, server.cloth().x);
  for (int i = 0; i < 400; ++i) {
    driver.Tick(1, PressFeed());
    const ProxyTickResult& r = server.haptic().last_result(0);
    const GodObject& body = server.haptic().proxy_state(0).body;
    by_tick.push_back({r.goal_W_m, r.proxy_W_m, r.force_W_N, body.num_contacts,
                       body.num_contacts > 0 ? body.contacts[0].triangle : -1});
    while (cloth_by_frame.size() <= server.sim_frames()) cloth_by_frame.push_back(server.cloth().x);
  }
  ASSERT_EQ(by_tick.size() - 1, server.haptic().counters().ticks.load());

  const int fd = ConnectWebSocket(view.port());
  ASSERT_GE(fd, 0);
  const WsMessage hello = RecvMessage(fd);
  ASSERT_EQ(hello.opcode, 1);
  const auto doc = nlohmann::json::parse(hello.payload.begin(), hello.payload.end());
  EXPECT_EQ(doc["width"], 16);
  EXPECT_EQ(doc["height"], 16);
  EXPECT_EQ(doc["triangles"].size(), 3u * 2u * 15u * 15u);
  EXPECT_EQ(doc["devices"].size(), 1u);
  EXPECT_EQ(doc["layout"]["header_bytes"], kViewHeaderBytes);

  const WsMessage frame = RecvMessage(fd);
  close(fd);
  ASSERT_EQ(frame.opcode, 2);
  const int32_t n = server.model().num_particles();
  ASSERT_EQ(frame.payload.size(), ViewFrameBytes(n, 1));
  EXPECT_EQ(ViewU32(frame.payload, 0), kViewMagic);
  EXPECT_EQ(ViewU32(frame.payload, 4), kViewVersion | (kViewHeaderBytes << 16));
  EXPECT_EQ(ViewU32(frame.payload, 8), static_cast<uint32_t>(n));
  EXPECT_EQ(ViewU32(frame.payload, 12), 1u);
  double frame_number = 0, tick_number = 0;
  std::memcpy(&frame_number, frame.payload.data() + 32, 8);
  std::memcpy(&tick_number, frame.payload.data() + 40, 8);
  // A sim frame and a tick that happened (the newest, or one the view thread held).
  EXPECT_GE(frame_number, 1.0);
  EXPECT_LE(frame_number, static_cast<double>(server.sim_frames()));
  EXPECT_GE(tick_number, 1.0);
  EXPECT_LE(tick_number, static_cast<double>(by_tick.size() - 1));
  const auto frame_index = static_cast<size_t>(frame_number);
  const auto tick_index = static_cast<size_t>(tick_number);
  ASSERT_LT(frame_index, cloth_by_frame.size());
  ASSERT_LT(tick_index, by_tick.size());
  const std::vector<Vec3>& x = cloth_by_frame[frame_index];
  for (int32_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(ViewF32(frame.payload, kViewHeaderBytes + 4 * (3 * static_cast<size_t>(i) + k)),
                static_cast<float>(x[static_cast<size_t>(i)][k]))
          << "particle " << i << " of sim frame " << frame_index;
    }
  }
  const size_t dev = kViewHeaderBytes + 12 * static_cast<size_t>(n);
  const TickRecord& r = by_tick[tick_index];
  ASSERT_GT(r.force.norm(), 0.01) << "the press should push back (tick " << tick_index << ")";
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(ViewF32(frame.payload, dev + 4 * k), static_cast<float>(r.goal[k])) << tick_index;
    EXPECT_EQ(ViewF32(frame.payload, dev + 12 + 4 * k), static_cast<float>(r.proxy[k]))
        << tick_index;
    EXPECT_EQ(ViewF32(frame.payload, dev + 24 + 4 * k), static_cast<float>(r.force[k]))
        << tick_index;
  }
  ASSERT_GT(r.contacts, 0);
  EXPECT_EQ(ViewF32(frame.payload, dev + 40), static_cast<float>(r.contacts));
  EXPECT_EQ(ViewF32(frame.payload, dev + 4 * (12 + 6)), static_cast<float>(r.first_triangle));
  // The sender counts a frame once its write has returned, which may be after the client has read
  // it (a release run in CI read 0 here): wait for the count, up to 5 s.
  EXPECT_TRUE(
      transport::WaitUntil([&] { return view.stats().frames_sent >= 1u; }, std::chrono::seconds(5)))
      << "frames_sent " << view.stats().frames_sent;
}

TEST(ViewServer, RefusesClientsBeyondTheLimit) {
  ServerSpec spec = SmallCurtain();
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  Server server(spec, &source, &sink);
  ViewOptions options;
  options.max_clients = 1;
  ViewServer view(&server, options);
  const int first = ConnectWebSocket(view.port());
  ASSERT_GE(first, 0);
  ASSERT_EQ(RecvMessage(first).opcode, 1);
  EXPECT_LT(ConnectWebSocket(view.port()), 0);
  close(first);
}

}  // namespace
}  // namespace felt
