// Residual and consistent tangent of the accurate tier (ACCURATE.md sections 1-2).

#include "core/hyperelastic/assembly.hpp"

#include "core/team_affinity.hpp"

#include "core/hyperelastic/quadrature.hpp"
#include "core/hyperelastic/shape_functions.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include <omp.h>

namespace fiberfem::core::hyperelastic {
namespace {

Mat3 skew(const Vec3& v) {
  Mat3 s;
  s << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return s;
}

}  // namespace

Assembler::Assembler(const Problem& problem) : problem_(problem), governor_(std::max(1, omp_get_max_threads())) {
  problem.validate();
  const ElementMesh& mesh = *problem.mesh;
  order_ = mesh.order();
  nodes_per_element_ = mesh.nodes_per_element();
  points_ = problem.points();
  num_nodes_ = mesh.num_nodes();
  const int ne = mesh.num_elements();

  // Free displacement components, node-major.
  free_eq_.assign(static_cast<size_t>(3 * num_nodes_), -1);
  for (int d = 0; d < 3 * num_nodes_; ++d)
    if (problem.fixed_dofs.empty() || !problem.fixed_dofs[static_cast<size_t>(d)]) free_eq_[static_cast<size_t>(d)] = num_free_u_++;

  // Pressure unknowns of incompressible elements: P1 on corners (order 2), P0 (order 1).
  pressures_per_element_ = problem.mixed() ? (order_ == 2 ? 4 : 1) : 0;
  pressure_eq_.assign(static_cast<size_t>(ne), {-1, -1, -1, -1});
  if (pressures_per_element_ > 0) {
    std::vector<int> corner_eq(static_cast<size_t>(mesh.num_corner_nodes()), -1);
    for (int e = 0; e < ne; ++e) {
      if (!problem.region_laws[static_cast<size_t>(problem.element_region[static_cast<size_t>(e)])].incompressible) continue;
      auto& pe = pressure_eq_[static_cast<size_t>(e)];
      if (pressures_per_element_ == 1) {
        pe[0] = num_free_u_ + num_pressures_++;
        continue;
      }
      for (int k = 0; k < 4; ++k) {
        int& c = corner_eq[static_cast<size_t>(mesh.elements()[static_cast<size_t>(e)][static_cast<size_t>(k)])];
        if (c < 0) c = num_free_u_ + num_pressures_++;
        pe[static_cast<size_t>(k)] = c;
      }
    }
  }

  // Quadrature data: dN/dX = dN/dxi J0^-1 with J0 = dX/dxi, and the weight times det J0.
  const TetRule& rule = tetrahedron_rule(points_);
  pressure_shape_.resize(static_cast<size_t>(points_));
  std::vector<TetShape> shapes(static_cast<size_t>(points_));
  for (int q = 0; q < points_; ++q) {
    const Eigen::Vector3d& xi = rule.points[static_cast<size_t>(q)];
    shapes[static_cast<size_t>(q)] = tet_shape(order_, xi);
    pressure_shape_[static_cast<size_t>(q)] =
        pressures_per_element_ == 4 ? Eigen::Vector4d(1 - xi.sum(), xi.x(), xi.y(), xi.z()) : Eigen::Vector4d(1, 0, 0, 0);
  }
  points_data_.resize(static_cast<size_t>(ne) * static_cast<size_t>(points_));
  body_force_ = Eigen::VectorXd::Zero(num_free_u_);
  const Positions& X = mesh.rest_positions();
  for (int e = 0; e < ne; ++e) {
    const auto& nodes = mesh.elements()[static_cast<size_t>(e)];
    for (int q = 0; q < points_; ++q) {
      const TetShape& sh = shapes[static_cast<size_t>(q)];
      Mat3 J0 = Mat3::Zero();
      for (int a = 0; a < nodes_per_element_; ++a) J0 += X.col(nodes[static_cast<size_t>(a)]) * sh.dN.row(a);
      const double det = J0.determinant();
      if (!(det > 0))
        throw std::invalid_argument("element " + std::to_string(e) + ": rest Jacobian " + std::to_string(det) +
                                    " is not positive at quadrature point " + std::to_string(q) +
                                    " (a curved element folded over; refine the mesh)");
      PointData& pd = points_data_[static_cast<size_t>(e * points_ + q)];
      pd.dNdX.setZero();
      pd.dNdX.topRows(nodes_per_element_) = sh.dN.topRows(nodes_per_element_) * J0.inverse();
      pd.dV = rule.weights[static_cast<size_t>(q)] * det;
      volume_ += pd.dV;
    }
  }
  build_pattern();
  build_colours();
  diagonal_slot_.resize(static_cast<size_t>(num_free_u_));
  for (int eq = 0; eq < num_free_u_; ++eq) {
    const int* inner = pattern_.innerIndexPtr();
    const int* at = std::lower_bound(inner + pattern_.outerIndexPtr()[eq], inner + pattern_.outerIndexPtr()[eq + 1], eq);
    diagonal_slot_[static_cast<size_t>(eq)] = static_cast<int>(at - inner);
  }

  std::vector<double> densities;
  for (int e = 0; e < ne; ++e)
    densities.push_back(problem.region_density_kg_m3.empty()
                            ? 0.0
                            : problem.region_density_kg_m3[static_cast<size_t>(problem.element_region[static_cast<size_t>(e)])]);
  masses_ = std::all_of(densities.begin(), densities.end(), [](double r) { return r > 0; }) ? lumped_masses(mesh, densities)
                                                                                            : Eigen::VectorXd::Zero(num_nodes_);
  // Gravity on the lumped masses (rho g times each node's mass): the load that a lumped
  // mass carries in free fall, so a body falls without deforming (at order 2 the
  // consistent load would put negative forces on the corners, against positive masses).
  for (int d = 0; d < 3 * num_nodes_; ++d) {
    const int eq = free_eq_[static_cast<size_t>(d)];
    if (eq >= 0) body_force_(eq) = masses_(d / 3) * problem.gravity_m_s2(d % 3);
  }
  // A load scale for convergence tests: the rest-shape load at factor 1.
  Eigen::VectorXd R = Eigen::VectorXd::Zero(num_equations());
  Eigen::VectorXd ext = -body_force_;
  ext.conservativeResize(num_equations());
  ext.tail(num_pressures_).setZero();
  Eigen::VectorXd faces = Eigen::VectorXd::Zero(num_equations());
  add_faces(X, Loading{}, faces, nullptr);
  double active = 0;
  for (double t : problem.active_tension_pa) active = std::max(active, std::abs(t));
  // Active tension has no external force; its scale is T_a times a face area.
  const double length = std::cbrt(std::max(volume_, 1e-300));
  reference_load_ = std::max({(ext + faces).head(num_free_u_).norm(), active * length * length, 1e-300});
}

// Elements are scattered in patches of up to 32 consecutive elements (patch_) (neighbours in a
// generated or meshed body, so one patch's writes to K stay in cache), and patches are
// coloured greedily: each takes the first colour that no patch sharing a node with it has.
// Patches of one colour write disjoint equations, so they scatter without atomics, and
// every entry of R and K is summed in the same order (colour, patch, element) whatever
// the thread count. The patch size depends on the mesh alone, never on the threads.
void Assembler::build_colours() {
  const ElementMesh& mesh = *problem_.mesh;
  const int ne = mesh.num_elements();
  patch_ = std::clamp(ne / 128, 1, 32);  // at least ~128 patches to share among threads
  std::vector<std::vector<int>> node_colours(static_cast<size_t>(num_nodes_));
  std::vector<int> patch_nodes;
  for (int first = 0; first < ne; first += patch_) {
    const int last = std::min(first + patch_, ne);
    patch_nodes.clear();
    for (int e = first; e < last; ++e) {
      const auto& nodes = mesh.elements()[static_cast<size_t>(e)];
      patch_nodes.insert(patch_nodes.end(), nodes.begin(), nodes.begin() + nodes_per_element_);
    }
    std::sort(patch_nodes.begin(), patch_nodes.end());
    patch_nodes.erase(std::unique(patch_nodes.begin(), patch_nodes.end()), patch_nodes.end());
    std::vector<char> taken(colours_.size() + 1, 0);
    for (int node : patch_nodes)
      for (int c : node_colours[static_cast<size_t>(node)]) taken[static_cast<size_t>(c)] = 1;
    const int colour = static_cast<int>(std::find(taken.begin(), taken.end(), 0) - taken.begin());
    if (colour == static_cast<int>(colours_.size())) colours_.emplace_back();
    colours_[static_cast<size_t>(colour)].push_back(first / patch_);
    for (int node : patch_nodes) node_colours[static_cast<size_t>(node)].push_back(colour);
  }
}

void Assembler::build_pattern() {
  const ElementMesh& mesh = *problem_.mesh;
  const int ne = mesh.num_elements();
  local_size_ = 3 * nodes_per_element_ + pressures_per_element_;
  auto local_equations = [&](int e, std::vector<int>& eqs) {
    eqs.clear();
    const auto& nodes = mesh.elements()[static_cast<size_t>(e)];
    for (int a = 0; a < nodes_per_element_; ++a)
      for (int i = 0; i < 3; ++i) eqs.push_back(equation_of_dof(3 * nodes[static_cast<size_t>(a)] + i));
    for (int m = 0; m < pressures_per_element_; ++m) eqs.push_back(pressure_eq_[static_cast<size_t>(e)][static_cast<size_t>(m)]);
  };
  std::vector<Eigen::Triplet<double, int>> triplets;
  triplets.reserve(static_cast<size_t>(ne) * static_cast<size_t>(local_size_ * local_size_));
  std::vector<int> eqs;
  for (int e = 0; e < ne; ++e) {
    local_equations(e, eqs);
    for (int r : eqs)
      for (int c : eqs)
        if (r >= 0 && c >= 0) triplets.emplace_back(r, c, 0.0);
  }
  pattern_.resize(num_equations(), num_equations());
  pattern_.setFromTriplets(triplets.begin(), triplets.end());
  pattern_.makeCompressed();
  // Value index of every local (row, col) pair, by a search in the column's sorted rows.
  slots_.assign(static_cast<size_t>(ne) * static_cast<size_t>(local_size_ * local_size_), -1);
  const int* outer = pattern_.outerIndexPtr();
  const int* inner = pattern_.innerIndexPtr();
  for (int e = 0; e < ne; ++e) {
    local_equations(e, eqs);
    for (int j = 0; j < local_size_; ++j) {
      const int c = eqs[static_cast<size_t>(j)];
      if (c < 0) continue;
      for (int i = 0; i < local_size_; ++i) {
        const int r = eqs[static_cast<size_t>(i)];
        if (r < 0) continue;
        const int* pos = std::lower_bound(inner + outer[c], inner + outer[c + 1], r);
        slots_[static_cast<size_t>(e) * static_cast<size_t>(local_size_ * local_size_) + static_cast<size_t>(j * local_size_ + i)] =
            static_cast<int>(pos - inner);
      }
    }
  }
}

// Internal force and tangent per quadrature point (total Lagrangian):
//   R_ai  += P_iJ dN_a/dX_J dV
//   K_ai,bk += dN_a/dX_J A_iJ,kL dN_b/dX_L dV
// Mixed pressure p = sum_m psi_m p_m (P = P_iso - p J F^-T):
//   R_m   -= psi_m (J - 1) dV,   K_ai,m = K_m,ai -= Cof_iJ dN_a/dX_J psi_m dV.
Evaluation Assembler::evaluate(const Positions& x, const Eigen::VectorXd& p, const Loading& loading, Eigen::VectorXd& R,
                               SparseMatrix* K) const {
  const ElementMesh& mesh = *problem_.mesh;
  const int ne = mesh.num_elements();
  R.setZero(num_equations());
  R.head(num_free_u_) -= loading.body_factor * body_force_;
  if (K != nullptr) {
    if (K->nonZeros() != pattern_.nonZeros() || K->rows() != pattern_.rows()) *K = pattern_;
    std::fill(K->valuePtr(), K->valuePtr() + K->nonZeros(), 0.0);
  }
  const bool per_point_axes = problem_.axes.size() == static_cast<size_t>(ne) * static_cast<size_t>(points_);
  const int n = nodes_per_element_;
  const int ls = local_size_;
  Evaluation ev;
  double energy = 0;
  int inverted = 0;
  // Tangent evaluations are the comparable steps the governor measures; residual-only
  // ones (the line search) run on its current count.
  const int threads = threads_ > 0 ? threads_ : governor_.threads();
  const auto t0 = std::chrono::steady_clock::now();
  const int cpu = current_cpu();
#pragma omp parallel num_threads(threads) reduction(+ : energy, inverted)
  {
    keep_team_apart(cpu);
    Eigen::VectorXd Rl(ls);
    Eigen::MatrixXd Kl(ls, ls);
    Eigen::Matrix<double, 10, 3> xe;
    for (const std::vector<int>& colour : colours_) {
#pragma omp for schedule(static)
    for (int i = 0; i < static_cast<int>(colour.size()); ++i) {
    const int first = colour[static_cast<size_t>(i)] * patch_;
    for (int e = first; e < std::min(first + patch_, ne); ++e) {
      const auto& nodes = mesh.elements()[static_cast<size_t>(e)];
      const LawParameters& law =
          problem_.region_laws[static_cast<size_t>(problem_.element_region[static_cast<size_t>(e)])];
      const double tension = loading.active_tension_pa ? (*loading.active_tension_pa)[static_cast<size_t>(e)]
                              : problem_.active_tension_pa.empty()
                                  ? 0.0
                                  : loading.active_factor * problem_.active_tension_pa[static_cast<size_t>(e)];
      for (int a = 0; a < n; ++a) xe.row(a) = x.col(nodes[static_cast<size_t>(a)]).transpose();
      Rl.setZero();
      if (K != nullptr) Kl.setZero();
      bool element_inverted = false;
      for (int q = 0; q < points_; ++q) {
        const PointData& pd = points_data_[static_cast<size_t>(e * points_ + q)];
        const Mat3 F = xe.topRows(n).transpose() * pd.dNdX.topRows(n);
        const double J = F.determinant();
        if (!(J > 0)) {
          element_inverted = true;
          continue;
        }
        const MaterialAxes& ax = problem_.axes.empty() ? MaterialAxes{}
                                 : per_point_axes     ? problem_.axes[static_cast<size_t>(e * points_ + q)]
                                                      : problem_.axes[static_cast<size_t>(e)];
        Response r = isochoric_response(law, ax, F, K != nullptr);
        double pq = 0;
        const Eigen::Vector4d& psi = pressure_shape_[static_cast<size_t>(q)];
        if (law.incompressible) {
          for (int m = 0; m < pressures_per_element_; ++m) pq += psi(m) * p(pressure_eq_[static_cast<size_t>(e)][static_cast<size_t>(m)] - num_free_u_);
          add_volumetric_stress(-pq, 0.0, F, r, K != nullptr);
        } else {
          const Volumetric v = volumetric_penalty(law.bulk_modulus_pa, J);
          r.energy_j_m3 += v.U;
          add_volumetric_stress(v.dU, v.d2U, F, r, K != nullptr);
        }
        if (tension != 0) add_active_stress(tension, ax.f, F, r, K != nullptr);
        energy += r.energy_j_m3 * pd.dV;
        // Displacement rows: P : grad N_a.
        const Eigen::Matrix<double, 10, 3> PdN = pd.dNdX * r.P.transpose();  // row a: (P dN_a)^T
        for (int a = 0; a < n; ++a) Rl.segment<3>(3 * a) += pd.dV * PdN.row(a).transpose();
        Mat3 cof;
        if (law.incompressible) {
          cof = cofactor(F);
          for (int m = 0; m < pressures_per_element_; ++m) Rl(3 * n + m) -= psi(m) * (J - 1) * pd.dV;
        }
        if (K == nullptr) continue;
        // B_b(iJ, k) = sum_L A(iJ, kL) dN_b/dX_L, then K_ab(i, k) = sum_J dN_a/dX_J B_b(iJ, k).
        // A has major symmetry (A(iJ, kL) = A(kL, iJ): every term is a second derivative of
        // an energy), so K_ba = K_ab^T: the blocks a <= b here, the rest mirrored below.
        for (int b = 0; b < n; ++b) {
          Eigen::Matrix<double, 9, 3> B;
          for (int k = 0; k < 3; ++k)
            B.col(k) = r.A.col(k) * pd.dNdX(b, 0) + r.A.col(k + 3) * pd.dNdX(b, 1) + r.A.col(k + 6) * pd.dNdX(b, 2);
          for (int a = 0; a <= b; ++a) {
            const Eigen::Matrix<double, 3, 3> Kab = (B.topRows<3>() * pd.dNdX(a, 0) + B.middleRows<3>(3) * pd.dNdX(a, 1) +
                                                     B.bottomRows<3>() * pd.dNdX(a, 2));
            Kl.block<3, 3>(3 * a, 3 * b) += pd.dV * Kab;
          }
        }
        if (law.incompressible) {
          // Column 3n + m: -psi_m dV Cof dN_a in rows 3a..3a+2 (the rows of cdN laid end
          // to end); the symmetric row is mirrored below.
          const Eigen::Matrix<double, 10, 3, Eigen::RowMajor> cdN = pd.dNdX * cof.transpose();
          const Eigen::Map<const Eigen::VectorXd> c(cdN.data(), 3 * n);
          for (int m = 0; m < pressures_per_element_; ++m) Kl.col(3 * n + m).head(3 * n) -= (psi(m) * pd.dV) * c;
        }
      }
      if (element_inverted) {
        ++inverted;
        continue;
      }
      if (K != nullptr) {
        for (int b = 1; b < n; ++b)
          for (int a = 0; a < b; ++a) Kl.block<3, 3>(3 * b, 3 * a) = Kl.block<3, 3>(3 * a, 3 * b).transpose();
        for (int m = 0; m < pressures_per_element_; ++m) Kl.row(3 * n + m).head(3 * n) = Kl.col(3 * n + m).head(3 * n).transpose();
      }
      // Scatter.
      for (int a = 0; a < n; ++a)
        for (int i = 0; i < 3; ++i) {
          const int eq = equation_of_dof(3 * nodes[static_cast<size_t>(a)] + i);
          if (eq >= 0) R(eq) += Rl(3 * a + i);
        }
      for (int m = 0; m < pressures_per_element_; ++m) {
        const int eq = pressure_eq_[static_cast<size_t>(e)][static_cast<size_t>(m)];
        if (eq >= 0) R(eq) += Rl(3 * n + m);
      }
      if (K == nullptr) continue;
      const int* slot = &slots_[static_cast<size_t>(e) * static_cast<size_t>(ls * ls)];
      double* values = K->valuePtr();
      for (int j = 0; j < ls; ++j)
        for (int i = 0; i < ls; ++i) {
          const int s = slot[j * ls + i];
          if (s < 0) continue;
          values[s] += Kl(i, j);
        }
    }  // the patch's elements
    }  // the for's barrier: a colour is complete before the next one starts
    }
  }
  if (threads_ == 0 && K != nullptr)
    governor_.record(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), true);
  ev.energy_j = energy;
  ev.inverted_elements = inverted;
  add_faces(x, loading, R, K);
  if (loading.nodal_forces_n != nullptr) {
    const double* f = loading.nodal_forces_n->data();
    for (int d = 0; d < 3 * num_nodes_; ++d) {
      const int eq = free_eq_[static_cast<size_t>(d)];
      if (eq >= 0) R(eq) -= f[d];
    }
  }
  ev.finite = R.allFinite();
  return ev;
}

// Pressure on a face (ACCURATE.md section 2): with the face parametrised by the reference
// triangle, n = x_xi x x_eta is its outward area vector, and the pressure's force on node a
// is -p integral N_a n. The residual R = f_int - f_ext gains +p N_a n w per point; for a
// follower load the tangent gains dR_a/dx_b = p N_a (N_b,eta [x_xi]x - N_b,xi [x_eta]x) w.
void Assembler::add_faces(const Positions& x, const Loading& loading, Eigen::VectorXd& R, SparseMatrix* K) const {
  if (problem_.pressures.empty()) return;
  const ElementMesh& mesh = *problem_.mesh;
  const int nf = triangle_nodes(order_);
  const TriangleRule& rule = triangle_rule(order_ == 1 ? 3 : 6);
  for (size_t i = 0; i < problem_.pressures.size(); ++i) {
    const PressureLoad& load = problem_.pressures[i];
    const double p = loading.pressure_factor * (loading.pressure_factors.empty() ? 1.0 : loading.pressure_factors[i]) * load.pressure_pa;
    if (p == 0) continue;
    const Positions& at = load.follower ? x : mesh.rest_positions();
    for (int f : load.faces) {
      const auto& nodes = mesh.boundary_faces()[static_cast<size_t>(f)];
      Eigen::Matrix<double, 18, 18> Kf = Eigen::Matrix<double, 18, 18>::Zero();
      for (size_t q = 0; q < rule.weights.size(); ++q) {
        const TriangleShape sh = triangle_shape(order_, rule.points[q]);
        Vec3 x_xi = Vec3::Zero(), x_eta = Vec3::Zero();
        for (int a = 0; a < nf; ++a) {
          x_xi += at.col(nodes[static_cast<size_t>(a)]) * sh.dN(a, 0);
          x_eta += at.col(nodes[static_cast<size_t>(a)]) * sh.dN(a, 1);
        }
        const Vec3 normal = x_xi.cross(x_eta);
        const double w = rule.weights[q];
        for (int a = 0; a < nf; ++a)
          for (int i = 0; i < 3; ++i) {
            const int eq = equation_of_dof(3 * nodes[static_cast<size_t>(a)] + i);
            if (eq >= 0) R(eq) += p * sh.N(a) * normal(i) * w;
          }
        if (K == nullptr || !load.follower) continue;
        const Mat3 sxi = skew(x_xi), seta = skew(x_eta);
        for (int a = 0; a < nf; ++a)
          for (int b = 0; b < nf; ++b)
            Kf.block<3, 3>(3 * a, 3 * b) += p * w * sh.N(a) * (sh.dN(b, 1) * sxi - sh.dN(b, 0) * seta);
      }
      if (K == nullptr || !load.follower) continue;
      for (int a = 0; a < nf; ++a)
        for (int b = 0; b < nf; ++b)
          for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k) {
              const int r = equation_of_dof(3 * nodes[static_cast<size_t>(a)] + i);
              const int c = equation_of_dof(3 * nodes[static_cast<size_t>(b)] + k);
              if (r >= 0 && c >= 0) K->coeffRef(r, c) += Kf(3 * a + i, 3 * b + k);
            }
    }
  }
}

// Backward Euler in positions (ACCURATE.md section 4): v1 = (x1 - x0)/h, and
// M (v1 - v0)/h + alpha M v1 = M (c (x1 - x0) - v0/h) with c = 1/h^2 + alpha/h.
void Assembler::add_inertia(const Positions& x, const Positions& x0, const Positions& v0, double h_s, double alpha_1_s,
                            Eigen::VectorXd& R, SparseMatrix* K) const {
  const double c = 1.0 / (h_s * h_s) + alpha_1_s / h_s;
  for (int d = 0; d < 3 * num_nodes_; ++d) {
    const int eq = free_eq_[static_cast<size_t>(d)];
    if (eq < 0) continue;
    const double m = masses_(d / 3);
    R(eq) += m * (c * (x.data()[d] - x0.data()[d]) - v0.data()[d] / h_s);
    if (K != nullptr) K->valuePtr()[diagonal_slot_[static_cast<size_t>(eq)]] += c * m;
  }
}

Eigen::VectorXd Assembler::unit_pressure_residual(const Positions& x, int k) const {
  Loading unit;
  unit.pressure_factors.assign(problem_.pressures.size(), 0.0);
  unit.pressure_factors.at(static_cast<size_t>(k)) = 1.0 / problem_.pressures[static_cast<size_t>(k)].pressure_pa;
  Eigen::VectorXd R = Eigen::VectorXd::Zero(num_equations());
  add_faces(x, unit, R, nullptr);
  return R;
}

Eigen::VectorXd Assembler::equation_rows(const Positions& field) const {
  Eigen::VectorXd r = Eigen::VectorXd::Zero(num_equations());
  for (int d = 0; d < 3 * num_nodes_; ++d) {
    const int eq = free_eq_[static_cast<size_t>(d)];
    if (eq >= 0) r(eq) = field.data()[d];
  }
  return r;
}

void Assembler::add_increment(const Eigen::VectorXd& delta, double alpha, Positions& x, Eigen::VectorXd& p) const {
  for (int d = 0; d < 3 * num_nodes_; ++d) {
    const int eq = free_eq_[static_cast<size_t>(d)];
    if (eq >= 0) x.data()[d] += alpha * delta(eq);
  }
  if (num_pressures_ > 0) p += alpha * delta.tail(num_pressures_);
}

}  // namespace fiberfem::core::hyperelastic
