#include "transport/dds_config.h"

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "transport/security.h"

namespace felt::transport {

TopicNames TopicNames::WithAffixes(const std::string& prefix, const std::string& suffix) {
  TopicNames names;
  names.pointer = prefix + names.pointer + suffix;
  names.force = prefix + names.force + suffix;
  names.status = prefix + names.status + suffix;
  return names;
}

const std::string& DefaultLoopbackConfig() {
  // Loopback only, unicast discovery through 127.0.0.1. ParticipantIndex auto is required: without
  // it each participant binds random ports that unicast discovery never probes
  // (shared/notes/cyclonedds-and-realtime.md). 30 indices = 30 processes per domain and host.
  static const std::string kConfig =
      "<CycloneDDS xmlns=\"https://cdds.io/config\">"
      "<Domain id=\"any\">"
      "<General>"
      "<Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
      "<AllowMulticast>false</AllowMulticast>"
      "</General>"
      "<Discovery>"
      "<ParticipantIndex>auto</ParticipantIndex>"
      "<MaxAutoParticipantIndex>30</MaxAutoParticipantIndex>"
      "<Peers><Peer address=\"127.0.0.1\"/></Peers>"
      "</Discovery>"
      "</Domain>"
      "</CycloneDDS>";
  return kConfig;
}

ResolvedConfig ResolveConfig(const DdsSettings& settings) {
  // 1. An explicit file wins: read it here so that a missing file gets a clear message.
  if (!settings.config_file.empty()) {
    std::ifstream in(settings.config_file);
    if (!in) {
      throw std::runtime_error("--dds-config " + settings.config_file + ": cannot open the file");
    }
    std::ostringstream text;
    text << in.rdbuf();
    if (text.str().find('<') == std::string::npos) {
      throw std::runtime_error("--dds-config " + settings.config_file +
                               ": not a Cyclone XML configuration (no element found)");
    }
    return {text.str(), "file " + settings.config_file};
  }
  // 2. Cyclone's own environment variable, passed through unchanged (XML or file:// list).
  const char* uri = std::getenv("CYCLONEDDS_URI");
  if (uri != nullptr && uri[0] != '\0') return {uri, "CYCLONEDDS_URI"};
  // 3. The embedded loopback configuration.
  return {DefaultLoopbackConfig(), "embedded"};
}

dds_return_t CheckDds(dds_return_t ret, const std::string& what) {
  if (ret < 0) throw std::runtime_error(what + ": " + dds_strretcode(ret));
  return ret;
}

Entity& Entity::operator=(Entity&& other) noexcept {
  if (this != &other) {
    Reset();
    handle_ = other.handle_;
    other.handle_ = 0;
  }
  return *this;
}

void Entity::Reset() {
  // A failed delete at tear-down has no caller to report to; the handle is gone either way.
  if (handle_ > 0) (void)dds_delete(handle_);
  handle_ = 0;
}

Domain::Domain(uint32_t domain_id, ResolvedConfig config)
    : id_(domain_id), config_(std::move(config)) {
  if (domain_id > 230) {
    throw std::invalid_argument("--domain " + std::to_string(domain_id) +
                                ": a DDS domain id must be in 0..230");
  }
  const dds_entity_t handle = dds_create_domain(domain_id, config_.config.c_str());
  if (handle == DDS_RETCODE_PRECONDITION_NOT_MET) {
    throw std::runtime_error("DDS domain " + std::to_string(domain_id) +
                             " already exists in this process (created outside felt::transport)");
  }
  CheckDds(handle, "DDS domain " + std::to_string(domain_id) + " with the " + config_.source +
                       " configuration");
  handle_ = Entity(handle);
}

std::shared_ptr<Domain> AcquireDomain(const DdsSettings& settings) {
  static std::mutex mutex;
  static std::map<uint32_t, std::weak_ptr<Domain>> live;
  ResolvedConfig config = ResolveConfig(settings);
  std::lock_guard<std::mutex> lock(mutex);
  // Share the live instance when there is one; two configurations for one domain cannot coexist.
  if (std::shared_ptr<Domain> domain = live[settings.domain_id].lock()) {
    if (domain->config().config != config.config) {
      throw std::runtime_error("DDS domain " + std::to_string(settings.domain_id) +
                               " is already in use in this process with the " +
                               domain->config().source + " configuration, not the " +
                               config.source + " one");
    }
    return domain;
  }
  auto domain = std::make_shared<Domain>(settings.domain_id, std::move(config));
  live[settings.domain_id] = domain;
  return domain;
}

Participant::Participant(std::shared_ptr<Domain> domain) : domain_(std::move(domain)) {
  entity_ = Entity(CheckDds(dds_create_participant(domain_->id(), nullptr, nullptr),
                            "dds_create_participant in domain " + std::to_string(domain_->id())));
}

Participant::Participant(const DdsSettings& settings, const std::string& default_identity) {
  // DDS Security through the participant's QoS properties (not the XML <Security> element): each
  // participant carries its own identity, so one process can hold a server and a device (the
  // domain and its XML configuration are shared per process, AcquireDomain), and a user's
  // --dds-config or CYCLONEDDS_URI needs no merging.
  const auto properties = SecurityProperties(settings, default_identity);
  domain_ = AcquireDomain(settings);
  const std::string what = "dds_create_participant in domain " + std::to_string(domain_->id());
  if (properties.empty()) {
    entity_ = Entity(CheckDds(dds_create_participant(domain_->id(), nullptr, nullptr), what));
    return;
  }
  std::unique_ptr<dds_qos_t, decltype(&dds_delete_qos)> qos(dds_create_qos(), &dds_delete_qos);
  for (const auto& [name, value] : properties)
    dds_qset_prop(qos.get(), name.c_str(), value.c_str());
  const dds_entity_t handle = dds_create_participant(domain_->id(), qos.get(), nullptr);
  if (handle < 0) {
    std::string files;
    for (const auto& [name, value] : properties) {
      if (value.rfind("file:", 0) == 0) files += (files.empty() ? "" : ", ") + value.substr(5);
    }
    throw std::runtime_error(
        what + " with DDS Security (--security " + settings.security_dir +
        "): " + dds_strretcode(handle) +
        ": Cyclone refused the identity (its message above says why: a certificate or "
        "permissions document not signed by the CA, expired, a subject the permissions do not "
        "name, or a plugin that failed to load); files: " +
        files);
  }
  entity_ = Entity(handle);
}

Entity CreateTopic(const Participant& participant, const dds_topic_descriptor_t* descriptor,
                   const std::string& name) {
  return Entity(
      CheckDds(dds_create_topic(participant.get(), descriptor, name.c_str(), nullptr, nullptr),
               "dds_create_topic \"" + name + "\""));
}

Entity CreateReader(const Participant& participant, const Entity& topic, const dds_qos_t* qos,
                    const dds_listener_t* listener, const std::string& what) {
  return Entity(CheckDds(dds_create_reader(participant.get(), topic.get(), qos, listener),
                         "dds_create_reader for " + what));
}

Entity CreateWriter(const Participant& participant, const Entity& topic, const dds_qos_t* qos,
                    const std::string& what) {
  return Entity(CheckDds(dds_create_writer(participant.get(), topic.get(), qos, nullptr),
                         "dds_create_writer for " + what));
}

uint32_t MatchedReaders(const Entity& writer) {
  dds_publication_matched_status_t status{};
  if (dds_get_publication_matched_status(writer.get(), &status) < 0) return 0;
  return status.current_count;
}

uint32_t MatchedWriters(const Entity& reader) {
  dds_subscription_matched_status_t status{};
  if (dds_get_subscription_matched_status(reader.get(), &status) < 0) return 0;
  return status.current_count;
}

void CopyId(const std::string& id, char (&out)[65], const std::string& what) {
  if (id.empty() || id.size() > kMaxIdLength || id.find('\0') != std::string::npos) {
    throw std::invalid_argument(what + " \"" + id + "\": must be 1 to " +
                                std::to_string(kMaxIdLength) + " characters without NUL");
  }
  std::memset(out, 0, sizeof(out));
  std::memcpy(out, id.data(), id.size());
}

}  // namespace felt::transport
