#pragma once
/// @file Batch runs of a scene without the bus (`fiberfem run`): the time loop (a
/// RunDriver) or static solve, a progress bar on a terminal, a summary, and the JSON
/// report (docs/report-format.md).

#include "core/static_solver.hpp"
#include "io/scene.hpp"
#include "service/run_driver.hpp"

#include <iosfwd>
#include <string>
#include <vector>

namespace fiberfem::service {

struct BatchOptions {
  std::string source;                  ///< Where the scene came from (file path or "builtin:NAME").
  std::vector<std::string> overrides;  ///< The --set assignments applied (recorded in the report).
  bool force_static = false;           ///< --static: solve for equilibrium instead of stepping.
  int steps = 0;                       ///< --steps: step count; 0 takes it from until_s.
  double until_s = 0;                  ///< --until: simulated time, s; 0 takes the scene's.
  bool compare_static = false;         ///< After a dynamic run, also solve statically and compare probes.
  std::string report_path;             ///< --report: where to write the JSON report; empty for none.
  bool progress_bar = false;           ///< Redraw a progress bar on stderr (a terminal).
  /// Recording into an HDF5 archive (docs/archive.md): the scene's `archive` key with the
  /// --archive ... options applied over it; off unless `archive.enabled`.
  io::ArchiveSettings archive;
  /// --resume RUN.h5[@t]: continue from the archive's last checkpoint at or before that
  /// time (to the same end step). Empty: start from rest.
  ResumeFrom resume;
  /// --log-frames: print "frame F step S" after each recorded frame (scripts and tests
  /// following a run).
  bool log_frames = false;
};

/// Runs the scene and prints status lines and a summary to `out`. Stops at the first step
/// that fails (the reason goes to the summary and the report) or at SIGINT/SIGTERM (the
/// report is still written, with status "interrupted").
/// @return 0 if the run completed (and a static solve converged), 1 otherwise.
int run_batch(const io::Scene& scene, const BatchOptions& options, std::ostream& out);

/// The static equilibrium of the scene into `x` (Newton with the scene's rotation and
/// corotation; no active stress, so a contraction is left out).
core::StaticReport static_equilibrium(const io::Scene& scene, core::Positions& x);

}  // namespace fiberfem::service
