#pragma once
// What a Felt program chooses about DDS, without any DDS type: the domain, the configuration and
// the topic names. Server, clients, tools and tests fill these; transport/ turns them into DDS.

#include <cstdint>
#include <string>

namespace felt::transport {

/// Where Cyclone's configuration comes from and which domain to join.
/// Precedence: `config_file` (the `--dds-config FILE` option) when not empty, else the
/// CYCLONEDDS_URI environment variable when set and not empty, else the embedded loopback
/// configuration (DefaultLoopbackConfig() in transport/dds_config.h).
struct DdsSettings {
  uint32_t domain_id = 0;   ///< DDS domain id (`--domain N`), 0..230
  std::string config_file;  ///< path of a Cyclone XML configuration file; "" = not given
  /// DDS Security: a directory made by `felt security init` (`--security DIR`, the scene's
  /// [transport] security); "" = no security. Participants then authenticate with `identity`.
  std::string security_dir;
  /// The identity in `security_dir` (its subdirectory, e.g. "server", "device-default",
  /// "recorder"; "device:default" is accepted for "device-default"). "" = the program's default.
  std::string identity;
};

/// The three topic names. Defaults are Felt's public names; tests and tools may add a prefix and a
/// suffix (WithAffixes) so that runs sharing a machine never see each other's samples.
struct TopicNames {
  std::string pointer = "felt/pointer";  ///< PointerSample, device -> server
  std::string force = "felt/force";      ///< ForceCommand, server -> device
  std::string status = "felt/status";    ///< ServerStatus, server -> anyone

  /// The default names with `prefix` before and `suffix` after each, e.g. ("", "/test_42_1")
  /// gives "felt/pointer/test_42_1". Both may be empty.
  static TopicNames WithAffixes(const std::string& prefix, const std::string& suffix);
};

}  // namespace felt::transport
