#include "service/batch_run.hpp"
#include "service/stop_signals.hpp"

#include "core/corotation.hpp"
#include "core/element.hpp"
#include "core/mesh_quality.hpp"
#include "core/simulator.hpp"
#include "core/static_solver.hpp"

#ifdef FIBERFEM_HAVE_ARCHIVE
#include "service/archive/archive.hpp"
#endif

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <ostream>
#include <stdexcept>

namespace fiberfem::service {
namespace {

using json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;


json vec(const core::Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  return v[m];
}

json energies_json(const core::Energies& e) {
  return {{"kinetic_j", e.kinetic_j}, {"elastic_j", e.elastic_j}, {"gravity_j", e.gravity_j}};
}

json probes_json(const io::Scene& sc, const core::Positions& x) {
  json out = json::array();
  for (const io::Probe& p : sc.probes) {
    const core::Vec3 u = p.displacement(sc.model.mesh, x);
    out.push_back({{"name", p.name}, {"rest_m", vec(p.point_m)}, {"final_m", vec(p.point_m + u)}, {"displacement_m", vec(u)},
                   {"element", p.element}});
  }
  return out;
}

void print_probes(std::ostream& out, const io::Scene& sc, const core::Positions& x) {
  char line[256];
  for (const io::Probe& p : sc.probes) {
    const core::Vec3 u = p.displacement(sc.model.mesh, x);
    std::snprintf(line, sizeof line, "probe %s: displacement [%+.6e, %+.6e, %+.6e] m (|u| %.6e m)\n", p.name.c_str(), u.x(),
                  u.y(), u.z(), u.norm());
    out << line;
  }
}

// Energies of a state at rest velocity (the static solution's).
core::Energies energies_of(const io::Scene& sc, const core::Positions& x) {
  core::Simulator sim(sc.model, sc.settings);
  sim.set_state(x, core::Positions::Zero(3, x.cols()));
  return sim.energies();
}

core::StaticReport solve_static(const io::Scene& sc, core::Positions& x) {
  core::StaticSettings ss;
  ss.rotation = sc.settings.rotation;
  ss.corotation = sc.settings.corotation;
  return core::solve_static(sc.model, x, ss);
}

// Written to a temporary file and renamed, so a reader never sees half a report.
void write_report(const std::string& path, const json& report) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error("--report " + path + ": cannot write " + tmp);
    f << report.dump(2) << "\n";
    if (!f) throw std::runtime_error("--report " + path + ": write failed");
  }
  std::filesystem::rename(tmp, path);
}

// A quantity sampled every step of a dynamic run: its extremes over the run and per beat.
// The first beat starts from the rest sample, and the sample at a beat's boundary belongs
// to both beats.
class BeatSeries {
 public:
  struct Range {
    double min = HUGE_VAL, max = -HUGE_VAL;
    long count = 0;
    void add(double v) { min = std::min(min, v), max = std::max(max, v), ++count; }
  };
  explicit BeatSeries(double rest) : last_(rest) {
    run_.add(rest);
    beat_.add(rest);
  }
  void add(double v) {
    last_ = v;
    run_.add(v);
    beat_.add(v);
  }
  const Range& run() const { return run_; }
  /// Ends beat `index`: its entry is {beat, complete} plus what `describe(range, entry)` adds.
  template <class Describe>
  void close(long index, bool complete, Describe&& describe) {
    json entry = {{"beat", index}, {"complete", complete}};
    describe(beat_, entry);
    beats_.push_back(entry);
    beat_ = Range{};
    beat_.add(last_);
  }
  const json& beats() const { return beats_; }

 private:
  Range run_, beat_;
  double last_;
  json beats_ = json::array();
};

void draw_bar(double fraction, const std::string& text) {
  constexpr int kWidth = 30;
  const int filled = std::clamp(static_cast<int>(fraction * kWidth + 0.5), 0, kWidth);
  std::fprintf(stderr, "\r[%s%s] %3.0f%% %s\033[K", std::string(static_cast<size_t>(filled), '#').c_str(),
               std::string(static_cast<size_t>(kWidth - filled), '.').c_str(), 100 * fraction, text.c_str());
  std::fflush(stderr);
}

}  // namespace

bool has_archive() {
#ifdef FIBERFEM_HAVE_ARCHIVE
  return true;
#else
  return false;
#endif
}

io::Scene scene_from_archive(const std::string& h5_path, const std::vector<std::string>& overrides) {
#ifdef FIBERFEM_HAVE_ARCHIVE
  const archive::ArchiveReader r(h5_path);
  return io::parse_scene(r.header().scene_yaml, "archive:" + h5_path, r.header().scene_base_dir, overrides);
#else
  (void)overrides;
  throw std::runtime_error("cannot read '" + h5_path + "': this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5)");
#endif
}

int run_batch(const io::Scene& sc, const BatchOptions& o, std::ostream& out) {
  const core::Model& model = sc.model;
  const bool is_static = o.force_static || sc.mode == io::Mode::static_;
  char line[512];
  const core::MeshQuality quality = core::mesh_quality(model.mesh);
  std::snprintf(line, sizeof line,
                "fiberfem: scene '%s' (%s): %d tets, %d nodes, %d regions, dihedral angles %.1f to %.1f deg, %s\n",
                sc.name.c_str(), o.source.c_str(), model.mesh.num_elements(), model.mesh.num_nodes(),
                model.mesh.num_regions(), quality.min_dihedral_deg, quality.max_dihedral_deg, is_static ? "static" : "dynamic");
  out << line << std::flush;
  for (const std::string& w : sc.warnings) out << "fiberfem: warning: " << w << "\n";

  json report;
  report["format"] = "fiberfem-run-report";
  report["version"] = 1;
  report["scene"] = {{"name", sc.name},
                     {"source", o.source},
                     {"sha256", sc.hash_sha256},
                     {"overrides", o.overrides},
                     {"mesh_file", sc.mesh_file},
                     {"nodes", model.mesh.num_nodes()},
                     {"elements", model.mesh.num_elements()},
                     {"regions", model.mesh.num_regions()},
                     {"min_dihedral_deg", quality.min_dihedral_deg},
                     {"max_dihedral_deg", quality.max_dihedral_deg},
                     {"min_radius_ratio", quality.min_radius_ratio}};
  report["mode"] = is_static ? "static" : "dynamic";
  const auto t0 = Clock::now();
  int rc = 0;

  if (is_static) {
    if (model.contraction.enabled())
      out << "static: note: the static solve has no active stress; the contraction is left out (passive equilibrium)\n";
    if (!sc.cavities.empty()) out << "static: note: cavity volumes are reported by dynamic runs only\n";
    core::Positions x;
    const core::StaticReport r = solve_static(sc, x);
    const double wall = seconds_since(t0);
    std::snprintf(line, sizeof line, "static: %s after %d Newton iterations in %d load steps, relative residual %.2e, %.2f s\n",
                  r.converged ? "converged" : "NOT converged", r.newton_iterations, r.load_steps, r.relative_residual, wall);
    out << line;
    if (!r.converged) out << "static: " << r.message << "\n";
    print_probes(out, sc, x);
    report["status"] = r.converged ? "completed" : "failed";
    report["reason"] = r.converged ? "" : r.message;
    report["static"] = {{"converged", r.converged},
                        {"newton_iterations", r.newton_iterations},
                        {"load_steps", r.load_steps},
                        {"relative_residual", r.relative_residual},
                        {"residual_history", r.residual_history}};
    report["timing"] = {{"wall_s", wall}};
    report["energies"] = {{"final", energies_json(energies_of(sc, x))}};
    report["probes"] = probes_json(sc, x);
    rc = r.converged ? 0 : 1;
  } else {
    core::Simulator sim(model, sc.settings);
    const double until = o.until_s > 0 ? o.until_s : sc.until_s;
    const double wanted = o.steps > 0 ? o.steps : std::max(1.0, std::round(until / sc.settings.dt_s));
    if (wanted > 1e9)
      throw std::invalid_argument("run: " + std::to_string(until) + " s at dt " + std::to_string(sc.settings.dt_s) +
                                  " s is over 1e9 steps");
    const int steps = static_cast<int>(wanted);
    const core::Energies e0 = sim.energies();
    // Handlers for the loop, restored however it ends (a step can throw).
    const StopSignals stop_signals;

    // Per-beat extremes. A beat is the contraction's period (the whole run without one);
    // the state at a beat's boundary belongs to both beats, and beat 0 starts from rest.
    const double beat_period = model.contraction.enabled() ? model.contraction.period_s : HUGE_VAL;
    const double dt = sc.settings.dt_s;
    auto beat_of = [&](double t) { return beat_period < HUGE_VAL ? static_cast<long>(std::floor((t - 0.5 * dt) / beat_period)) : 0L; };
    // Per-beat series: cavity volumes (the ejection fraction), each probe's displacement
    // (the apex excursion) and, when contracting, the volume-weighted mean fiber stretch
    // |F f| (the peak shortening).
    std::vector<BeatSeries> volumes, probe_u;
    std::vector<double> rest_volume;
    for (const io::CavityMeasure& c : sc.cavities) {
      rest_volume.push_back(core::cavity_volume(c.surface, sim.positions()));
      volumes.emplace_back(rest_volume.back());
    }
    for (size_t k = 0; k < sc.probes.size(); ++k) probe_u.emplace_back(0.0);
    const bool contracting = model.contraction.enabled();
    BeatSeries stretch(1.0);
    const double total_volume = model.mesh.total_volume();
    auto mean_fiber_stretch = [&]() {
      const std::vector<core::Mat3>& Dm_inv = sim.caches().Dm_inv;
      double sum = 0;
      for (int e = 0; e < model.mesh.num_elements(); ++e) {
        const size_t i = static_cast<size_t>(e);
        const core::Mat3 F = core::deformation_gradient(core::gather(sim.positions(), model.mesh.tets()[i]), Dm_inv[i]);
        sum += model.mesh.rest_volume(e) * (F * model.fibers[i]).norm();
      }
      return sum / total_volume;
    };
    long current_beat = 0, steps_in_beat = 0;
    auto complete = [&](long beat) { return beat_period < HUGE_VAL && (beat + 1) * beat_period <= sim.time_s() + 0.5 * dt; };
    auto close_beat = [&](long beat) {
      for (BeatSeries& v : volumes)
        v.close(beat, complete(beat), [](const BeatSeries::Range& r, json& e) {
          e["end_diastolic_m3"] = r.max;
          e["end_systolic_m3"] = r.min;
          e["ejection_fraction"] = r.max > 0 ? (r.max - r.min) / r.max : 0.0;
        });
      for (BeatSeries& u : probe_u)
        u.close(beat, complete(beat), [](const BeatSeries::Range& r, json& e) { e["max_displacement_norm_m"] = r.max; });
      if (contracting)
        stretch.close(beat, complete(beat),
                      [](const BeatSeries::Range& r, json& e) { e["peak_fiber_shortening"] = 1.0 - r.min; });
      steps_in_beat = 0;
    };
    std::vector<double> step_s;
    step_s.reserve(static_cast<size_t>(std::min(steps, 1 << 20)));
    core::PhaseTimes total;
    long iterations = 0, factorizations = 0, substeps = 0;
    int max_iterations = 0, recovered = 0, max_inverted = 0, done = 0;
    double max_residual = 0, max_kinetic = e0.kinetic_j, max_speed = 0;
    std::string status = "completed", reason;
    auto last_draw = Clock::now();
    // Resume (--resume RUN.h5[@t]): the archived checkpoint replaces the state; the run
    // continues to the same end step. Recording starts with the state the loop starts from.
    int first_step = 1;
    if (!o.resume_path.empty()) {
#ifdef FIBERFEM_HAVE_ARCHIVE
      const archive::ArchiveReader from(o.resume_path);
      const size_t k = from.checkpoint_at_or_before(o.resume_time_s);  // inf: the last
      try {
        sim.restore(from.read_checkpoint(k));
      } catch (const std::invalid_argument& e) {  // another scene's archive
        throw std::invalid_argument("--resume " + o.resume_path + ": " + e.what() + " (the archive is of another scene or mesh)");
      }
      first_step = static_cast<int>(sim.step_count()) + 1;
      std::snprintf(line, sizeof line, "resume: from %s, checkpoint at t = %.6g s (step %ld)\n", o.resume_path.c_str(),
                    sim.time_s(), sim.step_count());
      out << line;
      report["resumed_from"] = {{"archive", o.resume_path}, {"time_s", sim.time_s()}, {"step", sim.step_count()}};
#else
      throw std::runtime_error("--resume: this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5)");
#endif
    }
#ifdef FIBERFEM_HAVE_ARCHIVE
    std::unique_ptr<archive::ArchiveWriter> recorder;
    std::vector<std::pair<std::string, double>> cavity_now;
    auto measure_cavities = [&] {
      cavity_now.clear();
      for (const io::CavityMeasure& c : sc.cavities) cavity_now.emplace_back(c.name, core::cavity_volume(c.surface, sim.positions()));
    };
    if (o.archive.enabled) {
      archive::ArchiveOptions ao;
      ao.path = o.archive.path;
      ao.flush_frames = o.archive.flush_frames;
      ao.flush_seconds = o.archive.flush_seconds;
      ao.every_steps = o.archive.every_steps;
      ao.velocities = o.archive.velocities;
      ao.displacement = o.archive.displacement;
      ao.checkpoint_every_s = o.archive.checkpoint_every_s;
      ao.compression = o.archive.compression;
      recorder = std::make_unique<archive::ArchiveWriter>(ao, sc, sim, o.resume_path.empty() ? o.source : "resume:" + o.resume_path);
      core::StepReport initial;
      initial.time_s = sim.time_s();
      measure_cavities();
      recorder->record_frame(sim, initial, {cavity_now});
      if (o.log_frames) out << "frame " << recorder->frames() << " step " << sim.step_count() << "\n" << std::flush;
      report["archive"] = {{"path", ao.path}};
    }
#else
    if (o.archive.enabled) throw std::runtime_error("--archive: this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5)");
#endif
    for (int s = first_step; s <= steps; ++s) {
      if (stop_signals.caught()) {
        status = "interrupted";
        reason = std::string("stopped by signal ") + stop_signals.name();
        break;
      }
      const core::StepReport r = sim.step();
      if (r.status == core::StepStatus::failed) {
        status = "failed";
        reason = "step " + std::to_string(s) + " at t = " + std::to_string(sim.time_s()) + " s failed: " + r.message;
        break;
      }
      done = s;
      step_s.push_back(r.time.total_s);
      const long beat = beat_of(sim.time_s());
      if (beat != current_beat) {
        close_beat(current_beat);
        current_beat = beat;
      }
      for (size_t k = 0; k < sc.probes.size(); ++k) probe_u[k].add(sc.probes[k].displacement(model.mesh, sim.positions()).norm());
      if (contracting) stretch.add(mean_fiber_stretch());
#ifdef FIBERFEM_HAVE_ARCHIVE
      if (recorder) {
        measure_cavities();
        for (size_t k = 0; k < volumes.size(); ++k) volumes[k].add(cavity_now[k].second);
        const long before = recorder->frames();
        recorder->record_frame(sim, r, {cavity_now});
        if (o.log_frames && recorder->frames() != before)
          out << "frame " << recorder->frames() << " step " << sim.step_count() << "\n" << std::flush;
      } else
#endif
      {
        for (size_t k = 0; k < volumes.size(); ++k) volumes[k].add(core::cavity_volume(sc.cavities[k].surface, sim.positions()));
      }
      ++steps_in_beat;
      total.rotations_s += r.time.rotations_s;
      total.assembly_s += r.time.assembly_s;
      total.solve_s += r.time.solve_s;
      total.total_s += r.time.total_s;
      iterations += r.solver_iterations;
      factorizations += r.solver_factorizations;
      substeps += r.substeps;
      max_iterations = std::max(max_iterations, r.solver_iterations);
      max_residual = std::max(max_residual, r.solver_residual);
      max_kinetic = std::max(max_kinetic, r.kinetic_energy_j);
      max_speed = std::max(max_speed, r.max_speed_m_s);
      max_inverted = std::max(max_inverted, r.inverted_elements);
      if (r.status == core::StepStatus::recovered) ++recovered;

      const core::Vec3 u = sc.probes.empty() ? core::Vec3::Zero() : sc.probes[0].displacement(model.mesh, sim.positions());
      std::snprintf(line, sizeof line, "t=%7.3f s  step %5d/%d  %s%s%.3e m  iters %3d  %s  %5.0f steps/s", r.time_s, s, steps,
                    sc.probes.empty() ? "" : sc.probes[0].name.c_str(), sc.probes.empty() ? "|u| n/a " : " |u| ", u.norm(),
                    r.solver_iterations, core::to_string(r.status), s / total.total_s);
      if (o.progress_bar) {
        if (s == steps || seconds_since(last_draw) > 0.1) {
          draw_bar(static_cast<double>(s) / steps, line);
          last_draw = Clock::now();
        }
      } else if (s % std::max(1, steps / 5) == 0 || s == steps) {
        out << line << "\n" << std::flush;
      }
    }
    if (o.progress_bar) std::fprintf(stderr, "\n");
#ifdef FIBERFEM_HAVE_ARCHIVE
    if (recorder) {  // a last checkpoint (a run can be continued past its end), then the sidecar
      recorder->checkpoint(sim, "{}");
      const long frames = recorder->frames();
      recorder->close();
      out << "archive: " << o.archive.path << ": " << frames << " frames\n";
      report["archive"]["frames"] = frames;
    }
#endif
    const double wall = seconds_since(t0);
    const core::Energies e1 = sim.energies();

    std::snprintf(line, sizeof line,
                  "summary: %s: %d of %d steps, t = %.4g s, %.2f s wall (%.0f steps/s of engine time), %.1f solver "
                  "iterations/step, %d steps recovered with substeps\n",
                  status.c_str(), done, steps, sim.time_s(), wall, done > 0 ? done / total.total_s : 0.0,
                  done > 0 ? static_cast<double>(iterations) / done : 0.0, recovered);
    out << line;
    if (!reason.empty()) out << "summary: " << reason << "\n";
    print_probes(out, sc, sim.positions());

    const double n = std::max(1, done);
    report["status"] = status;
    report["reason"] = reason;
    report["steps"] = {{"requested", steps},
                       {"completed", done},
                       {"dt_s", sc.settings.dt_s},
                       {"simulated_time_s", sim.time_s()},
                       {"recovered", recovered},
                       {"substeps", substeps}};
    report["timing"] = {{"wall_s", wall},
                        {"engine_s", total.total_s},
                        {"steps_per_s", done > 0 ? done / total.total_s : 0.0},
                        {"median_step_s", median(step_s)},
                        {"max_step_s", step_s.empty() ? 0.0 : *std::max_element(step_s.begin(), step_s.end())},
                        {"mean_per_step_s",
                         {{"rotations", total.rotations_s / n},
                          {"assembly", total.assembly_s / n},
                          {"solve", total.solve_s / n},
                          {"total", total.total_s / n}}}};
    report["solver"] = {{"method", core::to_string(sc.settings.solver.method)},
                        {"preconditioner", core::to_string(sc.settings.solver.preconditioner)},
                        {"tolerance", sc.settings.solver.tolerance},
                        {"rotation", core::to_string(sc.settings.rotation)},
                        {"iterations_total", iterations},
                        {"iterations_mean", static_cast<double>(iterations) / n},
                        {"iterations_max", max_iterations},
                        {"factorizations", factorizations},
                        {"max_relative_residual", max_residual}};
    report["energies"] = {{"initial", energies_json(e0)},
                          {"final", energies_json(e1)},
                          {"max_kinetic_j", std::max(max_kinetic, e1.kinetic_j)}};
    report["state"] = {{"max_speed_m_s", max_speed}, {"max_inverted_elements", max_inverted}};
    report["probes"] = probes_json(sc, sim.positions());
    if (steps_in_beat > 0) close_beat(current_beat);  // the last beat, if a step fell in it
    for (size_t k = 0; k < sc.probes.size(); ++k) {
      report["probes"][k]["max_displacement_norm_m"] = probe_u[k].run().max;
      report["probes"][k]["beats"] = probe_u[k].beats();
    }
    if (contracting) {
      report["contraction"] = {{"mode", core::to_string(model.contraction.mode)},
                               {"period_s", model.contraction.period_s},
                               {"peak_fiber_shortening", 1.0 - stretch.run().min},
                               {"beats", stretch.beats()}};
      std::snprintf(line, sizeof line, "contraction: peak fiber shortening %.3f (1 - the volume-weighted mean of |F f|)\n",
                    1.0 - stretch.run().min);
      out << line;
    }
    if (!volumes.empty()) {
      json cj = json::array();
      for (size_t k = 0; k < volumes.size(); ++k) {
        const BeatSeries::Range& r = volumes[k].run();
        const double ef = r.max > 0 ? (r.max - r.min) / r.max : 0.0;
        std::snprintf(line, sizeof line, "cavity %s: rest %.4g mL, %.4g to %.4g mL over the run, ejection fraction %.3f\n",
                      sc.cavities[k].name.c_str(), 1e6 * rest_volume[k], 1e6 * r.min, 1e6 * r.max, ef);
        out << line;
        cj.push_back({{"name", sc.cavities[k].name},
                      {"rest_m3", rest_volume[k]},
                      {"min_m3", r.min},
                      {"max_m3", r.max},
                      {"ejection_fraction", ef},
                      {"beats", volumes[k].beats()}});
      }
      report["cavities"] = cj;
    }
    rc = status == "completed" ? 0 : 1;

    if (o.compare_static && rc == 0) {
      core::Positions xs;
      const core::StaticReport r = solve_static(sc, xs);
      json cmp = json::array();
      for (const io::Probe& p : sc.probes) {
        const core::Vec3 ud = p.displacement(model.mesh, sim.positions()), us = p.displacement(model.mesh, xs);
        std::snprintf(line, sizeof line, "static: probe %s: static |u| %.6e m, dynamic - static %.3e m (%.2f%% of static)\n",
                      p.name.c_str(), us.norm(), (ud - us).norm(), us.norm() > 0 ? 100 * (ud - us).norm() / us.norm() : 0.0);
        out << line;
        cmp.push_back({{"name", p.name}, {"static_displacement_m", vec(us)}, {"dynamic_minus_static_m", vec(ud - us)}});
      }
      report["static_comparison"] = {{"converged", r.converged}, {"newton_iterations", r.newton_iterations}, {"probes", cmp}};
      if (!r.converged) out << "static: NOT converged: " << r.message << "\n";
    }
  }

  if (!o.report_path.empty()) {
    write_report(o.report_path, report);
    out << "report: " << o.report_path << "\n";
  }
  return rc;
}

}  // namespace fiberfem::service
