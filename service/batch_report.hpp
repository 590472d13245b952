#pragma once
/// @file Pieces of the batch run's JSON report (docs/report-format.md) and of its
/// printed summary: the scene, energies, probes, and writing the file.

#include "core/mesh_quality.hpp"
#include "core/simulator.hpp"
#include "core/static_solver.hpp"
#include "io/scene.hpp"
#include "service/batch_run.hpp"

#include <nlohmann/json.hpp>

#include <iosfwd>
#include <string>

namespace fiberfem::service::detail {

using json = nlohmann::ordered_json;

json vec_json(const core::Vec3& v);
json energies_json(const core::Energies& e);
/// The report's first sections: format, version, "scene" and "mode".
json report_head(const io::Scene& sc, const BatchOptions& o, const core::MeshQuality& quality, bool is_static);
/// Each probe's rest point, final point and displacement in state `x`.
json probes_json(const io::Scene& sc, const core::Positions& x);
/// "probe NAME: displacement [...] m (|u| ... m)", a line per probe.
void print_probes(std::ostream& out, const io::Scene& sc, const core::Positions& x);
/// A static solve on the accurate tier (material.law, mesh.order 2), into the report's
/// status, static, timing and probes sections. @return 0 when it converged, else 1.
int run_static_accurate(const io::Scene& sc, json& report, std::ostream& out);
/// A dynamic run to step `steps` on the accurate tier (backward Euler, Newton per step; a
/// RunDriver, so resumed and recorded as the options say), into the report's status,
/// dynamic, timing and probes sections. @return 0 when every step converged.
int run_dynamic_accurate(const io::Scene& sc, const BatchOptions& o, int steps, json& report, std::ostream& out);
/// Before a batch run's loop (batch_recording.cpp): --resume (the archived checkpoint
/// replaces the state; the run continues to the same end step), then --archive, which
/// starts with the state the loop starts from.
void start_run(RunDriver& run, const BatchOptions& o, json& report, std::ostream& out);
/// "frame F step S" after a recorded frame, with --log-frames.
void log_frame(const RunDriver& run, const BatchOptions& o, std::ostream& out);
/// After the loop: closes the recording, its frames into the report.
void stop_run_recording(RunDriver& run, const BatchOptions& o, json& report, std::ostream& out);
/// Energies of a state at rest velocity (the static solution's).
core::Energies energies_at_rest(const io::Scene& sc, const core::Positions& x);
/// Writes the report to a temporary file and renames it, so a reader never sees half a
/// report. @throws std::runtime_error naming --report.
void write_report(const std::string& path, const json& report);

}  // namespace fiberfem::service::detail
