#include "core/fiber_fields.hpp"

#include "core/element.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::core {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Harmonic extension: the nodal values that solve the Laplace equation (linear tetrahedra)
// with the rows of `held_values` held at `held` (each column one problem).
Eigen::MatrixXd harmonic_extension(const TetMesh& mesh, const std::vector<int>& held, const Eigen::MatrixXd& held_values) {
  const int n = mesh.num_nodes();
  std::vector<int> index(static_cast<size_t>(n), -1);  // free-node index, or -1 when held
  std::vector<char> is_held(static_cast<size_t>(n), 0);
  for (int node : held) is_held[static_cast<size_t>(node)] = 1;
  int nf = 0;
  for (int i = 0; i < n; ++i)
    if (!is_held[static_cast<size_t>(i)]) index[static_cast<size_t>(i)] = nf++;
  // Every free node must connect to a held one through elements, or its value is
  // undetermined (a singular system the factorisation may not notice).
  {
    std::vector<std::vector<int>> adj(static_cast<size_t>(n));
    for (const Tet& t : mesh.tets())
      for (int a : t)
        for (int b : t)
          if (a != b) adj[static_cast<size_t>(a)].push_back(b);
    std::vector<char> seen(static_cast<size_t>(n), 0);
    std::vector<int> queue(held.begin(), held.end());
    for (int v : held) seen[static_cast<size_t>(v)] = 1;
    for (size_t q = 0; q < queue.size(); ++q)
      for (int w : adj[static_cast<size_t>(queue[q])])
        if (!seen[static_cast<size_t>(w)]) seen[static_cast<size_t>(w)] = 1, queue.push_back(w);
    const long unreached = std::count(seen.begin(), seen.end(), 0);
    if (unreached > 0)
      throw std::invalid_argument("laplace: " + std::to_string(unreached) +
                                  " nodes are not connected to any held node (a separate piece of the mesh?)");
  }
  Eigen::MatrixXd values = Eigen::MatrixXd::Zero(n, held_values.cols());
  for (size_t k = 0; k < held.size(); ++k) values.row(held[k]) = held_values.row(static_cast<Eigen::Index>(k));
  if (nf == 0) return values;

  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(mesh.num_elements()) * 16);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nf, held_values.cols());
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const Tet& t = mesh.tets()[static_cast<size_t>(e)];
    const Mat3 Dm_inv = rest_shape_inverse(gather(mesh.rest_positions(), t));
    Eigen::Matrix<double, 3, 4> G;  // shape-function gradients
    G.rightCols<3>() = Dm_inv.transpose();
    G.col(0) = -G.rightCols<3>().rowwise().sum();
    const double V = mesh.rest_volume(e);
    for (int a = 0; a < 4; ++a) {
      const int ia = index[static_cast<size_t>(t[static_cast<size_t>(a)])];
      if (ia < 0) continue;
      for (int b = 0; b < 4; ++b) {
        const double k = V * G.col(a).dot(G.col(b));
        const int nb = t[static_cast<size_t>(b)];
        const int ib = index[static_cast<size_t>(nb)];
        if (ib >= 0)
          triplets.emplace_back(ia, ib, k);
        else
          rhs.row(ia) -= k * values.row(nb);
      }
    }
  }
  Eigen::SparseMatrix<double> K(nf, nf);
  K.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(K);
  if (ldlt.info() != Eigen::Success)
    throw std::invalid_argument("laplace: the free nodes are not connected to a held node (singular system)");
  const Eigen::MatrixXd solved = ldlt.solve(rhs);
  for (int i = 0; i < n; ++i)
    if (index[static_cast<size_t>(i)] >= 0) values.row(i) = solved.row(index[static_cast<size_t>(i)]);
  return values;
}

void check_nodes(const TetMesh& mesh, const std::vector<int>& nodes, const char* what) {
  if (nodes.empty()) throw std::invalid_argument(std::string(what) + ": no nodes");
  for (int node : nodes)
    if (node < 0 || node >= mesh.num_nodes())
      throw std::invalid_argument(std::string(what) + ": node " + std::to_string(node) + " is out of range");
}

}  // namespace

Eigen::VectorXd laplace_coordinate(const TetMesh& mesh, const std::vector<int>& zero_nodes, const std::vector<int>& one_nodes) {
  check_nodes(mesh, zero_nodes, "laplace_coordinate: zero_nodes");
  check_nodes(mesh, one_nodes, "laplace_coordinate: one_nodes");
  std::vector<int> a = zero_nodes, b = one_nodes;
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  a.erase(std::unique(a.begin(), a.end()), a.end());
  b.erase(std::unique(b.begin(), b.end()), b.end());
  std::vector<int> both;
  std::set_intersection(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(both));
  if (!both.empty())
    throw std::invalid_argument("laplace_coordinate: node " + std::to_string(both.front()) + " is in both sets");
  std::vector<int> held = a;
  held.insert(held.end(), b.begin(), b.end());
  Eigen::MatrixXd values(static_cast<Eigen::Index>(held.size()), 1);
  values.topRows(static_cast<Eigen::Index>(a.size())).setZero();
  values.bottomRows(static_cast<Eigen::Index>(b.size())).setOnes();
  return harmonic_extension(mesh, held, values).col(0);
}

void HelixRule::validate() const {
  if (!std::isfinite(endo_angle_deg)) throw std::invalid_argument("helix rule: endo_angle_deg must be finite");
  if (!std::isfinite(epi_angle_deg)) throw std::invalid_argument("helix rule: epi_angle_deg must be finite");
  if (!apex_to_base.allFinite() || apex_to_base.norm() < 1e-12)
    throw std::invalid_argument("helix rule: apex_to_base must be a finite non-zero vector");
}

FiberField helix_rule_fibers(const TetMesh& mesh, const Eigen::VectorXd& t, const HelixRule& rule) {
  rule.validate();
  if (t.size() != mesh.num_nodes())
    throw std::invalid_argument("helix rule: " + std::to_string(t.size()) + " transmural values for " +
                                std::to_string(mesh.num_nodes()) + " nodes");
  if (!t.allFinite()) throw std::invalid_argument("helix rule: non-finite transmural coordinate");
  const Vec3 axis = rule.apex_to_base.normalized();
  const int ne = mesh.num_elements();
  FiberField out;
  out.fiber.resize(static_cast<size_t>(ne));
  out.sheet.resize(static_cast<size_t>(ne));
  out.transmural.resize(static_cast<size_t>(ne));
  // Nodal gradients (volume-weighted means of the element gradients): the fallback for an
  // element whose own gradient vanishes (all four nodes on one surface).
  std::vector<Vec3> grad_e(static_cast<size_t>(ne));
  std::vector<Vec3> grad_n(static_cast<size_t>(mesh.num_nodes()), Vec3::Zero());
  for (int e = 0; e < ne; ++e) {
    const Tet& tet = mesh.tets()[static_cast<size_t>(e)];
    const Mat3 Dm_inv = rest_shape_inverse(gather(mesh.rest_positions(), tet));
    const Vec3 dt(t(tet[1]) - t(tet[0]), t(tet[2]) - t(tet[0]), t(tet[3]) - t(tet[0]));
    grad_e[static_cast<size_t>(e)] = Dm_inv.transpose() * dt;
    for (int node : tet) grad_n[static_cast<size_t>(node)] += mesh.rest_volume(e) * grad_e[static_cast<size_t>(e)];
  }
  for (int e = 0; e < ne; ++e) {
    const Tet& tet = mesh.tets()[static_cast<size_t>(e)];
    double te = 0;
    for (int node : tet) te += 0.25 * t(node);
    Vec3 g = grad_e[static_cast<size_t>(e)];
    const double h = std::cbrt(mesh.rest_volume(e));
    if (g.norm() * h < 1e-9) {
      g.setZero();
      for (int node : tet) g += grad_n[static_cast<size_t>(node)];
    }
    const Vec3 en = g.norm() > 0 ? Vec3(g.normalized()) : Vec3(Vec3::UnitX());
    Vec3 el = -(axis - axis.dot(en) * en);
    if (el.norm() < 1e-9) el = en.unitOrthogonal();
    el.normalize();
    const Vec3 ec = en.cross(el);
    const double alpha = (rule.endo_angle_deg + (rule.epi_angle_deg - rule.endo_angle_deg) * te) * kPi / 180.0;
    out.fiber[static_cast<size_t>(e)] = (std::cos(alpha) * ec + std::sin(alpha) * el).normalized();
    out.sheet[static_cast<size_t>(e)] = en;
    out.transmural[static_cast<size_t>(e)] = te;
  }
  return out;
}

std::vector<Vec3> interpolate_directions(const TetMesh& mesh, const std::vector<int>& nodes, const std::vector<Vec3>& directions) {
  check_nodes(mesh, nodes, "interpolate_directions");
  if (directions.size() != nodes.size())
    throw std::invalid_argument("interpolate_directions: " + std::to_string(directions.size()) + " directions for " +
                                std::to_string(nodes.size()) + " nodes");
  std::vector<int> sorted = nodes;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
    throw std::invalid_argument("interpolate_directions: a node is given twice");
  // Structure tensors d d^T as six components (xx, yy, zz, xy, yz, zx).
  Eigen::MatrixXd held(static_cast<Eigen::Index>(nodes.size()), 6);
  for (size_t k = 0; k < nodes.size(); ++k) {
    const Vec3& d = directions[k];
    if (!d.allFinite() || d.norm() < 1e-12)
      throw std::invalid_argument("interpolate_directions: direction " + std::to_string(k) + " (node " +
                                  std::to_string(nodes[k]) + ") is zero or not finite");
    const Vec3 u = d.normalized();
    held.row(static_cast<Eigen::Index>(k)) << u.x() * u.x(), u.y() * u.y(), u.z() * u.z(), u.x() * u.y(), u.y() * u.z(),
        u.z() * u.x();
  }
  const Eigen::MatrixXd T = harmonic_extension(mesh, nodes, held);
  std::vector<Vec3> out(static_cast<size_t>(mesh.num_elements()));
  for (int e = 0; e < mesh.num_elements(); ++e) {
    Eigen::Matrix<double, 1, 6> s = Eigen::Matrix<double, 1, 6>::Zero();
    for (int node : mesh.tets()[static_cast<size_t>(e)]) s += 0.25 * T.row(node);
    Mat3 M;
    M << s(0), s(3), s(5), s(3), s(1), s(4), s(5), s(4), s(2);
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(M);
    out[static_cast<size_t>(e)] = eig.eigenvectors().col(2).normalized();  // largest eigenvalue
  }
  return out;
}

double fiber_angle_deg(const Vec3& a, const Vec3& b) {
  const double c = std::min(1.0, std::abs(a.normalized().dot(b.normalized())));
  return std::acos(c) * 180.0 / kPi;
}

}  // namespace fiberfem::core
