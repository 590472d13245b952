// `fiberfem run SCENE.yaml` (or `--builtin cantilever`, an embedded copy of
// configs/scenes/demo-cantilever.yaml) runs a scene in batch: a progress bar on a
// terminal, a summary, and an optional JSON report (docs/options.md, docs/report-format.md).

#include "io/scene.hpp"
#include "service/batch_run.hpp"
#include "service/builtin_scenes.hpp"
#include "service/commands.hpp"

#include <CLI/CLI.hpp>

#include <charconv>
#include <cstdio>
#include <iostream>
#include <memory>
#include <unistd.h>

namespace fiberfem::service {
namespace {

// Shortest text that reads back as `v` (so `--dt 0.005` is `solver.dt=0.005`).
std::string format_number(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

struct RunArgs {
  std::string scene_file, builtin = "cantilever", solver, preconditioner, rotation, max_energy_gain;
  double dt = 0, tolerance = 0;
  std::vector<int> cells;
  BatchOptions o;
};

int run_command(CLI::App& run, RunArgs& a) {
  BatchOptions& o = a.o;
  std::vector<std::string> sets;
  if (run.count("--dt")) sets.push_back("solver.dt=" + format_number(a.dt));
  if (!a.solver.empty()) sets.push_back("solver.method=" + a.solver);
  if (!a.preconditioner.empty()) sets.push_back("solver.preconditioner=" + a.preconditioner);
  if (run.count("--tolerance")) sets.push_back("solver.tolerance=" + format_number(a.tolerance));
  if (!a.rotation.empty()) sets.push_back("solver.rotation=" + a.rotation);
  if (!a.max_energy_gain.empty()) sets.push_back("solver.max_energy_gain=" + a.max_energy_gain);
  if (!a.cells.empty())
    sets.push_back("mesh.cells=[" + std::to_string(a.cells[0]) + ", " + std::to_string(a.cells[1]) + ", " +
                   std::to_string(a.cells[2]) + "]");
  sets.insert(sets.end(), o.overrides.begin(), o.overrides.end());
  o.overrides = sets;
  o.progress_bar = isatty(fileno(stderr)) != 0;

  try {
    if (!a.scene_file.empty()) {
      o.source = a.scene_file;
      return run_batch(io::load_scene(a.scene_file, o.overrides), o, std::cout);
    }
    if (!builtin_scenes().count(a.builtin)) {
      std::cerr << "fiberfem: unknown built-in scene '" << a.builtin << "' (available: cantilever, heart)\n";
      return 2;
    }
    o.source = "builtin:" + a.builtin;
    return run_batch(load_builtin_scene(a.builtin, o.overrides), o, std::cout);
  } catch (const std::exception& e) {
    std::cerr << "fiberfem: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

void add_run_command(CLI::App& app, int& exit_code) {
  auto* run = app.add_subcommand("run", "Run a scene in batch (no bus)");
  auto a = std::make_shared<RunArgs>();
  BatchOptions& o = a->o;
  run->add_option("scene", a->scene_file, "Scene file (YAML, docs/scenes.md); without one, --builtin runs");
  run->add_option("--scene", a->scene_file, "Same as the positional scene file");
  run->add_option("--builtin", a->builtin, "Built-in scene when no file is given: cantilever | heart")->capture_default_str();
  run->add_option("--set", o.overrides, "Override a scene key: key.path=value (repeatable)");
  run->add_flag("--static", o.force_static, "Solve for static equilibrium instead of time stepping");
  run->add_option("--steps", o.steps, "Number of steps (instead of --until)")->check(CLI::PositiveNumber);
  run->add_option("--until", o.until_s, "Simulated time, s (default: the scene's solver.until)")->check(CLI::PositiveNumber);
  run->add_option("--report", o.report_path, "Write a JSON report here (docs/report-format.md)");
  run->add_flag("--compare-static", o.compare_static, "After a dynamic run, solve statically and compare the probes");
  // Shorthands for scene keys (each becomes a --set before the explicit ones).
  run->add_option("--dt", a->dt, "Time step, s (solver.dt)")->check(CLI::Range(1e-6, 10.0));
  run->add_option("--solver", a->solver, "pcg | direct (solver.method)")->check(CLI::IsMember({"pcg", "direct"}));
  run->add_option("--preconditioner", a->preconditioner, "cholesky | block_jacobi (solver.preconditioner)")
      ->check(CLI::IsMember({"cholesky", "block_jacobi"}));
  run->add_option("--tolerance", a->tolerance, "PCG relative tolerance (solver.tolerance)")->check(CLI::Range(1e-14, 0.5));
  run->add_option("--rotation", a->rotation, "polar | svd (solver.rotation)")->check(CLI::IsMember({"svd", "polar"}));
  run->add_option("--max-energy-gain", a->max_energy_gain, "Energy check per step, relative; inf: off (solver.max_energy_gain)");
  run->add_option("--cells", a->cells, "Box cells along x y z (mesh.cells)")->expected(3)->check(CLI::Range(1, 2000));
  run->callback([run, a, &exit_code] { exit_code = run_command(*run, *a); });
}

}  // namespace fiberfem::service
