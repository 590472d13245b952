// A static solve on the accurate tier (material.law, mesh.order 2): Newton with load steps
// on the scene's element mesh, its probes interpolated with the element's shape functions,
// in the same report sections as the real-time tier's static solve.

#include "service/batch_circulation.hpp"
#include "service/batch_report.hpp"
#include "service/batch_series.hpp"

#include "core/hyperelastic/dynamic.hpp"
#include "io/scene_accurate.hpp"
#include "service/engine_accurate.hpp"
#include "service/run_driver.hpp"
#include "service/stop_signals.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <chrono>
#include <cstdio>
#include <ostream>

namespace fiberfem::service::detail {

namespace {

// Each probe interpolated with the element's shape functions: a printed line and a report entry.
json probes_report(const io::Scene& sc, const core::hyperelastic::ElementMesh& mesh, const core::Positions& x, std::ostream& out) {
  json probes = json::array();
  for (const io::Probe& pr : sc.probes) {
    const core::Vec3 u = io::accurate_probe_displacement(mesh, pr, x);
    char line[256];
    std::snprintf(line, sizeof line, "probe %s: displacement [%+.6e, %+.6e, %+.6e] m (|u| %.6e m)\n", pr.name.c_str(), u.x(),
                  u.y(), u.z(), u.norm());
    out << line;
    probes.push_back({{"name", pr.name}, {"rest_m", vec_json(pr.point_m)}, {"final_m", vec_json(pr.point_m + u)}, {"displacement_m", vec_json(u)}});
  }
  return probes;
}

}  // namespace

int run_static_accurate(const io::Scene& sc, json& report, std::ostream& out) {
  char line[512];
  const auto t0 = std::chrono::steady_clock::now();
  const io::AccurateProblem ap = io::accurate_problem(sc);
  const core::hyperelastic::ElementMesh& mesh = *ap.mesh;
  std::snprintf(line, sizeof line, "static: accurate tier, order %d, %d nodes, %d quadrature points per element%s\n",
                mesh.order(), mesh.num_nodes(), ap.problem->points(),
                ap.problem->mixed() ? ", incompressible (mixed displacement-pressure)" : "");
  out << line;
  if (!ap.problem->active_tension_pa.empty()) out << "static: the contraction is held at its peak tension\n";
  if (sc.model.circulation.enabled()) out << "static: note: the circulation loads the cavities in dynamic runs only\n";
  core::Positions x;
  Eigen::VectorXd p;
  const core::hyperelastic::NewtonReport r = core::hyperelastic::solve_static(*ap.problem, x, p, ap.newton);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::snprintf(line, sizeof line,
                "static: %s after %d Newton iterations in %d load steps (%d cut-backs), relative residual %.2e, %d "
                "unknowns, %.2f s (assembly %.2f s, linear solves %.2f s: %d factorisations, %d GMRES iterations on "
                "lagged factors)\n",
                r.converged ? "converged" : "NOT converged", r.iterations, r.load_steps, r.cutbacks, r.relative_residual,
                r.equations, wall, r.assembly_s, r.factor_s, r.factorisations, r.krylov_iterations);
  out << line;
  if (!r.converged) out << "static: " << r.message << "\n";
  const json probes = probes_report(sc, mesh, x, out);
  report["status"] = r.converged ? "completed" : "failed";
  report["reason"] = r.converged ? "" : r.message;
  report["static"] = {{"converged", r.converged},
                      {"tier", "accurate"},
                      {"order", mesh.order()},
                      {"quadrature_points", ap.problem->points()},
                      {"unknowns", r.equations},
                      {"load_factor", r.load_factor},
                      {"newton_iterations", r.iterations},
                      {"load_steps", r.load_steps},
                      {"cutbacks", r.cutbacks},
                      {"factorisations", r.factorisations},
                      {"krylov_iterations", r.krylov_iterations},
                      {"relative_residual", r.relative_residual},
                      {"residual_history", r.residual_history}};
  report["timing"] = {{"wall_s", wall}, {"assembly_s", r.assembly_s}, {"linear_solve_s", r.factor_s}};
  report["probes"] = probes;
  return r.converged ? 0 : 1;
}

// A dynamic run on the accurate tier: backward-Euler steps solved by Newton (the
// RunDriver's AccurateEngine, so --resume and --archive work as on the real-time tier), to
// the scene's end time, with a status line every fifth of the run.
int run_dynamic_accurate(const io::Scene& sc, const BatchOptions& o, int steps, json& report, std::ostream& out) {
  char line[512];
  const auto t0 = std::chrono::steady_clock::now();
  RunDriver run(sc, Parameters::fixed);
  const AccurateEngine& engine = *run.engine().accurate();
  const core::hyperelastic::ElementMesh& mesh = engine.element_mesh();
  std::snprintf(line, sizeof line, "dynamic: accurate tier, order %d, %d nodes, %d unknowns, step %.4g s, %d steps\n", mesh.order(),
                mesh.num_nodes(), engine.totals().equations, engine.dt_s(), steps);
  out << line;
  const StopSignals stop_signals;  // an interrupted run still writes its report
  RunSeries series(sc, run.engine());  // cavity volumes and probes per beat, from the rest state
  CirculationSeries circulation(sc, run.engine());
  start_run(run, o, report, out);
  std::string reason;
  int done = static_cast<int>(engine.step_count()), most_iterations = 0, recovered = 0;
  for (int s = done + 1; s <= steps && !stop_signals.caught(); ++s) {
    const long frames_before = run.recorded_frames();
    const core::StepReport& r = run.step(/*record_failure=*/false);
    if (r.status == core::StepStatus::failed) {
      reason = "step " + std::to_string(s) + " at t = " + std::to_string(engine.time_s() + engine.dt_s()) + " s: " + r.message;
      break;
    }
    done = s;
    series.add(run.engine(), run.cavity_volumes());
    circulation.add(run.engine());
    if (run.recorded_frames() != frames_before) log_frame(run, o, out);
    most_iterations = std::max(most_iterations, r.solver_iterations);
    if (r.substeps > 1) ++recovered;
    if (steps >= 5 && s % (steps / 5) != 0 && s != steps) continue;
    const core::Vec3 u = sc.probes.empty() ? core::Vec3::Zero() : io::accurate_probe_displacement(mesh, sc.probes[0], engine.element_positions());
    std::snprintf(line, sizeof line, "t=%7.3f s  step %5d/%d  %s%s%.3e m  Newton %d\n", engine.time_s(), s, steps,
                  sc.probes.empty() ? "" : sc.probes[0].name.c_str(), sc.probes.empty() ? "|u| n/a " : " |u| ", u.norm(),
                  r.solver_iterations);
    out << line << std::flush;
  }
  stop_run_recording(run, o, report, out);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const core::hyperelastic::NewtonReport totals = engine.totals();
  const json probes = probes_report(sc, mesh, engine.element_positions(), out);
  const bool completed = done == steps;
  std::snprintf(line, sizeof line,
                "dynamic: %s, %d of %d steps in %.2f s (%.1f steps/s), %d Newton iterations (at most %d in a step), %d "
                "factorisations, %d steps recovered with substeps\n",
                completed ? "completed" : (reason.empty() ? "interrupted" : "FAILED"), done, steps, wall, done / std::max(wall, 1e-9),
                totals.iterations, most_iterations, totals.factorisations, recovered);
  out << line;
  if (!reason.empty()) out << "dynamic: " << reason << "\n";
  report["status"] = completed ? "completed" : (reason.empty() ? "interrupted" : "failed");
  report["reason"] = reason;
  report["dynamic"] = {{"tier", "accurate"},
                       {"order", mesh.order()},
                       {"unknowns", totals.equations},
                       {"steps", done},
                       {"time_s", engine.time_s()},
                       {"newton_iterations", totals.iterations},
                       {"most_newton_iterations", most_iterations},
                       {"factorisations", totals.factorisations},
                       {"krylov_iterations", totals.krylov_iterations},
                       {"recovered_with_substeps", recovered}};
  report["timing"] = {{"wall_s", wall}, {"assembly_s", totals.assembly_s}, {"linear_solve_s", totals.factor_s}};
  report["steps"] = {{"requested", steps}, {"completed", done}, {"dt_s", engine.dt_s()}, {"simulated_time_s", engine.time_s()}};
  report["probes"] = probes;
  series.finish(run.engine(), report, out);
  circulation.finish(report, out);
  return completed ? 0 : 1;
}

}  // namespace fiberfem::service::detail
