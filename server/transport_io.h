#pragma once
// The DDS transport behind the server's PointerSource and ForceSink (issue 6's ServerTransport):
// the default input and output of `felt serve`. Header-only on purpose: felt_haptic_loop is
// linked below felt_transport, so only the programs that link the transport (the `felt` command,
// the tests) instantiate these. Every call is one lock-free slot or queue operation of the
// transport: no DDS call on the haptic thread.
#include <cstdint>

#include "haptic_loop/pointer_source.h"
#include "haptic_loop/safety.h"
#include "transport/server_transport.h"
#include "transport/views.h"

namespace felt {

/// Reads the transport's per-device newest-sample slots. Device index = the order of
/// ServerTransportConfig::devices (the scene's device order in `felt serve`).
class TransportPointerSource final : public PointerSource {
 public:
  /// `transport` must outlive this source.
  explicit TransportPointerSource(transport::ServerTransport* transport) : transport_(transport) {}
  /// Real-time safe: ServerTransport::LatestPointer (one atomic exchange and a copy).
  bool Latest(uint32_t device_index, int64_t /*now_ns*/, PointerInput* out) override {
    transport::PointerSampleView view;
    if (!transport_->LatestPointer(device_index, &view)) return false;
    out->seq = view.seq;
    out->device_time_ns = view.device_time_ns;
    out->receive_time_ns = view.receive_time_ns;
    out->p_D_m = Vec3(view.position_m_D[0], view.position_m_D[1], view.position_m_D[2]);
    out->v_D_m_per_s =
        Vec3(view.velocity_m_per_s_D[0], view.velocity_m_per_s_D[1], view.velocity_m_per_s_D[2]);
    out->buttons = view.buttons;
    return true;
  }
  /// The transport's count of accepted samples of the device (ServerTransport::Arrivals).
  const ArrivalSignal* Arrivals(uint32_t device_index) const override {
    return transport_->Arrivals(device_index);
  }

 private:
  transport::ServerTransport* transport_;
};

/// Pushes forces into the transport's SPSC queue (its writer thread publishes them on
/// felt/force). A full queue is counted by the transport (TransportStats::forces_queue_full).
class TransportForceSink final : public ForceSink {
 public:
  /// `transport` must outlive this sink.
  explicit TransportForceSink(transport::ServerTransport* transport) : transport_(transport) {}
  /// Real-time safe: ServerTransport::PushForce.
  void Push(uint32_t device_index, const ForceOutput& force) override {
    transport::ForceCommandView view;
    view.device_index = device_index;
    view.answers_seq = force.answers_seq;
    view.answers_device_time_ns = force.answers_device_time_ns;
    view.force_N_D = {force.force_D_N.x(), force.force_D_N.y(), force.force_D_N.z()};
    view.proxy_position_m_D = {force.proxy_D_m.x(), force.proxy_D_m.y(), force.proxy_D_m.z()};
    view.in_contact = force.in_contact;
    view.flags = force.flags;
    for (int k = 0; k < 3; ++k) {
      view.contact_point_m_D[k] = force.contact_point_D_m[k];
      view.contact_normal_D[k] = force.contact_normal_D[k];
    }
    view.contact_stiffness_N_per_m = force.contact_stiffness_N_per_m;
    transport_->PushForce(view);
  }

 private:
  transport::ServerTransport* transport_;
};

// The safety flags are the wire's flags.
static_assert(kSafetyClamped == transport::kForceClamped);
static_assert(kSafetyStaleInput == transport::kForceStaleInput);
static_assert(kSafetySimStalled == transport::kForceSimStalled);
static_assert(kSafetyRamping == transport::kForceRamping);

}  // namespace felt
