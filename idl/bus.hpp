#pragma once
/// @file The one DDS wrapper (STYLE.md habit 9): RAII handles over the Cyclone DDS C API,
/// the six fiberfem topics and their QoS, chosen here and nowhere else (docs/dds.md).
///
/// Samples are the idlc-generated C structs (idl/*.idl). Writers take them filled with
/// pointers into caller-owned buffers (no copy); readers lend them to a callback and
/// return the loan after it.

#include "circulation.h"
#include "control.h"
#include "mesh.h"
#include "status.h"

#include <dds/dds.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::dds {

/// A DDS call failed; the message names the call and Cyclone's reason.
class DdsError : public std::runtime_error {
 public:
  explicit DdsError(const std::string& what, dds_return_t code = DDS_RETCODE_ERROR)
      : std::runtime_error(what), code_(code) {}
  /// Cyclone's return code (DDS_RETCODE_NOT_ALLOWED_BY_SECURITY when DDS Security's
  /// access control refused the entity, docs/security.md).
  dds_return_t code() const { return code_; }

 private:
  dds_return_t code_;
};

/// Throws DdsError naming `what` when `rc` is a DDS error code; returns rc otherwise.
dds_return_t check(dds_return_t rc, const char* what);

/// Owns one DDS entity (participant, topic, reader, writer, waitset, condition).
class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t handle) : handle_(handle) {}
  Entity(Entity&& o) noexcept : handle_(o.handle_) { o.handle_ = 0; }
  Entity& operator=(Entity&& o) noexcept;
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;
  ~Entity();
  dds_entity_t get() const { return handle_; }

 private:
  dds_entity_t handle_ = 0;
};

/// A domain participant. The domain and the network come from CYCLONEDDS_URI (use
/// configs/dds/loopback.xml for tests and on hosts with a preferred non-loopback interface).
class Participant {
 public:
  explicit Participant(dds_domainid_t domain = DDS_DOMAIN_DEFAULT);
  dds_entity_t get() const { return pp_.get(); }

 private:
  Entity pp_;
};

/// The fiberfem topics. Names and QoS live in bus.cpp (docs/dds.md has the table).
enum class Topic { topology, state, command, ack, status, circulation };

/// Traits of each sample type: its topic and descriptor.
template <class T>
struct TopicOf;
template <>
struct TopicOf<fiberfem_MeshTopology> {
  static constexpr Topic topic = Topic::topology;
  static const dds_topic_descriptor_t* desc() { return &fiberfem_MeshTopology_desc; }
};
template <>
struct TopicOf<fiberfem_MeshState> {
  static constexpr Topic topic = Topic::state;
  static const dds_topic_descriptor_t* desc() { return &fiberfem_MeshState_desc; }
};
template <>
struct TopicOf<fiberfem_Command> {
  static constexpr Topic topic = Topic::command;
  static const dds_topic_descriptor_t* desc() { return &fiberfem_Command_desc; }
};
template <>
struct TopicOf<fiberfem_CommandAck> {
  static constexpr Topic topic = Topic::ack;
  static const dds_topic_descriptor_t* desc() { return &fiberfem_CommandAck_desc; }
};
template <>
struct TopicOf<fiberfem_ServiceStatus> {
  static constexpr Topic topic = Topic::status;
  static const dds_topic_descriptor_t* desc() { return &fiberfem_ServiceStatus_desc; }
};
template <>
struct TopicOf<fiberfem_CirculationState> {
  static constexpr Topic topic = Topic::circulation;
  static const dds_topic_descriptor_t* desc() { return &fiberfem_CirculationState_desc; }
};

/// DDS topic name of a topic ("fiberfem_mesh_state", ...).
const char* topic_name(Topic t);

namespace detail {
dds_entity_t create_topic(const Participant& pp, Topic t, const dds_topic_descriptor_t* desc);
dds_entity_t create_writer(const Participant& pp, dds_entity_t topic, Topic t);
dds_entity_t create_reader(const Participant& pp, dds_entity_t topic, Topic t);
void write(dds_entity_t writer, const void* sample, const char* what);
/// Blocks until the reader has data or `timeout` passes; true when data arrived.
bool wait_for_data(dds_entity_t waitset, std::chrono::nanoseconds timeout);
}  // namespace detail

/// A writer of one topic with that topic's QoS.
template <class T>
class Writer {
 public:
  explicit Writer(const Participant& pp)
      : topic_(detail::create_topic(pp, TopicOf<T>::topic, TopicOf<T>::desc())),
        writer_(detail::create_writer(pp, topic_.get(), TopicOf<T>::topic)) {}
  void write(const T& sample) { detail::write(writer_.get(), &sample, topic_name(TopicOf<T>::topic)); }
  /// Disposes the sample's instance (its key): readers see the run end.
  void dispose(const T& sample) { check(dds_writedispose(writer_.get(), &sample), "dds_writedispose"); }
  /// Readers currently matched.
  int matched() const {
    dds_publication_matched_status_t s{};
    check(dds_get_publication_matched_status(writer_.get(), &s), "dds_get_publication_matched_status");
    return static_cast<int>(s.current_count);
  }
  dds_entity_t get() const { return writer_.get(); }

 private:
  Entity topic_, writer_;
};

/// A reader of one topic with that topic's QoS.
template <class T>
class Reader {
 public:
  explicit Reader(const Participant& pp)
      : topic_(detail::create_topic(pp, TopicOf<T>::topic, TopicOf<T>::desc())),
        reader_(detail::create_reader(pp, topic_.get(), TopicOf<T>::topic)),
        waitset_(check(dds_create_waitset(pp.get()), "dds_create_waitset")),
        condition_(check(dds_create_readcondition(reader_.get(), DDS_ANY_STATE), "dds_create_readcondition")) {
    check(dds_waitset_attach(waitset_.get(), condition_.get(), 0), "dds_waitset_attach");
  }
  ~Reader() {
    if (waitset_.get() > 0 && condition_.get() > 0) dds_waitset_detach(waitset_.get(), condition_.get());
  }
  Reader(Reader&&) = default;

  /// Takes every available sample and calls fn(const T&, const dds_sample_info_t&) for
  /// each valid one (disposals and unregistrations have no data and are skipped, unless
  /// `with_invalid` is set, when fn is called with the key fields only), at most
  /// `max_samples` of them (the rest stay for the next take).
  /// @return the number of samples passed to fn.
  template <class F>
  int take(F&& fn, bool with_invalid = false, int max_samples = 1 << 30) {
    constexpr int kBatch = 16;
    int n_total = 0;
    while (n_total < max_samples) {
      void* samples[kBatch] = {};
      dds_sample_info_t infos[kBatch];
      const int want = std::min(kBatch, max_samples - n_total);
      const dds_return_t n = dds_take(reader_.get(), samples, infos, static_cast<size_t>(want), static_cast<uint32_t>(want));
      if (n <= 0) {
        check(n, "dds_take");
        break;
      }
      struct Loan {  // the loan goes back even when fn throws
        dds_entity_t reader;
        void** samples;
        int32_t n;
        ~Loan() { dds_return_loan(reader, samples, n); }
      } loan{reader_.get(), samples, n};
      for (int i = 0; i < n; ++i)
        if (infos[i].valid_data || with_invalid) {
          fn(*static_cast<const T*>(samples[i]), infos[i]);
          ++n_total;
        }
      if (n < want) break;
    }
    return n_total;
  }
  /// Blocks until data is available or `timeout` passes; true when data is available.
  bool wait(std::chrono::nanoseconds timeout) { return detail::wait_for_data(waitset_.get(), timeout); }
  /// Writers currently matched.
  int matched() const {
    dds_subscription_matched_status_t s{};
    check(dds_get_subscription_matched_status(reader_.get(), &s), "dds_get_subscription_matched_status");
    return static_cast<int>(s.current_count);
  }
  dds_entity_t get() const { return reader_.get(); }

 private:
  Entity topic_, reader_, waitset_, condition_;
};

/// A sequence view over caller-owned memory (the writer does not free it).
template <class Seq, class V>
Seq borrow(std::vector<V>& v) {
  Seq s{};
  s._length = s._maximum = static_cast<uint32_t>(v.size());
  s._buffer = v.data();
  s._release = false;
  return s;
}

/// A string member of a sample as std::string ("" for null).
inline std::string str(const char* s) { return s ? std::string(s) : std::string(); }

}  // namespace fiberfem::dds
