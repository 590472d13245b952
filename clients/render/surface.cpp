#include "clients/render/surface.hpp"

#include "core/element.hpp"

#include <algorithm>
#include <cmath>

namespace fiberfem::render {
namespace {

// Twice the area times the unit normal of triangle (a, b, c): (b - a) x (c - a).
core::Vec3 area_normal(const Eigen::Ref<const core::Positions>& x, const core::Tri& t) {
  const core::Vec3 a = x.col(t[0]);
  return (x.col(t[1]) - a).cross(x.col(t[2]) - a);
}

}  // namespace

Surface::Surface(const core::TetMesh& mesh) : tris_(mesh.boundary_triangles()), elements_(mesh.boundary_triangle_elements()) {
  const core::Positions& X = mesh.rest_positions();
  // Distinct surface elements and their Dm^-1 (core::rest_shape_inverse, as the engine's caches).
  surface_elements_ = elements_;
  std::sort(surface_elements_.begin(), surface_elements_.end());
  surface_elements_.erase(std::unique(surface_elements_.begin(), surface_elements_.end()), surface_elements_.end());
  tri_surface_element_.resize(tris_.size());
  for (size_t t = 0; t < tris_.size(); ++t)
    tri_surface_element_[t] = static_cast<int>(std::lower_bound(surface_elements_.begin(), surface_elements_.end(), elements_[t]) -
                                               surface_elements_.begin());
  dm_inv_.reserve(surface_elements_.size());
  for (int e : surface_elements_) dm_inv_.push_back(core::rest_shape_inverse(core::gather(X, mesh.tets()[static_cast<size_t>(e)])));

  // Faces around each node (CSR), then the smoothing group of every corner.
  const int n = mesh.num_nodes();
  std::vector<int> start(static_cast<size_t>(n) + 1, 0), faces;
  for (const core::Tri& t : tris_)
    for (int v : t) ++start[static_cast<size_t>(v) + 1];
  for (int i = 0; i < n; ++i) start[static_cast<size_t>(i) + 1] += start[static_cast<size_t>(i)];
  faces.resize(static_cast<size_t>(start.back()));
  std::vector<int> fill(start.begin(), start.end() - 1);
  std::vector<core::Vec3> rest_normal(tris_.size());
  double edges = 0;
  for (size_t f = 0; f < tris_.size(); ++f) {
    for (int v : tris_[f]) faces[static_cast<size_t>(fill[static_cast<size_t>(v)]++)] = static_cast<int>(f);
    rest_normal[f] = area_normal(X, tris_[f]).normalized();
    for (int k = 0; k < 3; ++k) edges += (X.col(tris_[f][static_cast<size_t>(k)]) - X.col(tris_[f][static_cast<size_t>((k + 1) % 3)])).norm();
  }
  mean_edge_m_ = tris_.empty() ? 0 : edges / (3.0 * static_cast<double>(tris_.size()));
  const double cos_crease = std::cos(kCreaseDeg * 3.14159265358979323846 / 180);
  group_start_.assign(1, 0);
  group_start_.reserve(3 * tris_.size() + 1);
  for (size_t f = 0; f < tris_.size(); ++f)
    for (int v : tris_[f]) {
      for (int i = start[static_cast<size_t>(v)]; i < start[static_cast<size_t>(v) + 1]; ++i) {
        const int g = faces[static_cast<size_t>(i)];
        if (rest_normal[f].dot(rest_normal[static_cast<size_t>(g)]) >= cos_crease) group_faces_.push_back(g);
      }
      group_start_.push_back(static_cast<int>(group_faces_.size()));
    }
}

void Surface::corner_normals(const Eigen::Ref<const core::Positions>& x, Eigen::Matrix3Xf& out) const {
  face_normals_.resize(tris_.size());
  for (size_t f = 0; f < tris_.size(); ++f) face_normals_[f] = area_normal(x, tris_[f]);
  out.resize(3, static_cast<Eigen::Index>(3 * tris_.size()));
  for (size_t c = 0; c + 1 < group_start_.size(); ++c) {
    core::Vec3 s = core::Vec3::Zero();
    for (int i = group_start_[c]; i < group_start_[c + 1]; ++i) s += face_normals_[static_cast<size_t>(group_faces_[static_cast<size_t>(i)])];
    const double len = s.norm();
    const core::Vec3 n = len > 0 ? core::Vec3(s / len) : core::Vec3::UnitZ();
    out.col(static_cast<Eigen::Index>(c)) = n.cast<float>();
  }
}

core::Positions surface_points(const core::TetMesh& mesh) {
  const std::vector<int> nodes = mesh.boundary_nodes();
  core::Positions p(3, static_cast<Eigen::Index>(nodes.size()));
  for (size_t i = 0; i < nodes.size(); ++i) p.col(static_cast<Eigen::Index>(i)) = mesh.rest_positions().col(nodes[i]);
  return p;
}

}  // namespace fiberfem::render
