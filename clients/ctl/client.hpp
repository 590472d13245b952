#pragma once
/// @file A client of fiberfem services on DDS (docs/dds.md): discover runs from their
/// status, read topology and states, send a command and wait for its acknowledgement.
/// The command-line client (`fiberfem ctl`) and the cycle-script player use it.

#include "idl/bus.hpp"
#include "idl/records.hpp"

#include <chrono>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::clients {

/// The latest status of one run: fiberfem::ServiceStatus as C++ values (idl/records.hpp).
using RunStatus = dds::Status;

/// One state sample, copied out of DDS.
struct State {
  std::string run_id;
  unsigned long frame = 0;
  double time_s = 0;
  unsigned parameter_version = 0;
  double source_time_s = 0;       ///< When the service wrote it (DDS source timestamp, s since the epoch).
  std::vector<float> positions;   ///< 3 per state node, metres.
  std::vector<float> activation;  ///< Per element, 0..1.
};

/// The topology of a run, copied out of DDS (idl/records.hpp).
using Topology = dds::Topology;

/// A run's circulation at one frame, copied out of DDS (idl/records.hpp).
using Circulation = dds::Circulation;

/// The acknowledgement of a command.
struct Ack {
  bool accepted = false;
  std::string reason;
  unsigned long frame = 0;
  unsigned parameter_version = 0;
};

/// DDS Security's access control refused this client's identity what it asked for
/// (commands from an observer identity, docs/security.md).
class NotPermitted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What a flood of commands got back (Client::flood).
struct FloodReport {
  int sent = 0;            ///< Commands written.
  int acked = 0;           ///< Commands with an acknowledgement.
  int accepted = 0;        ///< ... of which accepted.
  int duplicate_acks = 0;  ///< Acknowledgements received again for an already answered command.
  int resent = 0;          ///< Commands written again (same id) after kResendAfter without an answer.
  std::vector<unsigned> versions;     ///< Parameter version of each accepted command's ack.
  std::vector<double> latencies_ms;   ///< Write to acknowledgement, per acknowledged command, ms.
  double seconds = 0;      ///< Wall time from the first write to the last acknowledgement, s.
};

class Client {
 public:
  /// Joins the DDS domain (CYCLONEDDS_URI). `client_id` tags every command sent.
  explicit Client(std::string client_id = "");

  /// Reads status samples for `wait` and returns the runs seen (by run id).
  std::map<std::string, RunStatus> discover(std::chrono::milliseconds wait);
  /// The single run on the domain if `run_id` is empty, else `run_id` once its status is
  /// seen. @throws std::runtime_error when none (or several, run_id empty) are found in `wait`.
  std::string resolve_run(const std::string& run_id, std::chrono::milliseconds wait);
  /// Newest status of `run_id` seen within `wait`, if any.
  std::optional<RunStatus> status(const std::string& run_id, std::chrono::milliseconds wait);
  /// The topology of `run_id` (transient-local: a late joiner gets it), within `wait`.
  std::optional<Topology> topology(const std::string& run_id, std::chrono::milliseconds wait);
  /// The next state of `run_id` newer than `after_frame` (any if negative), within `wait`.
  std::optional<State> next_state(const std::string& run_id, std::chrono::milliseconds wait, long after_frame = -1);
  /// The circulation samples of `run_id` newer than `after_frame` (any if negative), oldest
  /// first: those that have arrived, waiting up to `wait` for one. Empty when none came (a
  /// run without a circulation publishes none). The reader is made at the first call
  /// unless listen_circulation() made it before.
  std::vector<Circulation> circulation(const std::string& run_id, std::chrono::milliseconds wait, long after_frame = -1);
  /// Makes the circulation reader now (it then matches the services' writers while the
  /// caller looks for its run; samples are volatile: none written before it matched arrive).
  /// @return false when DDS Security's access control refuses it (circulation_refused()
  /// says why; circulation() then gives nothing).
  bool listen_circulation();
  /// Why the circulation reader was refused, or "".
  const std::string& circulation_refused() const { return circulation_refused_; }
  /// Sends a command and waits for its acknowledgement, writing it again under the same id
  /// every kResendAfter without one (a command written just before the service had
  /// discovered this client is not delivered; the service applies an id once and answers
  /// a repeat with the first answer). @throws std::runtime_error when no
  /// acknowledgement arrives within `wait` (the message says whether the service was seen);
  /// NotPermitted when the identity may not send commands (secure mode, an observer).
  Ack send(const std::string& run_id, const std::string& kind, const std::string& args_json,
           std::chrono::milliseconds wait = std::chrono::seconds(10));

  /// Sends `count` commands of one kind with up to `window` (in [1, 64]) unacknowledged at
  /// a time, and collects every acknowledgement within `wait` (docs/reliability.md).
  FloodReport flood(const std::string& run_id, const std::string& kind, const std::string& args_json, int count, int window,
                    std::chrono::milliseconds wait);

  /// Whether `run_id` is live: a status seen within `lost_after` and its status writer
  /// neither gone (liveliness lost, disposed) nor reporting "stopped". When not, `why`
  /// (if given) says what was seen. Reads the status samples that have arrived.
  bool live(const std::string& run_id, std::chrono::milliseconds lost_after, std::string* why = nullptr);
  /// The runs live in the sense of live(), newest status each.
  std::map<std::string, RunStatus> live_runs(std::chrono::milliseconds lost_after);
  /// Drops the states of `run_id` waiting in the reader (a follower that lost the run).
  void drop_states(const std::string& run_id);

  /// The newest status of each run read so far.
  const std::map<std::string, RunStatus>& runs() const { return runs_; }
  const std::string& client_id() const { return client_id_; }
  /// How long a command waits for its answer before it is written again (same id).
  static constexpr std::chrono::milliseconds kResendAfter{1000};

 private:
  using Clock = std::chrono::steady_clock;
  std::string client_id_;
  long next_command_ = 0;
  dds::Participant pp_;
  dds::Reader<fiberfem_ServiceStatus> status_reader_;
  // The command path; the writer is absent when DDS Security refuses it to this identity
  // (an observer may read states and status only), with the reason in commands_refused_.
  std::optional<dds::Writer<fiberfem_Command>> command_writer_;
  std::string commands_refused_;
  // Created at the first command (keep-all: a client that never sends must not gather
  // every other client's acknowledgements).
  std::optional<dds::Reader<fiberfem_CommandAck>> ack_reader_;
  std::optional<dds::Reader<fiberfem_MeshState>> state_reader_;
  std::optional<dds::Reader<fiberfem_MeshTopology>> topology_reader_;
  std::optional<dds::Reader<fiberfem_CirculationState>> circulation_reader_;
  std::string circulation_refused_;
  std::map<std::string, RunStatus> runs_;  // newest status per run
  std::map<std::string, dds_guid_t> participants_;  // the participant of each run (from its newest status writer)
  std::map<std::string, Clock::time_point> seen_;   // when each run's newest status arrived
  std::map<std::string, std::string> gone_;         // runs whose status writer went, and how
  /// Whether the command writer has matched a reader of `run_id`'s participant.
  bool command_reader_matched(const std::string& run_id) const;
  /// Whether the ack reader has matched the ack writer of `run_id`'s participant.
  bool ack_writer_matched(const std::string& run_id) const;
  /// Waits until the command reader of `run_id`'s participant is matched. @throws on timeout.
  void await_command_reader(const std::string& run_id, Clock::time_point deadline);
  // The command writer (else NotPermitted) and the ack reader, made at the first command.
  void ensure_command_path();
  /// Writes one command under `id`.
  void post(const std::string& run_id, const std::string& id, const std::string& kind, const std::string& args_json);
  std::string next_id() { return client_id_ + "-" + std::to_string(++next_command_); }
  /// Reads the status samples that arrived; returns the run ids with a new status.
  std::vector<std::string> poll_status();
};

/// Follows one run's states across service restarts and hosts cut off and back
/// (docs/ctl.md, "Following a run"). The rule for which run to follow:
///  - given a run id: that run id, whichever service carries it (a service restarted with
///    the same `--run-id`);
///  - given none: the only live run on the domain; after it is lost, the only live run of
///    the same scene (a restarted service with a new default id), never a guess between
///    several.
/// A run is lost when no status arrives for `lost_after` (the status liveliness lease,
/// 3 s), when its status writer's liveliness is lost or it reports "stopped".
class RunFollower {
 public:
  struct Event {
    enum class Kind { state, lost, found };
    Kind kind = Kind::state;
    std::string run_id;
    std::string message;         ///< lost: why; found: scene, host and pid.
    std::optional<State> state;  ///< kind == state.
  };
  RunFollower(Client& client, std::string run_id, std::chrono::milliseconds lost_after = std::chrono::seconds(3));
  /// The next event within `wait`, or nullopt when nothing happened.
  std::optional<Event> next(std::chrono::milliseconds wait);
  /// The run followed now (empty while none is).
  const std::string& run_id() const { return run_; }

 private:
  Client& client_;
  std::string wanted_, run_, scene_;
  std::chrono::milliseconds lost_after_;
  long last_frame_ = -1;
  int pid_ = 0;  // of the service followed: another pid under the same run id is a restart
  std::string host_;
};

}  // namespace fiberfem::clients
