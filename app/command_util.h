#pragma once
// What several `felt` commands share beyond the registry (app/command.h): the stop flag that
// SIGINT/SIGTERM set, the DDS options, the --duration check and writing an output file named by an
// option. Not real-time safe; for the commands' set-up and reports only.

#include <CLI/CLI.hpp>
#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace felt::app {

/// The flag SIGINT and SIGTERM set once InstallStopHandlers ran (false before); lock-free, so
/// async-signal-safe.
std::atomic<bool>& StopRequested();

/// Installs the SIGINT and SIGTERM handlers that set StopRequested(), without SA_RESTART, so
/// sleeps and poll() return early when a signal comes.
void InstallStopHandlers();

/// Adds `--domain` (DDS domain id 0 to 230, default 0) and `--dds-config` (a Cyclone DDS
/// configuration file; default CYCLONEDDS_URI, else loopback) to `cmd`, bound to `domain` and
/// `dds_config`.
void AddDdsOptions(CLI::App& cmd, uint32_t* domain, std::string* dds_config);

/// Adds `--security DIR` (a directory made by `felt security init`; DDS Security on) and
/// `--identity NAME` (the identity in DIR; default: the command's own, e.g. "recorder") to `cmd`.
void AddSecurityOptions(CLI::App& cmd, std::string* security_dir, std::string* identity);

/// Throws std::invalid_argument ("--duration must be in (0, 86400] s, got X") unless
/// `duration_s` [s] is absent or in (0, 86400] (one day).
void CheckDurationOption(const std::optional<double>& duration_s);

/// Writes `text` to the file at `path`, which the command-line option `option` (e.g. "--json")
/// named; throws std::runtime_error ("cannot write --json file 'PATH'") when it cannot.
void WriteOptionFile(std::string_view option, const std::string& path, std::string_view text);

}  // namespace felt::app
