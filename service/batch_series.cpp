#include "service/batch_series.hpp"
#include "service/batch_report.hpp"
#include "service/median.hpp"

#include "core/cavity.hpp"
#include "core/corotation.hpp"
#include "core/element.hpp"

#include <algorithm>
#include <cstdio>
#include <ostream>

namespace fiberfem::service::detail {

void StepTotals::add(const core::StepReport& r) {
  step_s.push_back(r.time.total_s);
  total.rotations_s += r.time.rotations_s;
  total.assembly_s += r.time.assembly_s;
  total.solve_s += r.time.solve_s;
  total.total_s += r.time.total_s;
  iterations += r.solver_iterations;
  factorizations += r.solver_factorizations;
  substeps += r.substeps;
  max_iterations = std::max(max_iterations, r.solver_iterations);
  max_residual = std::max(max_residual, r.solver_residual);
  max_kinetic_j = std::max(max_kinetic_j, r.kinetic_energy_j);
  max_speed_m_s = std::max(max_speed_m_s, r.max_speed_m_s);
  max_inverted = std::max(max_inverted, r.inverted_elements);
  if (r.status == core::StepStatus::recovered) ++recovered;
}

void StepTotals::report(const io::Scene& sc, const core::Simulator& sim, const core::Energies& initial, int requested, int done,
                        double wall_s, json& out) const {
  const double n = std::max(1, done);
  const core::Energies final_energies = sim.energies();
  out["steps"] = {{"requested", requested},
                  {"completed", done},
                  {"dt_s", sc.settings.dt_s},
                  {"simulated_time_s", sim.time_s()},
                  {"recovered", recovered},
                  {"substeps", substeps}};
  out["timing"] = {{"wall_s", wall_s},
                   {"engine_s", total.total_s},
                   {"steps_per_s", done > 0 ? done / total.total_s : 0.0},
                   {"median_step_s", median(step_s)},
                   {"max_step_s", step_s.empty() ? 0.0 : *std::max_element(step_s.begin(), step_s.end())},
                   {"mean_per_step_s",
                    {{"rotations", total.rotations_s / n},
                     {"assembly", total.assembly_s / n},
                     {"solve", total.solve_s / n},
                     {"total", total.total_s / n}}}};
  out["solver"] = {{"method", core::to_string(sc.settings.solver.method)},
                   {"preconditioner", core::to_string(sc.settings.solver.preconditioner)},
                   {"tolerance", sc.settings.solver.tolerance},
                   {"rotation", core::to_string(sc.settings.rotation)},
                   {"iterations_total", iterations},
                   {"iterations_mean", static_cast<double>(iterations) / n},
                   {"iterations_max", max_iterations},
                   {"factorizations", factorizations},
                   {"max_relative_residual", max_residual}};
  out["energies"] = {{"initial", energies_json(initial)},
                     {"final", energies_json(final_energies)},
                     {"max_kinetic_j", std::max(max_kinetic_j, final_energies.kinetic_j)}};
  out["state"] = {{"max_speed_m_s", max_speed_m_s}, {"max_inverted_elements", max_inverted}};
}

BeatSeries::BeatSeries(double rest) : last_(rest) {
  run_.add(rest);
  beat_.add(rest);
}

void BeatSeries::add(double v) {
  last_ = v;
  run_.add(v);
  beat_.add(v);
}

RunSeries::RunSeries(const io::Scene& sc, const Engine& engine)
    : sc_(sc),
      beat_period_s_(sc.model.contraction.enabled() ? sc.model.contraction.period_s : HUGE_VAL),
      dt_s_(sc.settings.dt_s),
      total_volume_m3_(sc.model.mesh.total_volume()),
      contracting_(sc.model.contraction.enabled()),
      fiber_stretch_(contracting_ && engine.real_time() != nullptr) {
  for (const io::CavityMeasure& c : sc.cavities) {
    rest_volume_m3_.push_back(core::cavity_volume(c.surface, engine.positions()));
    volumes_.emplace_back(rest_volume_m3_.back());
  }
  for (size_t k = 0; k < sc.probes.size(); ++k) probe_u_.emplace_back(0.0);
  if (fiber_stretch_) {
    const core::TetMesh& mesh = sc.model.mesh;
    dm_inv_.reserve(static_cast<size_t>(mesh.num_elements()));
    for (const core::Tet& t : mesh.tets()) dm_inv_.push_back(core::rest_shape_inverse(core::gather(mesh.rest_positions(), t)));
  }
}

// The beat a state at time t belongs to: the state at a boundary closes the beat before.
long RunSeries::beat_of(double t) const {
  return beat_period_s_ < HUGE_VAL ? static_cast<long>(std::floor((t - 0.5 * dt_s_) / beat_period_s_)) : 0L;
}

void RunSeries::add(const Engine& engine, const CavityVolumes& volumes) {
  const long beat = beat_of(engine.time_s());
  if (beat != current_beat_) {
    close_beat(current_beat_, engine.time_s());
    current_beat_ = beat;
  }
  if (!sc_.probes.empty()) {  // Probe::displacement takes Positions: one copy of the state, only for probes
    const core::Positions x = engine.positions();
    for (size_t k = 0; k < sc_.probes.size(); ++k) probe_u_[k].add(sc_.probes[k].displacement(sc_.model.mesh, x).norm());
  }
  if (fiber_stretch_) stretch_.add(mean_fiber_stretch(*engine.real_time()));
  for (size_t k = 0; k < volumes_.size(); ++k) volumes_[k].add(volumes[k].second);
  ++steps_in_beat_;
}

void RunSeries::close_beat(long beat, double now_s) {
  const bool complete = beat_period_s_ < HUGE_VAL && (beat + 1) * beat_period_s_ <= now_s + 0.5 * dt_s_;
  for (BeatSeries& v : volumes_)
    v.close(beat, complete, [](const BeatSeries::Range& r, json& e) {
      e["end_diastolic_m3"] = r.max;
      e["end_systolic_m3"] = r.min;
      e["ejection_fraction"] = r.max > 0 ? (r.max - r.min) / r.max : 0.0;
    });
  for (BeatSeries& u : probe_u_)
    u.close(beat, complete, [](const BeatSeries::Range& r, json& e) { e["max_displacement_norm_m"] = r.max; });
  if (fiber_stretch_)
    stretch_.close(beat, complete, [](const BeatSeries::Range& r, json& e) { e["peak_fiber_shortening"] = 1.0 - r.min; });
  steps_in_beat_ = 0;
}

// The volume-weighted mean of |F f| over the mesh.
double RunSeries::mean_fiber_stretch(const core::Simulator& sim) const {
  const core::Model& model = sc_.model;
  const std::vector<core::Mat3>& Dm_inv = dm_inv_;
  double sum = 0;
  for (int e = 0; e < model.mesh.num_elements(); ++e) {
    const size_t i = static_cast<size_t>(e);
    const core::Mat3 F = core::deformation_gradient(core::gather(sim.positions(), model.mesh.tets()[i]), Dm_inv[i]);
    sum += model.mesh.rest_volume(e) * (F * model.fibers[i]).norm();
  }
  return sum / total_volume_m3_;
}

void RunSeries::finish(const Engine& engine, json& report, std::ostream& out) {
  char line[512];
  if (steps_in_beat_ > 0) close_beat(current_beat_, engine.time_s());  // the last beat, if a step fell in it
  for (size_t k = 0; k < sc_.probes.size(); ++k) {
    report["probes"][k]["max_displacement_norm_m"] = probe_u_[k].run().max;
    report["probes"][k]["beats"] = probe_u_[k].beats();
  }
  if (fiber_stretch_) {
    report["contraction"] = {{"mode", core::to_string(sc_.model.contraction.mode)},
                             {"period_s", sc_.model.contraction.period_s},
                             {"peak_fiber_shortening", 1.0 - stretch_.run().min},
                             {"beats", stretch_.beats()}};
    std::snprintf(line, sizeof line, "contraction: peak fiber shortening %.3f (1 - the volume-weighted mean of |F f|)\n",
                  1.0 - stretch_.run().min);
    out << line;
  }
  if (volumes_.empty()) return;
  json cavities = json::array();
  for (size_t k = 0; k < volumes_.size(); ++k) {
    const BeatSeries::Range& r = volumes_[k].run();
    const double ef = r.max > 0 ? (r.max - r.min) / r.max : 0.0;
    std::snprintf(line, sizeof line, "cavity %s: rest %.4g mL, %.4g to %.4g mL over the run, ejection fraction %.3f\n",
                  sc_.cavities[k].name.c_str(), 1e6 * rest_volume_m3_[k], 1e6 * r.min, 1e6 * r.max, ef);
    out << line;
    cavities.push_back({{"name", sc_.cavities[k].name},
                        {"rest_m3", rest_volume_m3_[k]},
                        {"min_m3", r.min},
                        {"max_m3", r.max},
                        {"ejection_fraction", ef},
                        {"beats", volumes_[k].beats()}});
  }
  report["cavities"] = cavities;
}

}  // namespace fiberfem::service::detail
