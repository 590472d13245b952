// fixed and loads (docs/scenes.md): the boundary conditions and the external loads.

#include "io/scene_internal.hpp"

#include <algorithm>

namespace fiberfem::io::detail {

using core::Vec3;

void read_fixed(const CheckedMap& top, core::Model& model) {
  if (!top.has("fixed")) return;
  const Checks& checks = top.checks();
  const YAML::Node fx = top["fixed"];
  if (!fx.IsSequence()) checks.fail(fx, "fixed", "expected a list of node selectors");
  for (size_t i = 0; i < fx.size(); ++i) {
    const std::string path = "fixed[" + std::to_string(i) + "]";
    const std::vector<int> nodes = read_node_selector(checks, fx[i], path, model.mesh, nullptr, {"components"});
    unsigned mask = 0b111;
    if (fx[i]["components"].IsDefined()) {
      const YAML::Node c = fx[i]["components"];
      if (!c.IsSequence() || c.size() == 0 || c.size() > 3)
        checks.fail(c, path + ".components", "expected a list of x, y, z (the fixed displacement components)");
      mask = 0;
      for (size_t k = 0; k < c.size(); ++k) {
        const std::string at = path + ".components[" + std::to_string(k) + "]";
        const unsigned bit = 1u << (checks.choice(c[k], at, {"x", "y", "z"})[0] - 'x');
        if (mask & bit) checks.fail(c[k], at, "repeated");
        mask |= bit;
      }
    }
    model.fix_nodes(nodes, mask);
  }
}

namespace {

core::SurfaceLoad traction(const Checks& checks, const YAML::Node& node, const std::string& path, const core::TetMesh& mesh) {
  const CheckedMap t(checks, node, path, {"on", "pressure", "force_per_area", "follower", "ramp"});
  if (!t.has("on")) t.fail("needs on: <node selector>");
  const std::vector<int> nodes = read_node_selector(checks, t["on"], t.sub("on"), mesh);
  core::SurfaceLoad load;
  for (const core::Tri& tri : mesh.boundary_triangles())
    if (std::all_of(tri.begin(), tri.end(), [&](int n) { return std::binary_search(nodes.begin(), nodes.end(), n); }))
      load.faces.push_back(tri);
  if (load.faces.empty()) checks.fail(t["on"], t.sub("on"), "selects no boundary face (all three nodes must match)");
  if (t.has("pressure") == t.has("force_per_area")) t.fail("give exactly one of pressure, force_per_area");
  if (t.has("pressure")) load.pressure_pa = t.number("pressure");
  if (t.has("force_per_area")) load.force_per_area_pa = t.vec3("force_per_area");
  if (t.has("follower")) {
    load.follower = t.boolean("follower");
    if (load.follower && !t.has("pressure")) checks.fail(t["follower"], t.sub("follower"), "goes with pressure");
  }
  if (t.has("ramp")) load.ramp_s = t.number("ramp", 0, 1e6);
  return load;
}

// A force at the node nearest `at`.
core::PointForce point_force(const Checks& checks, const YAML::Node& node, const std::string& path, const core::TetMesh& mesh) {
  const CheckedMap p(checks, node, path, {"at", "force"});
  if (!p.has("at") || !p.has("force")) p.fail("needs at and force");
  const Vec3 at = p.vec3("at");
  int best = 0;
  double bd = HUGE_VAL;
  for (int n = 0; n < mesh.num_nodes(); ++n) {
    const double d = (mesh.rest_positions().col(n) - at).squaredNorm();
    if (d < bd) bd = d, best = n;
  }
  return {best, p.vec3("force")};
}

}  // namespace

void read_loads(const CheckedMap& top, core::Model& model, std::optional<Vec3>& gravity) {
  if (!top.has("loads")) return;
  const Checks& checks = top.checks();
  const CheckedMap l(checks, top["loads"], "loads", {"gravity", "tractions", "point_forces"});
  if (l.has("gravity")) gravity = model.loads.gravity_m_s2 = l.vec3("gravity");
  if (l.has("tractions")) {
    const YAML::Node tr = l["tractions"];
    if (!tr.IsSequence()) checks.fail(tr, "loads.tractions", "expected a list");
    for (size_t i = 0; i < tr.size(); ++i)
      model.loads.surface_loads.push_back(traction(checks, tr[i], "loads.tractions[" + std::to_string(i) + "]", model.mesh));
  }
  if (l.has("point_forces")) {
    const YAML::Node pf = l["point_forces"];
    if (!pf.IsSequence()) checks.fail(pf, "loads.point_forces", "expected a list");
    for (size_t i = 0; i < pf.size(); ++i)
      model.loads.point_forces.push_back(point_force(checks, pf[i], "loads.point_forces[" + std::to_string(i) + "]", model.mesh));
  }
}

}  // namespace fiberfem::io::detail
