#include "core/cavity.hpp"

#include <algorithm>
#include <map>
#include <stdexcept>

namespace fiberfem::core {

CavitySurface cavity_surface(const TetMesh& mesh, const std::vector<int>& surface_nodes) {
  std::vector<char> in(static_cast<size_t>(mesh.num_nodes()), 0);
  for (int n : surface_nodes) {
    if (n < 0 || n >= mesh.num_nodes()) throw std::invalid_argument("cavity: node " + std::to_string(n) + " is out of range");
    in[static_cast<size_t>(n)] = 1;
  }
  CavitySurface s;
  for (const Tri& t : mesh.boundary_triangles())
    if (in[static_cast<size_t>(t[0])] && in[static_cast<size_t>(t[1])] && in[static_cast<size_t>(t[2])]) s.faces.push_back(t);
  if (s.faces.empty()) throw std::invalid_argument("cavity: no boundary triangle has all three nodes on the surface");
  // Rim: directed edges whose reverse is not in the surface.
  std::map<std::pair<int, int>, int> count;
  for (const Tri& t : s.faces)
    for (int k = 0; k < 3; ++k) ++count[{t[static_cast<size_t>(k)], t[static_cast<size_t>((k + 1) % 3)]}];
  for (const auto& [edge, n] : count)
    if (!count.count({edge.second, edge.first})) {
      for (int i = 0; i < n; ++i) s.rim_edges.push_back(edge);
      s.rim_nodes.push_back(edge.first);
      s.rim_nodes.push_back(edge.second);
    }
  std::sort(s.rim_nodes.begin(), s.rim_nodes.end());
  s.rim_nodes.erase(std::unique(s.rim_nodes.begin(), s.rim_nodes.end()), s.rim_nodes.end());
  return s;
}

double cavity_volume(const CavitySurface& s, const Eigen::Ref<const Positions>& x) {
  // Relative to a point near the surface, to keep round-off small far from the origin.
  const Vec3 o = x.col(s.faces.front()[0]);
  double six_v = 0;
  for (const Tri& t : s.faces) {  // reversed: cavity-outward
    const Vec3 a = x.col(t[0]) - o, b = x.col(t[1]) - o, c = x.col(t[2]) - o;
    six_v -= a.dot(b.cross(c));
  }
  if (!s.rim_nodes.empty()) {
    Vec3 centre = Vec3::Zero();
    for (int n : s.rim_nodes) centre += x.col(n);
    centre = centre / static_cast<double>(s.rim_nodes.size()) - o;
    for (const auto& [u, v] : s.rim_edges) six_v += centre.dot((x.col(u) - o).cross(x.col(v) - o));
  }
  return six_v / 6.0;
}

Positions cavity_volume_gradient(const CavitySurface& s, const Eigen::Ref<const Positions>& x) {
  // The closed surface's volume does not depend on the origin: take it near the surface.
  Positions g = Positions::Zero(3, x.cols());
  const Vec3 o = x.col(s.faces.front()[0]);
  for (const Tri& t : s.faces) {  // six V -= a . (b x c)
    const Vec3 a = x.col(t[0]) - o, b = x.col(t[1]) - o, c = x.col(t[2]) - o;
    g.col(t[0]) -= b.cross(c) / 6.0;
    g.col(t[1]) -= c.cross(a) / 6.0;
    g.col(t[2]) -= a.cross(b) / 6.0;
  }
  if (!s.rim_nodes.empty()) {  // six V += centre . (u x v), the centre the rim's mean
    Vec3 centre = Vec3::Zero();
    for (int n : s.rim_nodes) centre += x.col(n);
    centre = centre / static_cast<double>(s.rim_nodes.size()) - o;
    Vec3 d_centre = Vec3::Zero();
    for (const auto& [u, v] : s.rim_edges) {
      const Vec3 a = x.col(u) - o, b = x.col(v) - o;
      d_centre += a.cross(b) / 6.0;
      g.col(u) += b.cross(centre) / 6.0;
      g.col(v) += centre.cross(a) / 6.0;
    }
    for (int n : s.rim_nodes) g.col(n) += d_centre / static_cast<double>(s.rim_nodes.size());
  }
  return g;
}

int open_rim_nodes(const CavitySurface& surface, const std::vector<std::uint8_t>& fixed_dofs) {
  int open = 0;
  for (int n : surface.rim_nodes)
    for (int k = 0; k < 3; ++k)
      if (fixed_dofs.empty() || !fixed_dofs[static_cast<size_t>(3 * n + k)]) {
        ++open;
        break;
      }
  return open;
}

}  // namespace fiberfem::core
