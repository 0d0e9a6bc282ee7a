#include "transport/qos.h"

#include <new>

namespace felt::transport {
namespace {
Qos NewQos() {
  Qos qos(dds_create_qos());
  if (!qos) throw std::bad_alloc();
  return qos;
}
}  // namespace

Qos StreamQos(std::chrono::nanoseconds deadline) {
  Qos qos = NewQos();
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  dds_qset_deadline(qos.get(), static_cast<dds_duration_t>(deadline.count()));
  return qos;
}

Qos StatusQos() {
  Qos qos = NewQos();
  // max_blocking_time bounds dds_write when a reader's buffer is full (monitor thread only).
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(qos.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
  return qos;
}

}  // namespace felt::transport
