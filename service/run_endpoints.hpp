#pragma once
/// @file The DDS side of one run, shared by the live service and the archive replay:
/// writers of the topology, states, status, acknowledgements and (a run with a
/// circulation) the circulation, and the reader of commands, all keyed by the run id
/// (docs/dds.md).

#include "core/types.hpp"
#include "idl/bus.hpp"
#include "idl/records.hpp"

#include <deque>
#include <functional>
#include <unordered_map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace fiberfem::service {

/// The topology and status records a run publishes (idl/records.hpp); the endpoints fill
/// their run id (and the status's host and pid).
using TopologyData = dds::Topology;
using StatusData = dds::Status;

/// The answer to one command.
struct CommandReply {
  bool accepted = false;
  std::string reason;
};

class RunEndpoints {
 public:
  /// Joins the domain (CYCLONEDDS_URI). @throws dds::DdsError when DDS cannot start.
  explicit RunEndpoints(std::string run_id);
  /// Delivers the last answer before going (the answer to a shutdown is written just
  /// before the service exits): waits up to kLastAnswerWait for the acknowledgement writer
  /// to know an acknowledgement reader of the participant that sent the last command
  /// (discovery runs each way on its own: a client that has just made its reader can
  /// see the service's writer, and send, before the service has seen the reader), then
  /// up to a second for the matched readers to acknowledge. A sender that has gone (its
  /// command writer no longer matched) is not waited for.
  ~RunEndpoints();
  static constexpr std::chrono::seconds kLastAnswerWait{3};

  const std::string& run_id() const { return run_id_; }
  void publish_topology(const TopologyData& t);
  /// `positions`: 3 floats per state node; `activation`: one per element (may be empty).
  void publish_state(unsigned long frame, double time_s, unsigned parameter_version, std::vector<float>& positions,
                     std::vector<float>& activation);
  /// The same from the engine's numbers, converted to the wire's floats: `x` 3 x N
  /// positions, m (of `nodes` only when that is not empty), `activation` per element, 0..1.
  void publish_state(unsigned long frame, double time_s, unsigned parameter_version, const Eigen::Ref<const core::Positions>& x,
                     const std::vector<int>& nodes, const std::vector<double>& activation);
  void publish_status(const StatusData& s);
  /// Creates the circulation writer (a run with a circulation; without one the run
  /// publishes nothing on that topic). Call it before the first state, so that readers
  /// are matched by the time samples come. @return "" or, when DDS Security's access
  /// control refuses the writer, why (the run goes on without publishing its circulation).
  std::string enable_circulation();
  /// The circulation of the state published as `frame` (creates the writer if need be;
  /// nothing when it was refused).
  void publish_circulation(unsigned long frame, const core::circulation::Snapshot& s);
  /// Takes the commands addressed to this run, calls `apply(kind, args, id)` for each and
  /// acknowledges it with the frame and parameter version `stamp()` gives after it. A
  /// command whose id was already handled (one of the last kRememberedCommands) is not
  /// applied again: its first acknowledgement is written again.
  /// At least one command is handled, then more while less than `budget` of wall time has
  /// passed (the rest wait for the next boundary: a flood of commands cannot starve steps).
  /// @return the number of commands handled (applied or answered again).
  int handle_commands(const std::function<CommandReply(const std::string& kind, const std::string& args, const std::string& id)>& apply,
                      const std::function<std::pair<unsigned long, unsigned>()>& stamp,
                      std::chrono::nanoseconds budget = std::chrono::hours(1));
  /// Blocks until a command may be waiting or `timeout` passes.
  void wait_for_command(std::chrono::nanoseconds timeout) { commands_.wait(timeout); }
  /// Commands received again under an id already handled (not applied again).
  long duplicate_commands() const { return duplicates_; }
  /// How many handled command ids are remembered for the duplicate check.
  static constexpr size_t kRememberedCommands = 4096;

 private:
  struct Answer {
    bool accepted = false;
    std::string reason;
    unsigned long frame = 0;
    unsigned parameter_version = 0;
  };
  std::vector<float> positions_, activation_;  // publish_state's conversion buffers
  std::unordered_map<std::string, Answer> answered_;  // by command id, the last kRememberedCommands
  std::deque<std::string> answered_order_;
  long duplicates_ = 0;
  dds_instance_handle_t last_sender_writer_ = 0;  // the last command's writer; 0: none yet
  bool ack_reader_matched(const dds_guid_t& participant) const;
  void write_ack(const std::string& command_id, const std::string& client_id, const Answer& a);

  std::string run_id_, host_;
  dds::Participant pp_;
  dds::Writer<fiberfem_MeshTopology> topology_;
  dds::Writer<fiberfem_MeshState> state_;
  dds::Writer<fiberfem_ServiceStatus> status_;
  dds::Writer<fiberfem_CommandAck> ack_;
  dds::Reader<fiberfem_Command> commands_;
  std::optional<dds::Writer<fiberfem_CirculationState>> circulation_;
  std::string circulation_refused_;
};

/// "<scene>-<host>-<pid>".
std::string default_run_id(const std::string& scene);

}  // namespace fiberfem::service
