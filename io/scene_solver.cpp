// solver and fidelity (docs/scenes.md): the step, the linear solver and the rotation, read
// onto a SolverSpec, built into core::SimulatorSettings, and written back.

#include "io/scene_internal.hpp"

#include <limits>
#include <map>

namespace fiberfem::io {

namespace {

// The scene's names of an engine choice, in the order messages list them.
template <class E>
using Names = std::vector<std::pair<std::string, E>>;

const Names<core::LinearSolverKind> kMethods = {{"pcg", core::LinearSolverKind::pcg}, {"direct", core::LinearSolverKind::direct}};
const Names<core::PreconditionerKind> kPreconditioners = {{"cholesky", core::PreconditionerKind::cholesky},
                                                          {"block_jacobi", core::PreconditionerKind::block_jacobi},
                                                          {"amg", core::PreconditionerKind::amg}};
const Names<core::RotationMethod> kRotations = {{"svd", core::RotationMethod::svd}, {"polar", core::RotationMethod::polar}};
const Names<core::FirstFactorisation> kFirstFactorisations = {{"auto", core::FirstFactorisation::automatic},
                                                               {"wait", core::FirstFactorisation::wait},
                                                               {"beside", core::FirstFactorisation::beside}};
const Names<Mode> kModes = {{"dynamic", Mode::dynamic}, {"static", Mode::static_}};
const Names<Tier> kTiers = {{"auto", Tier::automatic}, {"real_time", Tier::real_time}, {"accurate", Tier::accurate}};

template <class E>
E read_name(const Checks& checks, const YAML::Node& n, const std::string& path, const Names<E>& names) {
  std::vector<std::string> options;
  for (const auto& [name, value] : names) options.push_back(name);
  const std::string v = checks.choice(n, path, options);
  for (const auto& [name, value] : names)
    if (name == v) return value;
  return names.front().second;
}

template <class E>
std::string name_of(E value, const Names<E>& names) {
  for (const auto& [name, v] : names)
    if (v == value) return name;
  return names.front().first;
}

// The fidelity presets (scene key `fidelity`, docs/scenes.md), chosen from the measured
// Pareto fronts of docs/speed-accuracy.md. Explicit keys of the scene override them.
const std::map<std::string, detail::Fidelity>& fidelity_presets() {
  static const std::map<std::string, detail::Fidelity> p{
      {"interactive", {"interactive", 1.0 / 30.0, 0.5, 1e-3, true}},
      {"balanced", {"balanced", 1.0 / 60.0, 1.0, 1e-6, false}},
      {"accurate", {"accurate", 1.0 / 120.0, 1.5, 1e-6, false}},
  };
  return p;
}

}  // namespace

core::LinearSolverKind read_solver_method(const Checks& checks, const YAML::Node& n, const std::string& path) {
  return read_name(checks, n, path, kMethods);
}
core::PreconditionerKind read_preconditioner(const Checks& checks, const YAML::Node& n, const std::string& path) {
  return read_name(checks, n, path, kPreconditioners);
}
core::RotationMethod read_rotation(const Checks& checks, const YAML::Node& n, const std::string& path) {
  return read_name(checks, n, path, kRotations);
}

void read_solver(const Checks& checks, const YAML::Node& node, SolverSpec& spec) {
  const CheckedMap s(checks, node, "solver",
                     {"mode", "dt", "method", "tolerance", "max_iterations", "rotation", "preconditioner", "warm_start",
                      "max_energy_gain", "until", "recycled_solutions", "threads", "corotation", "first_factorisation",
                      "jacobi_first", "load_steps", "newton", "quadrature", "tier"});
  SolverSpec r = spec;
  if (s.has("threads")) r.threads = s.integer("threads", 0, 1024);
  if (s.has("recycled_solutions")) r.recycled_solutions = s.integer("recycled_solutions", 0, 64);
  if (s.has("until")) r.until_s = s.number("until", 0, 1e9, true);
  if (s.has("mode")) r.mode = read_name(checks, s["mode"], "solver.mode", kModes);
  if (s.has("tier")) r.tier = read_name(checks, s["tier"], "solver.tier", kTiers);
  if (s.has("dt")) r.dt_s = s.number("dt", 0, 10, true);
  if (s.has("method")) r.method = read_solver_method(checks, s["method"], "solver.method");
  if (s.has("tolerance")) r.tolerance = s.number("tolerance", 0, 1, true);
  if (s.has("max_iterations")) r.max_iterations = s.integer("max_iterations", 1, 1 << 30);
  if (s.has("rotation")) r.rotation = read_rotation(checks, s["rotation"], "solver.rotation");
  if (s.has("preconditioner")) r.preconditioner = read_preconditioner(checks, s["preconditioner"], "solver.preconditioner");
  if (s.has("corotation")) r.corotation = s.boolean("corotation");
  if (s.has("first_factorisation"))
    r.first_factorisation = read_name(checks, s["first_factorisation"], "solver.first_factorisation", kFirstFactorisations);
  if (s.has("jacobi_first")) {
    const YAML::Node j = s["jacobi_first"];
    r.jacobi_first = j.IsScalar() && j.Scalar() == "auto" ? core::kJacobiFirstAuto : s.integer("jacobi_first", 0, 100000);
  }
  if (s.has("warm_start")) r.warm_start = s.boolean("warm_start");
  if (s.has("load_steps")) r.load_steps = s.integer("load_steps", 1, 1000000);
  if (s.has("quadrature")) {
    r.quadrature = s.integer("quadrature", 1, 14);
    if (*r.quadrature != 1 && *r.quadrature != 4 && *r.quadrature != 11 && *r.quadrature != 14)
      checks.fail(s["quadrature"], "solver.quadrature", "must be 1, 4, 11 or 14 points per element");
  }
  if (s.has("newton")) {
    const CheckedMap nw(checks, s["newton"], "solver.newton",
                        {"tolerance", "increment_tolerance", "max_iterations", "line_search"});
    if (nw.has("tolerance")) r.newton_tolerance = nw.number("tolerance", 0, 1, true);
    if (nw.has("increment_tolerance")) r.newton_increment_tolerance = nw.number("increment_tolerance", 0, 1, true);
    if (nw.has("max_iterations")) r.newton_max_iterations = nw.integer("max_iterations", 1, 100000);
    if (nw.has("line_search")) r.newton_line_search = nw.boolean("line_search");
  }
  if (s.has("max_energy_gain")) {
    const YAML::Node g = s["max_energy_gain"];
    r.max_energy_gain = g.IsScalar() && (g.Scalar() == "inf" || g.Scalar() == ".inf")
                            ? std::numeric_limits<double>::infinity()
                            : s.number("max_energy_gain", 0, HUGE_VAL);
  }
  spec = r;
}

core::SimulatorSettings solver_settings(const SolverSpec& s, core::SimulatorSettings st) {
  if (s.threads) st.threads = *s.threads;
  if (s.recycled_solutions) st.solver.recycled_solutions = *s.recycled_solutions;
  if (s.dt_s) st.dt_s = *s.dt_s;
  if (s.method) st.solver.method = *s.method;
  if (s.tolerance) st.solver.tolerance = *s.tolerance;
  if (s.max_iterations) st.solver.max_iterations = *s.max_iterations;
  if (s.rotation) st.rotation = *s.rotation;
  if (s.preconditioner) st.solver.preconditioner = *s.preconditioner;
  if (s.corotation) st.corotation = *s.corotation;
  if (s.first_factorisation) st.solver.first_factorisation = *s.first_factorisation;
  if (s.jacobi_first) st.solver.jacobi_first = *s.jacobi_first;
  if (s.warm_start) st.solver.warm_start = *s.warm_start;
  if (s.max_energy_gain) st.max_energy_gain = *s.max_energy_gain;
  return st;
}

YAML::Node write_solver(const SolverSpec& s) {
  YAML::Node n(YAML::NodeType::Map);
  if (s.mode) n["mode"] = name_of(*s.mode, kModes);
  if (s.dt_s) n["dt"] = *s.dt_s;
  if (s.method) n["method"] = name_of(*s.method, kMethods);
  if (s.tolerance) n["tolerance"] = *s.tolerance;
  if (s.max_iterations) n["max_iterations"] = *s.max_iterations;
  if (s.rotation) n["rotation"] = name_of(*s.rotation, kRotations);
  if (s.preconditioner) n["preconditioner"] = name_of(*s.preconditioner, kPreconditioners);
  if (s.warm_start) n["warm_start"] = *s.warm_start;
  if (s.max_energy_gain) n["max_energy_gain"] = *s.max_energy_gain;
  if (s.until_s) n["until"] = *s.until_s;
  if (s.recycled_solutions) n["recycled_solutions"] = *s.recycled_solutions;
  if (s.threads) n["threads"] = *s.threads;
  if (s.corotation) n["corotation"] = *s.corotation;
  if (s.first_factorisation) n["first_factorisation"] = name_of(*s.first_factorisation, kFirstFactorisations);
  if (s.jacobi_first) {
    if (*s.jacobi_first == core::kJacobiFirstAuto)
      n["jacobi_first"] = "auto";
    else
      n["jacobi_first"] = *s.jacobi_first;
  }
  if (s.load_steps) n["load_steps"] = *s.load_steps;
  if (s.quadrature) n["quadrature"] = *s.quadrature;
  if (s.tier) n["tier"] = name_of(*s.tier, kTiers);
  if (s.newton_tolerance) n["newton"]["tolerance"] = *s.newton_tolerance;
  if (s.newton_increment_tolerance) n["newton"]["increment_tolerance"] = *s.newton_increment_tolerance;
  if (s.newton_max_iterations) n["newton"]["max_iterations"] = *s.newton_max_iterations;
  if (s.newton_line_search) n["newton"]["line_search"] = *s.newton_line_search;
  return n;
}

namespace detail {

std::optional<Fidelity> read_fidelity(const CheckedMap& top) {
  if (!top.has("fidelity")) return std::nullopt;
  std::vector<std::string> names;
  for (const auto& [k, v] : fidelity_presets()) names.push_back(k);
  return fidelity_presets().at(top.choice("fidelity", names));
}

}  // namespace detail
}  // namespace fiberfem::io
