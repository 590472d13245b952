#pragma once
/// @file Batch runs of a scene without the bus (`fiberfem run`): the time loop or static
/// solve, a progress bar on a terminal, a summary, and the JSON report
/// (docs/report-format.md).

#include "io/scene.hpp"

#include <cmath>
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
  /// --resume RUN.h5[@t]: continue from the archive's last checkpoint at or before
  /// resume_time_s (infinity: its last checkpoint). Empty: start from rest.
  std::string resume_path;
  double resume_time_s = HUGE_VAL;     ///< Simulated time, s, of the checkpoint to resume from.
  /// --log-frames: print "frame F step S" after each recorded frame (scripts and tests
  /// following a run).
  bool log_frames = false;
};

/// Whether this build records archives (FIBERFEM_WITH_HDF5 and HDF5 found).
bool has_archive();

/// The scene stored in an archive (its YAML after the original overrides, looked up from
/// its original directory), with `overrides` applied.
/// @throws std::runtime_error if the file is not a readable archive or the build has none.
io::Scene scene_from_archive(const std::string& h5_path, const std::vector<std::string>& overrides);

/// Runs the scene and prints status lines and a summary to `out`. Stops at the first step
/// that fails (the reason goes to the summary and the report) or at SIGINT/SIGTERM (the
/// report is still written, with status "interrupted").
/// @return 0 if the run completed (and a static solve converged), 1 otherwise.
int run_batch(const io::Scene& scene, const BatchOptions& options, std::ostream& out);

}  // namespace fiberfem::service
