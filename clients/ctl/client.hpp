#pragma once
/// @file A client of fiberfem services on DDS (docs/dds.md): discover runs from their
/// status, read topology and states, send a command and wait for its acknowledgement.
/// The command-line client (`fiberfem ctl`) and the cycle-script player use it.

#include "service/dds/bus.hpp"

#include <chrono>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::clients {

/// The latest status of one run (the fields of fiberfem::ServiceStatus that clients show).
struct RunStatus {
  std::string run_id, scene_name, host, state, mode, last_message, recording;
  int pid = 0;
  bool replay = false;
  unsigned long frame = 0;
  double time_s = 0, frames_per_second = 0, real_time_factor = 0, step_ms = 0, solve_ms = 0, publish_ms = 0;
  int solver_iterations = 0, inverted_elements = 0;
  double solver_residual = 0, kinetic_energy_j = 0, elastic_energy_j = 0;
  unsigned recovered_steps = 0, failed_steps = 0, parameter_version = 0;
  double heart_rate_bpm = 0, peak_tension_pa = 0, dt_s = 0;
  unsigned long recorded_frames = 0;
};

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

/// The topology of a run, copied out of DDS.
struct Topology {
  std::string run_id, scene_name, scene_hash;
  bool replay = false;
  unsigned num_nodes = 0, num_elements = 0;
  std::vector<float> rest_positions, fibers;
  std::vector<int> tets, triangles, triangle_elements, state_nodes, fixed_nodes;
  std::vector<int> element_regions;
  std::vector<std::string> region_names;
};

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
  /// Sends a command and waits for its acknowledgement. @throws std::runtime_error when no
  /// acknowledgement arrives within `wait` (the message says whether the service was seen);
  /// NotPermitted when the identity may not send commands (secure mode, an observer).
  Ack send(const std::string& run_id, const std::string& kind, const std::string& args_json,
           std::chrono::milliseconds wait = std::chrono::seconds(10));

  const std::string& client_id() const { return client_id_; }

 private:
  std::string client_id_;
  long next_command_ = 0;
  dds::Participant pp_;
  dds::Reader<fiberfem_ServiceStatus> status_reader_;
  // The command path; absent when DDS Security refuses it to this identity (an observer
  // may read states and status only), with the reason in commands_refused_.
  std::optional<dds::Writer<fiberfem_Command>> command_writer_;
  std::optional<dds::Reader<fiberfem_CommandAck>> ack_reader_;
  std::string commands_refused_;
  std::optional<dds::Reader<fiberfem_MeshState>> state_reader_;
  std::optional<dds::Reader<fiberfem_MeshTopology>> topology_reader_;
  std::map<std::string, RunStatus> runs_;  // newest status per run
  std::map<std::string, dds_guid_t> participants_;  // the participant of each run (from its status writer)
  /// Whether the command writer has matched a reader of `run_id`'s participant.
  bool command_reader_matched(const std::string& run_id) const;
  void poll_status();
};

}  // namespace fiberfem::clients
