#include "transport/security.h"

#include <dds/dds.h>
#include <dlfcn.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include "base/process.h"

namespace felt::transport {
namespace {

namespace fs = std::filesystem;

constexpr uint32_t kSecurityMaxDomain = 230;  // every DDS domain id Felt accepts

// The whole file at `path`; throws naming the file when it cannot be read or is empty.
std::string ReadSecurityFile(const fs::path& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) {
    throw std::runtime_error(what + path.string() +
                             ": cannot read the file (make it with `felt security init`)");
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (text.str().empty()) throw std::runtime_error(what + path.string() + ": the file is empty");
  return text.str();
}

// Checks that `path` holds `marker` (a PEM header, an S/MIME header); throws naming the file.
void ExpectSecurityContent(const fs::path& path, const std::string& what, const char* marker,
                           const char* kind) {
  if (ReadSecurityFile(path, what).find(marker) == std::string::npos) {
    throw std::runtime_error(what + path.string() + ": not " + kind + " (no \"" + marker +
                             "\" in it)");
  }
}

// The `openssl` executable in PATH; throws when there is none.
std::string FindOpenssl() {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path != nullptr ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const fs::path candidate = fs::path(dir.empty() ? "." : dir) / "openssl";
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  throw std::runtime_error(
      "the openssl command was not found in PATH: install Debian's openssl package "
      "(apt-get install openssl)");
}

// Runs openssl with `args`; throws with its output when it fails.
void RunOpenssl(const std::string& openssl, const std::vector<std::string>& args,
                const std::string& step) {
  std::vector<std::string> argv{openssl};
  argv.insert(argv.end(), args.begin(), args.end());
  const CapturedRun run = RunCaptured(argv, std::chrono::minutes(1));
  if (run.exit_code != 0) {
    throw std::runtime_error(
        "openssl failed to " + step + " (" +
        (run.timed_out ? "timed out" : "exit code " + std::to_string(run.exit_code)) +
        "): " + run.output);
  }
}

// UTC time `offset_s` from now as "YYYY-MM-DDThh:mm:ss" (DDS Security 1.1, 9.4.1.3.2.3.1.2).
std::string SecurityUtc(int64_t offset_s) {
  const std::time_t t = std::time(nullptr) + static_cast<std::time_t>(offset_s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%S", &tm);
  return text;
}

// The certificate subject of identity `name`, as openssl's -subj and as the permissions
// document's subject_name (RFC 4514 order, most specific first; Cyclone compares the parsed names).
std::string SubjectOpenssl(const std::string& name) { return "/O=Felt/CN=" + name; }
std::string SubjectRfc4514(const std::string& name) { return "CN=" + name + ",O=Felt"; }

void WriteSecurityText(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::trunc);
  out << text;
  if (!out.flush()) throw std::runtime_error(path.string() + ": cannot write the file");
}

// The topic and its suffixed variants (tests' TopicNames::WithAffixes("", "/x")).
void AppendTopics(std::ostringstream& xml, std::initializer_list<const char*> topics) {
  xml << "        <topics>\n";
  for (const char* topic : topics) {
    xml << "          <topic>" << topic << "</topic>\n";
    xml << "          <topic>" << topic << "/*</topic>\n";
  }
  xml << "        </topics>\n";
}

}  // namespace

std::string SecurityIdentity::Name() const {
  switch (role) {
    case SecurityRole::kServer:
      return "server";
    case SecurityRole::kRecorder:
      return "recorder";
    case SecurityRole::kDevice:
      return "device-" + device_id;
  }
  return "";
}

std::vector<SecurityIdentity> ParseSecurityParticipants(const std::string& list) {
  std::vector<SecurityIdentity> identities;
  std::set<std::string> names;
  std::istringstream in(list);
  for (std::string entry; std::getline(in, entry, ',');) {
    SecurityIdentity identity;
    if (entry == "server") {
      identity.role = SecurityRole::kServer;
    } else if (entry == "recorder") {
      identity.role = SecurityRole::kRecorder;
    } else if (entry.rfind("device:", 0) == 0) {
      identity.role = SecurityRole::kDevice;
      identity.device_id = entry.substr(7);
      const bool ok = !identity.device_id.empty() && identity.device_id.size() <= 64 &&
                      identity.device_id.find_first_not_of(
                          "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_.-") ==
                          std::string::npos;
      if (!ok) {
        throw std::invalid_argument("--participants: \"" + entry +
                                    "\": a device id must be 1 to 64 of A-Z a-z 0-9 _ . -");
      }
    } else {
      throw std::invalid_argument("--participants: \"" + entry +
                                  "\" is not server, recorder or device:ID");
    }
    if (!names.insert(identity.Name()).second) {
      throw std::invalid_argument("--participants: \"" + entry + "\" is listed twice");
    }
    identities.push_back(identity);
  }
  if (identities.empty()) throw std::invalid_argument("--participants: the list is empty");
  return identities;
}

std::string SecurityIdentityName(const std::string& identity) {
  if (identity.rfind("device:", 0) == 0) return "device-" + identity.substr(7);
  return identity;
}

std::string GovernanceXml() {
  // OMG DDS Security 1.1, 9.4.1.2 (the governance document) and its XSD
  // omg_shared_ca_governance.xsd. Protection kinds chosen in docs/transport.md, "Security".
  std::ostringstream xml;
  xml << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
         "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" "
         "xsi:noNamespaceSchemaLocation="
         "\"http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd\">\n"
         "  <domain_access_rules>\n"
         "    <domain_rule>\n"
         "      <domains><id_range><min>0</min><max>"
      << kSecurityMaxDomain
      << "</max></id_range></domains>\n"
         "      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>\n"
         "      <enable_join_access_control>true</enable_join_access_control>\n"
         "      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>\n"
         "      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>\n"
         "      <rtps_protection_kind>NONE</rtps_protection_kind>\n"
         "      <topic_access_rules>\n"
         "        <topic_rule>\n"
         "          <topic_expression>felt/*</topic_expression>\n"
         "          <enable_discovery_protection>true</enable_discovery_protection>\n"
         "          <enable_liveliness_protection>false</enable_liveliness_protection>\n"
         "          <enable_read_access_control>true</enable_read_access_control>\n"
         "          <enable_write_access_control>true</enable_write_access_control>\n"
         "          <metadata_protection_kind>NONE</metadata_protection_kind>\n"
         "          <data_protection_kind>ENCRYPT</data_protection_kind>\n"
         "        </topic_rule>\n"
         "      </topic_access_rules>\n"
         "    </domain_rule>\n"
         "  </domain_access_rules>\n"
         "</dds>\n";
  return xml.str();
}

std::string PermissionsXml(const SecurityIdentity& identity, const std::string& subject,
                           const std::string& not_before, const std::string& not_after) {
  // OMG DDS Security 1.1, 9.4.1.3 (the permissions document), omg_shared_ca_permissions.xsd.
  // No <partitions>: the rules apply to the default partition, the only one Felt uses.
  std::ostringstream xml;
  xml << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
         "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" "
         "xsi:noNamespaceSchemaLocation="
         "\"http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd\">\n"
         "  <permissions>\n"
         "    <grant name=\"felt_"
      << identity.Name() << "\">\n      <subject_name>" << subject
      << "</subject_name>\n"
         "      <validity><not_before>"
      << not_before << "</not_before><not_after>" << not_after
      << "</not_after></validity>\n"
         "      <allow_rule>\n"
         "        <domains><id_range><min>0</min><max>"
      << kSecurityMaxDomain << "</max></id_range></domains>\n";
  switch (identity.role) {
    case SecurityRole::kServer:
      xml << "        <publish>\n";
      AppendTopics(xml, {"felt/force", "felt/status"});
      xml << "        </publish>\n        <subscribe>\n";
      AppendTopics(xml, {"felt/pointer"});
      xml << "        </subscribe>\n";
      break;
    case SecurityRole::kDevice:
      xml << "        <publish>\n";
      AppendTopics(xml, {"felt/pointer"});
      xml << "        </publish>\n        <subscribe>\n";
      AppendTopics(xml, {"felt/force", "felt/status"});
      xml << "        </subscribe>\n";
      break;
    case SecurityRole::kRecorder:
      xml << "        <subscribe>\n";
      AppendTopics(xml, {"felt/pointer", "felt/force", "felt/status"});
      xml << "        </subscribe>\n";
      break;
  }
  xml << "      </allow_rule>\n"
         "      <default>DENY</default>\n"
         "    </grant>\n"
         "  </permissions>\n"
         "</dds>\n";
  return xml.str();
}

std::vector<std::string> InitSecurityDir(const SecurityInitOptions& options) {
  if (options.dir.empty()) throw std::invalid_argument("felt security init: DIR is empty");
  if (options.identities.empty()) {
    throw std::invalid_argument("felt security init: no identity to make");
  }
  const std::string openssl = FindOpenssl();
  const fs::path dir(options.dir);
  std::error_code error;
  fs::create_directories(dir, error);
  if (error || !fs::is_directory(dir)) {
    throw std::runtime_error(options.dir + ": cannot create the directory (" +
                             (error ? error.message() : "not a directory") + ")");
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw std::runtime_error(options.dir + ": the directory is not writable");
  }
  // Never replace a key without --force: check every identity before writing anything.
  if (!options.force) {
    for (const SecurityIdentity& identity : options.identities) {
      for (const char* file : {"key.pem", "cert.pem"}) {
        const fs::path path = dir / identity.Name() / file;
        if (fs::exists(path)) {
          throw std::runtime_error(path.string() +
                                   " exists: use --force to replace the identity's key");
        }
      }
    }
  }
  std::vector<std::string> written;
  const fs::path ca_key = dir / "ca_key.pem";
  const fs::path ca_cert = dir / "ca_cert.pem";
  const std::string days = std::to_string(options.validity_days);
  // 1. The CA (identity CA and permissions CA in one): an EC P-256 key and a self-signed
  //    certificate. Reused when it is there and --force is not given, so identities can be added.
  const bool have_ca = fs::exists(ca_key) && fs::exists(ca_cert);
  if (options.force || !have_ca) {
    RunOpenssl(openssl,
               {"genpkey", "-algorithm", "EC", "-pkeyopt", "ec_paramgen_curve:P-256", "-out",
                ca_key.string()},
               "make the CA key " + ca_key.string());
    fs::permissions(ca_key, fs::perms::owner_read | fs::perms::owner_write);
    RunOpenssl(openssl,
               {"req", "-x509", "-new", "-key", ca_key.string(), "-out", ca_cert.string(), "-days",
                days, "-subj", "/O=Felt/CN=Felt CA"},
               "make the CA certificate " + ca_cert.string());
    written.push_back(ca_key.string());
    written.push_back(ca_cert.string());
  }
  // 2. The governance document, signed by the (permissions) CA.
  const fs::path governance_xml = dir / "governance.xml";
  const fs::path governance = dir / "governance.p7s";
  WriteSecurityText(governance_xml, GovernanceXml());
  RunOpenssl(openssl,
             {"smime", "-sign", "-text", "-in", governance_xml.string(), "-out",
              governance.string(), "-signer", ca_cert.string(), "-inkey", ca_key.string()},
             "sign " + governance_xml.string());
  written.push_back(governance_xml.string());
  written.push_back(governance.string());
  // 3. Each identity: key, certificate signed by the CA, permissions signed by the CA.
  const std::string not_before = SecurityUtc(-3600);  // an hour back: clocks of peers differ
  const std::string not_after = SecurityUtc(int64_t{options.validity_days} * 86400);
  for (const SecurityIdentity& identity : options.identities) {
    const std::string name = identity.Name();
    const fs::path sub = dir / name;
    fs::create_directories(sub);
    const fs::path key = sub / "key.pem";
    const fs::path csr = sub / "cert.csr";
    const fs::path cert = sub / "cert.pem";
    RunOpenssl(openssl,
               {"genpkey", "-algorithm", "EC", "-pkeyopt", "ec_paramgen_curve:P-256", "-out",
                key.string()},
               "make the key " + key.string());
    fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write);
    RunOpenssl(
        openssl,
        {"req", "-new", "-key", key.string(), "-out", csr.string(), "-subj", SubjectOpenssl(name)},
        "make the signing request " + csr.string());
    RunOpenssl(openssl,
               {"x509", "-req", "-in", csr.string(), "-CA", ca_cert.string(), "-CAkey",
                ca_key.string(), "-CAcreateserial", "-CAserial", (dir / "ca_cert.srl").string(),
                "-days", days, "-out", cert.string()},
               "sign the certificate " + cert.string());
    fs::remove(csr);
    const fs::path permissions_xml = sub / "permissions.xml";
    const fs::path permissions = sub / "permissions.p7s";
    WriteSecurityText(permissions_xml,
                      PermissionsXml(identity, SubjectRfc4514(name), not_before, not_after));
    RunOpenssl(openssl,
               {"smime", "-sign", "-text", "-in", permissions_xml.string(), "-out",
                permissions.string(), "-signer", ca_cert.string(), "-inkey", ca_key.string()},
               "sign " + permissions_xml.string());
    for (const fs::path& path : {key, cert, permissions_xml, permissions}) {
      written.push_back(path.string());
    }
  }
  return written;
}

std::string SecurityPluginDir() {
  // Where libddsc itself was loaded from; Debian puts the plugins in libddsc0debian/ beside it.
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&dds_create_participant), &info) == 0 ||
      info.dli_fname == nullptr) {
    return "";
  }
  const fs::path lib_dir = fs::path(info.dli_fname).parent_path();
  for (const fs::path& dir : {lib_dir / "libddsc0debian", lib_dir}) {
    if (fs::exists(dir / "libdds_security_auth.so")) return dir.string();
  }
  return "";
}

std::vector<std::pair<std::string, std::string>> SecurityProperties(
    const DdsSettings& settings, const std::string& default_identity) {
  if (settings.security_dir.empty()) {
    if (!settings.identity.empty()) {
      throw std::runtime_error("--identity " + settings.identity +
                               ": an identity needs --security DIR (or [transport] security)");
    }
    return {};
  }
  const std::string name =
      SecurityIdentityName(settings.identity.empty() ? default_identity : settings.identity);
  const std::string what = "--security " + settings.security_dir + ": ";
  const fs::path dir(settings.security_dir);
  if (!fs::is_directory(dir)) {
    throw std::runtime_error(what + "not a directory (make it with `felt security init " +
                             settings.security_dir + "`)");
  }
  if (!fs::is_directory(dir / name)) {
    std::string have;
    for (const auto& entry : fs::directory_iterator(dir)) {
      if (entry.is_directory())
        have += (have.empty() ? "" : ", ") + entry.path().filename().string();
    }
    throw std::runtime_error(what + "no identity '" + name + "' (" + (dir / name).string() +
                             " is missing; the directory has: " + (have.empty() ? "none" : have) +
                             ")");
  }
  const fs::path ca = dir / "ca_cert.pem";
  const fs::path governance = dir / "governance.p7s";
  const fs::path cert = dir / name / "cert.pem";
  const fs::path key = dir / name / "key.pem";
  const fs::path permissions = dir / name / "permissions.p7s";
  ExpectSecurityContent(ca, what, "-----BEGIN CERTIFICATE-----", "a PEM certificate");
  ExpectSecurityContent(cert, what, "-----BEGIN CERTIFICATE-----", "a PEM certificate");
  ExpectSecurityContent(key, what, "PRIVATE KEY-----", "a PEM private key");
  ExpectSecurityContent(governance, what, "MIME-Version", "an S/MIME signed document");
  ExpectSecurityContent(permissions, what, "MIME-Version", "an S/MIME signed document");
  const std::string plugin_dir = SecurityPluginDir();
  const auto plugin = [&](const char* short_name) {
    if (plugin_dir.empty()) return std::string(short_name);  // Cyclone adds lib and .so
    return (fs::path(plugin_dir) / ("lib" + std::string(short_name) + ".so")).string();
  };
  const auto file_uri = [](const fs::path& path) {
    return "file:" + fs::absolute(path).lexically_normal().string();
  };
  // Cyclone's names for the plugin settings (its manual, "Set the security properties in
  // participant QoS"; DDS Security 1.1 table 47 for the builtin plugins' properties).
  return {
      {"dds.sec.auth.library.path", plugin("dds_security_auth")},
      {"dds.sec.auth.library.init", "init_authentication"},
      {"dds.sec.auth.library.finalize", "finalize_authentication"},
      {"dds.sec.auth.identity_ca", file_uri(ca)},
      {"dds.sec.auth.identity_certificate", file_uri(cert)},
      {"dds.sec.auth.private_key", file_uri(key)},
      {"dds.sec.crypto.library.path", plugin("dds_security_crypto")},
      {"dds.sec.crypto.library.init", "init_crypto"},
      {"dds.sec.crypto.library.finalize", "finalize_crypto"},
      {"dds.sec.access.library.path", plugin("dds_security_ac")},
      {"dds.sec.access.library.init", "init_access_control"},
      {"dds.sec.access.library.finalize", "finalize_access_control"},
      {"dds.sec.access.permissions_ca", file_uri(ca)},
      {"dds.sec.access.governance", file_uri(governance)},
      {"dds.sec.access.permissions", file_uri(permissions)},
  };
}

}  // namespace felt::transport
