// The server connected over the real DDS transport on loopback (issue 6's ServerTransport and
// ClientTransport, unique topic names): a client's pointer samples reach the haptic tick, its
// forces come back answering them, and the monitor publishes the status.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <memory>
#include <string>

#include "rt/periodic_loop.h"
#include "server/server.h"
#include "server/transport_io.h"
#include "tests/server/server_test_util.h"
#include "transport/client_transport.h"
#include "transport/server_transport.h"

namespace felt {
namespace {

TEST(ServerDds, ClientPressesTheClothAndGetsForcesAndStatus) {
  const transport::TopicNames topics =
      transport::TopicNames::WithAffixes("", "/server_dds_" + std::to_string(getpid()));
  transport::ServerTransportConfig server_config;
  server_config.dds.domain_id = 43;
  server_config.topics = topics;
  transport::DeviceLimits limits;
  limits.device_id = "default";
  server_config.devices.push_back(limits);
  transport::ServerTransport dds(server_config);
  TransportPointerSource source(&dds);
  TransportForceSink sink(&dds);
  ServerOptions options;
  options.apply_realtime = false;
  options.monitor_log = false;
  options.on_report = [&dds](const ServerReport& r) {
    transport::ServerStatusView s;
    s.server_id = "server_dds_test";
    s.haptic_ticks = r.haptic.ticks;
    dds.PublishStatus(s);
  };
  ServerSpec spec = testing_server::SmallCurtain();
  spec.haptic.monitor_period_s = 0.1;
  spec.haptic.safety.ramp_in_s = 0.05;
  Server server(spec, &source, &sink, options);

  transport::ClientTransportConfig client_config;
  client_config.dds.domain_id = 43;
  client_config.topics = topics;
  client_config.device_ids = {"default"};
  transport::ClientTransport client(client_config);
  ASSERT_TRUE(transport::WaitUntil(
      [&] { return client.MatchedPointerReaders() > 0 && client.MatchedForceWriters() > 0; },
      std::chrono::seconds(10)));
  server.Start();
  // Press at ~1 kHz until a force in contact comes back (deadline 5 s).
  const int64_t start = MonotonicNowNs();
  uint64_t seq = 0;
  bool touched = false;
  uint64_t answered = 0;
  while (!touched && MonotonicNowNs() - start < 5'000'000'000) {
    const double ms = static_cast<double>(MonotonicNowNs() - start) * 1e-6;
    transport::PointerSampleView sample;
    sample.seq = ++seq;
    sample.device_time_ns = MonotonicNowNs();
    const Vec3 p = testing_server::PressPosition(ms);
    sample.position_m_D = {p.x(), p.y(), p.z()};
    client.PublishPointer(sample);
    transport::ForceCommandView force;
    if (client.WaitForce(0, std::chrono::milliseconds(1), &force)) {
      answered = force.answers_seq;
      touched = force.in_contact && force.force_N_D[2] > 0.05;
    }
  }
  transport::ServerStatusView status;
  const bool got_status =
      transport::WaitUntil([&] { return client.LatestStatus(&status) && status.haptic_ticks > 0; },
                           std::chrono::seconds(5));
  server.Stop();
  EXPECT_TRUE(touched);
  EXPECT_GT(answered, 0u);
  EXPECT_LE(answered, seq);
  EXPECT_TRUE(got_status);
  EXPECT_GT(server.Report()->contacts, 0u);
  EXPECT_GT(dds.Stats().pointer_accepted, 0u);
}

}  // namespace
}  // namespace felt
