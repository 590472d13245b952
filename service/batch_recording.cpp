// The start and end of a batch run's recording, on either tier: resume from an archive's
// checkpoint, record into a new archive, close it (docs/archive.md).

#include "service/batch_report.hpp"

#include <cstdio>
#include <ostream>
#include <stdexcept>

namespace fiberfem::service::detail {

void log_frame(const RunDriver& run, const BatchOptions& o, std::ostream& out) {
  if (o.log_frames) out << "frame " << run.recorded_frames() << " step " << run.engine().step_count() << "\n" << std::flush;
}

void start_run(RunDriver& run, const BatchOptions& o, json& report, std::ostream& out) {
  if (!o.resume.empty()) {
    run.resume(o.resume);
    const Engine& sim = run.engine();
    char line[512];
    std::snprintf(line, sizeof line, "resume: from %s, checkpoint at t = %.6g s (step %ld)\n", o.resume.path.c_str(), sim.time_s(),
                  sim.step_count());
    out << line;
    report["resumed_from"] = {{"archive", o.resume.path}, {"time_s", sim.time_s()}, {"step", sim.step_count()}};
  }
  if (!o.archive.enabled) return;
  if (!has_archive()) throw std::runtime_error("--archive: this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5)");
  run.start_recording(o.archive, o.resume.empty() ? o.source : "resume:" + o.resume.path);
  log_frame(run, o, out);
  report["archive"] = {{"path", o.archive.path}};
}

void stop_run_recording(RunDriver& run, const BatchOptions& o, json& report, std::ostream& out) {
  if (!run.recording()) return;
  const long frames = run.stop_recording();
  out << "archive: " << o.archive.path << ": " << frames << " frames\n";
  report["archive"]["frames"] = frames;
}

}  // namespace fiberfem::service::detail
