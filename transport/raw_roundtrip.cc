#include "transport/raw_roundtrip.h"

#include <poll.h>
#include <time.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <exception>
#include <stdexcept>
#include <string>

#include "base/process.h"
#include "felt_types.h"
#include "transport/client_transport.h"
#include "transport/dds_config.h"
#include "transport/qos.h"

namespace felt::transport {
namespace {

constexpr int64_t kWarmupNs = 500000000;  // 0.5 s of pings not recorded

// The echo's settings: the pinger's, with the default identity ("server": it reads felt/pointer
// and writes felt/force) whatever identity the pinger uses.
DdsSettings EchoDds(DdsSettings dds) {
  dds.identity.clear();
  return dds;
}

// The echo side: answers every PointerSample with a ForceCommand carrying its seq and time.
class Echo {
 public:
  Echo(const RawRoundTripOptions& options, const TopicNames& topics)
      : participant_(EchoDds(options.dds), "server") {
    ping_topic_ = CreateTopic(participant_, &felt_msgs_PointerSample_desc, topics.pointer);
    pong_topic_ = CreateTopic(participant_, &felt_msgs_ForceCommand_desc, topics.force);
    const Qos qos = StreamQos();
    pong_writer_ = CreateWriter(participant_, pong_topic_, qos.get(), topics.force);
    if (options.echo_mode == ReceiveMode::kListener) {
      dds_listener_t* listener = dds_create_listener(this);
      if (listener == nullptr) throw std::runtime_error("dds_create_listener failed");
      dds_lset_data_available(listener, &Echo::OnData);
      ping_reader_ = CreateReader(participant_, ping_topic_, qos.get(), listener, topics.pointer);
      dds_delete_listener(listener);
    } else {
      ping_reader_ = CreateReader(participant_, ping_topic_, qos.get(), nullptr, topics.pointer);
      waitset_ = Entity(CheckDds(dds_create_waitset(participant_.get()), "dds_create_waitset"));
      condition_ = Entity(CheckDds(dds_create_readcondition(ping_reader_.get(), DDS_ANY_STATE),
                                   "dds_create_readcondition"));
      CheckDds(dds_waitset_attach(waitset_.get(), condition_.get(), 0), "dds_waitset_attach");
    }
  }
  ~Echo() { (void)dds_set_listener(ping_reader_.get(), nullptr); }

  // Waits for pings (waitset mode) or just for the stop pipe (listener mode) until `stop_fd` ends.
  void Run(int stop_fd) {
    pollfd pfd{stop_fd, POLLIN, 0};
    for (;;) {
      if (waitset_.get() == 0) {
        if (poll(&pfd, 1, -1) != 0) return;  // EOF or error on the pipe: the parent is done
        continue;
      }
      if (poll(&pfd, 1, 0) != 0) return;
      if (dds_waitset_wait(waitset_.get(), nullptr, 0, DDS_MSECS(50)) > 0) Answer();
    }
  }

 private:
  static void OnData(dds_entity_t, void* arg) { static_cast<Echo*>(arg)->Answer(); }

  void Answer() {
    std::array<felt_msgs_PointerSample, 8> pings{};
    std::array<void*, 8> ptrs{};
    std::array<dds_sample_info_t, 8> infos{};
    for (size_t i = 0; i < pings.size(); ++i) ptrs[i] = &pings[i];
    // A failed take (n < 0) shows as lost answers in the pinger's counts.
    const dds_return_t n = dds_take(ping_reader_.get(), ptrs.data(), infos.data(), 8, 8);
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      felt_msgs_ForceCommand pong{};
      std::snprintf(pong.device_id, sizeof(pong.device_id), "%s", pings[i].device_id);
      pong.seq = pings[i].seq;
      pong.answers_seq = pings[i].seq;
      pong.answers_device_time_ns = pings[i].device_time_ns;
      // A failed write shows as a lost answer in the pinger's counts.
      (void)dds_write(pong_writer_.get(), &pong);
    }
  }

  Participant participant_;
  Entity ping_topic_, pong_topic_, pong_writer_, ping_reader_, waitset_, condition_;
};

void SleepUntil(int64_t deadline_ns) {
  const timespec ts{static_cast<time_t>(deadline_ns / 1000000000),
                    static_cast<long>(deadline_ns % 1000000000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace

RawRoundTripResult RunRawRoundTrip(const RawRoundTripOptions& options) {
  if (!(options.seconds > 0) || !(options.rate_hz > 0)) {
    throw std::invalid_argument("raw round trip: --seconds and the rate must be positive");
  }
  const TopicNames topics = TopicNames::WithAffixes("", options.topic_suffix);
  // The echo process: its own domain instance, stopped when the pipe closes.
  int stop_pipe[2];
  if (pipe(stop_pipe) != 0) throw std::runtime_error("raw round trip: pipe() failed");
  Process echo_process = Process::Fork([&] {
    close(stop_pipe[1]);
    try {
      Echo echo(options, topics);
      echo.Run(stop_pipe[0]);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "raw round trip echo: %s\n", e.what());
      return 1;
    }
    return 0;
  });
  close(stop_pipe[0]);
  const auto stop_child = [&] {
    close(stop_pipe[1]);
    echo_process.Wait();
    return echo_process.exit_code() == 0;
  };

  RawRoundTripResult result;
  try {
    // The pinger: the same entities a device client has, used without the client's bookkeeping.
    Participant participant(options.dds, "device-bench");
    Entity ping_topic = CreateTopic(participant, &felt_msgs_PointerSample_desc, topics.pointer);
    Entity pong_topic = CreateTopic(participant, &felt_msgs_ForceCommand_desc, topics.force);
    const Qos qos = StreamQos();
    Entity ping_writer = CreateWriter(participant, ping_topic, qos.get(), topics.pointer);
    Entity pong_reader = CreateReader(participant, pong_topic, qos.get(), nullptr, topics.force);
    Entity waitset(CheckDds(dds_create_waitset(participant.get()), "dds_create_waitset"));
    Entity condition(CheckDds(dds_create_readcondition(pong_reader.get(), DDS_ANY_STATE),
                              "dds_create_readcondition"));
    CheckDds(dds_waitset_attach(waitset.get(), condition.get(), 0), "dds_waitset_attach");

    // Discovery: both directions matched, polled with a deadline.
    const bool matched = WaitUntil(
        [&] {
          dds_publication_matched_status_t pub{};
          dds_subscription_matched_status_t sub{};
          return dds_get_publication_matched_status(ping_writer.get(), &pub) >= 0 &&
                 dds_get_subscription_matched_status(pong_reader.get(), &sub) >= 0 &&
                 pub.current_count > 0 && sub.current_count > 0;
        },
        std::chrono::seconds(10));
    if (!matched) throw std::runtime_error("raw round trip: the echo process was not discovered");

    // Ping at the rate on absolute deadlines; between pings, take answers as they arrive.
    const auto period_ns = static_cast<int64_t>(1e9 / options.rate_hz);
    const auto total = static_cast<uint64_t>(options.seconds * options.rate_hz);
    result.roundtrip_us.reserve(total);
    felt_msgs_PointerSample ping{};
    std::snprintf(ping.device_id, sizeof(ping.device_id), "raw-roundtrip");
    std::array<felt_msgs_ForceCommand, 8> pongs{};
    std::array<void*, 8> ptrs{};
    std::array<dds_sample_info_t, 8> infos{};
    for (size_t i = 0; i < pongs.size(); ++i) ptrs[i] = &pongs[i];
    const int64_t start_ns = MonotonicNowNs();
    const int64_t measure_from_ns = start_ns + kWarmupNs;
    const int64_t end_ns = measure_from_ns + static_cast<int64_t>(options.seconds * 1e9);
    int64_t next_ns = start_ns;
    uint64_t seq = 0;
    // A ping is measured when its deadline (not the time it was sent) lies after the warm-up, so
    // warm-up pings sent late (a stalled loop, a secure handshake) are never counted: seq >=
    // first_measured (ping k's deadline is start + (k - 1) period).
    const auto first_measured = static_cast<uint64_t>((kWarmupNs + period_ns - 1) / period_ns) + 1;
    while (next_ns < end_ns + 50000000) {  // 50 ms after the last ping for late answers
      SleepUntil(next_ns);
      const int64_t now_ns = MonotonicNowNs();
      if (next_ns < end_ns) {
        ping.seq = ++seq;
        ping.device_time_ns = now_ns;
        if (dds_write(ping_writer.get(), &ping) >= 0 && ping.seq >= first_measured) {
          ++result.pings_sent;
        }
      }
      next_ns += period_ns;
      // Take answers until the next deadline.
      for (;;) {
        const int64_t left_ns = next_ns - MonotonicNowNs();
        if (left_ns <= 0) break;
        if (dds_waitset_wait(waitset.get(), nullptr, 0, left_ns) <= 0) continue;
        const dds_return_t n = dds_take(pong_reader.get(), ptrs.data(), infos.data(), 8, 8);
        const int64_t received_ns = MonotonicNowNs();
        for (dds_return_t i = 0; i < n; ++i) {
          if (!infos[i].valid_data || pongs[i].answers_seq < first_measured) continue;
          ++result.pongs_received;
          result.roundtrip_us.push_back(
              static_cast<double>(received_ns - pongs[i].answers_device_time_ns) / 1e3);
        }
      }
    }
  } catch (...) {
    stop_child();
    throw;
  }
  if (!stop_child()) throw std::runtime_error("raw round trip: the echo process failed");
  return result;
}

}  // namespace felt::transport
