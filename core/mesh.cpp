#include "core/mesh.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <array>
#include <vector>

namespace fiberfem::core {

double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

TetMesh::TetMesh(Positions rest_positions, std::vector<Tet> tets, std::vector<int> regions,
                 double degenerate_tolerance)
    : rest_(std::move(rest_positions)), tets_(std::move(tets)), regions_(std::move(regions)) {
  const int n = static_cast<int>(rest_.cols());
  if (n < 4) throw std::invalid_argument("mesh: needs at least 4 nodes, got " + std::to_string(n));
  if (tets_.empty()) throw std::invalid_argument("mesh: has no elements");
  for (int i = 0; i < n; ++i) {
    if (!rest_.col(i).allFinite())
      throw std::invalid_argument("mesh: node " + std::to_string(i) + " has a non-finite coordinate");
  }
  set_regions(std::move(regions_));
  volumes_.resize(tets_.size());
  for (size_t e = 0; e < tets_.size(); ++e) {
    const auto id = [e] { return "mesh: element " + std::to_string(e); };  // only for an error
    Tet& t = tets_[e];
    for (int a = 0; a < 4; ++a) {
      if (t[a] < 0 || t[a] >= n)
        throw std::invalid_argument(id() + " references node " + std::to_string(t[a]) +
                                    ", outside [0, " + std::to_string(n) + ")");
      for (int b = 0; b < a; ++b)
        if (t[a] == t[b])
          throw std::invalid_argument(id() + " uses node " + std::to_string(t[a]) + " twice");
    }
    double v = signed_volume(rest_.col(t[0]), rest_.col(t[1]), rest_.col(t[2]), rest_.col(t[3]));
    double h = 0.0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) h = std::max(h, (rest_.col(t[a]) - rest_.col(t[b])).norm());
    if (!(std::abs(v) > degenerate_tolerance * h * h * h))
      throw std::invalid_argument(id() + " is degenerate (volume " + std::to_string(v) +
                                  " m^3, longest edge " + std::to_string(h) + " m)");
    if (v < 0) {
      std::swap(t[2], t[3]);
      v = -v;
      reoriented_.push_back(static_cast<int>(e));
    }
    volumes_[e] = v;
  }
  build_boundary();
}

void TetMesh::set_regions(std::vector<int> regions) {
  if (regions.empty()) regions.assign(tets_.size(), 0);
  if (regions.size() != tets_.size())
    throw std::invalid_argument("mesh: " + std::to_string(regions.size()) + " region ids for " +
                                std::to_string(tets_.size()) + " elements");
  int count = 0;
  for (size_t e = 0; e < regions.size(); ++e) {
    if (regions[e] < 0)
      throw std::invalid_argument("mesh: element " + std::to_string(e) + " has negative region id " +
                                  std::to_string(regions[e]));
    count = std::max(count, regions[e] + 1);
  }
  regions_ = std::move(regions);
  num_regions_ = count;
}

// A face is on the boundary when exactly one element uses it. The face opposite local
// node k of a positively oriented tet, listed so its normal points away from node k.
// The faces are sorted by their node triple (a hash map of 1 M faces took 0.34 s at
// 250,000 tets, the sort a quarter of it), so equal faces are neighbours.
void TetMesh::build_boundary() {
  static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  // A face by its two larger nodes (the smallest is its bucket's), one 64-bit key, and
  // its use; ordered by key, then use (the element order).
  struct Face {
    std::uint64_t key;  // second smallest node << 32 | largest
    int use;            // element * 4 + face
    bool operator<(const Face& o) const { return key != o.key ? key < o.key : use < o.use; }
  };
  // Faces bucketed by their smallest node (a counting sort, in element order), each
  // bucket then sorted: the order of one sort of all of them (1 M faces at 250,000 tets),
  // in a fraction of its time.
  const size_t n = static_cast<size_t>(num_nodes());
  std::vector<int> start(n + 1, 0);
  std::vector<int> lowest(tets_.size() * 4);
  std::vector<Face> made(tets_.size() * 4);
  for (size_t e = 0; e < tets_.size(); ++e)
    for (int f = 0; f < 4; ++f) {
      int a = tets_[e][kFace[f][0]], b = tets_[e][kFace[f][1]], c = tets_[e][kFace[f][2]];
      if (a > b) std::swap(a, b);
      if (b > c) std::swap(b, c);
      if (a > b) std::swap(a, b);
      const size_t u = e * 4 + static_cast<size_t>(f);
      made[u] = {static_cast<std::uint64_t>(b) << 32 | static_cast<std::uint32_t>(c), static_cast<int>(u)};
      lowest[u] = a;
      ++start[static_cast<size_t>(a) + 1];
    }
  for (size_t v = 0; v < n; ++v) start[v + 1] += start[v];
  std::vector<Face> all(made.size());
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (size_t u = 0; u < made.size(); ++u) all[static_cast<size_t>(fill[static_cast<size_t>(lowest[u])]++)] = made[u];
  }
  // (On this thread: a mesh is read before a run's thread count is known.)
  for (size_t v = 0; v < n; ++v) std::sort(all.begin() + start[v], all.begin() + start[v + 1]);
  std::vector<std::pair<int, int>> faces;  // (element, face) of boundary faces
  const Face* over = nullptr;              // the face whose third use comes first in element order
  size_t over_bucket = 0;
  for (size_t v = 0; v < n; ++v)
    for (size_t a = static_cast<size_t>(start[v]), b = a; a < static_cast<size_t>(start[v + 1]); a = b) {
      for (b = a + 1; b < static_cast<size_t>(start[v + 1]) && all[b].key == all[a].key;) ++b;
      if (b - a == 1) faces.emplace_back(all[a].use / 4, all[a].use % 4);
      if (b - a > 2 && (!over || all[a + 2].use < over->use)) {
        over = &all[a + 2];
        over_bucket = v;
      }
    }
  if (over)
    throw std::invalid_argument("mesh: face (" + std::to_string(over_bucket) + ", " + std::to_string(over->key >> 32) + ", " +
                                std::to_string(over->key & 0xffffffffu) + ") is shared by more than two elements (element " +
                                std::to_string(over->use / 4) + ")");
  std::sort(faces.begin(), faces.end());  // deterministic order
  boundary_.reserve(faces.size());
  boundary_elements_.reserve(faces.size());
  for (auto [e, f] : faces) {
    // Outward for the face opposite node f: orientation check against the opposite node.
    const Tet& t = tets_[static_cast<size_t>(e)];
    Tri tri{t[kFace[f][0]], t[kFace[f][1]], t[kFace[f][2]]};
    const Vec3 a = rest_.col(tri[0]), b = rest_.col(tri[1]), c = rest_.col(tri[2]);
    const Vec3 opp = rest_.col(t[f]);
    if ((b - a).cross(c - a).dot(opp - a) > 0) std::swap(tri[1], tri[2]);
    boundary_.push_back(tri);
    boundary_elements_.push_back(e);
  }
}

std::vector<int> TetMesh::boundary_nodes() const {
  std::vector<int> nodes;
  nodes.reserve(boundary_.size() * 3);
  for (const Tri& t : boundary_) nodes.insert(nodes.end(), t.begin(), t.end());
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

void TetMesh::set_node_set(const std::string& name, std::vector<int> nodes) {
  for (int i : nodes)
    if (i < 0 || i >= num_nodes())
      throw std::invalid_argument("mesh: node set '" + name + "' references node " +
                                  std::to_string(i) + ", outside [0, " +
                                  std::to_string(num_nodes()) + ")");
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  node_sets_[name] = std::move(nodes);
}

const std::vector<int>& TetMesh::node_set(const std::string& name) const {
  auto it = node_sets_.find(name);
  if (it == node_sets_.end()) throw std::out_of_range("mesh: no node set named '" + name + "'");
  return it->second;
}

std::pair<Vec3, Vec3> TetMesh::bounding_box() const {
  return {rest_.rowwise().minCoeff(), rest_.rowwise().maxCoeff()};
}

double TetMesh::total_volume() const {
  double v = 0.0;
  for (double x : volumes_) v += x;
  return v;
}

TetMesh renumber_nodes(const TetMesh& mesh, const std::vector<int>& old_of_new) {
  const int n = mesh.num_nodes();
  if (static_cast<int>(old_of_new.size()) != n)
    throw std::invalid_argument("renumber_nodes: permutation has wrong size");
  std::vector<int> new_of_old(static_cast<size_t>(n), -1);
  Positions x(3, n);
  for (int i = 0; i < n; ++i) {
    const int o = old_of_new[static_cast<size_t>(i)];
    if (o < 0 || o >= n || new_of_old[static_cast<size_t>(o)] != -1)
      throw std::invalid_argument("renumber_nodes: not a permutation");
    new_of_old[static_cast<size_t>(o)] = i;
    x.col(i) = mesh.rest_positions().col(o);
  }
  std::vector<Tet> tets = mesh.tets();
  for (Tet& t : tets)
    for (int& i : t) i = new_of_old[static_cast<size_t>(i)];
  TetMesh out(std::move(x), std::move(tets), mesh.regions());
  for (const auto& [name, nodes] : mesh.node_sets()) {
    std::vector<int> renum;
    renum.reserve(nodes.size());
    for (int i : nodes) renum.push_back(new_of_old[static_cast<size_t>(i)]);
    out.set_node_set(name, std::move(renum));
  }
  return out;
}

}  // namespace fiberfem::core
