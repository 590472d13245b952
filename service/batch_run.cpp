// A batch run: a RunDriver stepped as fast as it goes to an end step (or a static solve),
// measured into the JSON report (batch_series, batch_report) with a progress bar or a
// status line every fifth of the run.

#include "service/batch_run.hpp"
#include "service/batch_report.hpp"
#include "service/batch_circulation.hpp"
#include "service/batch_series.hpp"
#include "service/stop_signals.hpp"

#include "core/mesh_quality.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <stdexcept>

namespace fiberfem::service {
namespace {

using detail::json;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// The step status lines: a progress bar redrawn on stderr (a terminal, at most ten times
// a second) or a line on `out` every fifth of the run.
class Progress {
 public:
  Progress(bool bar, int steps, std::ostream& out) : bar_(bar), steps_(steps), out_(out) {}
  ~Progress() {
    if (bar_) std::fprintf(stderr, "\n");
  }
  void show(int s, const char* line) {
    if (!bar_) {
      if (s % std::max(1, steps_ / 5) == 0 || s == steps_) out_ << line << "\n" << std::flush;
      return;
    }
    if (s != steps_ && seconds_since(last_draw_) <= 0.1) return;
    constexpr int kWidth = 30;
    const double fraction = static_cast<double>(s) / steps_;
    const int filled = std::clamp(static_cast<int>(fraction * kWidth + 0.5), 0, kWidth);
    std::fprintf(stderr, "\r[%s%s] %3.0f%% %s\033[K", std::string(static_cast<size_t>(filled), '#').c_str(),
                 std::string(static_cast<size_t>(kWidth - filled), '.').c_str(), 100 * fraction, line);
    std::fflush(stderr);
    last_draw_ = Clock::now();
  }

 private:
  bool bar_;
  int steps_;
  std::ostream& out_;
  Clock::time_point last_draw_ = Clock::now();
};

int run_static(const io::Scene& sc, json& report, std::ostream& out) {
  if (sc.accurate()) return detail::run_static_accurate(sc, report, out);
  char line[512];
  if (sc.model.contraction.enabled())
    out << "static: note: the static solve has no active stress; the contraction is left out (passive equilibrium)\n";
  if (!sc.cavities.empty()) out << "static: note: cavity volumes are reported by dynamic runs only\n";
  if (sc.model.circulation.enabled()) out << "static: note: the circulation loads the cavities in dynamic runs only\n";
  const auto t0 = Clock::now();
  core::Positions x;
  const core::StaticReport r = static_equilibrium(sc, x);
  const double wall = seconds_since(t0);
  std::snprintf(line, sizeof line, "static: %s after %d Newton iterations in %d load steps, relative residual %.2e, %.2f s\n",
                r.converged ? "converged" : "NOT converged", r.newton_iterations, r.load_steps, r.relative_residual, wall);
  out << line;
  if (!r.converged) out << "static: " << r.message << "\n";
  detail::print_probes(out, sc, x);
  report["status"] = r.converged ? "completed" : "failed";
  report["reason"] = r.converged ? "" : r.message;
  report["static"] = {{"converged", r.converged},
                      {"newton_iterations", r.newton_iterations},
                      {"load_steps", r.load_steps},
                      {"relative_residual", r.relative_residual},
                      {"residual_history", r.residual_history}};
  report["timing"] = {{"wall_s", wall}};
  report["energies"] = {{"final", detail::energies_json(detail::energies_at_rest(sc, x))}};
  report["probes"] = detail::probes_json(sc, x);
  return r.converged ? 0 : 1;
}

int requested_steps(const io::Scene& sc, const BatchOptions& o) {
  const double until = o.until_s > 0 ? o.until_s : sc.until_s;
  const double wanted = o.steps > 0 ? o.steps : std::max(1.0, std::round(until / sc.settings.dt_s));
  if (wanted > 1e9)
    throw std::invalid_argument("run: " + std::to_string(until) + " s at dt " + std::to_string(sc.settings.dt_s) +
                                " s is over 1e9 steps");
  return static_cast<int>(wanted);
}

// "t=... s  step S/N  PROBE |u| ... m  iters I  STATUS  R steps/s".
void step_line(char* line, size_t size, const io::Scene& sc, const core::Simulator& sim, const core::StepReport& r, int s,
               int steps, double engine_s) {
  const core::Vec3 u = sc.probes.empty() ? core::Vec3::Zero() : sc.probes[0].displacement(sc.model.mesh, sim.positions());
  std::snprintf(line, size, "t=%7.3f s  step %5d/%d  %s%s%.3e m  iters %3d  %s  %5.0f steps/s", r.time_s, s, steps,
                sc.probes.empty() ? "" : sc.probes[0].name.c_str(), sc.probes.empty() ? "|u| n/a " : " |u| ", u.norm(),
                r.solver_iterations, core::to_string(r.status), s / engine_s);
}

// After a converged dynamic run: the static solution and each probe's difference to it.
void compare_static(const io::Scene& sc, const core::Simulator& sim, json& report, std::ostream& out) {
  char line[512];
  core::Positions xs;
  const core::StaticReport r = static_equilibrium(sc, xs);
  json probes = json::array();
  for (const io::Probe& p : sc.probes) {
    const core::Vec3 ud = p.displacement(sc.model.mesh, sim.positions()), us = p.displacement(sc.model.mesh, xs);
    std::snprintf(line, sizeof line, "static: probe %s: static |u| %.6e m, dynamic - static %.3e m (%.2f%% of static)\n",
                  p.name.c_str(), us.norm(), (ud - us).norm(), us.norm() > 0 ? 100 * (ud - us).norm() / us.norm() : 0.0);
    out << line;
    probes.push_back({{"name", p.name}, {"static_displacement_m", detail::vec_json(us)}, {"dynamic_minus_static_m", detail::vec_json(ud - us)}});
  }
  report["static_comparison"] = {{"converged", r.converged}, {"newton_iterations", r.newton_iterations}, {"probes", probes}};
  if (!r.converged) out << "static: NOT converged: " << r.message << "\n";
}

int run_dynamic(const io::Scene& sc, const BatchOptions& o, json& report, std::ostream& out) {
  const auto t0 = Clock::now();
  const int steps = requested_steps(sc, o);
  RunDriver run(sc, Parameters::fixed);
  const core::Energies e0 = run.simulator().energies();
  const StopSignals stop_signals;  // restored however the loop ends (a step can throw)
  detail::RunSeries series(sc, run.engine());
  detail::CirculationSeries circulation(sc, run.engine());
  detail::StepTotals totals;
  totals.max_kinetic_j = e0.kinetic_j;
  detail::start_run(run, o, report, out);
  const int first_step = static_cast<int>(run.simulator().step_count()) + 1;
  std::string status = "completed", reason;
  int done = 0;
  {
    Progress progress(o.progress_bar, steps, out);
    for (int s = first_step; s <= steps; ++s) {
      if (stop_signals.caught()) {
        status = "interrupted";
        reason = std::string("stopped by signal ") + stop_signals.name();
        break;
      }
      const long frames_before = run.recorded_frames();
      const core::StepReport& r = run.step(/*record_failure=*/false);
      if (r.status == core::StepStatus::failed) {
        status = "failed";
        reason = "step " + std::to_string(s) + " at t = " + std::to_string(run.simulator().time_s()) + " s failed: " + r.message;
        break;
      }
      done = s;
      series.add(run.engine(), run.cavity_volumes());
      circulation.add(run.engine());
      if (run.recorded_frames() != frames_before) detail::log_frame(run, o, out);
      totals.add(r);
      char line[512];
      step_line(line, sizeof line, sc, run.simulator(), r, s, steps, totals.total.total_s);
      progress.show(s, line);
    }
  }
  detail::stop_run_recording(run, o, report, out);
  const core::Simulator& sim = run.simulator();
  const double wall = seconds_since(t0);
  char line[512];
  std::snprintf(line, sizeof line,
                "summary: %s: %d of %d steps, t = %.4g s, %.2f s wall (%.0f steps/s of engine time), %.1f solver "
                "iterations/step, %d steps recovered with substeps\n",
                status.c_str(), done, steps, sim.time_s(), wall, done > 0 ? done / totals.total.total_s : 0.0,
                done > 0 ? static_cast<double>(totals.iterations) / done : 0.0, totals.recovered);
  out << line;
  if (!reason.empty()) out << "summary: " << reason << "\n";
  detail::print_probes(out, sc, sim.positions());
  report["status"] = status;
  report["reason"] = reason;
  totals.report(sc, sim, e0, steps, done, wall, report);
  report["probes"] = detail::probes_json(sc, sim.positions());
  series.finish(run.engine(), report, out);
  circulation.finish(report, out);
  const int rc = status == "completed" ? 0 : 1;
  if (o.compare_static && rc == 0) compare_static(sc, sim, report, out);
  return rc;
}

}  // namespace

core::StaticReport static_equilibrium(const io::Scene& sc, core::Positions& x) {
  core::StaticSettings ss;
  ss.rotation = sc.settings.rotation;
  ss.corotation = sc.settings.corotation;
  return core::solve_static(sc.model, x, ss);
}

int run_batch(const io::Scene& sc, const BatchOptions& o, std::ostream& out) {
  const core::TetMesh& mesh = sc.model.mesh;
  const bool is_static = o.force_static || sc.mode == io::Mode::static_;
  const core::MeshQuality quality = core::mesh_quality(mesh);
  char line[512];
  std::snprintf(line, sizeof line,
                "fiberfem: scene '%s' (%s): %d tets, %d nodes, %d regions, dihedral angles %.1f to %.1f deg, %s\n",
                sc.name.c_str(), o.source.c_str(), mesh.num_elements(), mesh.num_nodes(), mesh.num_regions(),
                quality.min_dihedral_deg, quality.max_dihedral_deg, is_static ? "static" : "dynamic");
  out << line << std::flush;
  for (const std::string& w : sc.warnings) out << "fiberfem: warning: " << w << "\n";
  if (sc.accurate() && !is_static && o.compare_static)
    throw std::invalid_argument("run: scene '" + sc.name +
                                "' is on the accurate tier (material.law or mesh.order 2): --compare-static is for the "
                                "real-time tier (run it with --static to compare)");
  json report = detail::report_head(sc, o, quality, is_static);
  const int rc = is_static         ? run_static(sc, report, out)
                 : sc.accurate()   ? detail::run_dynamic_accurate(sc, o, requested_steps(sc, o), report, out)
                                   : run_dynamic(sc, o, report, out);
  if (!o.report_path.empty()) {
    detail::write_report(o.report_path, report);
    out << "report: " << o.report_path << "\n";
  }
  return rc;
}

}  // namespace fiberfem::service
