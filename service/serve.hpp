#pragma once
/// @file The service (`fiberfem serve`): runs a scene (a RunDriver), publishes its
/// topology, states and status on DDS, applies commands at step boundaries and
/// acknowledges each (docs/dds.md, docs/commands.md).

#include "io/scene.hpp"
#include "service/run_driver.hpp"

#include <iosfwd>
#include <string>

namespace fiberfem::service {

struct ServeOptions {
  std::string source;         ///< Where the scene came from (file or "builtin:NAME").
  std::string run_id;         ///< Key of every sample; empty: "<scene>-<host>-<pid>".
  bool realtime = true;       ///< Pace steps to the wall clock; false: as fast as possible.
  double real_time_factor = 1.0;  ///< Simulated seconds per wall second when realtime, in (0, 100]. Default 1.
  double publish_hz = 30.0;   ///< Largest state publish rate, 1/s, in (0, 1000]. Default 30.
  double status_hz = 2.0;     ///< Status publish rate, 1/s, in (0, 100]. Default 2.
  double until_s = 0.0;       ///< Stop at this simulation time, s; 0: run until shut down.
  bool surface_only = false;  ///< States carry the boundary nodes only (topology.state_nodes).
  bool start_paused = false;  ///< Start paused (step or resume by command).
  bool status_line = false;   ///< Redraw one status line on stderr (a terminal).
  /// Wall time spent on commands at one step boundary, ms, in (0, 1e4]: at least one is
  /// handled, more while within it; the rest wait for the next boundary, so a flood of
  /// commands does not starve the steps. Default 4.
  double command_budget_ms = 4.0;
  /// Record from the start (the scene's `archive` key or --archive); start_recording
  /// and stop_recording commands control it while running (docs/archive.md).
  io::ArchiveSettings archive;
  /// Start from an archive's checkpoint (--resume RUN.h5[@t]), with the parameters the
  /// archived run had.
  ResumeFrom resume;
  const io::EmbeddedFiles* files = nullptr;  ///< In-memory files of a built-in scene.
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

/// Runs the service until shutdown (command, SIGINT, SIGTERM, or until_s).
/// Prints a start line, periodic status (or the live line) and a summary to `out`.
/// @return 0 on a clean stop, 1 when DDS could not start.
int serve(const io::Scene& scene, const ServeOptions& options, std::ostream& out);

}  // namespace fiberfem::service
