#pragma once
/// @file A running scene and everything a command can change (docs/commands.md), with no
/// DDS in it: the service feeds it commands at step boundaries, tests call it directly.
///
/// A command is a kind and a JSON (or YAML) object of arguments. Each is checked whole
/// before anything changes: a rejected command changes nothing and its reason names the
/// argument at fault. The commands are a table (RunControl::table: kind, allowed arguments,
/// handler), their handlers one file per family. A parameter command is read onto the
/// running typed value of its scene section (io/scene_sections.hpp; material, contraction
/// and fibers by the scene's own readers, so with the same keys, units and checks as a
/// scene file), applied to the engine, and kept as the running parameter state; the scene
/// text is written from that state only when it is asked for.

#include "core/simulator.hpp"
#include "io/scene.hpp"
#include "service/engine.hpp"

#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace YAML {
class Node;
}

namespace fiberfem::service {

namespace detail {
class Args;
}

/// What a command did.
struct CommandResult {
  bool accepted = false;
  std::string reason;  ///< Why it was rejected, or a short account of what it did.
};

/// A force applied by a command: a total force spread evenly over nodes.
struct AppliedForce {
  std::vector<int> nodes;
  std::vector<core::Vec3> force_n;  ///< Per node, newtons.
  double until_s = std::numeric_limits<double>::infinity();  ///< Cleared at this simulation time.
};

class RunControl {
 public:
  /// Builds the engine of `scene`'s tier (service/engine.hpp); `files` are the in-memory
  /// files a built-in scene reads (kept for re-parsing the running scene).
  /// @throws std::invalid_argument as the engine does.
  explicit RunControl(io::Scene scene, const io::EmbeddedFiles* files = nullptr);

  /// The running parameters as JSON: {"scene_yaml": the scene with its parameter sections
  /// written from the running ones (every accepted parameter command in), "forces": [...]}.
  /// With the engine's checkpoint it resumes the run exactly (restore_parameter_state,
  /// then Engine::restore).
  std::string parameter_state_json() const;
  /// Rebuilds the engine for a parameter state (the scene text re-parsed, forces
  /// re-applied); the state is then the rest state until Engine::restore.
  /// @throws std::invalid_argument (io::SceneError) naming what is wrong.
  void restore_parameter_state(const std::string& json);
  /// The running scene (scene_yaml parsed again): what a recording started now records.
  io::Scene running_scene() const;

  /// Applies one command now (between steps). Never throws.
  CommandResult apply(const std::string& kind, const std::string& args_json);

  /// Called before every step: clears timed forces that have expired.
  void before_step();
  /// Whether the run should step now (not paused, or steps ordered by `step`); counts
  /// one ordered step down.
  bool take_step_permission();

  /// The running engine (a command may replace it: do not keep the reference).
  Engine& engine() { return *engine_; }
  const Engine& engine() const { return *engine_; }
  /// The real-time simulator. @throws std::logic_error on the accurate tier.
  core::Simulator& simulator();
  const core::Simulator& simulator() const { return const_cast<RunControl*>(this)->simulator(); }
  const io::Scene& scene() const { return scene_; }
  bool paused() const { return paused_; }
  bool shutdown_requested() const { return shutdown_; }
  /// Bumped by every accepted command that changes the run.
  unsigned parameter_version() const { return version_; }
  /// Bumped when the topology's published content (fibers) changed.
  unsigned topology_version() const { return topology_version_; }
  const std::map<std::string, AppliedForce>& forces() const { return forces_; }
  /// Heart rate of the running contraction, beats/min (0 when off).
  double heart_rate_bpm() const;
  /// Largest peak tension of the running contraction, Pa.
  double peak_tension_pa() const;
  /// The kinds this accepts (the command table's, in its order).
  static const std::vector<std::string>& kinds();

  /// Handles start_recording and stop_recording (the service sets it; without one they are
  /// refused). Not counted as run changes (the parameter version stays).
  using RecordingHandler = std::function<CommandResult(const std::string& kind, const std::string& args)>;
  void set_recording_handler(RecordingHandler h) { recording_ = std::move(h); }

 private:
  // One command kind: the arguments it allows, its handler (nullptr: the recording
  // handler's), and whether an accepted one bumps the parameter version.
  using Handler = CommandResult (RunControl::*)(const detail::Args&);
  struct Entry {
    std::string kind;
    std::vector<std::string> args;
    Handler handler;
    bool changes_run;
    /// Whether the handler may change the parameter sections (the written scene text is
    /// then written again when next asked for). True unless the row says otherwise.
    bool changes_parameters = true;
  };
  static const std::vector<Entry>& table();
  // Handlers, by family: run_control_flow.cpp, _forces.cpp, _parameters.cpp.
  CommandResult on_pause(const detail::Args& a);
  CommandResult on_resume(const detail::Args& a);
  CommandResult on_step(const detail::Args& a);
  CommandResult on_shutdown(const detail::Args& a);
  CommandResult on_reset(const detail::Args& a);
  CommandResult on_checkpoint(const detail::Args& a);
  CommandResult on_restore(const detail::Args& a);
  CommandResult on_apply_force(const detail::Args& a);
  CommandResult on_clear_force(const detail::Args& a);
  CommandResult on_set_material(const detail::Args& a);
  CommandResult on_set_damping(const detail::Args& a);
  CommandResult on_set_contraction(const detail::Args& a);
  CommandResult on_set_fibers(const detail::Args& a);
  CommandResult on_set_gravity(const detail::Args& a);
  CommandResult on_set_time_step(const detail::Args& a);
  CommandResult on_set_solver(const detail::Args& a);
  CommandResult on_set_circulation(const detail::Args& a);  // run_control_circulation.cpp
  // The running circulation section: the scene's, with the keys commands set.
  YAML::Node circulation_section() const;
  // A loop that beats with the contraction (no circulation.heart_rate given) takes the
  // contraction's new period, keeping its beat's phase (after set_contraction).
  void follow_contraction_rate();
  RecordingHandler recording_;
  void refresh_loads();
  // The accurate engine built again from the running scene (its state carried over) after
  // a command changed params_; on failure params_ goes back to `before`. Nothing on the
  // real-time tier, whose setters changed the simulator already.
  void rebuild_accurate(io::SceneParameters before);

  io::Scene scene_;             // as loaded (reset with parameters restores it)
  std::string scene_doc_;       // the scene text the parameter sections are written into (loaded or restored)
  io::SceneParameters params_;  // the running parameter sections (the scene's, commands read onto them)
  // scene_doc_ with params_ written in (io::write_scene_parameters), kept between the
  // commands that change params_; empty: to be written at the next use.
  mutable std::string scene_text_;
  const std::string& scene_text() const;
  const io::EmbeddedFiles* files_ = nullptr;
  struct Saved {
    EngineCheckpoint state;
    std::string parameters;
  };
  std::map<std::string, Saved> checkpoints_;  // named, in memory (checkpoint / restore)
  std::unique_ptr<Engine> engine_;
  core::Loads base_loads_;  // the scene's loads with commanded gravity (forces come on top)
  std::map<std::string, AppliedForce> forces_;
  bool paused_ = false;
  long ordered_steps_ = 0;
  bool shutdown_ = false;
  unsigned version_ = 0;
  unsigned topology_version_ = 0;
  int force_counter_ = 0;
};

}  // namespace fiberfem::service
