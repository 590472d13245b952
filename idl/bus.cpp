// QoS of the fiberfem topics, in one place (DESIGN.md section 4, docs/dds.md):
//   topology  reliable, transient-local, keep-last 1   (late joiners get the mesh)
//   state     reliable, volatile, keep-last 1, deadline (large samples: best effort
//             would drop a whole frame when one fragment is lost; keep-last 1 never
//             blocks the writer on a slow reader, it replaces the frame)
//   command   reliable, volatile, keep-all              (no command is lost)
//   ack       reliable, transient-local, keep-last 1024 per run, the last 64 for late
//             joiners (an answer written before the service discovered the asking
//             client's reader still reaches it); readers
//             keep all: the acks of every client of a run share one instance, and a client
//             that took its samples late under a flood of others' would lose its own
//   status    reliable, volatile, keep-last 1, deadline, liveliness lease
//   circulation  reliable, volatile, keep-last 16 (readers 256): small samples, one per
//             published state; a reader polling a few times a second still gets every
//             one (a whole pressure-volume loop); no deadline (the state's covers the run)

#include "idl/bus.hpp"

namespace fiberfem::dds {
namespace {

// The state deadline a reader may request: a service publishes at least this often,
// paused or not.
constexpr dds_duration_t kStateDeadline = DDS_SECS(2);
constexpr dds_duration_t kStatusDeadline = DDS_SECS(2);
constexpr dds_duration_t kLivelinessLease = DDS_SECS(3);
// Acks a run keeps unacknowledged by a reader before the oldest goes: how far a client's
// receive thread may lag under a flood of other clients' commands (64 lost acks on a
// machine at load 12 with four clients of 8 commands in flight each; docs/reliability.md).
constexpr int32_t kAckHistory = 1024;
// Acks a client that joins late receives.
constexpr int32_t kAckLateJoiners = 64;
// Circulation samples the writer keeps for a slow reader, and a reader keeps untaken.
constexpr int32_t kCirculationHistory = 16;
constexpr int32_t kCirculationReaderHistory = 256;

struct Qos {
  dds_qos_t* q = dds_create_qos();
  ~Qos() { dds_delete_qos(q); }
};

void set_qos(dds_qos_t* q, Topic t) {
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(10));
  switch (t) {
    case Topic::topology:
      dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
      break;
    case Topic::state:
      dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
      dds_qset_deadline(q, kStateDeadline);
      break;
    case Topic::command:
      dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
      dds_qset_history(q, DDS_HISTORY_KEEP_ALL, DDS_LENGTH_UNLIMITED);
      break;
    case Topic::ack:
      dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, kAckHistory);
      dds_qset_durability_service(q, 0, DDS_HISTORY_KEEP_LAST, kAckLateJoiners, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED,
                                  DDS_LENGTH_UNLIMITED);
      break;
    case Topic::status:
      dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
      dds_qset_deadline(q, kStatusDeadline);
      dds_qset_liveliness(q, DDS_LIVELINESS_AUTOMATIC, kLivelinessLease);
      break;
    case Topic::circulation:
      dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, kCirculationHistory);
      break;
  }
}

}  // namespace

dds_return_t check(dds_return_t rc, const char* what) {
  if (rc == DDS_RETCODE_NOT_ALLOWED_BY_SECURITY)
    throw DdsError(std::string(what) + " refused by DDS Security access control (the permissions of this identity "
                   "do not grant it)", rc);
  if (rc < 0) throw DdsError(std::string(what) + " failed: " + dds_strretcode(rc), rc);
  return rc;
}

Entity& Entity::operator=(Entity&& o) noexcept {
  if (this != &o) {
    if (handle_ > 0) dds_delete(handle_);
    handle_ = o.handle_;
    o.handle_ = 0;
  }
  return *this;
}

Entity::~Entity() {
  if (handle_ > 0) dds_delete(handle_);
}

Participant::Participant(dds_domainid_t domain)
    : pp_(check(dds_create_participant(domain, nullptr, nullptr),
                "dds_create_participant (check CYCLONEDDS_URI, e.g. configs/dds/loopback.xml)")) {}

const char* topic_name(Topic t) {
  switch (t) {
    case Topic::topology: return "fiberfem_mesh_topology";
    case Topic::state: return "fiberfem_mesh_state";
    case Topic::command: return "fiberfem_command";
    case Topic::ack: return "fiberfem_command_ack";
    case Topic::status: return "fiberfem_status";
    case Topic::circulation: return "fiberfem_circulation";
  }
  return "?";
}

namespace detail {

dds_entity_t create_topic(const Participant& pp, Topic t, const dds_topic_descriptor_t* desc) {
  Qos qos;
  set_qos(qos.q, t);
  return check(dds_create_topic(pp.get(), desc, topic_name(t), qos.q, nullptr),
               (std::string("dds_create_topic ") + topic_name(t)).c_str());
}

dds_entity_t create_writer(const Participant& pp, dds_entity_t topic, Topic t) {
  Qos qos;
  set_qos(qos.q, t);
  return check(dds_create_writer(pp.get(), topic, qos.q, nullptr), (std::string("dds_create_writer on ") + topic_name(t)).c_str());
}

dds_entity_t create_reader(const Participant& pp, dds_entity_t topic, Topic t) {
  Qos qos;
  set_qos(qos.q, t);
  if (t == Topic::state || t == Topic::status) dds_qset_deadline(qos.q, DDS_INFINITY);  // readers ask none
  if (t == Topic::ack) dds_qset_history(qos.q, DDS_HISTORY_KEEP_ALL, DDS_LENGTH_UNLIMITED);
  if (t == Topic::circulation) dds_qset_history(qos.q, DDS_HISTORY_KEEP_LAST, kCirculationReaderHistory);
  return check(dds_create_reader(pp.get(), topic, qos.q, nullptr), (std::string("dds_create_reader on ") + topic_name(t)).c_str());
}

void write(dds_entity_t writer, const void* sample, const char* what) {
  const dds_return_t rc = dds_write(writer, sample);
  if (rc < 0) throw DdsError(std::string("dds_write on ") + what + " failed: " + dds_strretcode(rc), rc);
}

bool wait_for_data(dds_entity_t waitset, std::chrono::nanoseconds timeout) {
  dds_attach_t triggered = 0;
  const dds_return_t n = dds_waitset_wait(waitset, &triggered, 1, static_cast<dds_duration_t>(timeout.count()));
  check(n, "dds_waitset_wait");
  return n > 0;
}

}  // namespace detail
}  // namespace fiberfem::dds
