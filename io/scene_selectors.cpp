// Node selectors (docs/scenes.md): a plane, a box or a named node set, as fixed, loads,
// fibers.rule and measure.cavities use them.

#include "io/input_file.hpp"
#include "io/scene_internal.hpp"

namespace fiberfem::io {

using core::Vec3;

namespace detail {

std::pair<Vec3, Vec3> read_box(const Checks& checks, const YAML::Node& node, const std::string& path) {
  if (!node.IsSequence() || node.size() != 2) checks.fail(node, path, "expected [[x0, y0, z0], [x1, y1, z1]]");
  const Vec3 a = checks.vec3(node[0], path + "[0]"), b = checks.vec3(node[1], path + "[1]");
  if ((b.array() < a.array()).any()) checks.fail(node, path, "the second corner must not be below the first");
  return {a, b};
}

YAML::Node flow_vec3(const Vec3& v) {
  YAML::Node l(std::vector<double>{v.x(), v.y(), v.z()});
  l.SetStyle(YAML::EmitterStyle::Flow);
  return l;
}

}  // namespace detail

std::vector<int> read_node_selector(const Checks& checks, const YAML::Node& node, const std::string& path,
                                    const core::TetMesh& mesh, NodeSelector* spec,
                                    const std::vector<std::string>& also_allowed) {
  std::vector<std::string> allowed{"plane", "box", "node_set"};
  allowed.insert(allowed.end(), also_allowed.begin(), also_allowed.end());
  const CheckedMap m(checks, node, path, allowed);
  NodeSelector s;
  std::vector<int> nodes;
  const auto& X = mesh.rest_positions();
  int kinds = 0;
  if (m.has("plane")) {
    ++kinds;
    const CheckedMap p(checks, m["plane"], m.sub("plane"), {"axis", "value", "tol"});
    if (!p.has("axis") || !p.has("value")) p.fail("needs axis and value");
    s.kind = NodeSelector::Kind::plane;
    s.axis = p.choice("axis", {"x", "y", "z"})[0] - 'x';
    s.value_m = p.number("value");
    if (p.has("tol")) s.tol_m = p.number("tol", 0, HUGE_VAL);
    for (int i = 0; i < mesh.num_nodes(); ++i)
      if (std::abs(X(s.axis, i) - s.value_m) <= s.tol_m) nodes.push_back(i);
  }
  if (m.has("box")) {
    ++kinds;
    s.kind = NodeSelector::Kind::box;
    std::tie(s.lo_m, s.hi_m) = detail::read_box(checks, m["box"], m.sub("box"));
    for (int i = 0; i < mesh.num_nodes(); ++i)
      if ((X.col(i).array() >= s.lo_m.array()).all() && (X.col(i).array() <= s.hi_m.array()).all()) nodes.push_back(i);
  }
  if (m.has("node_set")) {
    ++kinds;
    s.kind = NodeSelector::Kind::node_set;
    s.node_set = m.text("node_set");
    const auto& sets = mesh.node_sets();
    const auto it = sets.find(s.node_set);
    if (it == sets.end()) {
      std::vector<std::string> names;
      for (const auto& kv : sets) names.push_back(kv.first);
      checks.fail(m["node_set"], m.sub("node_set"),
                  "no node set '" + printable(s.node_set) + "' (the mesh has: " + join(names) + ")");
    }
    nodes = it->second;
  }
  if (kinds != 1) m.fail("give exactly one of plane, box, node_set");
  if (nodes.empty()) m.fail("matches no node");
  if (spec) *spec = s;
  return nodes;
}

YAML::Node write_node_selector(const NodeSelector& s) {
  YAML::Node n(YAML::NodeType::Map);
  switch (s.kind) {
    case NodeSelector::Kind::plane: {
      YAML::Node p(YAML::NodeType::Map);
      p["axis"] = std::string(1, static_cast<char>('x' + s.axis));
      p["value"] = s.value_m;
      p["tol"] = s.tol_m;
      n["plane"] = p;
      break;
    }
    case NodeSelector::Kind::box: {
      YAML::Node b(YAML::NodeType::Sequence);
      b.push_back(detail::flow_vec3(s.lo_m));
      b.push_back(detail::flow_vec3(s.hi_m));
      n["box"] = b;
      break;
    }
    case NodeSelector::Kind::node_set: n["node_set"] = s.node_set; break;
  }
  return n;
}

}  // namespace fiberfem::io
