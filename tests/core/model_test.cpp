// The scene model (core/model.hpp): fixed-DOF masks, validation errors naming the field
// and index, lumped masses against rho V computed here, and external loads against
// closed-form totals (gravity m g, zero net force and torque of a pressure on a closed
// surface, traction times area, pressure work -3 p V).

#include "core/box_generator.hpp"
#include "core/model.hpp"
#include "test_support.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

namespace core = fiberfem::core;
using core::Vec3;
using fiberfem::testing::expect_invalid;

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

core::BoxSpec small_box() {
  core::BoxSpec s;
  s.size_m = Vec3(0.04, 0.02, 0.03);
  s.cells = {2, 1, 2};
  s.origin_m = Vec3(0.1, -0.2, 0.05);
  return s;
}

core::Model box_model(double rho = 1100.0) {
  core::Model m(core::make_box(small_box()));
  m.region_materials = {core::Material::isotropic(30e3, 0.4, rho)};
  return m;
}

// The box with its elements split into two regions by x (cells below / above mid-length).
core::Model two_region_model(double rho0, double rho1) {
  const core::TetMesh box = core::make_box(small_box());
  std::vector<int> regions(static_cast<size_t>(box.num_elements()));
  const double xmid = small_box().origin_m.x() + 0.5 * small_box().size_m.x();
  for (int e = 0; e < box.num_elements(); ++e) {
    double cx = 0;
    for (int v : box.tets()[static_cast<size_t>(e)]) cx += 0.25 * box.rest_positions()(0, v);
    regions[static_cast<size_t>(e)] = cx < xmid ? 0 : 1;
  }
  core::Model m(core::TetMesh(box.rest_positions(), box.tets(), regions));
  m.region_materials = {core::Material::isotropic(30e3, 0.4, rho0), core::Material::isotropic(30e3, 0.4, rho1)};
  return m;
}

double tet_volume(const core::Positions& x, const core::Tet& t) {
  return std::abs((x.col(t[1]) - x.col(t[0])).dot((x.col(t[2]) - x.col(t[0])).cross(x.col(t[3]) - x.col(t[0])))) / 6;
}

Vec3 total_force(const Eigen::VectorXd& f) {
  Vec3 s = Vec3::Zero();
  for (Eigen::Index i = 0; i < f.size() / 3; ++i) s += f.segment<3>(3 * i);
  return s;
}

Vec3 total_torque(const core::Positions& x, const Eigen::VectorXd& f) {
  Vec3 s = Vec3::Zero();
  for (Eigen::Index i = 0; i < f.size() / 3; ++i) s += x.col(i).cross(f.segment<3>(3 * i));
  return s;
}

// Boundary triangles whose three nodes are all in `set`.
std::vector<core::Tri> faces_on(const core::TetMesh& mesh, const std::vector<int>& set) {
  const std::set<int> s(set.begin(), set.end());
  std::vector<core::Tri> out;
  for (const core::Tri& t : mesh.boundary_triangles())
    if (s.count(t[0]) && s.count(t[1]) && s.count(t[2])) out.push_back(t);
  return out;
}

}  // namespace

TEST(Model, FixNodesSetsTheMaskedComponents) {
  core::Model m = box_model();
  const int n = m.mesh.num_nodes();
  m.fix_nodes({0, 3}, 0b101);  // x and z
  ASSERT_EQ(m.fixed_dofs.size(), static_cast<size_t>(3 * n));
  for (int d = 0; d < 3 * n; ++d) {
    const bool expected = d == 0 || d == 2 || d == 9 || d == 11;
    EXPECT_EQ(m.fixed_dofs[static_cast<size_t>(d)] != 0, expected) << "dof " << d;
  }
  m.fix_nodes({3});  // all three, accumulating
  EXPECT_EQ(m.fixed_dofs[10], 1);
  m.fix_nodes({5}, 0b010);
  int count = 0;
  for (auto f : m.fixed_dofs) count += f != 0;
  EXPECT_EQ(count, 6);  // 0x, 0z, 3xyz, 5y
  EXPECT_EQ(m.fixed_dofs[16], 1);
  expect_invalid([&] { m.fix_nodes({n}); }, {"fixed: node " + std::to_string(n), "out of range"});
  expect_invalid([&] { m.fix_nodes({-1}); }, {"fixed: node -1"});
  EXPECT_NO_THROW(m.validate());
}

TEST(Model, ValidateNormalisesFibersAndDefaultsToX) {
  core::Model m = box_model();
  m.validate();
  ASSERT_EQ(m.fibers.size(), static_cast<size_t>(m.mesh.num_elements()));
  for (const Vec3& f : m.fibers) EXPECT_EQ(f, Vec3::UnitX());
  m.set_uniform_fiber(Vec3(0, 3, 4));
  m.fibers[2] = Vec3(-1e-3, 0, 0);
  m.validate();
  EXPECT_LT((m.fibers[0] - Vec3(0, 0.6, 0.8)).norm(), 1e-15);
  EXPECT_LT((m.fibers[2] - Vec3(-1, 0, 0)).norm(), 1e-15);
}

TEST(Model, ValidateNamesTheOffendingFieldAndIndex) {
  {
    core::Model m = box_model();
    m.region_materials.clear();
    expect_invalid([&] { m.validate(); }, {"0 region materials for 1 regions"});
  }
  {
    core::Model m = two_region_model(1000, 1000);
    m.region_materials.pop_back();
    expect_invalid([&] { m.validate(); }, {"1 region materials for 2 regions"});
  }
  {
    core::Model m = two_region_model(1000, 1000);
    m.region_damping = {core::RayleighDamping{}};
    expect_invalid([&] { m.validate(); }, {"1 region dampings for 2 regions"});
    m.region_damping = {core::RayleighDamping{}, core::RayleighDamping{0.0, -0.1}};
    expect_invalid([&] { m.validate(); }, {"region 1", "stiffness (beta, s) must be >= 0"});
    m.region_damping = {core::RayleighDamping{kNan, 0.0}, core::RayleighDamping{}};
    expect_invalid([&] { m.validate(); }, {"region 0", "mass (alpha, 1/s) must be >= 0"});
    m.region_damping = {core::RayleighDamping{2.0, 0.01}, core::RayleighDamping{}};
    EXPECT_NO_THROW(m.validate());
  }
  {
    core::Model m = box_model();
    m.fibers.assign(3, Vec3::UnitZ());
    expect_invalid([&] { m.validate(); }, {"fibers: 3 vectors for " + std::to_string(m.mesh.num_elements()) + " elements"});
    m.set_uniform_fiber(Vec3::UnitZ());
    m.fibers[5] = Vec3::Zero();
    expect_invalid([&] { m.validate(); }, {"fibers: element 5", "zero or non-finite"});
    m.fibers[5] = Vec3(1, kNan, 0);
    expect_invalid([&] { m.validate(); }, {"fibers: element 5"});
    m.fibers[5] = Vec3(1e-13, 0, 0);
    expect_invalid([&] { m.validate(); }, {"fibers: element 5"});
  }
  {
    core::Model m = box_model();
    m.fixed_dofs.assign(7, 0);
    expect_invalid([&] { m.validate(); },
                   {"fixed: mask has 7 entries for " + std::to_string(3 * m.mesh.num_nodes()) + " DOFs"});
  }
  {
    core::Model m = box_model();
    m.loads.gravity_m_s2 = Vec3(0, 0, kNan);
    expect_invalid([&] { m.validate(); }, {"gravity must be finite"});
    m.loads.gravity_m_s2 = Vec3(0, std::numeric_limits<double>::infinity(), 0);
    expect_invalid([&] { m.validate(); }, {"gravity must be finite"});
  }
  {
    core::Model m = box_model();
    const int n = m.mesh.num_nodes();
    m.loads.point_forces = {{0, Vec3(1, 0, 0)}, {n, Vec3(0, 1, 0)}};
    expect_invalid([&] { m.validate(); }, {"point force 1 node " + std::to_string(n) + " out of range"});
    m.loads.point_forces = {{0, Vec3(1, 0, 0)}, {1, Vec3(0, 1, 0)}, {-2, Vec3::Zero()}};
    expect_invalid([&] { m.validate(); }, {"point force 2 node -2"});
    m.loads.point_forces = {{0, Vec3(kNan, 0, 0)}};
    expect_invalid([&] { m.validate(); }, {"point force 0 is not finite"});
  }
  {
    core::Model m = box_model();
    core::SurfaceLoad s;
    s.faces = {m.mesh.boundary_triangles()[0]};
    s.pressure_pa = kNan;
    m.loads.surface_loads = {core::SurfaceLoad{}, s};
    expect_invalid([&] { m.validate(); }, {"surface load 1 is not finite"});
    s.pressure_pa = 10;
    s.force_per_area_pa = Vec3(0, kNan, 0);
    m.loads.surface_loads = {s};
    expect_invalid([&] { m.validate(); }, {"surface load 0 is not finite"});
    s.force_per_area_pa = Vec3::Zero();
    s.faces.push_back({0, 1, m.mesh.num_nodes()});
    m.loads.surface_loads = {s};
    expect_invalid([&] { m.validate(); }, {"surface load 0 node out of range"});
  }
}

TEST(RayleighDamping, ValidateAndIsZero) {
  EXPECT_TRUE(core::RayleighDamping{}.is_zero());
  EXPECT_FALSE((core::RayleighDamping{0.1, 0.0}.is_zero()));
  EXPECT_FALSE((core::RayleighDamping{0.0, 0.1}.is_zero()));
  expect_invalid([] { core::RayleighDamping{-1.0, 0.0}.validate(); }, {"mass (alpha, 1/s)"});
  expect_invalid([] { core::RayleighDamping{0.0, std::numeric_limits<double>::infinity()}.validate(); },
                 {"stiffness (beta, s)"});
}

// Each node gets a quarter of rho V of every element around it; the total is rho V.
TEST(Model, LumpedMassesAreAQuarterOfEachElementMass) {
  const double rho0 = 900, rho1 = 2500;
  core::Model m = two_region_model(rho0, rho1);
  const Eigen::VectorXd mass = m.lumped_node_masses();
  Eigen::VectorXd expected = Eigen::VectorXd::Zero(m.mesh.num_nodes());
  double total = 0;
  for (int e = 0; e < m.mesh.num_elements(); ++e) {
    const core::Tet& t = m.mesh.tets()[static_cast<size_t>(e)];
    const double me = (m.mesh.regions()[static_cast<size_t>(e)] == 0 ? rho0 : rho1) * tet_volume(m.mesh.rest_positions(), t);
    total += me;
    for (int v : t) expected(v) += me / 4;
  }
  EXPECT_LT((mass - expected).norm(), 1e-14 * expected.norm());
  // Half the box volume each: total mass (rho0 + rho1) V / 2.
  const double V = small_box().size_m.prod();
  EXPECT_NEAR(mass.sum(), 0.5 * (rho0 + rho1) * V, 1e-12 * total);
  EXPECT_NEAR(total, 0.5 * (rho0 + rho1) * V, 1e-12 * total);
  EXPECT_GT(mass.minCoeff(), 0);
}

TEST(Model, GravityTotalIsMassTimesG) {
  const double rho = 1100;
  core::Model m = box_model(rho);
  m.loads.gravity_m_s2 = Vec3(1.0, -2.0, -9.81);
  m.validate();
  const Eigen::VectorXd f = m.external_forces();
  const double total_mass = rho * small_box().size_m.prod();
  EXPECT_LT((total_force(f) - total_mass * m.loads.gravity_m_s2).norm(), 1e-12 * total_mass * 10);
  // Node by node: m_i g.
  const Eigen::VectorXd mass = m.lumped_node_masses();
  for (int i = 0; i < m.mesh.num_nodes(); ++i)
    EXPECT_LT((f.segment<3>(3 * i) - mass(i) * m.loads.gravity_m_s2).norm(), 1e-15);
  // No loads, no force.
  core::Model none = box_model(rho);
  none.validate();
  EXPECT_EQ(none.external_forces().norm(), 0.0);
}

TEST(Model, PointForcesAddUp) {
  core::Model m = box_model();
  m.loads.point_forces = {{4, Vec3(1, 2, 3)}, {4, Vec3(-0.5, 0, 1)}, {7, Vec3(0, 0, -2)}};
  m.validate();
  const Eigen::VectorXd f = m.external_forces();
  EXPECT_EQ(Vec3(f.segment<3>(12)), Vec3(0.5, 2, 4));
  EXPECT_EQ(Vec3(f.segment<3>(21)), Vec3(0, 0, -2));
  EXPECT_DOUBLE_EQ(f.norm(), std::sqrt(0.25 + 4 + 16 + 4));
}

// One right triangle of area 1 in the z = 0 plane, counter-clockwise seen from +z.
TEST(SurfaceLoad, SingleTriangleByHand) {
  core::Positions x(3, 3);
  x << 0, 2, 0,  //
      0, 0, 1,   //
      0, 0, 0;
  core::SurfaceLoad s;
  s.faces = {{0, 1, 2}};
  s.pressure_pa = 6.0;
  Eigen::VectorXd f = Eigen::VectorXd::Zero(9);
  core::add_surface_load(x, s, f);
  for (int i = 0; i < 3; ++i) EXPECT_LT((f.segment<3>(3 * i) - Vec3(0, 0, -2)).norm(), 1e-15) << "node " << i;
  s.pressure_pa = 0;
  s.force_per_area_pa = Vec3(3, -6, 9);
  core::add_surface_load(x, s, f);  // accumulates
  for (int i = 0; i < 3; ++i) EXPECT_LT((f.segment<3>(3 * i) - Vec3(1, -2, 1)).norm(), 1e-15) << "node " << i;
}

// A uniform pressure on a closed surface: zero net force and torque (the integrals of n and
// x x n over a closed surface vanish), and its virtual work on the displacement u = x is
// -p times the integral of x . n, i.e. -3 p V.
TEST(SurfaceLoad, PressureOnAClosedSurface) {
  core::Model m = box_model();
  core::SurfaceLoad s;
  s.faces = m.mesh.boundary_triangles();
  s.pressure_pa = 250.0;
  m.loads.surface_loads = {s};
  m.validate();
  const Eigen::VectorXd f = m.external_forces();
  const double p = s.pressure_pa, V = small_box().size_m.prod();
  const core::Positions& x = m.mesh.rest_positions();
  const double scale = p * 2 * 0.04 * 0.03;  // pressure times a face area
  EXPECT_LT(total_force(f).norm(), 1e-12 * scale);
  EXPECT_LT(total_torque(x, f).norm(), 1e-12 * scale * 0.1);
  const Eigen::Map<const Eigen::VectorXd> xv(x.data(), x.size());
  EXPECT_NEAR(f.dot(xv), -3 * p * V, 1e-12 * p * V);
}

// A uniform traction t on the x = max face (area A = size_y size_z) totals t A; a pressure
// on it pushes along -x with p A.
TEST(SurfaceLoad, UniformTractionOnAFace) {
  core::Model m = box_model();
  const std::vector<core::Tri> face = faces_on(m.mesh, m.mesh.node_set("xmax"));
  ASSERT_EQ(face.size(), 2u * 1 * 2);  // 1 x 2 cells on that face, two triangles each
  const double A = small_box().size_m.y() * small_box().size_m.z();
  core::SurfaceLoad s;
  s.faces = face;
  s.force_per_area_pa = Vec3(10, -20, 5);
  m.loads.surface_loads = {s};
  m.validate();
  Eigen::VectorXd f = m.external_forces();
  EXPECT_LT((total_force(f) - A * s.force_per_area_pa).norm(), 1e-14);
  // Only the face's nodes are loaded.
  const std::vector<int>& xmax = m.mesh.node_set("xmax");
  for (int i = 0; i < m.mesh.num_nodes(); ++i)
    if (!std::binary_search(xmax.begin(), xmax.end(), i)) {
      EXPECT_EQ(f.segment<3>(3 * i).norm(), 0.0) << "node " << i;
    }
  s.force_per_area_pa = Vec3::Zero();
  s.pressure_pa = 400;
  m.loads.surface_loads = {s};
  f = m.external_forces();
  EXPECT_LT((total_force(f) - Vec3(-400 * A, 0, 0)).norm(), 1e-14);
}
