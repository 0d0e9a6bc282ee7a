#pragma once
// DDS Security for Felt (docs/transport.md, "Security"): what `felt security init DIR` makes with
// Debian's openssl (one CA, an identity per participant, a governance document and a permissions
// document per identity, both signed with S/MIME by the CA), and the participant QoS properties
// that load Cyclone's three plugins (authentication, access control, cryptography) with those
// files. No Cyclone type appears here; transport/dds_config.cc applies the properties.
//
// DIR's layout:
//   ca_cert.pem, ca_key.pem           the CA: identity CA and permissions CA are the same one
//   governance.xml, governance.p7s    the domain rule for domains 0..230 and the felt/* topic rule
//   <identity>/cert.pem, key.pem      the identity's certificate (signed by the CA) and EC key
//   <identity>/permissions.xml, .p7s  what the identity may publish and subscribe to

#include <string>
#include <utility>
#include <vector>

#include "transport/settings.h"

namespace felt::transport {

/// What an identity may do on Felt's topics (its permissions document).
enum class SecurityRole {
  kServer,    ///< subscribes felt/pointer; publishes felt/force and felt/status
  kDevice,    ///< publishes felt/pointer; subscribes felt/force and felt/status
  kRecorder,  ///< subscribes felt/pointer, felt/force and felt/status; publishes nothing
};

/// One identity of a security directory.
struct SecurityIdentity {
  SecurityRole role = SecurityRole::kServer;  ///< its permissions
  std::string device_id;  ///< the device of a kDevice identity (names it); "" otherwise

  /// The identity's name, its subdirectory and certificate common name: "server", "recorder",
  /// "device-<device_id>".
  std::string Name() const;
};

/// Parses `--participants`: a comma-separated list of "server", "recorder" and "device:ID"
/// (ID: 1..64 of A-Z a-z 0-9 _ . -). Throws std::invalid_argument naming the bad entry, or a
/// repeated or empty list.
std::vector<SecurityIdentity> ParseSecurityParticipants(const std::string& list);

/// The directory name of `identity` as a user writes it: "device:ID" becomes "device-ID", any
/// other name is returned unchanged.
std::string SecurityIdentityName(const std::string& identity);

/// The governance document: one domain rule for domains 0..230 (allow_unauthenticated_participants
/// false, enable_join_access_control true, discovery and liveliness protection ENCRYPT, rtps
/// protection NONE) and one topic rule for "felt/*" (read and write access control, data ENCRYPT,
/// metadata NONE). docs/transport.md, "Security", says why.
std::string GovernanceXml();

/// The permissions document of `identity`, whose certificate subject is `subject` (e.g.
/// "CN=server,O=Felt"), valid from `not_before` to `not_after` (UTC, "YYYY-MM-DDThh:mm:ss"), for
/// domains 0..230, default DENY.
std::string PermissionsXml(const SecurityIdentity& identity, const std::string& subject,
                           const std::string& not_before, const std::string& not_after);

/// What `felt security init` makes.
struct SecurityInitOptions {
  std::string dir;                           ///< created when missing
  std::vector<SecurityIdentity> identities;  ///< at least one
  bool force = false;                        ///< replace existing CA, keys and documents
  int validity_days = 3650;                  ///< certificates and permissions, days
};

/// Makes the CA (or reuses DIR's when it exists and `force` is false), the governance document
/// and each identity's key, certificate and permissions, with the `openssl` command found in PATH.
/// Returns the paths written. Throws std::runtime_error: openssl not found (naming the Debian
/// package), DIR not creatable or not writable, an identity's files already there without `force`
/// (naming the file), or an openssl step failing (with its output).
std::vector<std::string> InitSecurityDir(const SecurityInitOptions& options);

/// The participant QoS properties (name, value) that turn security on for `settings.identity`
/// of `settings.security_dir`, with `default_identity` when settings.identity is empty:
/// dds.sec.auth.*, dds.sec.access.*, dds.sec.crypto.* with the plugins' full paths.
/// Empty when settings.security_dir is empty. Throws std::runtime_error naming the file that is
/// missing, unreadable or not what it should be (a PEM certificate or key, an S/MIME document),
/// or when an identity is given without a security directory.
std::vector<std::pair<std::string, std::string>> SecurityProperties(
    const DdsSettings& settings, const std::string& default_identity);

/// The directory of Cyclone's security plugins (libdds_security_auth.so etc.): Debian installs
/// them in libddsc0debian/ beside libddsc; "" when they are not found there (Cyclone then tries
/// the library search path).
std::string SecurityPluginDir();

}  // namespace felt::transport
