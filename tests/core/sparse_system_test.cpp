// The sparse assembly (core/sparse_system.hpp): the coloured parallel assembly against a
// dense assembly written here with plain loops (with real element stiffnesses and with
// random non-symmetric blocks, which catch transposed scatter indices), the pattern, the
// free-DOF maps, diagonal positions, node blocks, and a timing-based check that elements
// sharing a node never run at the same time.

#include "core/box_generator.hpp"
#include "core/element.hpp"
#include "core/solvers/block_jacobi.hpp"
#include "core/sparse_system.hpp"
#include "test_support.hpp"

#include <omp.h>

#include <Eigen/Dense>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <chrono>
#include <cmath>
#include <random>
#include <set>

namespace core = fiberfem::core;
using core::Mat12;
using core::Vec12;
using core::Vec3;

namespace {

core::TetMesh box(std::array<int, 3> cells) {
  core::BoxSpec s;
  s.size_m = Vec3(0.03, 0.02, 0.025);
  s.cells = cells;
  return core::make_box(s);
}

// xmin fully fixed, one node fixed in y only, another in x and z.
std::vector<std::uint8_t> partly_fixed(const core::TetMesh& mesh) {
  std::vector<std::uint8_t> fixed(static_cast<size_t>(3 * mesh.num_nodes()), 0);
  for (int n : mesh.node_set("xmin"))
    for (int c = 0; c < 3; ++c) fixed[static_cast<size_t>(3 * n + c)] = 1;
  const int a = mesh.node_set("xmax").front(), b = mesh.node_set("xmax").back();
  fixed[static_cast<size_t>(3 * a + 1)] = 1;
  fixed[static_cast<size_t>(3 * b + 0)] = 1;
  fixed[static_cast<size_t>(3 * b + 2)] = 1;
  return fixed;
}

// The DOF of each free index of `sys` (whatever its DofOrder).
std::vector<int> free_dofs(const core::SparseSystem& sys) {
  std::vector<int> out(static_cast<size_t>(sys.num_free()), -1);
  for (int d = 0; d < sys.num_dofs(); ++d)
    if (sys.free_index()[static_cast<size_t>(d)] >= 0) out[static_cast<size_t>(sys.free_index()[static_cast<size_t>(d)])] = d;
  return out;
}

// The mesh with its nodes numbered at random (node sets carried over): a numbering that
// scatters every element's nodes, as a mesh generator's can.
core::TetMesh scrambled_nodes(const core::TetMesh& mesh, unsigned seed) {
  std::vector<int> to(static_cast<size_t>(mesh.num_nodes()));
  for (size_t i = 0; i < to.size(); ++i) to[i] = static_cast<int>(i);
  std::shuffle(to.begin(), to.end(), std::mt19937(seed));
  core::Positions x(3, mesh.num_nodes());
  for (int v = 0; v < mesh.num_nodes(); ++v) x.col(to[static_cast<size_t>(v)]) = mesh.rest_positions().col(v);
  std::vector<core::Tet> tets = mesh.tets();
  for (core::Tet& t : tets)
    for (int& v : t) v = to[static_cast<size_t>(v)];
  core::TetMesh out(x, tets);
  for (const auto& [name, nodes] : mesh.node_sets()) {
    std::vector<int> moved;
    for (int v : nodes) moved.push_back(to[static_cast<size_t>(v)]);
    std::sort(moved.begin(), moved.end());
    out.set_node_set(name, moved);
  }
  return out;
}

// Deterministic per-element random data (thread safe: a generator per call).
// A random symmetric element matrix (assemble's contract) whose off-diagonal node blocks
// are not symmetric, so a block written transposed or into the wrong place shows.
Mat12 random_block(int e) {
  std::mt19937 rng(1000u + static_cast<unsigned>(e));
  std::normal_distribution<double> n(0, 1);
  Mat12 K;
  for (int i = 0; i < 144; ++i) K(i) = n(rng);
  return K + K.transpose();
}
Mat12 random_unsymmetric_block(int e) {
  std::mt19937 rng(3000u + static_cast<unsigned>(e));
  std::normal_distribution<double> n(0, 1);
  Mat12 K;
  for (int i = 0; i < 144; ++i) K(i) = n(rng);
  return K;
}
Vec12 random_force(int e) {
  std::mt19937 rng(5000u + static_cast<unsigned>(e));
  std::normal_distribution<double> n(0, 1);
  Vec12 f;
  for (int i = 0; i < 12; ++i) f(i) = n(rng);
  return f;
}

// Plain dense assembly over all DOFs.
template <class BlockOf>
Eigen::MatrixXd dense_assembly(const core::TetMesh& mesh, BlockOf block_of, Eigen::VectorXd* f = nullptr) {
  const int nd = 3 * mesh.num_nodes();
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(nd, nd);
  if (f) *f = Eigen::VectorXd::Zero(nd);
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const core::Tet& t = mesh.tets()[static_cast<size_t>(e)];
    const Mat12 Ke = block_of(e);
    const Vec12 fe = random_force(e);
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i) {
        if (f) (*f)(3 * t[static_cast<size_t>(a)] + i) += fe(3 * a + i);
        for (int b = 0; b < 4; ++b)
          for (int j = 0; j < 3; ++j)
            K(3 * t[static_cast<size_t>(a)] + i, 3 * t[static_cast<size_t>(b)] + j) += Ke(3 * a + i, 3 * b + j);
      }
  }
  return K;
}

Eigen::MatrixXd restrict_dense(const Eigen::MatrixXd& K, const std::vector<int>& free) {
  const int nf = static_cast<int>(free.size());
  Eigen::MatrixXd R(nf, nf);
  for (int i = 0; i < nf; ++i)
    for (int j = 0; j < nf; ++j) R(i, j) = K(free[static_cast<size_t>(i)], free[static_cast<size_t>(j)]);
  return R;
}

// Assembles random_block and random_force into `sys` (a fresh system of `mesh`) and compares
// the matrix and the forces with the dense reference.
void expect_random_assembly_exact(const core::TetMesh& mesh, core::SparseSystem& sys) {
  Eigen::VectorXd f_ref;
  const Eigen::MatrixXd K_ref = restrict_dense(dense_assembly(mesh, random_block, &f_ref), free_dofs(sys));
  Eigen::VectorXd f = Eigen::VectorXd::Zero(sys.num_dofs());
  sys.assemble([](int e, Mat12& Ke, Vec12& fe) {
    Ke = random_block(e);
    fe = random_force(e);
  }, f);
  EXPECT_LT((Eigen::MatrixXd(sys.matrix()) - K_ref).norm(), 1e-13 * K_ref.norm());
  EXPECT_LT((f - f_ref).norm(), 1e-13 * f_ref.norm());
}

core::Material ti_material() {
  core::EngineeringConstants c;
  c.E_L = 90e3;
  c.E_T = 15e3;
  c.nu_T = 0.45;
  c.nu_LT = 0.3;
  c.G_L = 7e3;
  return core::Material::from_engineering(c, 1000);
}

// A fan of tetrahedra that all share node 0 and nothing else, so every element conflicts
// with every other.
core::TetMesh fan(int count) {
  core::Positions x(3, 1 + 3 * count);
  x.col(0).setZero();
  std::vector<core::Tet> tets;
  for (int i = 0; i < count; ++i) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(2 * M_PI * i / count, Vec3::UnitZ()).toRotationMatrix();
    const Vec3 lift(0, 0, 0.3 * i / count);
    x.col(3 * i + 1) = R * Vec3(1, 0, 0) + lift;
    x.col(3 * i + 2) = R * Vec3(1, 0.1, 0) + lift;
    x.col(3 * i + 3) = R * Vec3(1, 0, 0.1) + lift;
    tets.push_back({0, 3 * i + 1, 3 * i + 2, 3 * i + 3});
  }
  return core::TetMesh(x, tets);
}

}  // namespace

TEST(SparseSystem, AssemblyOfElementStiffnessesMatchesDenseReference) {
  const core::TetMesh mesh = box({3, 2, 2});
  const std::vector<std::uint8_t> fixed = partly_fixed(mesh);
  const core::Material mat = ti_material();
  std::vector<Vec3> fibers;
  std::mt19937 rng(61);
  std::normal_distribution<double> n(0, 1);
  for (int e = 0; e < mesh.num_elements(); ++e) fibers.emplace_back(n(rng), n(rng), n(rng));
  auto Ke_of = [&](int e) {
    return core::element_stiffness(core::gather(mesh.rest_positions(), mesh.tets()[static_cast<size_t>(e)]), mat,
                                   fibers[static_cast<size_t>(e)]);
  };
  core::SparseSystem sys(mesh, fixed, 4);
  Eigen::VectorXd f_ref;
  const Eigen::MatrixXd K_ref = restrict_dense(dense_assembly(mesh, Ke_of, &f_ref), free_dofs(sys));

  EXPECT_EQ(sys.num_dofs(), 3 * mesh.num_nodes());
  EXPECT_EQ(sys.num_free(), static_cast<int>(K_ref.rows()));
  Eigen::VectorXd f = Eigen::VectorXd::Zero(sys.num_dofs());
  sys.assemble([&](int e, Mat12& Ke, Vec12& fe) {
    Ke = Ke_of(e);
    fe = random_force(e);
  }, f);
  const Eigen::MatrixXd K = Eigen::MatrixXd(sys.matrix());
  EXPECT_LT((K - K_ref).norm(), 1e-13 * K_ref.norm());
  EXPECT_LT((K - K.transpose()).norm(), 1e-13 * K_ref.norm());
  EXPECT_LT((f - f_ref).norm(), 1e-13 * f_ref.norm());  // forces on every DOF, fixed ones too
  // With xmin clamped the restricted stiffness is positive definite.
  EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(K).info(), Eigen::Success);
}

// assemble_unsymmetric (the static solver's consistent tangent) places every entry of an
// unsymmetric element matrix, with and without fixed DOFs.
TEST(SparseSystem, UnsymmetricElementMatricesAssembleExactly) {
  const core::TetMesh mesh = box({3, 2, 2});
  for (bool with_fixed : {false, true}) {
    const std::vector<std::uint8_t> fixed = with_fixed ? partly_fixed(mesh) : std::vector<std::uint8_t>{};
    core::SparseSystem sys(mesh, fixed);
    Eigen::VectorXd f_ref;
    const Eigen::MatrixXd K_ref = restrict_dense(dense_assembly(mesh, random_unsymmetric_block, &f_ref), free_dofs(sys));
    Eigen::VectorXd f = Eigen::VectorXd::Zero(sys.num_dofs());
    sys.assemble_unsymmetric(
        [](int e, Mat12& Ke, Vec12& fe) {
          Ke = random_unsymmetric_block(e);
          fe = random_force(e);
        },
        f);
    EXPECT_LT((Eigen::MatrixXd(sys.matrix()) - K_ref).norm(), 1e-13 * K_ref.norm()) << "fixed " << with_fixed;
    EXPECT_GT((K_ref - K_ref.transpose()).norm(), 1.0);  // the check is not vacuous
  }
}

// assemble reads the upper node blocks (b >= a) only: garbage in the lower ones changes
// nothing, with and without fixed DOFs (the block and the general scatter).
TEST(SparseSystem, LowerNodeBlocksAreNotRead) {
  const core::TetMesh mesh = box({3, 2, 2});
  for (bool with_fixed : {false, true}) {
    const std::vector<std::uint8_t> fixed = with_fixed ? partly_fixed(mesh) : std::vector<std::uint8_t>{};
    core::SparseSystem sys(mesh, fixed);
    Eigen::VectorXd f_ref;
    const Eigen::MatrixXd K_ref = restrict_dense(dense_assembly(mesh, random_block, &f_ref), free_dofs(sys));
    Eigen::VectorXd f = Eigen::VectorXd::Zero(sys.num_dofs());
    sys.assemble(
        [](int e, Mat12& Ke, Vec12& fe) {
          Ke = random_block(e);
          for (int a = 0; a < 4; ++a)
            for (int b = 0; b < a; ++b) Ke.block<3, 3>(3 * a, 3 * b).setConstant(std::nan(""));
          fe = random_force(e);
        },
        f);
    EXPECT_LT((Eigen::MatrixXd(sys.matrix()) - K_ref).norm(), 1e-13 * K_ref.norm()) << "fixed " << with_fixed;
  }
}

TEST(SparseSystem, UnsymmetricNodeBlocksLandInTheRightPlaces) {
  const core::TetMesh mesh = box({3, 2, 2});
  for (int chunk : {1, 5, 32, 1000}) {
    for (bool with_fixed : {false, true}) {
      const std::vector<std::uint8_t> fixed = with_fixed ? partly_fixed(mesh) : std::vector<std::uint8_t>{};
      core::SparseSystem sys(mesh, fixed, chunk);
      Eigen::VectorXd f_ref;
      const Eigen::MatrixXd K_ref = restrict_dense(dense_assembly(mesh, random_block, &f_ref), free_dofs(sys));
      Eigen::VectorXd f = Eigen::VectorXd::Zero(sys.num_dofs());
      auto kernel = [](int e, Mat12& Ke, Vec12& fe) {
        Ke = random_block(e);
        fe = random_force(e);
      };
      sys.assemble(kernel, f);
      EXPECT_LT((Eigen::MatrixXd(sys.matrix()) - K_ref).norm(), 1e-13 * K_ref.norm()) << "chunk " << chunk;
      EXPECT_LT((f - f_ref).norm(), 1e-13 * f_ref.norm());
      // Assembling again adds; zero_matrix clears values but keeps the pattern.
      const Eigen::Index nnz = sys.matrix().nonZeros();
      sys.assemble(kernel, f);
      EXPECT_LT((Eigen::MatrixXd(sys.matrix()) - 2 * K_ref).norm(), 1e-13 * K_ref.norm());
      sys.zero_matrix();
      EXPECT_EQ(Eigen::MatrixXd(sys.matrix()).norm(), 0.0);
      EXPECT_EQ(sys.matrix().nonZeros(), nnz);
      f.setZero();
      sys.assemble(kernel, f);
      EXPECT_LT((Eigen::MatrixXd(sys.matrix()) - K_ref).norm(), 1e-13 * K_ref.norm());
    }
  }
}

// Pattern: exactly the free (row, column) pairs of nodes that share an element.
TEST(SparseSystem, PatternIsTheNodeAdjacencyOverFreeDofs) {
  const core::TetMesh mesh = box({3, 2, 2});
  const std::vector<std::uint8_t> fixed = partly_fixed(mesh);
  const core::SparseSystem sys(mesh, fixed);
  std::set<std::pair<int, int>> adjacent;
  for (const core::Tet& t : mesh.tets())
    for (int a : t)
      for (int b : t) adjacent.insert({a, b});
  long expected = 0;
  for (const auto& [a, b] : adjacent)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) expected += !fixed[static_cast<size_t>(3 * a + i)] && !fixed[static_cast<size_t>(3 * b + j)];
  EXPECT_EQ(sys.matrix().nonZeros(), expected);
  EXPECT_TRUE(sys.matrix().isCompressed());
  const std::vector<int> free = free_dofs(sys);
  for (int r = 0; r < sys.num_free(); ++r)
    for (core::SparseMatrix::InnerIterator it(sys.matrix(), r); it; ++it) {
      const int na = free[static_cast<size_t>(r)] / 3, nb = free[static_cast<size_t>(it.col())] / 3;
      EXPECT_TRUE(adjacent.count({na, nb})) << "entry (" << r << ", " << it.col() << ") not adjacent";
    }
}

TEST(SparseSystem, FreeIndexRestrictAndScatter) {
  const core::TetMesh mesh = box({2, 2, 1});
  const std::vector<std::uint8_t> fixed = partly_fixed(mesh);
  const core::SparseSystem sys(mesh, fixed, 32, core::LoopSchedule::automatic, core::DofOrder::nodes);
  int num_free = 0;
  for (std::uint8_t f : fixed) num_free += !f;
  ASSERT_EQ(sys.num_free(), num_free);
  ASSERT_EQ(sys.free_index().size(), static_cast<size_t>(sys.num_dofs()));
  int next = 0;  // DofOrder::nodes: the free DOFs in DOF order
  for (int d = 0; d < sys.num_dofs(); ++d) {
    if (fixed[static_cast<size_t>(d)]) {
      EXPECT_EQ(sys.free_index()[static_cast<size_t>(d)], -1) << d;
    } else {
      EXPECT_EQ(sys.free_index()[static_cast<size_t>(d)], next++) << d;
    }
  }
  EXPECT_TRUE(sys.natural_order().identity);
  const std::vector<int> free = free_dofs(sys);
  const Eigen::VectorXd full = Eigen::VectorXd::LinSpaced(sys.num_dofs(), 1.0, sys.num_dofs());
  const Eigen::VectorXd r = sys.restrict_to_free(full);
  ASSERT_EQ(r.size(), sys.num_free());
  for (int k = 0; k < sys.num_free(); ++k) EXPECT_EQ(r(k), full(free[static_cast<size_t>(k)]));
  Eigen::VectorXd back = Eigen::VectorXd::Constant(sys.num_dofs(), -7.0);
  sys.scatter_free(r, back);
  for (int d = 0; d < sys.num_dofs(); ++d) EXPECT_EQ(back(d), fixed[static_cast<size_t>(d)] ? -7.0 : full(d)) << d;
  // No fixed DOFs: identity maps.
  const core::SparseSystem all(mesh, {}, 32, core::LoopSchedule::automatic, core::DofOrder::nodes);
  EXPECT_EQ(all.num_free(), all.num_dofs());
  for (int d = 0; d < all.num_dofs(); ++d) EXPECT_EQ(all.free_index()[static_cast<size_t>(d)], d);
  EXPECT_EQ(all.restrict_to_free(full), full);
}

// DofOrder::bandwidth on a mesh whose nodes are numbered at random: the free DOFs are a
// permutation of the DOF order with each node's free components consecutive and in order,
// the node blocks follow it, the matrix's envelope shrinks (every row's earliest column comes
// close), restrict/scatter agree with it, and natural_order() maps every item (DOF, node
// block, non-zero) to its place under DofOrder::nodes.
TEST(SparseSystem, BandwidthOrderNumbersNeighboursCloseTogether) {
  const core::TetMesh mesh = scrambled_nodes(box({12, 3, 3}), 3);
  const std::vector<std::uint8_t> fixed = partly_fixed(mesh);
  const core::SparseSystem natural(mesh, fixed, 32, core::LoopSchedule::automatic, core::DofOrder::nodes);
  const core::SparseSystem sys(mesh, fixed);
  ASSERT_EQ(sys.dof_order(), core::DofOrder::bandwidth);
  ASSERT_EQ(sys.num_free(), natural.num_free());
  std::vector<int> seen(static_cast<size_t>(sys.num_free()), 0);
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    int last = -1;
    for (int c = 0; c < 3; ++c) {
      const int k = sys.free_index()[static_cast<size_t>(3 * v + c)];
      EXPECT_EQ(k < 0, fixed[static_cast<size_t>(3 * v + c)] != 0);
      if (k < 0) continue;
      ++seen[static_cast<size_t>(k)];
      if (last >= 0) {
        EXPECT_EQ(k, last + 1) << "node " << v;
      }
      last = k;
    }
  }
  for (int s : seen) EXPECT_EQ(s, 1);
  const std::vector<int> starts = sys.node_block_starts();
  ASSERT_EQ(starts.size(), sys.block_nodes().size() + 1);
  for (size_t k = 0; k < sys.block_nodes().size(); ++k) {
    const int v = sys.block_nodes()[k];
    int first = -1;
    for (int c = 2; c >= 0; --c)
      if (sys.free_index()[static_cast<size_t>(3 * v + c)] >= 0) first = sys.free_index()[static_cast<size_t>(3 * v + c)];
    EXPECT_EQ(starts[k], first);
  }
  const auto envelope = [](const core::SparseMatrix& A) {
    long sum = 0;
    for (int r = 0; r < A.rows(); ++r) sum += r - std::min(r, A.innerIndexPtr()[A.outerIndexPtr()[r]]);
    return sum;
  };
  EXPECT_LT(envelope(sys.matrix()), envelope(natural.matrix()) / 3);
  const Eigen::VectorXd full = Eigen::VectorXd::LinSpaced(sys.num_dofs(), 1.0, sys.num_dofs());
  const Eigen::VectorXd r = sys.restrict_to_free(full);
  const std::vector<int> free = free_dofs(sys);
  for (int k = 0; k < sys.num_free(); ++k) EXPECT_EQ(r(k), full(free[static_cast<size_t>(k)]));
  // natural_order(): the same matrix assembled both ways, item by item.
  const core::NaturalOrder& o = sys.natural_order();
  ASSERT_FALSE(o.identity);
  core::SparseSystem a(mesh, fixed), b(mesh, fixed, 32, core::LoopSchedule::automatic, core::DofOrder::nodes);
  Eigen::VectorXd fa = Eigen::VectorXd::Zero(a.num_dofs()), fb = fa;
  const auto kernel = [](int e, Mat12& Ke, Vec12& fe) {
    Ke = random_block(e);
    fe = random_force(e);
  };
  a.assemble(kernel, fa);
  b.assemble(kernel, fb);
  ASSERT_EQ(o.value.size(), static_cast<size_t>(a.matrix().nonZeros()));
  for (size_t p = 0; p < o.value.size(); ++p)
    EXPECT_EQ(b.matrix().valuePtr()[o.value[p]], a.matrix().valuePtr()[p]) << "non-zero " << p;
  const Eigen::VectorXd ra = a.restrict_to_free(full), rb = b.restrict_to_free(full);
  for (int k = 0; k < sys.num_free(); ++k) EXPECT_EQ(rb(o.free[static_cast<size_t>(k)]), ra(k));
  for (size_t k = 0; k < o.block.size(); ++k) EXPECT_EQ(natural.block_nodes()[static_cast<size_t>(o.block[k])], sys.block_nodes()[k]);
}

// Two bodies that share no node (Boost's ordering walks each connected component): every
// free DOF is numbered once, the numbering is taken, and the assembly is exact.
TEST(SparseSystem, BandwidthOrderNumbersEveryComponentOfADisconnectedMesh) {
  const core::TetMesh a = box({8, 2, 2});
  core::Positions x(3, 2 * a.num_nodes());
  x.leftCols(a.num_nodes()) = a.rest_positions();
  x.rightCols(a.num_nodes()) = a.rest_positions().colwise() + Vec3(1.0, 0.0, 0.0);
  std::vector<core::Tet> tets = a.tets();
  for (core::Tet t : a.tets()) {
    for (int& v : t) v += a.num_nodes();
    tets.push_back(t);
  }
  const core::TetMesh mesh = scrambled_nodes(core::TetMesh(x, tets), 11);
  core::SparseSystem sys(mesh, {});
  EXPECT_EQ(sys.dof_order(), core::DofOrder::bandwidth);
  std::vector<int> seen(static_cast<size_t>(sys.num_free()), 0);
  for (int k : sys.free_index()) {
    ASSERT_GE(k, 0);
    ++seen[static_cast<size_t>(k)];
  }
  for (int c : seen) EXPECT_EQ(c, 1);
  expect_random_assembly_exact(mesh, sys);
}

TEST(SparseSystem, DiagonalIndexPointsAtDiagonalEntries) {
  const core::TetMesh mesh = box({3, 2, 2});
  core::SparseSystem sys(mesh, partly_fixed(mesh));
  Eigen::VectorXd f = Eigen::VectorXd::Zero(sys.num_dofs());
  sys.assemble([](int e, Mat12& Ke, Vec12& fe) {
    Ke = random_block(e);
    fe.setZero();
  }, f);
  const core::SparseMatrix& A = sys.matrix();
  ASSERT_EQ(sys.diagonal_index().size(), static_cast<size_t>(sys.num_free()));
  for (int r = 0; r < sys.num_free(); ++r) {
    const int k = sys.diagonal_index()[static_cast<size_t>(r)];
    EXPECT_GE(k, A.outerIndexPtr()[r]);
    EXPECT_LT(k, A.outerIndexPtr()[r + 1]);
    EXPECT_EQ(A.innerIndexPtr()[k], r);
    EXPECT_EQ(A.valuePtr()[k], A.coeff(r, r));
  }
}

TEST(SparseSystem, NodeBlockStartsFollowTheNodesFreeComponents) {
  const core::TetMesh mesh = box({2, 2, 2});
  const std::vector<std::uint8_t> fixed = partly_fixed(mesh);
  const core::SparseSystem sys(mesh, fixed, 32, core::LoopSchedule::automatic, core::DofOrder::nodes);
  std::vector<int> expected;
  int f = 0;
  for (int n = 0; n < mesh.num_nodes(); ++n) {
    const int nfree = 3 - fixed[static_cast<size_t>(3 * n)] - fixed[static_cast<size_t>(3 * n + 1)] - fixed[static_cast<size_t>(3 * n + 2)];
    if (nfree > 0) expected.push_back(f);
    f += nfree;
  }
  expected.push_back(f);
  EXPECT_EQ(sys.node_block_starts(), expected);
  // Blocks of 1, 2 and 3 rows all occur with this mask.
  std::set<int> sizes;
  for (size_t k = 0; k + 1 < expected.size(); ++k) sizes.insert(expected[k + 1] - expected[k]);
  EXPECT_EQ(sizes, (std::set<int>{1, 2, 3}));
}

// Every element is visited once, and no two elements sharing a node ever run at the same
// time: each kernel call records the (global, atomic) ticks at which it starts and ends
// and busy-waits in between, so elements running concurrently have overlapping intervals.
TEST(SparseSystem, ColouredLoopNeverRunsNeighboursConcurrently) {
  const core::TetMesh mesh = box({8, 4, 4});
  const int ne = mesh.num_elements();
  std::vector<std::vector<int>> elements_of_node(static_cast<size_t>(mesh.num_nodes()));
  for (int e = 0; e < ne; ++e)
    for (int v : mesh.tets()[static_cast<size_t>(e)]) elements_of_node[static_cast<size_t>(v)].push_back(e);
  for (int chunk : {1, 8, 32})
  for (core::LoopSchedule schedule : {core::LoopSchedule::chunks, core::LoopSchedule::runs}) {
    const core::SparseSystem sys(mesh, {}, chunk, schedule);
    EXPECT_GE(sys.num_colours(), 2);
    if (ne / chunk >= 2 * core::SparseSystem::kRuns) {  // at least two chunks in each run
      EXPECT_EQ(sys.runs_in_runs(), schedule == core::LoopSchedule::runs) << "chunk " << chunk;
    }
    std::atomic<long> tick{0};
    std::vector<long> begin(static_cast<size_t>(ne), -1), end(static_cast<size_t>(ne), -1);
    std::vector<std::atomic<int>> calls(static_cast<size_t>(ne));
    sys.for_each_element_coloured([&](int e) {
      begin[static_cast<size_t>(e)] = tick++;
      const auto t0 = std::chrono::steady_clock::now();
      while (std::chrono::steady_clock::now() - t0 < std::chrono::microseconds(10)) {
      }
      end[static_cast<size_t>(e)] = tick++;
      calls[static_cast<size_t>(e)]++;
    });
    for (int e = 0; e < ne; ++e) ASSERT_EQ(calls[static_cast<size_t>(e)].load(), 1) << "element " << e;
    auto overlap = [&](int a, int b) {
      return begin[static_cast<size_t>(a)] < end[static_cast<size_t>(b)] && begin[static_cast<size_t>(b)] < end[static_cast<size_t>(a)];
    };
    int conflicts = 0;
    for (const auto& els : elements_of_node)
      for (size_t i = 0; i < els.size(); ++i)
        for (size_t j = i + 1; j < els.size(); ++j) conflicts += overlap(els[i], els[j]);
    EXPECT_EQ(conflicts, 0) << "chunk " << chunk << " runs " << sys.runs_in_runs();
    // The check has teeth only if elements did run concurrently.
    long concurrent = 0;
    for (int a = 0; a < ne; ++a)
      for (int b = a + 1; b < ne; ++b) concurrent += overlap(a, b);
    // (On a loaded machine the second thread may not get a core; then the check above is
    // vacuous for this run, which is reported rather than failed.)
    if (omp_get_max_threads() > 1 && concurrent == 0)
      std::printf("note: chunk %d ran without overlap on this run; the conflict check was vacuous\n", chunk);
  }
}

// The automatic schedule takes runs only where they pay: a mesh with at least
// kRunMinElements per run in a local order, including a scattered one (re-cut into slabs);
// runs colour in two colours there.
TEST(SparseSystem, AutomaticScheduleTakesRunsOnLargeMeshesOnly) {
  const int runs = core::SparseSystem::kRuns;
  // A bar two cells long per run, 4 x 4 cells across: each run meets only its neighbours.
  const int cells_needed = (core::SparseSystem::kRunMinElements * runs + 5) / 6;
  const int cx = std::max(2 * runs, (cells_needed + 15) / 16);
  const core::TetMesh large = box({cx, 4, 4});
  ASSERT_GE(large.num_elements(), core::SparseSystem::kRunMinElements * runs);
  const core::SparseSystem sys(large, {});
  EXPECT_TRUE(sys.runs_in_runs());
  EXPECT_EQ(sys.num_colours(), 2);
  std::vector<core::Tet> tets = large.tets();
  std::shuffle(tets.begin(), tets.end(), std::mt19937(3));
  const core::SparseSystem scattered(core::TetMesh(large.rest_positions(), tets), {});
  EXPECT_TRUE(scattered.runs_in_runs());
  EXPECT_LE(scattered.num_colours(), 3);
  const core::SparseSystem small(box({8, 4, 4}), {});
  EXPECT_FALSE(small.runs_in_runs());
  const core::SparseSystem forced(large, {}, 32, core::LoopSchedule::chunks);
  EXPECT_FALSE(forced.runs_in_runs());
}

// More than 64 mutually conflicting chunks: the first 64 take colours, the rest run one at
// a time; every element is still visited once and the assembly is still exact.
TEST(SparseSystem, MoreThanSixtyFourConflictingChunksStillAssembleExactly) {
  const core::TetMesh mesh = fan(100);
  core::SparseSystem sys(mesh, {}, 0);  // chunk size clamps to 1
  EXPECT_EQ(sys.num_colours(), 100);
  expect_random_assembly_exact(mesh, sys);
}

// A mesh whose elements come in a scattered order (as a mesh generator writes them):
// chunks of consecutive elements would conflict with nearly every other chunk, so the loop
// runs them in the Morton order of their centroids instead: few colours, the same
// assembly, every element once.
TEST(SparseSystem, ScatteredElementOrderIsRechunkedInSpace) {
  const core::TetMesh cells = box({12, 6, 6});
  std::vector<core::Tet> tets = cells.tets();
  std::mt19937 rng(17);
  std::shuffle(tets.begin(), tets.end(), rng);
  const core::TetMesh shuffled(cells.rest_positions(), tets);
  const core::SparseSystem natural(cells, {});
  core::SparseSystem sys(shuffled, {});
  EXPECT_LE(natural.num_colours(), 16);
  // Shuffled, nearly every chunk of 32 touches every other: over 64 colours, most chunks
  // serial. Regrouped in space, a few tens at most.
  EXPECT_LE(sys.num_colours(), 24) << "scattered chunks were not regrouped";
  Eigen::VectorXd f_ref;
  const Eigen::MatrixXd K_ref = restrict_dense(dense_assembly(shuffled, random_block, &f_ref), free_dofs(sys));
  Eigen::VectorXd f = Eigen::VectorXd::Zero(sys.num_dofs());
  std::vector<std::atomic<int>> calls(static_cast<size_t>(shuffled.num_elements()));
  sys.assemble([&](int e, Mat12& Ke, Vec12& fe) {
    calls[static_cast<size_t>(e)]++;
    Ke = random_block(e);
    fe = random_force(e);
  }, f);
  for (auto& c : calls) EXPECT_EQ(c.load(), 1);
  EXPECT_LT((Eigen::MatrixXd(sys.matrix()) - K_ref).norm(), 1e-13 * K_ref.norm());
  EXPECT_LT((f - f_ref).norm(), 1e-13 * f_ref.norm());
}

// assemble_batched against a dense assembly: each lane's upper blocks land in both
// triangles, the forces add up, and the values are replaced, not added to (each node's
// rows are zeroed inside the parallel loop by the first chunk that writes them): the
// matrix starts full of NaN and of an earlier assembly. Chunk sizes from one element (many
// colours) to all of them (one chunk); with fixed DOFs (the general scatter); and with the
// elements shuffled, so that the chunks are scattered over the body and the order is
// replaced by the Morton order (the zeroing plan follows whichever order is kept).
TEST(SparseSystem, BatchedAssemblyReplacesTheValues) {
  core::TetMesh ordered = box({5, 3, 4});
  std::vector<core::Tet> shuffled_tets = ordered.tets();
  std::shuffle(shuffled_tets.begin(), shuffled_tets.end(), std::mt19937(7));
  core::TetMesh shuffled(ordered.rest_positions(), shuffled_tets);
  for (const auto& [name, nodes] : ordered.node_sets()) shuffled.set_node_set(name, nodes);
  const core::TetMesh scrambled = scrambled_nodes(ordered, 5);  // numbered anew (DofOrder::bandwidth)
  ASSERT_EQ(core::SparseSystem(scrambled, {}).dof_order(), core::DofOrder::bandwidth);
  const core::TetMesh* meshes[] = {&ordered, &shuffled, &scrambled};
  for (const core::TetMesh* mesh : meshes)
    for (int chunk : {1, 5, 32, 100000})
      for (core::LoopSchedule schedule : {core::LoopSchedule::chunks, core::LoopSchedule::runs})
      for (int fixing : {0, 1, 2}) {  // none; the xmin face wholly (blocks kept); single components too
        const bool with_fixed = fixing > 0;
        std::vector<std::uint8_t> fixed;
        if (fixing == 2) fixed = partly_fixed(*mesh);
        if (fixing == 1) {
          fixed.assign(static_cast<size_t>(3 * mesh->num_nodes()), 0);
          for (int v : mesh->node_set("xmin"))
            for (int c = 0; c < 3; ++c) fixed[static_cast<size_t>(3 * v + c)] = 1;
        }
        core::SparseSystem sys(*mesh, fixed, chunk, schedule);
        Eigen::VectorXd f_ref;
        const Eigen::MatrixXd K_ref = restrict_dense(dense_assembly(*mesh, random_block, &f_ref), free_dofs(sys));
        // Runs are taken whenever forced and there is more than one chunk per run.
        if (schedule == core::LoopSchedule::runs && mesh->num_elements() / chunk >= 2 * core::SparseSystem::kRuns) {
          EXPECT_TRUE(sys.runs_in_runs());
        }
        if (schedule == core::LoopSchedule::chunks) {
          EXPECT_FALSE(sys.runs_in_runs());
        }
        auto kernel = [](const int* elems, int n, core::ElementBatch& batch) {
          for (int l = 0; l < n; ++l) {
            const Mat12 K = random_block(elems[l]);
            for (int a = 0; a < 4; ++a)
              for (int b = a; b < 4; ++b)
                for (int i = 0; i < 3; ++i)
                  for (int j = 0; j < 3; ++j)
                    batch.upper[9 * core::ElementBatch::block_index(a, b) + 3 * i + j][l] = K(3 * a + i, 3 * b + j);
            batch.force[l] = random_force(elems[l]);
          }
        };
        std::fill(sys.matrix().valuePtr(), sys.matrix().valuePtr() + sys.matrix().nonZeros(), std::nan(""));
        for (int pass = 0; pass < 2; ++pass) {
          Eigen::VectorXd f = Eigen::VectorXd::Zero(sys.num_dofs());
          sys.assemble_batched(kernel, f);
          // With every node wholly free or fixed the values went to the upper block store:
          // its products against the dense reference, then the CSR values synced from it.
          EXPECT_EQ(sys.has_blocks(), fixing < 2) << "partly_fixed fixes single components";
          if (sys.blocks_current()) {
            const Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(sys.num_free(), -1.0, 2.0);
            for (bool parallel : {false, true}) {
              Eigen::VectorXd y;
              const double xax = sys.block_product(x, y, parallel);
              EXPECT_LT((y - K_ref * x).norm(), 1e-13 * (K_ref * x).norm()) << "parallel " << parallel;
              EXPECT_NEAR(xax, x.dot(K_ref * x), 1e-12 * std::abs(x.dot(K_ref * x)) + 1e-12);
              Eigen::Matrix<double, Eigen::Dynamic, 8, Eigen::RowMajor> W(sys.num_free(), 8), AW(sys.num_free(), 8);
              for (int c = 0; c < 8; ++c) W.col(c) = Eigen::VectorXd::LinSpaced(sys.num_free(), -1.0 - c, 1.0 + c * c);
              sys.block_product8(W.data(), AW.data(), parallel);
              EXPECT_LT((Eigen::MatrixXd(AW) - K_ref * Eigen::MatrixXd(W)).norm(), 1e-13 * (K_ref * Eigen::MatrixXd(W)).norm());
            }
            // Block Jacobi read from the blocks (no CSR sync): the inverse of each node's
            // diagonal block of the dense reference.
            core::detail::BlockJacobiPreconditioner jacobi;
            jacobi.compute_from_blocks(sys);
            Eigen::VectorXd z(sys.num_free()), z_ref(sys.num_free());
            jacobi._solve_impl(x, z);
            for (int k = 0; k < sys.num_free() / 3; ++k)
              z_ref.segment<3>(3 * k) = K_ref.block<3, 3>(3 * k, 3 * k).inverse() * x.segment<3>(3 * k);
            EXPECT_LT((z - z_ref).norm(), 1e-11 * z_ref.norm());
            EXPECT_TRUE(sys.blocks_current());
            sys.sync_matrix();
            EXPECT_FALSE(sys.blocks_current());
          }
          const Eigen::MatrixXd K = sys.matrix();
          const int runs = sys.runs_in_runs();
          ASSERT_TRUE(K.allFinite()) << "chunk " << chunk << " runs " << runs << " fixed " << with_fixed << " pass " << pass;
          EXPECT_LT((K - K_ref).norm(), 1e-13 * K_ref.norm()) << "chunk " << chunk << " runs " << runs << " fixed " << with_fixed;
          EXPECT_LT((f - f_ref).norm(), 1e-13 * f_ref.norm());
        }
      }
}
