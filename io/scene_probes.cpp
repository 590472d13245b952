// probes and measure.cavities (docs/scenes.md): what a run reports besides its states.

#include "io/scene_internal.hpp"

namespace fiberfem::io {

using core::Vec3;

namespace {

// Barycentric weights of p in element e (sum to one).
Eigen::Vector4d barycentric(const core::TetMesh& mesh, int e, const Vec3& p) {
  const core::Tet& t = mesh.tets()[static_cast<size_t>(e)];
  const auto& X = mesh.rest_positions();
  core::Mat3 D;
  for (int j = 0; j < 3; ++j) D.col(j) = X.col(t[static_cast<size_t>(j + 1)]) - X.col(t[0]);
  const Vec3 l = D.inverse() * (p - X.col(t[0]));
  return {1 - l.sum(), l.x(), l.y(), l.z()};
}

}  // namespace

core::Vec3 Probe::displacement(const core::TetMesh& mesh, const core::Positions& x) const {
  Vec3 u = Vec3::Zero();
  const core::Tet& t = mesh.tets()[static_cast<size_t>(element)];
  for (int a = 0; a < 4; ++a) {
    const int n = t[static_cast<size_t>(a)];
    u += weights(a) * (x.col(n) - mesh.rest_positions().col(n));
  }
  return u;
}

namespace detail {

std::vector<Probe> read_probes(const CheckedMap& top, const core::TetMesh& mesh) {
  std::vector<Probe> probes;
  if (!top.has("probes")) return probes;
  const Checks& checks = top.checks();
  const YAML::Node pr = top["probes"];
  if (!pr.IsMap()) checks.fail(pr, "probes", "expected a mapping name: [x, y, z]");
  for (const auto& kv : pr) {
    if (!kv.first.IsScalar()) checks.fail(kv.first, "probes", "a probe's name must be a plain name, not a mapping or a list");
    const std::string name = kv.first.as<std::string>();
    Probe p{name, checks.vec3(kv.second, "probes." + name)};
    // The containing element (the least negative weight, within round-off of the hull).
    double best = -HUGE_VAL;
    for (int e = 0; e < mesh.num_elements(); ++e) {
      const Eigen::Vector4d w = barycentric(mesh, e, p.point_m);
      if (w.minCoeff() > best) best = w.minCoeff(), p.element = e, p.weights = w;
    }
    if (best < -1e-9) checks.fail(kv.second, "probes." + name, "the point is outside the mesh");
    probes.push_back(p);
  }
  return probes;
}

// Cavities: boundary parts (node selectors) whose enclosed volume is measured.
std::vector<CavityMeasure> read_cavities(const CheckedMap& top, const core::TetMesh& mesh) {
  std::vector<CavityMeasure> cavities;
  if (!top.has("measure")) return cavities;
  const Checks& checks = top.checks();
  const CheckedMap me(checks, top["measure"], "measure", {"cavities"});
  if (!me.has("cavities")) return cavities;
  const YAML::Node cv = me["cavities"];
  if (!cv.IsMap()) checks.fail(cv, "measure.cavities", "expected a mapping name: node selector");
  for (const auto& kv : cv) {
    const std::string name = checks.text(kv.first, "measure.cavities");
    const std::string path = "measure.cavities." + name;
    const std::vector<int> nodes = read_node_selector(checks, kv.second, path, mesh);
    try {
      cavities.push_back({name, core::cavity_surface(mesh, nodes)});
    } catch (const std::invalid_argument& e) {
      checks.fail(kv.second, path, e.what());
    }
    const double v = core::cavity_volume(cavities.back().surface, mesh.rest_positions());
    if (!(v > 0))
      checks.fail(kv.second, path,
                  "encloses a volume of " + std::to_string(v) + " m^3 at rest: select the cavity's own wall (an endocardium)");
  }
  return cavities;
}

}  // namespace detail
}  // namespace fiberfem::io
