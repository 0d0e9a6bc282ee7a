#pragma once
// Cyclone DDS set-up for Felt: the embedded loopback configuration, the override rules, and RAII
// owners for domain, participant, topic, reader and writer that check every dds_* return code.
// Only transport/ (and its tests) include this header: it pulls in Cyclone's C API.

#include <dds/dds.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "rt/clock.h"
#include "transport/settings.h"
#include "transport/views.h"

namespace felt::transport {

/// The embedded Cyclone configuration: loopback interface `lo` only, no multicast, unicast
/// discovery through the peer 127.0.0.1, ParticipantIndex auto with MaxAutoParticipantIndex 30
/// (so up to 30 Felt processes per domain on one host find each other with no set-up).
/// Valid for any domain id.
const std::string& DefaultLoopbackConfig();

/// A configuration chosen by the precedence rules of DdsSettings.
struct ResolvedConfig {
  std::string config;  ///< what dds_create_domain receives: XML text or Cyclone's URI list
  std::string source;  ///< "embedded", "CYCLONEDDS_URI" or "file <path>", for messages and logs
};

/// Applies DdsSettings' precedence (file, then CYCLONEDDS_URI, then embedded).
/// Throws std::runtime_error naming the file when `settings.config_file` cannot be read or is
/// empty.
ResolvedConfig ResolveConfig(const DdsSettings& settings);

/// Throws std::runtime_error("<what>: <dds_strretcode>") when `ret` is negative (a Cyclone error);
/// returns `ret` otherwise. For set-up code; run-time paths count errors instead.
dds_return_t CheckDds(dds_return_t ret, const std::string& what);

/// Owns one Cyclone entity handle and deletes it (dds_delete) on destruction. Move-only.
class Entity {
 public:
  Entity() = default;
  /// Takes ownership of `handle` (> 0).
  explicit Entity(dds_entity_t handle) : handle_(handle) {}
  ~Entity() { Reset(); }
  Entity(Entity&& other) noexcept : handle_(other.handle_) { other.handle_ = 0; }
  Entity& operator=(Entity&& other) noexcept;
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;

  /// The handle (0 when empty).
  dds_entity_t get() const { return handle_; }
  /// Deletes the entity now (and, as Cyclone does, its children). Safe when empty.
  void Reset();

 private:
  dds_entity_t handle_ = 0;
};

/// One Cyclone domain instance in this process, created with a resolved configuration.
/// Cyclone allows one instance per domain id per process, so instances are shared: AcquireDomain
/// returns the live one when it exists (and its configuration matches) and the domain is deleted
/// when the last owner lets go.
class Domain {
 public:
  /// Use AcquireDomain.
  Domain(uint32_t domain_id, ResolvedConfig config);
  ~Domain() = default;
  Domain(const Domain&) = delete;
  Domain& operator=(const Domain&) = delete;

  /// The domain id.
  uint32_t id() const { return id_; }
  /// The configuration it was created with.
  const ResolvedConfig& config() const { return config_; }

 private:
  uint32_t id_;
  ResolvedConfig config_;
  Entity handle_;
};

/// The process's instance of `settings.domain_id`, created on first use with
/// ResolveConfig(settings). Thread-safe. Throws std::runtime_error when the configuration cannot be
/// read or Cyclone refuses it, or when the domain is already live here with a different
/// configuration.
std::shared_ptr<Domain> AcquireDomain(const DdsSettings& settings);

/// A participant in a shared domain; keeps the domain alive.
class Participant {
 public:
  /// Creates a participant without DDS Security. Throws std::runtime_error on a Cyclone error.
  explicit Participant(std::shared_ptr<Domain> domain);
  /// The one way Felt's transports join a domain: AcquireDomain(settings), then a participant
  /// with DDS Security on when settings.security_dir is set (identity settings.identity, else
  /// `default_identity`: "server", "device-<id>", "recorder"; transport/security.h). Throws
  /// std::runtime_error naming the security file that is missing or malformed, or, when Cyclone
  /// refuses the identity, the files it was given.
  Participant(const DdsSettings& settings, const std::string& default_identity);
  /// The participant's handle.
  dds_entity_t get() const { return entity_.get(); }
  /// The domain it belongs to.
  const Domain& domain() const { return *domain_; }

 private:
  std::shared_ptr<Domain> domain_;  // destroyed after entity_ (declared first)
  Entity entity_;
};

/// Creates a topic of type `descriptor` named `name` in `participant`. Throws on a Cyclone error.
Entity CreateTopic(const Participant& participant, const dds_topic_descriptor_t* descriptor,
                   const std::string& name);

/// Creates a reader on `topic` with `qos` and an optional `listener` (may be null).
/// Throws std::runtime_error naming `what` on a Cyclone error.
Entity CreateReader(const Participant& participant, const Entity& topic, const dds_qos_t* qos,
                    const dds_listener_t* listener, const std::string& what);

/// Creates a writer on `topic` with `qos`. Throws std::runtime_error naming `what` on an error.
Entity CreateWriter(const Participant& participant, const Entity& topic, const dds_qos_t* qos,
                    const std::string& what);

/// Takes every sample `reader` holds, in batches of N into the preallocated `ptrs` / `infos` (the
/// fixed-size types: Cyclone copies into the caller's buffers and allocates nothing), calling
/// `on_valid(i, now_ns)` for each sample i of a batch that holds data (an invalid one is an
/// instance state change, not a sample); now_ns is MonotonicNowNs() when the batch was taken.
/// Returns false when dds_take failed (the taking stops there). Real-time safe when on_valid is.
/// `on_invalid(i)`, if given, is called for each invalid sample (its key fields and info hold the
/// instance and the writer whose state changed).
template <size_t N, class OnValid, class OnInvalid = void (*)(size_t)>
bool TakeEverySample(
    const Entity& reader, std::array<void*, N>& ptrs, std::array<dds_sample_info_t, N>& infos,
    OnValid&& on_valid, OnInvalid&& on_invalid = [](size_t) {}) {
  constexpr auto kBatch = static_cast<dds_return_t>(N);
  for (;;) {
    const dds_return_t n = dds_take(reader.get(), ptrs.data(), infos.data(), N, N);
    if (n < 0) return false;
    const int64_t now_ns = MonotonicNowNs();
    for (dds_return_t i = 0; i < n; ++i) {
      if (infos[static_cast<size_t>(i)].valid_data) {
        on_valid(static_cast<size_t>(i), now_ns);
      } else {
        on_invalid(static_cast<size_t>(i));
      }
    }
    if (n < kBatch) return true;
  }
}

/// The number of readers matched to `writer` now (its publication-matched status); 0 when Cyclone
/// reports an error. Does not allocate.
uint32_t MatchedReaders(const Entity& writer);

/// The number of writers matched to `reader` now (its subscription-matched status); 0 when
/// Cyclone reports an error. Does not allocate.
uint32_t MatchedWriters(const Entity& reader);

/// Copies `id` into a fixed IDL string field of kMaxIdLength + 1 bytes. Throws
/// std::invalid_argument naming `what` when `id` is empty, longer than 64 characters or holds NUL.
void CopyId(const std::string& id, char (&out)[65], const std::string& what);

}  // namespace felt::transport
