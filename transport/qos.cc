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

Qos StreamReaderQos() {
  Qos qos = StreamQos();
  dds_qset_deadline(qos.get(), DDS_INFINITY);
  return qos;
}

Qos Ros2WrenchWriterQos() {
  Qos qos(dds_create_qos());
  if (!qos) throw std::bad_alloc();
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(1));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  return qos;
}

Qos Ros2DiagnosticsWriterQos() {
  Qos qos = NewQos();
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 10);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  return qos;
}

Qos Ros2MarkerWriterQos() {
  Qos qos = NewQos();
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(qos.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
  return qos;
}

const char* QosPolicyName(uint32_t policy_id) {
  switch (static_cast<dds_qos_policy_id_t>(policy_id)) {
    case DDS_USERDATA_QOS_POLICY_ID:
      return "USER_DATA";
    case DDS_DURABILITY_QOS_POLICY_ID:
      return "DURABILITY";
    case DDS_PRESENTATION_QOS_POLICY_ID:
      return "PRESENTATION";
    case DDS_DEADLINE_QOS_POLICY_ID:
      return "DEADLINE";
    case DDS_LATENCYBUDGET_QOS_POLICY_ID:
      return "LATENCY_BUDGET";
    case DDS_OWNERSHIP_QOS_POLICY_ID:
      return "OWNERSHIP";
    case DDS_OWNERSHIPSTRENGTH_QOS_POLICY_ID:
      return "OWNERSHIP_STRENGTH";
    case DDS_LIVELINESS_QOS_POLICY_ID:
      return "LIVELINESS";
    case DDS_TIMEBASEDFILTER_QOS_POLICY_ID:
      return "TIME_BASED_FILTER";
    case DDS_PARTITION_QOS_POLICY_ID:
      return "PARTITION";
    case DDS_RELIABILITY_QOS_POLICY_ID:
      return "RELIABILITY";
    case DDS_DESTINATIONORDER_QOS_POLICY_ID:
      return "DESTINATION_ORDER";
    case DDS_HISTORY_QOS_POLICY_ID:
      return "HISTORY";
    case DDS_RESOURCELIMITS_QOS_POLICY_ID:
      return "RESOURCE_LIMITS";
    case DDS_ENTITYFACTORY_QOS_POLICY_ID:
      return "ENTITY_FACTORY";
    case DDS_WRITERDATALIFECYCLE_QOS_POLICY_ID:
      return "WRITER_DATA_LIFECYCLE";
    case DDS_READERDATALIFECYCLE_QOS_POLICY_ID:
      return "READER_DATA_LIFECYCLE";
    case DDS_TOPICDATA_QOS_POLICY_ID:
      return "TOPIC_DATA";
    case DDS_GROUPDATA_QOS_POLICY_ID:
      return "GROUP_DATA";
    case DDS_TRANSPORTPRIORITY_QOS_POLICY_ID:
      return "TRANSPORT_PRIORITY";
    case DDS_LIFESPAN_QOS_POLICY_ID:
      return "LIFESPAN";
    case DDS_DURABILITYSERVICE_QOS_POLICY_ID:
      return "DURABILITY_SERVICE";
    case DDS_PROPERTY_QOS_POLICY_ID:
      return "PROPERTY";
    case DDS_TYPE_CONSISTENCY_ENFORCEMENT_QOS_POLICY_ID:
      return "TYPE_CONSISTENCY_ENFORCEMENT";
    case DDS_DATA_REPRESENTATION_QOS_POLICY_ID:
      return "DATA_REPRESENTATION";
    case DDS_INVALID_QOS_POLICY_ID:
      break;
  }
  return "UNKNOWN";
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
