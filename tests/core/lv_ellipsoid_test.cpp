// Truncated ellipsoidal shell (core/lv_ellipsoid.hpp): volumes against the analytic shell,
// nodes on their surfaces, a conforming closed boundary made of endo, epi and base faces,
// element quality over a sweep of resolutions (printed as a table), bad specs.

#include "core/lv_ellipsoid.hpp"
#include "core/mesh_quality.hpp"
#include "test_support.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <vector>

namespace core = fiberfem::core;
using core::Vec3;
using fiberfem::testing::expect_invalid;

namespace {


using fiberfem::testing::lv_spec;
constexpr auto spec_of = lv_spec;
constexpr auto cap_volume = fiberfem::testing::truncated_ellipsoid_volume;

// x^2/rs^2 + y^2/rs^2 + z^2/rl^2: 1 on the ellipsoid.
double ellipsoid(const Vec3& p, double rs, double rl) {
  return (p.x() * p.x() + p.y() * p.y()) / (rs * rs) + p.z() * p.z() / (rl * rl);
}

bool in(const std::vector<int>& sorted, int i) { return std::binary_search(sorted.begin(), sorted.end(), i); }

// Volume enclosed by the faceted surface `set` (endo or epi) closed by the base plane z = b,
// by the divergence theorem with F = (0, 0, z - b), which has no flux through the base:
// V = sum over facets of (z_centroid - b) n_z A (exact for flat facets). The boundary
// triangles' outward normals point away from the wall, i.e. out of the epicardial solid
// and into the cavity, hence the absolute value.
double enclosed_volume(const core::TetMesh& m, const std::vector<int>& set, double b) {
  double v = 0;
  const auto& x = m.rest_positions();
  for (const core::Tri& t : m.boundary_triangles()) {
    if (!(in(set, t[0]) && in(set, t[1]) && in(set, t[2]))) continue;
    const Vec3 a = x.col(t[0]), p = x.col(t[1]), q = x.col(t[2]);
    const Vec3 n_area = 0.5 * (p - a).cross(q - a);
    v += ((a.z() + p.z() + q.z()) / 3 - b) * n_area.z();
  }
  return std::abs(v);
}

}  // namespace

// The faceted surfaces are inscribed in the convex truncated ellipsoids, so they enclose
// less than the analytic volumes, by O(h^2): halving the spacing (circumferential nodes
// doubled, longitudinal - 1 doubled) must shrink each error by about 4. The wall's volume
// is the difference of the two enclosed volumes (the interior layers do not change it).
TEST(MakeLvEllipsoid, VolumesConvergeToTheAnalyticShell) {
  const core::LvEllipsoidSpec d;
  const double cavity = cap_volume(d.endo_rs_m, d.endo_rl_m, d.base_z_m);
  const double solid = cap_volume(d.epi_rs_m, d.epi_rl_m, d.base_z_m);
  const double wall = solid - cavity;
  double last_cavity_error = 1, last_solid_error = 1, last_wall_error = 1;
  std::printf("%-14s %12s %12s %12s\n", "resolution", "cavity err", "epi err", "wall err");
  for (const auto& [c, l] : {std::pair{12, 4}, {24, 7}, {48, 13}, {96, 25}}) {
    const core::TetMesh m = core::make_lv_ellipsoid(spec_of(c, l, 2));
    const double v_cavity = enclosed_volume(m, m.node_set("endo"), d.base_z_m);
    const double v_solid = enclosed_volume(m, m.node_set("epi"), d.base_z_m);
    EXPECT_NEAR(m.total_volume(), v_solid - v_cavity, 1e-12 * wall) << c << "," << l;
    const double cavity_error = (cavity - v_cavity) / cavity, solid_error = (solid - v_solid) / solid,
                 wall_error = std::abs(m.total_volume() - wall) / wall;
    std::printf("(%3d,%3d,%2d)   %12.3e %12.3e %12.3e\n", c, l, 2, cavity_error, solid_error, wall_error);
    EXPECT_GT(cavity_error, 0) << c << "," << l;
    EXPECT_GT(solid_error, 0) << c << "," << l;
    EXPECT_LT(cavity_error, last_cavity_error / 3) << c << "," << l;
    EXPECT_LT(solid_error, last_solid_error / 3) << c << "," << l;
    EXPECT_LT(wall_error, last_wall_error / 3) << c << "," << l;
    if (c >= 48) {
      EXPECT_LT(wall_error, 0.01) << c << "," << l;
    }
    last_cavity_error = cavity_error;
    last_solid_error = solid_error;
    last_wall_error = wall_error;
  }
}

// Endo nodes lie on the inner ellipsoid, epi nodes on the outer, base nodes exactly on the
// base plane, apex nodes at (0, 0, -rl); each set holds exactly the nodes that satisfy its
// condition, and the node count is what the ring sizes predict.
TEST(MakeLvEllipsoid, NodeSetsLieOnTheirSurfaces) {
  core::LvEllipsoidSpec other = spec_of(30, 8, 2);
  other.base_z_m = -0.004;  // below the equator
  for (const core::LvEllipsoidSpec& s : {core::LvEllipsoidSpec{}, spec_of(12, 4, 1), spec_of(48, 20, 4), other}) {
    SCOPED_TRACE(testing::Message() << "resolution " << s.circumferential << "," << s.longitudinal << ","
                                    << s.transmural << " base " << s.base_z_m);
    const core::TetMesh m = core::make_lv_ellipsoid(s);
    EXPECT_EQ(m.node_sets().size(), 5u);
    EXPECT_TRUE(m.reoriented_elements().empty());
    EXPECT_EQ(m.num_regions(), 1);
    const auto& x = m.rest_positions();
    std::vector<int> endo, epi, base;
    for (int i = 0; i < m.num_nodes(); ++i) {
      if (std::abs(ellipsoid(x.col(i), s.endo_rs_m, s.endo_rl_m) - 1) < 1e-12) endo.push_back(i);
      if (std::abs(ellipsoid(x.col(i), s.epi_rs_m, s.epi_rl_m) - 1) < 1e-12) epi.push_back(i);
      if (x(2, i) == s.base_z_m) base.push_back(i);
    }
    EXPECT_EQ(m.node_set("endo"), endo);
    EXPECT_EQ(m.node_set("epi"), epi);
    EXPECT_EQ(m.node_set("base"), base);
    // Ring sizes min(C, max(6k, ceil(C k / K))), k = 1..K, plus the apex, on every layer;
    // the base ring has C nodes on every layer.
    const int K = s.longitudinal - 1, C = s.circumferential;
    int per_layer = 1;
    for (int k = 1; k <= K; ++k) per_layer += std::min(C, std::max(6 * k, (C * k + K - 1) / K));
    EXPECT_EQ(m.num_nodes(), per_layer * (s.transmural + 1));
    EXPECT_EQ(endo.size(), static_cast<size_t>(per_layer));
    EXPECT_EQ(epi.size(), static_cast<size_t>(per_layer));
    EXPECT_EQ(base.size(), static_cast<size_t>(C * (s.transmural + 1)));
    ASSERT_EQ(m.node_set("apex_endo").size(), 1u);
    ASSERT_EQ(m.node_set("apex_epi").size(), 1u);
    EXPECT_EQ(Vec3(x.col(m.node_set("apex_endo")[0])), Vec3(0, 0, -s.endo_rl_m));
    EXPECT_EQ(Vec3(x.col(m.node_set("apex_epi")[0])), Vec3(0, 0, -s.epi_rl_m));
    const auto [lo, hi] = m.bounding_box();
    EXPECT_EQ(hi.z(), s.base_z_m);
    EXPECT_EQ(lo.z(), -s.epi_rl_m);
  }
}

// Conforming and closed: counting every element face (a sorted node triple) here, each is
// used once or twice; the once-used faces are exactly TetMesh's boundary, and each has all
// three nodes in endo, epi or base, with the outward normal into the cavity (endo), out of
// the outer ellipsoid (epi) or along +z (base). The boundary is a closed surface of genus 0:
// V - E + F = 2. Counts: the parameter disk has P nodes and C boundary edges, so by Euler
// (P - E + F = 1, 3F = 2E - C) it has F = 2P - C - 2 triangles; endo and epi have F each,
// the base 2 C T (C quads per layer), and there are 3 F T tetrahedra.
TEST(MakeLvEllipsoid, ConformingClosedBoundaryOfEndoEpiAndBase) {
  for (const core::LvEllipsoidSpec& s : {core::LvEllipsoidSpec{}, spec_of(12, 4, 1), spec_of(6, 2, 1),
                                         spec_of(40, 3, 2), spec_of(48, 20, 4)}) {
    const int C = s.circumferential, T = s.transmural;
    SCOPED_TRACE(testing::Message() << "resolution " << C << "," << s.longitudinal << "," << T);
    const core::TetMesh m = core::make_lv_ellipsoid(s);
    const int P = m.num_nodes() / (T + 1);
    const int F = 2 * P - C - 2;
    EXPECT_EQ(m.num_elements(), 3 * F * T);
    const std::map<std::array<int, 3>, int> uses = fiberfem::testing::face_uses(m.tets());
    std::set<std::array<int, 3>> once;
    for (const auto& [f, n] : uses) {
      EXPECT_TRUE(n == 1 || n == 2) << "face used " << n << " times";
      if (n == 1) once.insert(f);
    }
    std::set<std::array<int, 3>> boundary;
    for (core::Tri t : m.boundary_triangles()) {
      std::sort(t.begin(), t.end());
      boundary.insert(t);
    }
    EXPECT_EQ(boundary, once);

    const auto& endo = m.node_set("endo");
    const auto& epi = m.node_set("epi");
    const auto& base = m.node_set("base");
    const auto& x = m.rest_positions();
    int n_endo = 0, n_epi = 0, n_base = 0;
    std::set<std::pair<int, int>> edges;
    std::set<int> vertices;
    for (const core::Tri& t : m.boundary_triangles()) {
      auto all_in = [&](const std::vector<int>& set) { return in(set, t[0]) && in(set, t[1]) && in(set, t[2]); };
      const Vec3 a = x.col(t[0]), b = x.col(t[1]), c = x.col(t[2]);
      const Vec3 n = (b - a).cross(c - a).normalized();
      const Vec3 centroid = (a + b + c) / 3;
      // Outward normal of the ellipsoid (rs, rl) at the centroid's direction.
      auto grad = [&](double rs, double rl) { return Vec3(centroid.x() / (rs * rs), centroid.y() / (rs * rs), centroid.z() / (rl * rl)); };
      if (all_in(endo)) {
        ++n_endo;
        EXPECT_LT(n.dot(grad(s.endo_rs_m, s.endo_rl_m)), 0) << "endo face into the cavity";
      } else if (all_in(epi)) {
        ++n_epi;
        EXPECT_GT(n.dot(grad(s.epi_rs_m, s.epi_rl_m)), 0) << "epi face outwards";
      } else if (all_in(base)) {
        ++n_base;
        EXPECT_NEAR(n.z(), 1, 1e-12) << "base face upwards";
      } else {
        ADD_FAILURE() << "boundary face (" << t[0] << ", " << t[1] << ", " << t[2] << ") is in no surface set";
      }
      for (int i = 0; i < 3; ++i) {
        vertices.insert(t[static_cast<size_t>(i)]);
        const int p = t[static_cast<size_t>(i)], q = t[static_cast<size_t>((i + 1) % 3)];
        edges.insert({std::min(p, q), std::max(p, q)});
      }
    }
    EXPECT_EQ(n_endo, F);
    EXPECT_EQ(n_epi, F);
    EXPECT_EQ(n_base, 2 * C * T);
    const long euler = static_cast<long>(vertices.size()) - static_cast<long>(edges.size()) +
                       static_cast<long>(m.boundary_triangles().size());
    EXPECT_EQ(euler, 2);
    // Every node of the wall's boundary belongs to a surface set and vice versa.
    std::vector<int> surface;
    std::set_union(endo.begin(), endo.end(), epi.begin(), epi.end(), std::back_inserter(surface));
    std::vector<int> all;
    std::set_union(surface.begin(), surface.end(), base.begin(), base.end(), std::back_inserter(all));
    EXPECT_EQ(m.boundary_nodes(), all);
  }
}

// Node p of the parameter disk on layer t has id p (T + 1) + t, and a tetrahedron spans
// two neighbouring rings (at most 2 C in-plane nodes apart) and two neighbouring layers.
TEST(MakeLvEllipsoid, NumberingKeepsTheBandwidthSmall) {
  for (const core::LvEllipsoidSpec& s : {core::LvEllipsoidSpec{}, spec_of(48, 20, 4), spec_of(96, 40, 6)}) {
    const core::TetMesh m = core::make_lv_ellipsoid(s);
    int bandwidth = 0;
    for (const core::Tet& t : m.tets())
      for (int a : t)
        for (int b : t) bandwidth = std::max(bandwidth, std::abs(a - b));
    EXPECT_LE(bandwidth, 2 * s.circumferential * (s.transmural + 1) + s.transmural) << s.circumferential;
  }
}

// No collapsed apex, no slivers: the smallest dihedral angle stays above 15 degrees from
// the coarsest to a fine resolution. The bound is the one the header documents for prisms
// of aspect A = meridional spacing / layer thickness in [0.7, 3.3] and B = base
// circumferential spacing / meridional spacing in [0.5, 1.5]; these resolutions have
// A = 3.3, 3.3, 2.1, 1.5 and B = 0.5, 0.8, 0.8, 0.9. Every mesh contains the apex, so its
// elements are covered. (6, 2, 1), a six-sided pyramid with one element through the wall
// (A = 9.7), is printed for comparison: valid, but flat.
TEST(MakeLvEllipsoid, QualityIsBoundedAtEveryResolution) {
  std::printf("%-14s %8s %8s %9s %9s %9s %8s\n", "resolution", "nodes", "tets", "min dih", "max dih",
              "min 3r/R", "build s");
  auto row = [](const core::LvEllipsoidSpec& s) {
    const auto t0 = std::chrono::steady_clock::now();
    const core::TetMesh m = core::make_lv_ellipsoid(s);
    const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const core::MeshQuality q = core::mesh_quality(m);
    std::printf("(%3d,%3d,%2d)   %8d %8d %9.2f %9.2f %9.3f %8.3f\n", s.circumferential, s.longitudinal,
                s.transmural, m.num_nodes(), m.num_elements(), q.min_dihedral_deg, q.max_dihedral_deg,
                q.min_radius_ratio, build_s);
    return q;
  };
  for (const core::LvEllipsoidSpec& s : {spec_of(12, 4, 1), core::LvEllipsoidSpec{}, spec_of(48, 20, 4),
                                         spec_of(96, 40, 6)}) {
    const core::MeshQuality q = row(s);
    SCOPED_TRACE(testing::Message() << s.circumferential << "," << s.longitudinal << "," << s.transmural);
    EXPECT_GE(q.min_dihedral_deg, 15.0);
    EXPECT_LE(q.max_dihedral_deg, 135.0);
    EXPECT_GE(q.min_radius_ratio, 0.35);
  }
  const core::MeshQuality coarse = row(spec_of(6, 2, 1));
  EXPECT_GT(coarse.min_dihedral_deg, 0.0);
}

// A resolution so anisotropic that the geometry folds (6 nodes around, 200 rings: the
// chord between two ring nodes cuts deeper into the wall than the rings are apart) is
// refused, not returned with flipped elements.
TEST(MakeLvEllipsoid, FoldedResolutionsAreRefused) {
  expect_invalid([] { core::make_lv_ellipsoid(spec_of(6, 200, 4)); },
                 {"inverted or flat", "circumferential 6", "longitudinal 200"});
  expect_invalid([] { core::make_lv_ellipsoid(spec_of(12, 200, 1)); }, {"inverted or flat"});
}

// apex_grading p puts ring k of K at the fraction (k / K)^p of each surface's apex-to-base
// meridian. Checked on the endocardium against the arc length integrated here (midpoint
// rule, 200,000 steps in u) from each ring's z; p = 1 spaces the rings evenly; nothing is
// inverted and the wall's volume is the analytic shell's less the facets' shortfall.
TEST(MakeLvEllipsoid, ApexGradingSpacesTheRingsAsAPowerOfTheArc) {
  const core::LvEllipsoidSpec defaults;
  const double rs = defaults.endo_rs_m, rl = defaults.endo_rl_m, b = defaults.base_z_m;
  auto arc_to = [&](double u_end) {  // meridian arc from the apex u = pi down to u_end
    const int n = 200000;
    const double du = (std::acos(-1.0) - u_end) / n;
    double s = 0;
    for (int i = 0; i < n; ++i) {
      const double u = std::acos(-1.0) - (i + 0.5) * du;
      s += std::hypot(rs * std::cos(u), rl * std::sin(u)) * du;
    }
    return s;
  };
  const double total = arc_to(std::acos(b / rl));
  for (double p : {1.0, 1.5, 2.5}) {
    core::LvEllipsoidSpec s = spec_of(24, 10, 2);
    s.apex_grading = p;
    const core::TetMesh m = core::make_lv_ellipsoid(s);
    EXPECT_TRUE(m.reoriented_elements().empty());
    std::set<double> ring_z;  // the endocardial rings' heights, apex to base
    for (int i : m.node_set("endo")) ring_z.insert(m.rest_positions()(2, i));
    ASSERT_EQ(ring_z.size(), 10u) << "p = " << p;
    int k = 0;
    for (double z : ring_z) {
      const double expected = std::pow(k / 9.0, p);
      EXPECT_NEAR(arc_to(std::acos(std::clamp(z / rl, -1.0, 1.0))) / total, expected, 2e-5) << "p = " << p << ", ring " << k;
      ++k;
    }
    double wall = 0;
    for (int e = 0; e < m.num_elements(); ++e) wall += m.rest_volume(e);
    const double exact = cap_volume(defaults.epi_rs_m, defaults.epi_rl_m, b) - cap_volume(rs, rl, b);
    EXPECT_LT(wall, exact) << "p = " << p;  // inscribed, short by the facets' O(h^2) (3% at p = 2.5)
    EXPECT_GT(wall / exact, 0.96) << "p = " << p;
  }
}

TEST(LvEllipsoidSpec, DefaultsAreTheLand2015Benchmark) {
  const core::LvEllipsoidSpec s;
  EXPECT_EQ(s.endo_rs_m, 0.007);
  EXPECT_EQ(s.endo_rl_m, 0.017);
  EXPECT_EQ(s.epi_rs_m, 0.010);
  EXPECT_EQ(s.epi_rl_m, 0.020);
  EXPECT_EQ(s.base_z_m, 0.005);
  EXPECT_EQ(s.circumferential, 24);
  EXPECT_EQ(s.longitudinal, 10);
  EXPECT_EQ(s.transmural, 3);
  EXPECT_EQ(s.apex_grading, 1.0);
  EXPECT_NO_THROW(s.validate());
}

TEST(LvEllipsoidSpec, ValidateNamesTheField) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  auto with = [](auto change) {
    core::LvEllipsoidSpec s;
    change(s);
    return s;
  };
  expect_invalid([&] { with([](auto& s) { s.endo_rs_m = 0; }).validate(); }, {"endo_rs_m", "> 0"});
  expect_invalid([&] { with([](auto& s) { s.endo_rl_m = -0.01; }).validate(); }, {"endo_rl_m", "> 0"});
  expect_invalid([&] { with([&](auto& s) { s.epi_rs_m = nan; }).validate(); }, {"epi_rs_m", "finite"});
  expect_invalid([&] { with([&](auto& s) { s.epi_rl_m = inf; }).validate(); }, {"epi_rl_m", "finite"});
  expect_invalid([&] { with([](auto& s) { s.epi_rs_m = 0.007; }).validate(); }, {"epi_rs_m", "endo_rs_m"});
  expect_invalid([&] { with([](auto& s) { s.epi_rl_m = 0.016; }).validate(); }, {"epi_rl_m", "endo_rl_m"});
  expect_invalid([&] { with([](auto& s) { s.base_z_m = 0.017; }).validate(); }, {"base_z_m"});
  expect_invalid([&] { with([](auto& s) { s.base_z_m = -0.017; }).validate(); }, {"base_z_m"});
  expect_invalid([&] { with([](auto& s) { s.base_z_m = 0.018; }).validate(); }, {"base_z_m"});
  expect_invalid([&] { with([&](auto& s) { s.base_z_m = nan; }).validate(); }, {"base_z_m"});
  expect_invalid([&] { with([](auto& s) { s.circumferential = 5; }).validate(); }, {"circumferential", ">= 6", "got 5"});
  expect_invalid([&] { with([](auto& s) { s.longitudinal = 1; }).validate(); }, {"longitudinal", ">= 2"});
  expect_invalid([&] { with([](auto& s) { s.transmural = 0; }).validate(); }, {"transmural", ">= 1"});
  expect_invalid([&] { with([](auto& s) { s.transmural = -2; }).validate(); }, {"transmural", "got -2"});
  expect_invalid([&] { with([](auto& s) { s.apex_grading = 0.5; }).validate(); }, {"apex_grading", "[1, 3]", "0.5"});
  expect_invalid([&] { with([&](auto& s) { s.apex_grading = nan; }).validate(); }, {"apex_grading"});
  expect_invalid([&] { with([](auto& s) { s.apex_grading = 4; }).validate(); }, {"apex_grading", "got 4"});
  expect_invalid([&] {
    with([](auto& s) {
      s.circumferential = 100000;
      s.longitudinal = 10000;
    }).validate();
  }, {"too many nodes"});
  expect_invalid([&] {
    with([](auto& s) {
      s.circumferential = std::numeric_limits<int>::max();
      s.longitudinal = std::numeric_limits<int>::max();
      s.transmural = std::numeric_limits<int>::max();
    }).validate();
  }, {"too many nodes"});
  // make_lv_ellipsoid validates too.
  expect_invalid([&] { core::make_lv_ellipsoid(with([](auto& s) { s.longitudinal = 0; })); }, {"longitudinal"});
}
