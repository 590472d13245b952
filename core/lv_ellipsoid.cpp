#include "core/lv_ellipsoid.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::core {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMaxNodes = 2.0e8;  // same limit as make_box

std::string str(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// Nodes on ring k of K (k = 0 the apex): n_k = min(C, max(6 k, ceil(C k / K))). 6 k is the
// k-th hexagonal ring of an equilateral lattice around a point; ceil(C k / K) takes over
// only when C > 6 K, so that the base ring still has C nodes.
long long ring_size(int k, int K, int C) {
  if (k == 0) return 1;
  const long long hex = 6LL * k;
  const long long linear = (static_cast<long long>(C) * k + K - 1) / K;
  return std::min<long long>(C, std::max(hex, linear));
}

// In-plane (parameter disk) node count: 1 + sum over rings k = 1..K of n_k. Every n_k is
// at least C k / K, so the sum is at least C (K + 1) / 2; that bound refuses absurd specs
// before the loop runs.
double disk_nodes(int K, int C) {
  if (0.5 * C * (K + 1.0) > kMaxNodes) return 0.5 * C * (K + 1.0);
  double n = 1;
  for (int k = 1; k <= K; ++k) n += static_cast<double>(ring_size(k, K, C));
  return n;
}

// Meridian of the ellipsoid of revolution (rs, rl): arc length from the apex u = pi to the
// base u_base = acos(base_z / rl), ds = sqrt(rs^2 cos^2 u + rl^2 sin^2 u) du, tabulated by
// Simpson's rule on kIntervals equal steps in u and inverted by linear interpolation. Only
// the spacing of the rings depends on this accuracy; nodes lie exactly on the surface for
// any u.
class Meridian {
 public:
  static constexpr int kIntervals = 1024;

  Meridian(double rs, double rl, double base_z)
      : rs_(rs), rl_(rl), u_base_(std::acos(base_z / rl)), du_((kPi - u_base_) / kIntervals) {
    auto speed = [&](double u) { return std::hypot(rs_ * std::cos(u), rl_ * std::sin(u)); };
    arc_.resize(kIntervals + 1);
    arc_[0] = 0.0;
    for (int i = 0; i < kIntervals; ++i) {
      const double u0 = kPi - i * du_;
      arc_[static_cast<size_t>(i) + 1] =
          arc_[static_cast<size_t>(i)] +
          du_ / 6.0 * (speed(u0) + 4.0 * speed(u0 - 0.5 * du_) + speed(u0 - du_));
    }
  }

  /// u at the fraction s in [0, 1] of the apex-to-base arc.
  double u_at(double s) const {
    if (s <= 0.0) return kPi;
    if (s >= 1.0) return u_base_;
    const double target = s * arc_.back();
    const size_t i = static_cast<size_t>(std::upper_bound(arc_.begin(), arc_.end(), target) - arc_.begin()) - 1;
    const double f = (target - arc_[i]) / (arc_[i + 1] - arc_[i]);
    return kPi - (static_cast<double>(i) + f) * du_;
  }

 private:
  double rs_, rl_, u_base_, du_;
  std::vector<double> arc_;  // arc_[i]: arc length from the apex to u = pi - i du
};

// The triangulated parameter disk: ring k holds in-plane nodes first[k] .. first[k+1]-1.
struct Disk {
  std::vector<int> first;
  std::vector<double> angle;  // v of each in-plane node, radians
  std::vector<std::array<int, 3>> tris;
};

// Rings stitched by an angular sweep. Angles are unwrapped: inner node i at
// alpha_i = 2 pi (i + phase_a) / n_a, outer node j at beta_j = 2 pi (j + phase_b) / n_b,
// starting from the outer node nearest alpha_0 and going once around; each step adds the
// triangle whose new vertex has the smaller angle. Triangles are clockwise in the polar
// plane (s cos v, s sin v), i.e. counter-clockwise seen from outside the surface (the apex
// is seen from below, from z = -infinity).
Disk make_disk(int K, int C) {
  Disk d;
  std::vector<double> phase(static_cast<size_t>(K) + 1, 0.0);
  d.first.push_back(0);
  d.angle.push_back(0.0);
  for (int k = 1; k <= K; ++k) {
    const int n = static_cast<int>(ring_size(k, K, C));
    // Odd rings are shifted by half a step, so neighbours of equal size are staggered
    // (isosceles, not right, triangles between them).
    phase[static_cast<size_t>(k)] = (k % 2) * 0.5;
    d.first.push_back(static_cast<int>(d.angle.size()));
    for (int j = 0; j < n; ++j) d.angle.push_back(2.0 * kPi * (j + phase[static_cast<size_t>(k)]) / n);
  }
  d.first.push_back(static_cast<int>(d.angle.size()));
  auto size = [&](int k) { return d.first[static_cast<size_t>(k) + 1] - d.first[static_cast<size_t>(k)]; };
  // Apex fan.
  for (int j = 0, n = size(1); j < n; ++j)
    d.tris.push_back({0, d.first[1] + (j + 1) % n, d.first[1] + j});
  for (int k = 1; k < K; ++k) {
    const int na = size(k), nb = size(k + 1), a0 = d.first[static_cast<size_t>(k)],
              b0 = d.first[static_cast<size_t>(k) + 1];
    const double pa = phase[static_cast<size_t>(k)], pb = phase[static_cast<size_t>(k) + 1];
    auto alpha = [&](int i) { return 2.0 * kPi * (i + pa) / na; };
    auto beta = [&](int j) { return 2.0 * kPi * (j + pb) / nb; };
    auto A = [&](int i) { return a0 + ((i % na) + na) % na; };
    auto B = [&](int j) { return b0 + ((j % nb) + nb) % nb; };
    const int j0 = static_cast<int>(std::floor(alpha(0) * nb / (2.0 * kPi) - pb + 0.5));
    int i = 0, j = j0;
    while (i < na || j < j0 + nb) {
      const bool advance_inner = j == j0 + nb || (i < na && alpha(i + 1) <= beta(j + 1));
      if (advance_inner) {
        d.tris.push_back({A(i), A(i + 1), B(j)});
        ++i;
      } else {
        d.tris.push_back({A(i), B(j + 1), B(j)});
        ++j;
      }
    }
  }
  return d;
}

}  // namespace

void LvEllipsoidSpec::validate() const {
  const std::pair<const char*, double> radii[4] = {
      {"endo_rs_m", endo_rs_m}, {"endo_rl_m", endo_rl_m}, {"epi_rs_m", epi_rs_m}, {"epi_rl_m", epi_rl_m}};
  for (const auto& [name, r] : radii)
    if (!(std::isfinite(r) && r > 0))
      throw std::invalid_argument(std::string("lv_ellipsoid: ") + name + " must be > 0 and finite, got " + str(r));
  if (!(epi_rs_m > endo_rs_m))
    throw std::invalid_argument("lv_ellipsoid: epi_rs_m (" + str(epi_rs_m) + ") must be > endo_rs_m (" +
                                str(endo_rs_m) + "): the wall needs a positive thickness");
  if (!(epi_rl_m > endo_rl_m))
    throw std::invalid_argument("lv_ellipsoid: epi_rl_m (" + str(epi_rl_m) + ") must be > endo_rl_m (" +
                                str(endo_rl_m) + "): the wall needs a positive thickness");
  if (!(base_z_m > -endo_rl_m && base_z_m < endo_rl_m))
    throw std::invalid_argument("lv_ellipsoid: base_z_m must be in (-endo_rl_m, endo_rl_m) = (" + str(-endo_rl_m) +
                                ", " + str(endo_rl_m) + ") so the base cuts the cavity, got " + str(base_z_m));
  if (!(apex_grading >= 1.0 && apex_grading <= 3.0))
    throw std::invalid_argument("lv_ellipsoid: apex_grading must be in [1, 3], got " + str(apex_grading));
  const std::pair<const char*, int> resolution[3] = {
      {"circumferential", circumferential}, {"longitudinal", longitudinal}, {"transmural", transmural}};
  const int minimum[3] = {6, 2, 1};
  for (int i = 0; i < 3; ++i)
    if (resolution[i].second < minimum[i])
      throw std::invalid_argument(std::string("lv_ellipsoid: ") + resolution[i].first + " must be >= " +
                                  std::to_string(minimum[i]) + ", got " + std::to_string(resolution[i].second));
  const double n = disk_nodes(longitudinal - 1, circumferential) * (transmural + 1.0);
  if (n > kMaxNodes)
    throw std::invalid_argument("lv_ellipsoid: too many nodes (at least " + str(n) + ", limit " + str(kMaxNodes) +
                                "): reduce circumferential, longitudinal or transmural");
}

TetMesh make_lv_ellipsoid(const LvEllipsoidSpec& spec) {
  spec.validate();
  const int K = spec.longitudinal - 1, T = spec.transmural, L = T + 1;
  const Disk disk = make_disk(K, spec.circumferential);
  const int np = static_cast<int>(disk.angle.size());
  auto id = [L](int p, int t) { return p * L + t; };

  // Layer t of T lies on the ellipsoid with radii interpolated at t / T; ring k at the
  // fraction (k / K)^apex_grading of that ellipsoid's apex-to-base meridian. Apex and base
  // ring are set exactly: (0, 0, -rl) and z = base_z, radius rs sqrt(1 - (base_z / rl)^2).
  Positions x(3, np * L);
  for (int t = 0; t < L; ++t) {
    const double w = static_cast<double>(t) / T;
    const double rs = spec.endo_rs_m + w * (spec.epi_rs_m - spec.endo_rs_m);
    const double rl = spec.endo_rl_m + w * (spec.epi_rl_m - spec.endo_rl_m);
    const Meridian meridian(rs, rl, spec.base_z_m);
    x.col(id(0, t)) = Vec3(0.0, 0.0, -rl);
    for (int k = 1; k <= K; ++k) {
      double radius, z;
      if (k == K) {
        const double c = spec.base_z_m / rl;
        radius = rs * std::sqrt(1.0 - c * c);
        z = spec.base_z_m;
      } else {
        const double u = meridian.u_at(std::pow(static_cast<double>(k) / K, spec.apex_grading));
        radius = rs * std::sin(u);
        z = rl * std::cos(u);
      }
      for (int p = disk.first[static_cast<size_t>(k)]; p < disk.first[static_cast<size_t>(k) + 1]; ++p) {
        const double v = disk.angle[static_cast<size_t>(p)];
        x.col(id(p, t)) = Vec3(radius * std::cos(v), radius * std::sin(v), z);
      }
    }
  }

  // Prism (a, b, c) x (t, t + 1) -> three tetrahedra (Dompierre et al. 1999, "How to
  // subdivide pyramids, prisms and hexahedra into tetrahedra"). Each quad face is cut along
  // the diagonal through its lowest global id; both prisms sharing the face see the same
  // four ids, so the cut is conforming. With the triangle rotated so that a has the lowest
  // in-plane index, V0 = id(a, t) is the lowest id of the prism, both its quads are cut
  // from V0, and the tetrahedron V0 V3 V4 V5 leaves the pyramid V0 + quad (V1 V2 V5 V4),
  // cut along V1 V5 or V2 V4. With (a, b, c) counter-clockwise seen from outside and
  // t + 1 outside t, each of the five possible tetrahedra below is positively oriented
  // (check on the right prism V0..V2 = 0, e1, e2, V3..V5 = those + e3). So a tetrahedron
  // that is not is a fold of the geometry, not a numbering accident: refused, not flipped.
  std::vector<Tet> tets;
  tets.reserve(disk.tris.size() * static_cast<size_t>(T) * 3);
  auto push = [&](int a, int b, int c, int d) {
    if (!(signed_volume(x.col(a), x.col(b), x.col(c), x.col(d)) > 0))
      throw std::invalid_argument(
          "lv_ellipsoid: element " + std::to_string(tets.size()) + " would be inverted or flat: circumferential " +
          std::to_string(spec.circumferential) + ", longitudinal " + std::to_string(spec.longitudinal) +
          " and transmural " + std::to_string(spec.transmural) +
          " give elements far longer in one direction than another; bring the spacings closer");
    tets.push_back({a, b, c, d});
  };
  for (std::array<int, 3> tri : disk.tris) {
    std::rotate(tri.begin(), std::min_element(tri.begin(), tri.end()), tri.end());
    for (int t = 0; t < T; ++t) {
      const int v0 = id(tri[0], t), v1 = id(tri[1], t), v2 = id(tri[2], t);
      const int v3 = id(tri[0], t + 1), v4 = id(tri[1], t + 1), v5 = id(tri[2], t + 1);
      push(v0, v3, v4, v5);
      if (std::min(v1, v5) < std::min(v2, v4)) {
        push(v0, v1, v2, v5);
        push(v0, v1, v5, v4);
      } else {
        push(v0, v1, v2, v4);
        push(v0, v4, v2, v5);
      }
    }
  }

  TetMesh mesh(std::move(x), std::move(tets));
  std::vector<int> endo, epi, base;
  for (int p = 0; p < np; ++p) {
    endo.push_back(id(p, 0));
    epi.push_back(id(p, T));
  }
  for (int p = disk.first[static_cast<size_t>(K)]; p < np; ++p)
    for (int t = 0; t < L; ++t) base.push_back(id(p, t));
  mesh.set_node_set("endo", std::move(endo));
  mesh.set_node_set("epi", std::move(epi));
  mesh.set_node_set("base", std::move(base));
  mesh.set_node_set("apex_endo", {id(0, 0)});
  mesh.set_node_set("apex_epi", {id(0, T)});
  return mesh;
}

}  // namespace fiberfem::core
