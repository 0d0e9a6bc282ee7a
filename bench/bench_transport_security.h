#pragma once
// `felt bench transport --security-cost`: the latency cost of DDS Security (transport/security.h)
// on the raw round trip (transport/raw_roundtrip.h), with and without security in one run.

#include <string>

#include "transport/settings.h"

namespace felt::bench {

/// What the security comparison measures and where it writes.
struct SecurityCostOptions {
  transport::DdsSettings dds;  ///< domain and Cyclone configuration (security_dir is ignored)
  double seconds = 10.0;       ///< measured seconds per condition (split over `rounds`)
  int rounds = 2;              ///< off/on alternations, so drift of the machine hits both alike
  std::string out_prefix = "bench/results/transport_security";  ///< writes PREFIX.md, .json
  std::string command;  ///< the command line, for the report
};

/// Makes a temporary security directory (`felt security init` with server and device:bench),
/// runs the raw round trip at 1 kHz alternately without and with security, prints the table and
/// writes out_prefix.md and out_prefix.json (medians, p99, ratios, set-up time, host CPU, date,
/// command). Call before this process creates any DDS entity (the round trip forks). Returns 0;
/// throws std::runtime_error when a run fails.
int RunSecurityCost(const SecurityCostOptions& options);

}  // namespace felt::bench
