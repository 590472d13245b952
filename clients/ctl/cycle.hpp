#pragma once
/// @file Scripted contraction cycles (docs/cycles.md): a YAML file of timed actions in
/// simulation time, played by a client against a running service, each action's
/// acknowledgement checked and logged.

#include "clients/ctl/client.hpp"

#include <iosfwd>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::clients {

/// A bad cycle script: the message names the file, the action and the key.
class CycleError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// One command to send when the run's simulation time reaches `time_s`.
struct CycleEvent {
  double time_s = 0;       ///< Script time, s (from the start of playing, or absolute).
  std::string kind;        ///< Command kind (docs/commands.md).
  std::string args;        ///< Arguments, YAML flow text (JSON is YAML).
  std::string label;       ///< "action 3 (ramp 2/5)", for the log.
  /// For `every: beat` repeats: the action repeats one heart period (from the service's
  /// status) after this event, until `repeat_until_s`; 0 otherwise.
  bool every_beat = false;
  double repeat_until_s = 0;
  int repeat_left = 0;
};

struct CycleScript {
  std::string name;
  bool absolute_time = false;  ///< Times are the run's simulation time instead of since start.
  bool stop_on_reject = true;  ///< Stop at the first rejected action (exit non-zero).
  std::vector<CycleEvent> events;  ///< Sorted by time.
};

/// Parses a script. @throws CycleError naming the action and key.
CycleScript parse_cycle(const std::string& yaml_text, const std::string& origin);
CycleScript load_cycle(const std::string& path);

/// Plays `script` against `run_id`, logging each action (sent time, acknowledgement, the
/// frame and time at which it took effect) to `log`. @return 0 when every action was
/// accepted, 3 when one was rejected, 4 when the service stopped answering.
int play_cycle(Client& client, const std::string& run_id, CycleScript script, std::ostream& log);

}  // namespace fiberfem::clients
