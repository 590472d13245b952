#include "core/mesh_quality.hpp"

#include <cmath>
#include <limits>

namespace fiberfem::core {

// The dihedral angle at edge (p, q) is the angle between the other two vertices r, s seen
// along the edge: project r - p and s - p onto the plane normal to q - p and take the angle
// between the projections, atan2(|u x w|, u . w), which stays accurate near 0 and 180.
std::array<double, 6> dihedral_angles_deg(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3* v[4] = {&a, &b, &c, &d};
  static constexpr int kEdge[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                      {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
  constexpr double kDeg = 180.0 / 3.14159265358979323846;
  std::array<double, 6> angles{};
  for (int i = 0; i < 6; ++i) {
    const Vec3& p = *v[kEdge[i][0]];
    const Vec3 e = *v[kEdge[i][1]] - p;
    const double e2 = e.squaredNorm();
    Vec3 u = *v[kEdge[i][2]] - p, w = *v[kEdge[i][3]] - p;
    if (e2 > 0) {
      u -= (u.dot(e) / e2) * e;
      w -= (w.dot(e) / e2) * e;
    }
    angles[static_cast<size_t>(i)] = kDeg * std::atan2(u.cross(w).norm(), u.dot(w));
  }
  return angles;
}

// r = 3 V / (sum of face areas). With edge vectors p = b - a, q = c - a, s = d - a, the
// circumcentre relative to a solves 2 [p q s]^T x = (|p|^2, |q|^2, |s|^2), whose solution is
// x = (|p|^2 q x s + |q|^2 s x p + |s|^2 p x q) / (2 p . (q x s)), and R = |x|.
double radius_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 p = b - a, q = c - a, s = d - a;
  const double six_v = std::abs(p.dot(q.cross(s)));
  if (!(six_v > 0)) return 0.0;
  const double area2 = p.cross(q).norm() + q.cross(s).norm() + s.cross(p).norm() +
                       (c - b).cross(d - b).norm();  // twice the total face area
  const double r = six_v / area2;                    // 3 V / A = (6 V) / (2 A)
  const Vec3 x = p.squaredNorm() * q.cross(s) + q.squaredNorm() * s.cross(p) +
                 s.squaredNorm() * p.cross(q);
  const double R = x.norm() / (2.0 * six_v);
  return 3.0 * r / R;
}

MeshQuality mesh_quality(const TetMesh& mesh) {
  MeshQuality q;
  q.min_dihedral_deg = std::numeric_limits<double>::infinity();
  q.max_dihedral_deg = -std::numeric_limits<double>::infinity();
  q.min_radius_ratio = std::numeric_limits<double>::infinity();
  const Positions& x = mesh.rest_positions();
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const Tet& t = mesh.tets()[static_cast<size_t>(e)];
    const Vec3 a = x.col(t[0]), b = x.col(t[1]), c = x.col(t[2]), d = x.col(t[3]);
    for (double angle : dihedral_angles_deg(a, b, c, d)) {
      if (angle < q.min_dihedral_deg) {
        q.min_dihedral_deg = angle;
        q.worst_element = e;
      }
      if (angle > q.max_dihedral_deg) q.max_dihedral_deg = angle;
    }
    const double ratio = radius_ratio(a, b, c, d);
    if (ratio < q.min_radius_ratio) q.min_radius_ratio = ratio;
  }
  return q;
}

}  // namespace fiberfem::core
