#include "bench/bench_transport_security.h"

#include <stdlib.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "base/json.h"
#include "base/report.h"
#include "transport/raw_roundtrip.h"
#include "transport/security.h"

namespace felt::bench {
namespace {

// One condition's pooled round trips and counts.
struct SecurityCostCondition {
  std::vector<double> roundtrip_us;
  uint64_t sent = 0, received = 0;
  std::vector<double> setup_s;  // wall time of a run minus its measured time and warm-up
};

double SecurityCostPercentile(const std::vector<double>& values, double p) {
  return report::Percentile(values, p);
}

Json SecurityCostJson(const SecurityCostCondition& c) {
  return Json{{"p50_us", SecurityCostPercentile(c.roundtrip_us, 50.0)},
              {"p99_us", SecurityCostPercentile(c.roundtrip_us, 99.0)},
              {"p999_us", SecurityCostPercentile(c.roundtrip_us, 99.9)},
              {"max_us", SecurityCostPercentile(c.roundtrip_us, 100.0)},
              {"n", c.roundtrip_us.size()},
              {"pings_sent", c.sent},
              {"pongs_received", c.received},
              {"setup_and_discovery_s_median", report::Median(c.setup_s)}};
}

}  // namespace

int RunSecurityCost(const SecurityCostOptions& options) {
  if (options.rounds < 1 || !(options.seconds > 0)) {
    throw std::invalid_argument("--security-cost: seconds and rounds must be positive");
  }
  const report::MachineInfo machine = report::ReadMachineInfo();
  // The identities: a temporary directory, removed at the end.
  char dir_template[] = "/tmp/felt_security_bench_XXXXXX";
  if (mkdtemp(dir_template) == nullptr) {
    throw std::runtime_error("--security-cost: cannot make a temporary directory in /tmp");
  }
  const std::string dir = dir_template;
  struct RemoveDir {
    std::string path;
    ~RemoveDir() {
      std::error_code ignored;
      std::filesystem::remove_all(path, ignored);
    }
  } remove_dir{dir};
  transport::SecurityInitOptions init;
  init.dir = dir;
  init.identities = transport::ParseSecurityParticipants("server,device:bench");
  init.validity_days = 1;
  transport::InitSecurityDir(init);

  // Alternate off and on, `rounds` times, each run seconds/rounds long.
  SecurityCostCondition conditions[2];  // 0 = off, 1 = on
  const double run_s = options.seconds / options.rounds;
  for (int round = 0; round < options.rounds; ++round) {
    for (int on = 0; on < 2; ++on) {
      transport::RawRoundTripOptions raw;
      raw.dds = options.dds;
      raw.dds.security_dir = on ? dir : std::string();
      raw.dds.identity.clear();  // echo "server", pinger "device-bench"
      raw.seconds = run_s;
      raw.echo_mode = transport::ReceiveMode::kListener;
      raw.topic_suffix = "/bench_security_" + std::to_string(getpid()) + "_" +
                         std::to_string(round) + "_" + std::to_string(on);
      const auto start = std::chrono::steady_clock::now();
      transport::RawRoundTripResult r = transport::RunRawRoundTrip(raw);
      const double wall_s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      SecurityCostCondition& c = conditions[on];
      c.roundtrip_us.insert(c.roundtrip_us.end(), r.roundtrip_us.begin(), r.roundtrip_us.end());
      c.sent += r.pings_sent;
      c.received += r.pongs_received;
      c.setup_s.push_back(wall_s - run_s - 0.5);  // 0.5 s: the round trip's warm-up
    }
  }

  // The table.
  const auto p = [&](int on, double q) {
    return SecurityCostPercentile(conditions[on].roundtrip_us, q);
  };
  const char* names[2] = {"security off", "security on (auth + access control + AES-GCM data)"};
  std::vector<std::vector<std::string>> rows;
  for (int on = 0; on < 2; ++on) {
    rows.push_back(
        {names[on], report::Fixed(p(on, 50), 1), report::Fixed(p(on, 99), 1),
         report::Fixed(p(on, 99.9), 1), report::Fixed(p(on, 100), 1),
         std::to_string(conditions[on].roundtrip_us.size()),
         std::to_string(conditions[on].received) + "/" + std::to_string(conditions[on].sent),
         report::Fixed(report::Median(conditions[on].setup_s), 2)});
  }
  rows.push_back({"ratio on/off", report::Fixed(p(1, 50) / p(0, 50), 2),
                  report::Fixed(p(1, 99) / p(0, 99), 2), report::Fixed(p(1, 99.9) / p(0, 99.9), 2),
                  "", "", "", ""});
  const std::string table =
      report::MarkdownTable({"raw round trip, us", "p50", "p99", "p99.9", "max", "n",
                             "answered/sent", "set-up + discovery, s"},
                            {false, true, true, true, true, true, true, true}, rows);
  std::printf(
      "felt bench transport --security-cost: %.0f s per condition in %d alternations, "
      "1 kHz, loopback, domain %u\n\n%s",
      options.seconds, options.rounds, options.dds.domain_id, table.c_str());

  const std::string md =
      "# felt bench transport --security-cost (issue 23)\n\nCommand: `" + options.command +
      "` (Release build, run from the repository root)\n\n- Machine: " +
      std::to_string(machine.cpus_online) + " CPUs online (nproc), " + machine.cpu_model +
      "; this process: niceness " + std::to_string(machine.niceness) + ", CPUs " +
      machine.affinity + "\n- Date: " + machine.date_utc +
      "\n- Load average (1, 5, 15 min) at the start: " + machine.load_average +
      "; at the end: " + report::LoadAverage() +
      " (a machine shared with other sessions)\n\nThe raw round trip of `felt bench transport` (a "
      "PointerSample from this process answered "
      "with a ForceCommand by a forked echo process; Felt's types, QoS and loopback "
      "configuration, echo by listener) at 1 kHz, without and with DDS Security, alternating " +
      std::to_string(options.rounds) + " times, " + report::Fixed(run_s, 1) +
      " s per run. With security both sides authenticate with identities of a fresh `felt "
      "security init` directory (server and device:bench, EC P-256, one CA) and the governance "
      "of transport/security.cc: discovery and liveliness ENCRYPT, felt/* topics with read and "
      "write access control and data ENCRYPT (AES-GCM), metadata and RTPS protection NONE. "
      "Set-up + discovery: the wall time of a run minus its measured time and warm-up (process "
      "fork, participants, matching), median of the runs.\n\n" +
      table +
      "\nOne run on a shared 2-core machine: figures vary up to 2x between runs; read the "
      "ratio of the medians, measured in the same run, as the cost.\n";
  report::WriteTextFile(options.out_prefix + ".md", md);
  Json json{{"command", options.command},
            {"seconds_per_condition", options.seconds},
            {"rounds", options.rounds},
            {"security_off", SecurityCostJson(conditions[0])},
            {"security_on", SecurityCostJson(conditions[1])},
            {"ratio_p50", p(1, 50) / p(0, 50)},
            {"ratio_p99", p(1, 99) / p(0, 99)}};
  report::AppendMachineJson(machine, report::LoadAverage(), &json);
  report::WriteTextFile(options.out_prefix + ".json", JsonText(json));
  std::printf("\nwrote %s.md and %s.json\n", options.out_prefix.c_str(),
              options.out_prefix.c_str());
  return 0;
}

}  // namespace felt::bench
