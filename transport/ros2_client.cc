#include "transport/ros2_client.h"

#include <new>
#include <stdexcept>

#include "ros2_types.h"
#include "transport/qos.h"
#include "transport/ros2_profile.h"

namespace felt::transport {

struct Ros2Client::Impl {
  explicit Impl(const Ros2ClientConfig& c) : frame(c.frame_id), participant(AcquireDomain(c.dds)) {}
  std::string frame;  // the poses' header.frame_id (pose.header points into it)
  Participant participant;
  Entity pose_topic, wrench_topic, pose_writer, wrench_reader, waitset, read_condition;
  geometry_msgs_msg_dds__PoseStamped_ pose{};
};

Ros2Client::Ros2Client(const Ros2ClientConfig& config) : impl_(std::make_unique<Impl>(config)) {
  Impl& d = *impl_;
  const std::string pose = Ros2DdsTopic(config.pose_topic, "Ros2ClientConfig.pose_topic");
  const std::string wrench = Ros2DdsTopic(config.wrench_topic, "Ros2ClientConfig.wrench_topic");
  d.pose_topic = CreateTopic(d.participant, &geometry_msgs_msg_dds__PoseStamped__desc, pose);
  d.wrench_topic = CreateTopic(d.participant, &geometry_msgs_msg_dds__WrenchStamped__desc, wrench);
  // rclcpp's default QoS (rmw_qos_profile_default) with depth 10.
  Qos qos(dds_create_qos());
  if (!qos) throw std::bad_alloc();
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 10);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  d.pose_writer = CreateWriter(d.participant, d.pose_topic, qos.get(), pose);
  d.wrench_reader = CreateReader(d.participant, d.wrench_topic, qos.get(), nullptr, wrench);
  d.waitset = Entity(CheckDds(dds_create_waitset(d.participant.get()), "dds_create_waitset"));
  d.read_condition = Entity(CheckDds(dds_create_readcondition(d.wrench_reader.get(), DDS_ANY_STATE),
                                     "dds_create_readcondition"));
  CheckDds(dds_waitset_attach(d.waitset.get(), d.read_condition.get(), 0), "dds_waitset_attach");
  d.pose.header.frame_id = d.frame.data();
  d.pose.pose.orientation.w = 1.0;
}

Ros2Client::~Ros2Client() = default;

bool Ros2Client::PublishPose(int64_t stamp_ns, const std::array<double, 3>& position_m) {
  Impl& d = *impl_;
  Ros2StampOf(stamp_ns, &d.pose.header.stamp.sec, &d.pose.header.stamp.nanosec);
  d.pose.pose.position = {position_m[0], position_m[1], position_m[2]};
  return dds_write(d.pose_writer.get(), &d.pose) >= 0;
}

bool Ros2Client::WaitWrench(std::chrono::nanoseconds timeout, Ros2WrenchReceived* out) {
  Impl& d = *impl_;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    // One sample on loan (the header's string is Cyclone's).
    void* ptr = nullptr;
    dds_sample_info_t info{};
    const dds_return_t n = dds_take(d.wrench_reader.get(), &ptr, &info, 1, 1);
    if (n < 0) return false;
    if (n == 1) {
      const int64_t now_ns = MonotonicNowNs();
      const bool valid = info.valid_data;
      if (valid) {
        const auto* m = static_cast<const geometry_msgs_msg_dds__WrenchStamped_*>(ptr);
        out->stamp_ns = Ros2StampNs(m->header.stamp.sec, m->header.stamp.nanosec);
        out->force_N = {m->wrench.force.x, m->wrench.force.y, m->wrench.force.z};
        out->receive_time_ns = now_ns;
      }
      (void)dds_return_loan(d.wrench_reader.get(), &ptr, 1);
      if (valid) return true;
      continue;
    }
    const auto left = deadline - std::chrono::steady_clock::now();
    if (left <= std::chrono::nanoseconds::zero()) return false;
    if (dds_waitset_wait(d.waitset.get(), nullptr, 0,
                         std::chrono::duration_cast<std::chrono::nanoseconds>(left).count()) < 0) {
      return false;
    }
  }
}

uint32_t Ros2Client::MatchedPoseReaders() const { return MatchedReaders(impl_->pose_writer); }

uint32_t Ros2Client::MatchedWrenchWriters() const { return MatchedWriters(impl_->wrench_reader); }

}  // namespace felt::transport
