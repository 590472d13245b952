#pragma once
// The stability map (issue 6, docs/speed-accuracy.md "Stability at the extremes"): one
// case per extreme value, shared by the tests (tests/core/stability_map_test.cpp) and the
// table program (bench_accuracy --stability), so the table shows what the tests check.
//
// Every case is the extremes tests' cantilever (10 x 2 x 2 cm, 6 x 2 x 2 cells, 144 tets,
// clamped at x = 0, Rayleigh damping 4 1/s and 5 ms) with one knob at an extreme:
//   1. loaded: gravity (times `load`) applied suddenly to the body at rest (or at a fully
//      inverted start), `load_steps_s` of simulated time; checked: no failed step, finite
//      state, K + E <= 2 W_static (the largest excursion of a damped linear system under a
//      suddenly applied load); the error of the tip against the converged static answer
//      (solve_static, the reference) at the end;
//   2. released: the load removed, `release_s` more; checked: K + E never above the energy
//      at release (times 1 + 1e-6: no external work, backward Euler dissipates), and the
//      body back at rest within `rest_tolerance` of the bounding-box diagonal.

#include "core/builtin_scenes.hpp"
#include "core/simulator.hpp"
#include "core/static_solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace fiberfem::stability {

namespace core = fiberfem::core;

struct Case {
  std::string group;     // "fiber ratio", "Poisson", "time step", "load", "inverted start"
  std::string value;     // shown in the table
  double ratio = 3;      // E_L / E_T (E_L fixed)
  double nu = -1;        // < 0: the transversely isotropic tissue; else isotropic with this nu
  double dt_s = 1.0 / 60.0;
  double load = 1;       // times the body's weight
  bool inverted_start = false;
  double stiffness_scale = 1;  // material moduli times this (1 = tissue, 60 kPa along fibers)
  core::RotationMethod rotation = core::RotationMethod::polar;
  double load_s = 4.0, release_s = 8.0;
  double rest_tolerance = 1e-4;  // relative to the bounding-box diagonal (10 um on this beam)
};

struct Result {
  bool finite = true;
  int failed_steps = 0, recovered_steps = 0, steps = 0;
  double energy_ratio = 0;          // max (K + E) / bound while loaded
  double release_energy_ratio = 0;  // max (K + E) / E at release
  bool static_converged = false;
  double static_tip_m = 0;          // |tip| of the reference
  double tip_error = std::numeric_limits<double>::quiet_NaN();  // |tip - tip_static| / |tip_static|
  /// While loaded, sampled every 0.5 s: max |tip - tip_ref| / max |tip_ref| against the same
  /// case run with a step of 1/960 s (the converged dynamic reference); NaN if not computed.
  double transient_error = std::numeric_limits<double>::quiet_NaN();
  double rest_error = std::numeric_limits<double>::quiet_NaN(); // after release, / diagonal
  int inverted_at_end = 0;
  std::vector<core::Vec3> tip_samples;  // tip displacement every 0.5 s while loaded
  std::string note;
  /// Bounded: kinetic + elastic energy at most kEnergySlack times its bound. The energy
  /// check lets a step gain up to 1e-3 of the state's energy (SimulatorSettings::
  /// max_energy_gain) and, at its finest substep level, any gain short of doubling: at a fiber
  /// ratio of 1,000 the first two steps after the release gain 4-5% at 16 substeps (1.044
  /// on one CPU, 1.053 on an AVX-512 one: the bits of that case follow the build's vector
  /// width), while an unstable case exceeds its bound many times over (ratio 10,000: 2,000).
  static constexpr double kEnergySlack = 1.10;
  bool stable(const Case& c) const {
    return finite && failed_steps == 0 && energy_ratio <= kEnergySlack && release_energy_ratio <= kEnergySlack &&
           inverted_at_end == 0 && rest_error < c.rest_tolerance;
  }
};

inline core::Model make_model(const Case& c) {
  core::CantileverSpec spec;
  spec.box.size_m = {0.1, 0.02, 0.02};
  spec.box.cells = {6, 2, 2};
  spec.damping.mass_1_s = 4.0;
  spec.damping.stiffness_s = 5e-3;
  spec.fiber = core::Vec3(1, 0, 1);  // 45 degrees in the bending plane: both moduli in every element
  spec.gravity_m_s2 = core::Vec3(0, 0, -9.81 * c.load);
  core::EngineeringConstants& m = spec.material;
  m.E_L = 60e3 * c.stiffness_scale;
  m.E_T = m.E_L / c.ratio;
  m.G_L = std::min(8e3 * c.stiffness_scale, m.E_L / 2.5);
  m.nu_LT = 0.25;
  m.nu_T = 0.45;
  core::Model model = core::make_cantilever(spec);
  if (c.nu >= 0) model.region_materials[0] = core::Material::isotropic(60e3 * c.stiffness_scale, c.nu, 1000.0);
  return model;
}

inline core::Vec3 tip(const core::Model& m, const core::Positions& x) {
  core::Vec3 u = core::Vec3::Zero();
  const auto& face = m.mesh.node_set("xmax");
  for (int n : face) u += x.col(n) - m.mesh.rest_positions().col(n);
  return u / static_cast<double>(face.size());
}

inline double diagonal(const core::TetMesh& mesh) {
  const auto [lo, hi] = mesh.bounding_box();
  return (hi - lo).norm();
}

inline Result run_case(const Case& c) {
  Result r;
  const core::Model model = make_model(c);
  // The reference: the converged static answer under the load.
  core::Positions xs;
  core::StaticSettings ss;
  ss.load_steps = c.load >= 1000 ? 40 : c.load >= 100 ? 10 : 4;
  const core::StaticReport sr = core::solve_static(model, xs, ss);
  r.static_converged = sr.converged;
  const core::Vec3 tip_s = tip(model, xs);
  r.static_tip_m = tip_s.norm();
  const Eigen::VectorXd mass = model.lumped_node_masses();
  double w_static = 0;
  for (int n = 0; n < model.mesh.num_nodes(); ++n)
    w_static += mass(n) * model.loads.gravity_m_s2.dot(xs.col(n) - model.mesh.rest_positions().col(n));

  core::SimulatorSettings set;
  set.dt_s = c.dt_s;
  set.rotation = c.rotation;
  set.threads = 1;
  core::Simulator sim(model, set);
  double bound = 2 * w_static;
  if (c.inverted_start) {
    // Every node mirrored through the clamped plane x = 0 (the beam turned inside out
    // through the wall): every element inverted (det F = -1), the clamped face in place.
    core::Positions x = model.mesh.rest_positions();
    for (int n = 0; n < x.cols(); ++n) x(0, n) = -x(0, n);
    sim.set_state(x, core::Positions::Zero(3, x.cols()));
    const core::Energies e = sim.energies();
    bound += e.elastic_j;  // stored energy of the inverted start plus the load's work
    if (sim.count_inverted() != model.mesh.num_elements()) r.note = "premise: not every element inverted";
  }
  std::vector<core::Vec3> samples;  // tip every 0.5 s while loaded
  const int per_sample = static_cast<int>(std::lround(0.5 / c.dt_s));
  auto advance = [&](double seconds, double bound_j, double& ratio, bool record) {
    const int n = static_cast<int>(std::lround(seconds / c.dt_s));
    for (int i = 0; i < std::max(n, 1); ++i) {
      const core::StepReport rep = sim.step();
      ++r.steps;
      if (rep.status == core::StepStatus::failed) ++r.failed_steps;
      if (rep.status == core::StepStatus::recovered) ++r.recovered_steps;
      if (!sim.positions().allFinite() || !sim.velocities().allFinite()) {
        r.finite = false;
        return false;
      }
      const core::Energies e = sim.energies();
      const double ke = e.kinetic_j + e.elastic_j;
      if (!std::isfinite(ke)) {
        r.finite = false;
        return false;
      }
      ratio = std::max(ratio, ke / bound_j);
      if (record && per_sample > 0 && (i + 1) % per_sample == 0) samples.push_back(tip(model, sim.positions()));
    }
    return true;
  };
  if (!advance(c.load_s, bound, r.energy_ratio, true)) return r;
  r.tip_samples = samples;
  if (sr.converged) r.tip_error = (tip(model, sim.positions()) - tip_s).norm() / tip_s.norm();
  sim.set_gravity(core::Vec3::Zero());
  const core::Energies e0 = sim.energies();
  const double e_release = std::max(e0.kinetic_j + e0.elastic_j, 1e-300);
  if (!advance(c.release_s, e_release, r.release_energy_ratio, false)) return r;
  const core::Positions& X = model.mesh.rest_positions();
  r.rest_error = (sim.positions() - X).colwise().norm().maxCoeff() / diagonal(model.mesh);
  r.inverted_at_end = sim.count_inverted();
  return r;
}

/// Adds the transient error: the same case with a 1/960 s step as the reference (loaded
/// phase only: the comparison needs no release).
inline void add_transient_error(const Case& c, Result& r) {
  Case ref = c;
  ref.dt_s = 1.0 / 960.0;
  ref.release_s = ref.dt_s;
  const Result rr = run_case(ref);
  if (!rr.finite || rr.tip_samples.size() != r.tip_samples.size() || r.tip_samples.empty()) return;
  double num = 0, den = 0;
  for (size_t k = 0; k < r.tip_samples.size(); ++k) {
    num = std::max(num, (r.tip_samples[k] - rr.tip_samples[k]).norm());
    den = std::max(den, rr.tip_samples[k].norm());
  }
  r.transient_error = num / den;
}

/// The map: every extreme the issue names, with values between.
inline std::vector<Case> cases() {
  std::vector<Case> v;
  for (double ratio : {1.0, 10.0, 100.0, 1000.0, 10000.0}) {
    Case c;
    c.group = "fiber/cross-fiber ratio";
    std::ostringstream s;
    s << ratio;
    c.value = s.str();
    c.ratio = ratio;
    v.push_back(c);
  }
  for (double nu : {0.3, 0.45, 0.49, 0.499, 0.4999}) {
    Case c;
    c.group = "Poisson's ratio";
    std::ostringstream s;
    s << nu;
    c.value = s.str();
    c.nu = nu;
    v.push_back(c);
  }
  for (double dt : {0.05, 0.1, 0.25, 0.5}) {
    Case c;
    c.group = "time step s";
    std::ostringstream s;
    s << dt;
    c.value = s.str();
    c.dt_s = dt;
    c.load_s = std::max(4.0, 10 * dt), c.release_s = std::max(8.0, 10 * dt);
    v.push_back(c);
  }
  for (double load : {10.0, 100.0, 1000.0, 10000.0}) {
    Case c;
    c.group = "load x weight";
    std::ostringstream s;
    s << load;
    c.value = s.str();
    c.load = load;
    c.stiffness_scale = 100;  // 6 MPa: a large but ordinary deflection (tip ~14 cm at 1,000x)
    v.push_back(c);
  }
  for (auto rot : {core::RotationMethod::svd, core::RotationMethod::polar}) {
    Case c;
    c.group = "fully inverted start";
    c.value = rot == core::RotationMethod::svd ? "svd" : "polar";
    c.inverted_start = true;
    c.rotation = rot;
    v.push_back(c);
  }
  return v;
}

}  // namespace fiberfem::stability
