// Forces applied by command (docs/commands.md): apply_force on a node, node list, node
// set, region or picked point, along a vector or the fibers; clear_force.

#include "service/run_control.hpp"

#include "service/command_args.hpp"

#include <cmath>

namespace fiberfem::service {

using detail::Args;
using detail::join;
using detail::Reject;
using core::Vec3;

CommandResult RunControl::on_apply_force(const Args& a) {
  const Engine& sim = *engine_;
  const core::TetMesh& mesh = sim.model().mesh;
  const auto& names = scene_.region_names;
  if (!a.has("target")) throw Reject("needs 'target': {node | nodes | node_set | region | point}");
  const YAML::Node t = a["target"];
  if (!t.IsMap() || t.size() != 1)
    throw Reject("'target' must be an object with exactly one of node, nodes, node_set, region, point");
  const std::string how = a.checks().text(t.begin()->first, "target's key");
  const YAML::Node v = t.begin()->second;
  std::vector<int> nodes;
  const int nn = mesh.num_nodes();
  if (how == "node") {
    nodes = {a.node_index(v, "target.node", nn)};
  } else if (how == "nodes") {
    if (!v.IsSequence() || v.size() == 0) throw Reject("'target.nodes' must be a non-empty list of node indices");
    std::vector<char> seen(static_cast<size_t>(nn), 0);
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string key = "target.nodes[" + std::to_string(i) + "]";
      nodes.push_back(a.node_index(v[i], key, nn));
      if (seen[static_cast<size_t>(nodes.back())]++)
        throw Reject("'" + key + "' = " + std::to_string(nodes.back()) + " is listed twice (the force is shared among distinct nodes)");
    }
  } else if (how == "node_set") {
    const std::string s = a.checks().text(v, "target.node_set");
    const auto it = mesh.node_sets().find(s);
    if (it == mesh.node_sets().end()) {
      std::vector<std::string> sets;
      for (const auto& kv : mesh.node_sets()) sets.push_back(kv.first);
      throw Reject("no node set '" + s + "' (node sets: " + join(sets) + ")");
    }
    nodes = it->second;
  } else if (how == "region") {
    const std::string s = a.checks().text(v, "target.region");
    const auto it = std::find(names.begin(), names.end(), s);
    if (it == names.end()) throw Reject("no region '" + s + "' (regions: " + join(names) + ")");
    const int r = static_cast<int>(it - names.begin());
    std::vector<char> in(static_cast<size_t>(nn), 0);
    for (int e = 0; e < mesh.num_elements(); ++e)
      if (mesh.regions()[static_cast<size_t>(e)] == r)
        for (int n : mesh.tets()[static_cast<size_t>(e)]) in[static_cast<size_t>(n)] = 1;
    for (int n = 0; n < nn; ++n)
      if (in[static_cast<size_t>(n)]) nodes.push_back(n);
  } else if (how == "point") {
    // The node nearest the point in the current (deformed) configuration: what a user
    // who clicks on the drawn mesh means.
    const Vec3 p = a.checks().vec3(v, "target.point", 1e12);
    const auto x = sim.positions();
    int best = 0;
    double best_d = HUGE_VAL;
    for (int n = 0; n < nn; ++n) {
      const double d = (x.col(n) - p).squaredNorm();
      if (d < best_d) best_d = d, best = n;
    }
    nodes = {best};
  } else {
    throw Reject("unknown target '" + how + "' (node, nodes, node_set, region, point)");
  }
  AppliedForce f;
  f.nodes = nodes;
  const double share = 1.0 / static_cast<double>(nodes.size());
  if (a.has("force") == a.has("magnitude")) throw Reject("give exactly one of 'force' [N, N, N] and 'magnitude' (N, with along)");
  if (a.has("force")) {
    if (a.has("along")) throw Reject("'along' goes with 'magnitude'");
    const Vec3 total = a.vec3("force");
    f.force_n.assign(nodes.size(), total * share);
  } else {
    const double mag = a.number("magnitude", -1e9, 1e9);
    if (!a.has("along") || a.text("along") != "fibers") throw Reject("'magnitude' needs along: fibers");
    // Along the fibers: each node's direction is the sum of the rest fibers of the
    // elements around it, sign-aligned to the first (a fiber has no sign).
    std::vector<Vec3> dir(static_cast<size_t>(nn), Vec3::Zero());
    const auto& fib = sim.model().fibers;
    for (int e = 0; e < mesh.num_elements(); ++e) {
      const Vec3 fe = fib.empty() ? Vec3(1, 0, 0) : fib[static_cast<size_t>(e)];
      for (int n : mesh.tets()[static_cast<size_t>(e)]) {
        Vec3& d = dir[static_cast<size_t>(n)];
        d += d.dot(fe) < 0 ? -fe : fe;
      }
    }
    for (int n : nodes) {
      Vec3 d = dir[static_cast<size_t>(n)];
      if (d.norm() == 0) throw Reject("node " + std::to_string(n) + " has no element to take a fiber from");
      f.force_n.push_back(d.normalized() * mag * share);
    }
  }
  if (a.has("duration")) f.until_s = sim.time_s() + a.number("duration", 1e-9, 1e9);
  const std::string name = a.has("name") ? a.text("name") : "force-" + std::to_string(++force_counter_);
  if (name.empty()) throw Reject("'name' must not be empty");
  auto saved = forces_;
  forces_[name] = f;
  try {
    refresh_loads();
  } catch (...) {
    forces_ = std::move(saved);
    refresh_loads();
    throw;
  }
  return {true, "force '" + name + "' on " + std::to_string(nodes.size()) + " node(s)"};
}

CommandResult RunControl::on_clear_force(const Args& a) {
  if (a.has("name")) {
    const std::string name = a.text("name");
    if (!forces_.erase(name)) throw Reject("no force named '" + name + "'");
  } else {
    forces_.clear();
  }
  refresh_loads();
  return {true, "cleared"};
}

}  // namespace fiberfem::service
