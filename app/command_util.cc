#include "app/command_util.h"

#include <spdlog/fmt/fmt.h>

#include <csignal>
#include <fstream>
#include <stdexcept>

namespace felt::app {
namespace {

std::atomic<bool> g_command_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free);

extern "C" void OnCommandStopSignal(int /*signal*/) { g_command_stop.store(true); }

}  // namespace

std::atomic<bool>& StopRequested() { return g_command_stop; }

void InstallStopHandlers() {
  struct sigaction action {};
  action.sa_handler = OnCommandStopSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: let sleeps return early
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

void AddDdsOptions(CLI::App& cmd, uint32_t* domain, std::string* dds_config) {
  cmd.add_option("--domain", *domain, "DDS domain id (default 0)")->check(CLI::Range(0, 230));
  cmd.add_option("--dds-config", *dds_config,
                 "Cyclone DDS configuration file (default: CYCLONEDDS_URI, else loopback)");
}

void AddSecurityOptions(CLI::App& cmd, std::string* security_dir, std::string* identity) {
  cmd.add_option("--security", *security_dir,
                 "DDS Security: a directory made by `felt security init` (default: none)");
  cmd.add_option("--identity", *identity,
                 "the identity in the --security directory (default: this command's role)");
}

void CheckDurationOption(const std::optional<double>& duration_s) {
  if (duration_s && !(*duration_s > 0.0 && *duration_s <= 86400.0)) {
    throw std::invalid_argument(
        fmt::format("--duration must be in (0, 86400] s, got {}", *duration_s));
  }
}

void WriteOptionFile(std::string_view option, const std::string& path, std::string_view text) {
  std::ofstream out(path);
  out << text;
  if (!out) throw std::runtime_error(fmt::format("cannot write {} file '{}'", option, path));
}

}  // namespace felt::app
