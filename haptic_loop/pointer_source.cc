#include "haptic_loop/pointer_source.h"

#include <cmath>
#include <utility>

#include "rt/clock.h"
#include "rt/counters.h"

namespace felt {
namespace {

/// `count` default slots, one device each; each on its own heap block, since a slot holds atomics
/// and a triple buffer, which never move.
template <class Slot>
std::vector<std::unique_ptr<Slot>> MakeSlots(uint32_t count) {
  std::vector<std::unique_ptr<Slot>> slots;
  for (uint32_t d = 0; d < count; ++d) slots.push_back(std::make_unique<Slot>());
  return slots;
}

/// The slot of device `index`, or nullptr when out of range. Real-time safe.
template <class Slot>
Slot* SlotAt(const std::vector<std::unique_ptr<Slot>>& slots, uint32_t index) {
  return index < slots.size() ? slots[index].get() : nullptr;
}

/// Writes `value` into the writer's slot of `buffer` and publishes it. Real-time safe.
template <class T>
void PublishValue(TripleBuffer<T>& buffer, const T& value) {
  buffer.write_slot() = value;
  buffer.Publish();
}

}  // namespace

TracePointerSource::TracePointerSource(std::vector<std::vector<TraceSample>> traces) {
  cursors_.resize(traces.size());
  for (size_t d = 0; d < traces.size(); ++d) cursors_[d].samples = std::move(traces[d]);
}

bool TracePointerSource::Latest(uint32_t device_index, int64_t now_ns, PointerInput* out) {
  if (!started_) {
    t0_ns_ = now_ns;
    started_ = true;
  }
  if (device_index >= cursors_.size()) return false;
  Cursor& c = cursors_[device_index];
  if (c.samples.empty()) return false;
  // Release every sample whose recorded time (relative to the first) has come.
  const double t_first_s = c.samples.front().t_s;
  const double elapsed_s = static_cast<double>(now_ns - t0_ns_) * 1e-9;
  while (c.next < c.samples.size() && c.samples[c.next].t_s - t_first_s <= elapsed_s) ++c.next;
  if (c.next == 0) return false;
  const TraceSample& s = c.samples[c.next - 1];
  out->seq = c.next;
  out->device_time_ns = std::llround(s.t_s * 1e9);
  out->receive_time_ns = t0_ns_ + std::llround((s.t_s - t_first_s) * 1e9);
  out->p_D_m = s.p_D;
  out->v_D_m_per_s = s.v_D;
  out->buttons = s.buttons;
  return true;
}

bool TracePointerSource::finished() const {
  for (const Cursor& c : cursors_) {
    if (c.next < c.samples.size()) return false;
  }
  return true;
}

LatestPointerSource::LatestPointerSource(uint32_t device_count) {
  slots_ = MakeSlots<Slot>(device_count);
}

void LatestPointerSource::Set(uint32_t device_index, const PointerInput& sample) {
  if (Slot* slot = SlotAt(slots_, device_index)) {
    PublishValue(slot->buffer, sample);
    slot->any.store(true, std::memory_order_release);
    slot->arrivals.Notify(MonotonicNowNs());
  }
}

const ArrivalSignal* LatestPointerSource::Arrivals(uint32_t device_index) const {
  return device_index < slots_.size() ? &slots_[device_index]->arrivals : nullptr;
}

bool LatestPointerSource::Latest(uint32_t device_index, int64_t /*now_ns*/, PointerInput* out) {
  if (device_index >= slots_.size()) return false;
  Slot& slot = *slots_[device_index];
  if (!slot.any.load(std::memory_order_acquire)) return false;
  slot.buffer.Acquire();
  *out = slot.buffer.read_slot();
  return true;
}

CapturingForceSink::CapturingForceSink(uint32_t device_count) {
  slots_ = MakeSlots<Slot>(device_count);
}

void CapturingForceSink::Push(uint32_t device_index, const ForceOutput& force) {
  Slot* slot = SlotAt(slots_, device_index);
  if (slot == nullptr) return;
  PublishValue(slot->buffer, force);
  RaiseTo(slot->peak_N, force.force_D_N.norm());
  // Released after the force: a reader that sees the count sees the force.
  slot->pushed.store(slot->pushed.load(std::memory_order_relaxed) + 1, std::memory_order_release);
}

uint64_t CapturingForceSink::pushed(uint32_t device_index) const {
  return device_index < slots_.size() ? slots_[device_index]->pushed.load(std::memory_order_acquire)
                                      : 0;
}

double CapturingForceSink::peak_force_N(uint32_t device_index) const {
  return device_index < slots_.size() ? slots_[device_index]->peak_N.load(std::memory_order_relaxed)
                                      : 0.0;
}

bool CapturingForceSink::Newest(uint32_t device_index, ForceOutput* out) {
  if (device_index >= slots_.size() || pushed(device_index) == 0) return false;
  slots_[device_index]->buffer.Acquire();
  *out = slots_[device_index]->buffer.read_slot();
  return true;
}

}  // namespace felt
