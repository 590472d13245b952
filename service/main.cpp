// The `fiberfem` command. `fiberfem run --builtin cantilever` runs the built-in cantilever
// in batch, with a progress line, and compares its settled tip with the static solution
// and with beam theory.

#include "core/builtin_scenes.hpp"
#include "io/scene.hpp"
#include "core/simulator.hpp"
#include "core/static_solver.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <unistd.h>

namespace core = fiberfem::core;

namespace {

struct RunOptions {
  std::string scene_file;
  std::vector<std::string> overrides;  // --set key.path=value
  bool force_static = false;           // --static
  int steps = 0;                       // --steps (0: from --until)
  std::string builtin = "cantilever", solver = "pcg", preconditioner = "cholesky", rotation = "polar";
  double seconds = 2.0, dt = 1.0 / 60.0, tol = 1e-6, max_energy_gain = 1e-3;
  std::vector<int> cells{20, 2, 2};
};

// Runs a scene file: dynamic to --until with a status line, or a static solve; prints the
// probes' displacements.
int run_scene(const RunOptions& o) {
  const fiberfem::io::Scene sc = fiberfem::io::load_scene(o.scene_file, o.overrides);
  const core::Model& model = sc.model;
  std::printf("fiberfem: scene '%s': %d tets, %d nodes, %d regions, %s\n", sc.name.c_str(), model.mesh.num_elements(),
              model.mesh.num_nodes(), model.mesh.num_regions(), sc.mode == fiberfem::io::Mode::dynamic ? "dynamic" : "static");
  auto print_probes = [&](const core::Positions& x) {
    for (const auto& p : sc.probes) {
      const core::Vec3 u = p.displacement(model.mesh, x);
      std::printf("probe %s: displacement [%+.6e, %+.6e, %+.6e] m\n", p.name.c_str(), u.x(), u.y(), u.z());
    }
  };
  if (sc.mode == fiberfem::io::Mode::static_ || o.force_static) {
    core::Positions x;
    core::StaticSettings ss;
    ss.rotation = sc.settings.rotation;
    const core::StaticReport r = core::solve_static(model, x, ss);
    std::printf("static: %s after %d Newton iterations, relative residual %.2e\n", r.converged ? "converged" : "NOT converged",
                r.newton_iterations, r.relative_residual);
    print_probes(x);
    return r.converged ? 0 : 1;
  }
  core::Simulator sim(model, sc.settings);
  const bool tty = isatty(fileno(stdout));
  const int steps = o.steps > 0 ? o.steps : std::max(1, static_cast<int>(std::lround(o.seconds / sc.settings.dt_s)));
  int failed = 0;
  double work = 0;
  for (int s = 1; s <= steps; ++s) {
    const core::StepReport r = sim.step();
    work += r.time.total_s;
    if (r.status == core::StepStatus::failed) ++failed;
    if ((tty && s % 10 == 0) || s == steps || (!tty && s % std::max(1, steps / 5) == 0)) {
      const core::Vec3 u = sc.probes.empty() ? core::Vec3::Zero() : sc.probes[0].displacement(model.mesh, sim.positions());
      std::printf("%st=%7.3f s  step %5d/%d  %s%s%+.3e m  iters %3d  %s  %6.0f steps/s%s", tty ? "\r" : "", r.time_s, s, steps,
                  sc.probes.empty() ? "" : sc.probes[0].name.c_str(), sc.probes.empty() ? "" : " |u| ", u.norm(),
                  r.solver_iterations, core::to_string(r.status), s / work, tty ? "" : "\n");
      std::fflush(stdout);
    }
  }
  if (tty) std::printf("\n");
  std::printf("summary: %d steps, %d failed\n", steps, failed);
  print_probes(sim.positions());
  return failed == 0 ? 0 : 1;
}

int run_builtin(const RunOptions& o) {
  const std::string& scene = o.builtin;
  const std::string& solver = o.solver;
  const std::string& rotation = o.rotation;
  const double seconds = o.seconds, dt = o.dt, tol = o.tol;
  const std::array<int, 3> cells{o.cells[0], o.cells[1], o.cells[2]};
  if (scene != "cantilever") {
    std::cerr << "fiberfem: unknown built-in scene '" << scene << "' (available: cantilever)\n";
    return 2;
  }
  core::CantileverSpec spec;
  spec.box.size_m = {0.1, 0.01, 0.01};
  spec.box.cells = cells;
  spec.damping.mass_1_s = 4.0;
  core::Model model = core::make_cantilever(spec);
  core::SimulatorSettings st;
  st.dt_s = dt;
  st.solver.method = solver == "direct" ? core::LinearSolverKind::direct : core::LinearSolverKind::pcg;
  st.solver.tolerance = tol;
  st.solver.preconditioner =
      o.preconditioner == "block_jacobi" ? core::PreconditionerKind::block_jacobi : core::PreconditionerKind::cholesky;
  st.max_energy_gain = o.max_energy_gain;
  st.rotation = rotation == "polar" ? core::RotationMethod::polar : core::RotationMethod::svd;
  core::Simulator sim(model, st);
  const int tip = [&] {
    const auto& face = model.mesh.node_set("xmax");
    int best = face.front();
    double bd = 1e300;
    for (int n : face) {
      const double d = (model.mesh.rest_positions().col(n) - core::Vec3(0.1, 0.005, 0.005)).norm();
      if (d < bd) bd = d, best = n;
    }
    return best;
  }();
  std::printf("fiberfem: cantilever 10 x 1 x 1 cm, %d tets, %d nodes, fibers along x, gravity -z, dt %.4g s, %s/%s\n",
              model.mesh.num_elements(), model.mesh.num_nodes(), dt, solver.c_str(), rotation.c_str());
  const bool tty = isatty(fileno(stdout));
  const int steps = static_cast<int>(std::lround(seconds / dt));
  const auto t0 = std::chrono::steady_clock::now();
  double work = 0;
  long iters = 0;
  int failed = 0;
  for (int s = 1; s <= steps; ++s) {
    const core::StepReport r = sim.step();
    work += r.time.total_s;
    iters += r.solver_iterations;
    if (r.status == core::StepStatus::failed) ++failed;
    if ((tty && s % 10 == 0) || s == steps || (!tty && s % (steps / 5 > 0 ? steps / 5 : 1) == 0)) {
      std::printf("%st=%6.3f s  step %5d/%d  tip z %+8.3f mm  iters %3d  E_kin %.3e J  %6.0f steps/s%s",
                  tty ? "\r" : "", r.time_s, s, steps, 1e3 * (sim.positions()(2, tip) - 0.005),
                  r.solver_iterations, r.kinetic_energy_j, s / work, tty ? "" : "\n");
      std::fflush(stdout);
    }
  }
  if (tty) std::printf("\n");
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  core::Positions xs;
  const core::StaticReport sr = core::solve_static(model, xs);
  const double dyn = sim.positions()(2, tip) - 0.005;
  const double sta = xs(2, tip) - 0.005;
  const double q = spec.density_kg_m3 * 9.81 * 0.01 * 0.01;
  const double beam = -core::cantilever_tip_deflection(0.1, 0.01, 0.01, spec.material.E_L, spec.material.G_L, q, 0);
  std::printf("summary: %d steps in %.2f s wall (%.0f steps/s, %.1f PCG iterations/step), %d failed steps\n", steps,
              wall, steps / wall, static_cast<double>(iters) / steps, failed);
  std::printf("summary: tip deflection after %.1f s: dynamic %.4f mm, static (Newton, %s) %.4f mm, "
              "linear Timoshenko beam theory %.4f mm%s\n",
              seconds, 1e3 * dyn, sr.converged ? "converged" : "NOT converged", 1e3 * sta, 1e3 * beam,
              std::abs(sta) > 0.1 * 0.1 ? " (not valid here: the deflection is over 10% of the length)"
                                        : "");
  return failed == 0 && sr.converged ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fiberfem: fiber-incorporated corotational FEM"};
  app.require_subcommand(1);
  auto* run = app.add_subcommand("run", "Run a scene in batch (no bus)");
  RunOptions o;
  run->add_option("scene", o.scene_file, "Scene file (YAML, docs/scenes.md); without one, --builtin runs");
  run->add_option("--scene", o.scene_file, "Same as the positional scene file");
  run->add_option("--set", o.overrides, "Override a scene key: key.path=value (repeatable)");
  run->add_flag("--static", o.force_static, "Static solve instead of time stepping (scene files)");
  run->add_option("--steps", o.steps, "Number of steps (instead of --until; scene files)")->check(CLI::PositiveNumber);
  run->add_option("--builtin", o.builtin, "Built-in scene: cantilever")->capture_default_str();
  run->add_option("--until", o.seconds, "Simulated time, s")->capture_default_str()->check(CLI::PositiveNumber);
  run->add_option("--dt", o.dt, "Time step, s")->capture_default_str()->check(CLI::Range(1e-6, 10.0));
  run->add_option("--solver", o.solver, "pcg | direct")->capture_default_str()->check(CLI::IsMember({"pcg", "direct"}));
  run->add_option("--preconditioner", o.preconditioner, "cholesky | block_jacobi (PCG)")
      ->capture_default_str()
      ->check(CLI::IsMember({"cholesky", "block_jacobi"}));
  run->add_option("--tolerance", o.tol, "PCG relative tolerance")->capture_default_str()->check(CLI::Range(1e-14, 0.5));
  run->add_option("--rotation", o.rotation, "polar | svd")->capture_default_str()->check(CLI::IsMember({"svd", "polar"}));
  // Validated by SimulatorSettings (CLI11's range checks refuse inf, which turns it off).
  run->add_option("--max-energy-gain", o.max_energy_gain, "Energy check per step, relative (inf: off)")
      ->capture_default_str();
  run->add_option("--cells", o.cells, "Cells along x y z")->expected(3)->capture_default_str()->check(CLI::Range(1, 2000));
  CLI11_PARSE(app, argc, argv);
  try {
    if (*run) return o.scene_file.empty() ? run_builtin(o) : run_scene(o);
  } catch (const std::exception& e) {
    std::cerr << "fiberfem: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
