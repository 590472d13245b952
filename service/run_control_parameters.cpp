// Parameter commands (docs/commands.md). Each reads its arguments onto the running typed
// value of its section (io/scene_sections.hpp: the scene's own readers, so the same keys,
// units and checks as a scene file, or the command's argument checks), applies the value
// built from it to the engine, and only then keeps it as the running parameter state.
// The scene text recorded from that state is written when it is asked for
// (RunControl::parameter_state_json).

#include "service/run_control.hpp"

#include "io/scene_sections.hpp"
#include "service/command_args.hpp"
#include "service/engine_accurate.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>

namespace fiberfem::service {

using detail::Args;
using detail::join;
using detail::Reject;
using core::Vec3;

namespace {

// Region ids named by an optional `region` argument (every region when absent).
std::vector<int> regions_of(const Args& a, const std::vector<std::string>& names) {
  if (!a.has("region")) {
    std::vector<int> all(names.size());
    for (size_t r = 0; r < names.size(); ++r) all[r] = static_cast<int>(r);
    return all;
  }
  const std::string name = a.text("region");
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw Reject("no region '" + name + "' (regions: " + join(names) + ")");
  return {static_cast<int>(it - names.begin())};
}


// A region with a law reads the command as the law's keys (its `law` may be left out: the
// running law's constants the command does not name stay).
YAML::Node material_arguments(const Args& a, const io::MaterialSpec& spec) {
  if (!spec.law) return a.node();
  YAML::Node node = YAML::Clone(a.node());
  node.remove("region");
  if (!node["law"]) {
    YAML::Node running;
    io::write_law(*spec.law, running);
    node["law"] = running["law"];
  }
  return node;
}

}  // namespace

CommandResult RunControl::on_set_material(const Args& a) {
  const auto& names = scene_.region_names;
  const std::vector<int> regions = regions_of(a, names);
  std::vector<io::MaterialSpec> specs;
  std::vector<core::Material> materials;
  for (int r : regions) {
    specs.push_back(params_.regions[static_cast<size_t>(r)].material);
    const io::Checks checks("set_material(" + names[static_cast<size_t>(r)] + ")");
    materials.push_back(io::read_material(checks, material_arguments(a, specs.back()), "material", specs.back(), {"region"}));
  }
  io::SceneParameters before = params_;
  for (size_t i = 0; i < regions.size(); ++i) {
    if (core::Simulator* sim = engine_->real_time()) sim->set_region_material(regions[i], materials[i]);
    params_.regions[static_cast<size_t>(regions[i])].material = specs[i];
  }
  rebuild_accurate(std::move(before));
  return {true, "material of " + std::to_string(regions.size()) + " region(s) set"};
}

CommandResult RunControl::on_set_damping(const Args& a) {
  if (!a.has("mass") && !a.has("stiffness")) throw Reject("give mass (1/s) and/or stiffness (s)");
  const std::vector<int> regions = regions_of(a, scene_.region_names);
  std::vector<core::RayleighDamping> d;
  for (int r : regions) {
    d.push_back(params_.regions[static_cast<size_t>(r)].damping.value_or(core::RayleighDamping{}));
    if (a.has("mass")) d.back().mass_1_s = a.number("mass", 0, 1e6);
    if (a.has("stiffness")) d.back().stiffness_s = a.number("stiffness", 0, 10);
    d.back().validate();
  }
  io::SceneParameters before = params_;
  for (size_t i = 0; i < regions.size(); ++i) {
    if (core::Simulator* sim = engine_->real_time()) sim->set_region_damping(regions[i], d[i]);
    params_.regions[static_cast<size_t>(regions[i])].damping = d[i];
  }
  rebuild_accurate(std::move(before));
  return {true, "damping of " + std::to_string(regions.size()) + " region(s) set"};
}

CommandResult RunControl::on_set_contraction(const Args& a) {
  io::ContractionSpec spec = params_.contraction.value_or(io::ContractionSpec{});
  core::Contraction c =
      io::read_contraction(io::Checks("set_contraction"), a.node(), engine_->model().mesh, scene_.region_names, spec);
  if (core::Simulator* sim = engine_->real_time()) sim->set_contraction(std::move(c));
  follow_contraction_rate();
  io::SceneParameters before = params_;
  params_.contraction = spec;
  rebuild_accurate(std::move(before));
  return {true, "contraction set"};
}

CommandResult RunControl::on_set_fibers(const Args& a) {
  io::FiberSpec spec;
  std::vector<core::Vec3> fibers = io::read_fibers(io::Checks("set_fibers"), a.node(), engine_->model().mesh, scene_.base_dir, spec);
  if (core::Simulator* sim = engine_->real_time()) sim->set_fibers(std::move(fibers));
  io::SceneParameters before = params_;
  params_.fibers = spec;
  rebuild_accurate(std::move(before));
  ++topology_version_;
  return {true, "fibers set"};
}

CommandResult RunControl::on_set_gravity(const Args& a) {
  if (!a.has("gravity")) throw Reject("needs 'gravity': [gx, gy, gz] in m/s^2");
  const Vec3 g = a.vec3("gravity");
  if (g.norm() > 1e4) throw Reject("'gravity' is larger than 1e4 m/s^2");
  if (core::Simulator* sim = engine_->real_time()) sim->set_gravity(g);
  io::SceneParameters before = params_;
  params_.gravity_m_s2 = g;
  rebuild_accurate(std::move(before));
  base_loads_.gravity_m_s2 = g;
  return {true, "gravity set"};
}

CommandResult RunControl::on_set_time_step(const Args& a) {
  if (!a.has("dt")) throw Reject("needs 'dt' in s");
  const double dt = a.number("dt", 1e-6, 10);
  if (core::Simulator* sim = engine_->real_time()) sim->set_time_step(dt);
  io::SceneParameters before = params_;
  params_.solver.dt_s = dt;
  rebuild_accurate(std::move(before));
  return {true, "time step set"};
}

CommandResult RunControl::on_set_solver(const Args& a) {
  if (engine_->accurate())
    throw Reject("set_solver sets the real-time tier's linear solver; this scene runs on the accurate tier, whose "
                 "Newton settings are the scene's solver.newton keys");
  io::SolverSpec given;  // the keys this command gives; the others stay as they run
  const io::Checks& checks = a.checks();
  if (a.has("method")) given.method = io::read_solver_method(checks, a["method"], "method");
  if (a.has("preconditioner")) given.preconditioner = io::read_preconditioner(checks, a["preconditioner"], "preconditioner");
  if (a.has("rotation")) given.rotation = io::read_rotation(checks, a["rotation"], "rotation");
  if (a.has("tolerance")) given.tolerance = a.number("tolerance", 1e-14, 0.5);
  if (a.has("max_iterations")) given.max_iterations = a.integer("max_iterations", 1, 1000000);
  if (a.has("recycled_solutions")) given.recycled_solutions = a.integer("recycled_solutions", 0, 64);
  core::Simulator& sim = simulator();
  const core::SimulatorSettings s = io::solver_settings(given, sim.settings());
  s.solver.validate();
  sim.set_solver_settings(s.solver);
  sim.set_rotation_method(s.rotation);
  io::SolverSpec& kept = params_.solver;
  if (given.method) kept.method = given.method;
  if (given.preconditioner) kept.preconditioner = given.preconditioner;
  if (given.rotation) kept.rotation = given.rotation;
  if (given.tolerance) kept.tolerance = given.tolerance;
  if (given.max_iterations) kept.max_iterations = given.max_iterations;
  if (given.recycled_solutions) kept.recycled_solutions = given.recycled_solutions;
  return {true, "solver settings set"};
}

}  // namespace fiberfem::service
