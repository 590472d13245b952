#include "core/corotated_linear_model.hpp"

#include "core/element.hpp"
#include "core/parallel.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace fiberfem::core {

CorotatedLinearModel::CorotatedLinearModel(const Model& model, std::vector<int> block_nodes,
                                           const std::vector<int>& element_order)
    : mesh_(model.mesh), order_(element_order), block_node_(std::move(block_nodes)) {
  const int ne = mesh_.num_elements();
  if (static_cast<int>(order_.size()) != ne) throw std::invalid_argument("CorotatedLinearModel: element order of the wrong size");
  position_.assign(static_cast<size_t>(ne), -1);
  for (size_t k = 0; k < order_.size(); ++k) position_[static_cast<size_t>(order_[k])] = static_cast<int>(k);
  elements_.resize(static_cast<size_t>(ne));
  tets_.resize(static_cast<size_t>(ne));
  region_.resize(static_cast<size_t>(ne));
  beta_.assign(static_cast<size_t>(ne), 0.0);
  parallel_for(ne, [&](int kk) {
    const size_t k = static_cast<size_t>(kk), i = static_cast<size_t>(order_[k]);
    const Vec12 X = gather(mesh_.rest_positions(), mesh_.tets()[i]);
    for (int j = 0; j < 3; ++j) elements_[k].Dm.col(j) = X.segment<3>(3 * (j + 1)) - X.segment<3>(0);
    // Out of line (core/element.cpp): inlined here, the compiler contracts the 3 x 3
    // inverse into FMAs differently in parallel_for's serial and threaded loops, and the
    // bits would depend on the thread count.
    elements_[k].Dm_inv = rest_shape_inverse(X);
    elements_[k].fiber = model.fibers[i];
    elements_[k].volume = mesh_.rest_volume(order_[k]);
    tets_[k] = mesh_.tets()[i];
    region_[k] = mesh_.regions()[i];
    if (!model.region_damping.empty()) beta_[k] = model.region_damping[static_cast<size_t>(region_[k])].stiffness_s;
  });
  for (const Material& m : model.region_materials) region_law_.push_back(SpencerConstants::of(m));
  // The elements around each node (CSR), for the node-block rotations.
  const int nn = mesh_.num_nodes();
  node_elem_start_.assign(static_cast<size_t>(nn) + 1, 0);
  for (const Tet& t : mesh_.tets())
    for (int n : t) ++node_elem_start_[static_cast<size_t>(n) + 1];
  for (int n = 0; n < nn; ++n) node_elem_start_[static_cast<size_t>(n) + 1] += node_elem_start_[static_cast<size_t>(n)];
  node_elems_.resize(static_cast<size_t>(node_elem_start_.back()));
  std::vector<int> fill(node_elem_start_.begin(), node_elem_start_.end() - 1);
  for (int e = 0; e < ne; ++e)  // in element order (the sums' order), holding loop positions
    for (int n : mesh_.tets()[static_cast<size_t>(e)])
      node_elems_[static_cast<size_t>(fill[static_cast<size_t>(n)]++)] = position_[static_cast<size_t>(e)];
}

// Ds - Dm of the element at loop position k at positions x (its edges' displacements), m.
Mat3 CorotatedLinearModel::element_edges(const Eigen::VectorXd& x, size_t k) const {
  const Tet& t = tets_[k];
  const Mat3& Dm = elements_[k].Dm;
  Mat3 D;
  const Vec3 x0 = x.segment<3>(3 * t[0]);
  for (int j = 0; j < 3; ++j) D.col(j) = (x.segment<3>(3 * t[static_cast<size_t>(j + 1)]) - x0) - Dm.col(j);
  return D;
}

// Deformation gradient of the element at loop position k at positions x, as
// F = I + (Ds - Dm) Dm^-1: the round-off is relative to the displacement (F is exactly I
// at rest, where Ds Dm^-1 would leave 1e-16 of strain and a non-zero energy).
Mat3 CorotatedLinearModel::element_gradient(const Eigen::VectorXd& x, size_t k) const {
  Mat3 F = element_edges(x, k) * elements_[k].Dm_inv;
  F.diagonal().array() += 1.0;
  return F;
}

// Rotations of the elements at loop positions first .. first + n - 1 (n <= 8) from their
// F into st.R (and the warm-start st.q); returns how many are inverted (det F <= 0).
int CorotatedLinearModel::rotate_elements(const ElementPass& pass, SimulatorState& st, int first, int n, const Mat3* F) {
  int inverted = 0;
  for (int l = 0; l < n; ++l) inverted += F[l].determinant() <= 0 ? 1 : 0;
  const size_t k0 = static_cast<size_t>(first);
  if (!pass.corotation) {
    for (int l = 0; l < n; ++l) st.R[k0 + static_cast<size_t>(l)] = Mat3::Identity();
  } else if (pass.rotation == RotationMethod::polar) {
    Eigen::Quaterniond* q[ElementBatch::kWidth];
    Mat3* R[ElementBatch::kWidth];
    for (int l = 0; l < n; ++l) {
      q[l] = &st.q[k0 + static_cast<size_t>(l)];
      R[l] = &st.R[k0 + static_cast<size_t>(l)];
    }
    for (int l0 = 0; l0 < n; l0 += 4)  // four lanes at a time (more wait for the slowest lane)
      rotation_polar_batch(F + l0, q + l0, R + l0, std::min(4, n - l0), pass.polar_tolerance_rad);
  } else {
    for (int l = 0; l < n; ++l) st.R[k0 + static_cast<size_t>(l)] = rotation_svd(F[l]);
  }
  return inverted;
}

// What linearised backward Euler (PHYSICS.md section 5) needs of element e at the current
// positions: its rotation R, the elastic force f_el = -R K^e (R^T x - X) = -V R sigma g_a,
// the active force -T_a R g^e (section 6), the energy V sigma : eps / 2 and the warped
// blocks (h beta_e + h^2) R K^e R^T.
double CorotatedLinearModel::assemble(const ElementPass& pass, SimulatorState& st, SparseSystem& sys, Eigen::VectorXd& f,
                                      Eigen::VectorXd& f_active) {
  const double h = pass.h_s;
  const Eigen::VectorXd& x = st.x;
  // Sums per chunk of the loop, added in chunk order below: the same bits on any thread count.
  acc_.resize(static_cast<size_t>(sys.num_chunks()));  // no allocation after the first step
  std::fill(acc_.begin(), acc_.end(), ChunkAcc{});
  std::vector<ChunkAcc>& acc = acc_;
  const bool rest_frame_active = pass.rest_frame_active;
  f.setZero(sys.num_dofs());  // (assemble_batched replaces the matrix values)
  const bool active = !st.active_tension_pa.empty();
  // The active forces' own vector is needed only for the energy check's work balance.
  const bool track_active_work = active && pass.track_active_work;
  if (track_active_work) f_active.setZero(sys.num_dofs());
  // One pass per element (rotations fused in unless the last step's check computed them):
  // F, R, the corotated strain's stress, forces, energy and the warped blocks in closed
  // form (core/spencer_element.hpp: no stored 12 x 12 K^e is read).
  const bool need_rotations = !st.rotations_current;
  constexpr int W = ElementBatch::kWidth;
  static_assert(W <= 8, "rotate_elements takes at most eight elements");
  using Lanes = double __attribute__((vector_size(W * sizeof(double))));
  sys.assemble_batched(
      [&](const int* elems, int n, ElementBatch& batch) {
        ChunkAcc& my = acc[static_cast<size_t>(batch.chunk)];
        // Lanes past n repeat the last element (computed, never scattered). The model's
        // per-element data and the state's rotations are read at the loop position (in
        // sequence), the active tension at the element.
        size_t lane_pos[W];
        for (int l = 0; l < W; ++l) lane_pos[l] = static_cast<size_t>(batch.first + std::min(l, n - 1));
        Mat3 D[W], F[W];
        for (int l = 0; l < W; ++l) {
          D[l] = element_edges(x, lane_pos[l]);
          if (l < n) {
            F[l].noalias() = D[l] * elements_[lane_pos[l]].Dm_inv;
            F[l].diagonal().array() += 1.0;
          }
        }
        if (need_rotations) my.inverted += rotate_elements(pass, st, batch.first, n, F);
        Lanes kv[5], cl, Rl[9], Dil[9], Dl[9], fl[3];
        for (int l = 0; l < W; ++l) {
          const size_t k = lane_pos[l];
          const SpencerElement& el = elements_[k];
          const SpencerConstants& law = region_law_[static_cast<size_t>(region_[k])];
          kv[0][l] = el.volume * law.lambda;
          kv[1][l] = el.volume * law.mu_t;
          kv[2][l] = el.volume * law.alpha;
          kv[3][l] = el.volume * law.gamma;
          kv[4][l] = el.volume * law.beta;
          cl[l] = h * beta_[k] + h * h;
          const Mat3& R = st.R[k];
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) {
              Rl[3 * r + c][l] = R(r, c);
              Dil[3 * r + c][l] = el.Dm_inv(r, c);
              Dl[3 * r + c][l] = D[l](r, c);
            }
          for (int c = 0; c < 3; ++c) fl[c][l] = el.fiber(c);
        }
        // Forces -V R sigma g_a and energies of all lanes at once.
        Lanes fel[12], energy;
        spencer_force_lanes(kv, Rl, Dil, Dl, fl, fel, energy);
        for (int l = 0; l < n; ++l) {
          Vec12& fe = batch.force[l];
          for (int c = 0; c < 12; ++c) fe(c) = fel[c][l];
          my.energy += energy[l];
        }
        if (active)
          for (int l = 0; l < n; ++l) {
            // g^e_a = V f (f . g_a) (PHYSICS.md section 6): the active force is
            // -T_a V (R f)(f . g_a), or along the rest fiber f in the paper's nodal mode.
            const size_t i = static_cast<size_t>(elems[l]), k = lane_pos[l];
            const SpencerElement& el = elements_[k];
            Vec12& fe = batch.force[l];
            const Vec3 dir = rest_frame_active ? el.fiber : Vec3(st.R[k] * el.fiber);
            const Vec3 s123 = el.Dm_inv * el.fiber;  // f . g_a, a = 1..3
            const double sa[4] = {-(s123(0) + s123(1) + s123(2)), s123(0), s123(1), s123(2)};
            const double tv = st.active_tension_pa[i] * el.volume;
            const Tet& t = tets_[k];
            for (int a = 0; a < 4; ++a) {
              const Vec3 fa = (-tv * sa[a]) * dir;
              fe.segment<3>(3 * a) += fa;
              if (track_active_work) f_active.segment<3>(3 * t[static_cast<size_t>(a)]) += fa;
            }
          }
        // The warped stiffness of all lanes at once: c R K^e R^T (core/spencer_element.hpp).
        Lanes k[5];
        for (int j = 0; j < 5; ++j) k[j] = cl * kv[j];
        Lanes out[90];
        spencer_upper_blocks(k, Rl, Dil, fl, out);
        std::memcpy(batch.upper, out, sizeof out);
      },
      f);
  if (need_rotations) {
    int inverted_sum = 0;
    for (const ChunkAcc& a : acc) inverted_sum += a.inverted;
    st.inverted_current = inverted_sum;
  }
  st.rotations_current = true;
  double elastic = 0;
  for (const ChunkAcc& c : acc) elastic += c.energy;
  return elastic;
}

double CorotatedLinearModel::elastic_energy(const Eigen::VectorXd& x, bool corotation) const {
  const int ne = mesh_.num_elements();
  return fixed_sum(ne, true, [&](int e) {  // in element order, as before the data was stored by position
    const size_t k = static_cast<size_t>(position_[static_cast<size_t>(e)]);
    const Mat3 F = element_gradient(x, k);
    const Mat3 R = corotation ? rotation_svd(F) : Mat3::Identity();
    return spencer_energy(region_law_[static_cast<size_t>(region_[k])], elements_[k], R, F);
  });
}

int CorotatedLinearModel::count_inverted(const Eigen::VectorXd& x) const {
  int count = 0;
  for (size_t k = 0; k < elements_.size(); ++k)
    if (element_gradient(x, k).determinant() <= 0) ++count;
  return count;
}

void CorotatedLinearModel::seed_rotations(SimulatorState& st, bool corotation) const {
  // Exact, by SVD: the warm-started polar iteration starts from these.
  const int ne = mesh_.num_elements();
  parallel_for(ne, [&](int kk) {
    const size_t k = static_cast<size_t>(kk);
    const Mat3 F = element_gradient(st.x, k);
    st.R[k] = corotation ? rotation_svd(F) : Mat3::Identity();
    st.q[k] = Eigen::Quaterniond(st.R[k]);
  });
}

// Rotation of each node block: the rotation nearest the sum of the rotations of the
// elements around the node (warm-started polar extraction). Only the warp preconditioner
// uses it.
void CorotatedLinearModel::update_node_rotations(SimulatorState& st, bool corotation) const {
  const int nb = static_cast<int>(block_node_.size());
  if (!corotation) {
    std::fill(st.block_R.begin(), st.block_R.end(), Mat3::Identity());
    return;
  }
  const int nbatch = (nb + 3) / 4;  // four blocks at a time (rotation_polar_batch)
  parallel_for(nbatch, [&](int b) {
    const int n4 = std::min(4, nb - 4 * b);
    Mat3 sum[4];
    Eigen::Quaterniond* q[4];
    Mat3* R[4];
    for (int l = 0; l < n4; ++l) {
      const size_t k = static_cast<size_t>(4 * b + l);
      const int n = block_node_[k];
      sum[l].setZero();
      for (int j = node_elem_start_[static_cast<size_t>(n)]; j < node_elem_start_[static_cast<size_t>(n) + 1]; ++j)
        sum[l] += st.R[static_cast<size_t>(node_elems_[static_cast<size_t>(j)])];
      q[l] = &st.block_q[k];
      R[l] = &st.block_R[k];
    }
    rotation_polar_batch(sum, q, R, n4, 1e-6);
  });
}

void CorotatedLinearModel::set_region_material(int region, const Material& material) {
  region_law_[static_cast<size_t>(region)] = SpencerConstants::of(material);
}

void CorotatedLinearModel::set_region_stiffness_damping(int region, double beta_s) {
  for (size_t k = 0; k < region_.size(); ++k)
    if (region_[k] == region) beta_[k] = beta_s;
}

void CorotatedLinearModel::set_fiber(int e, const Vec3& unit_fiber) {
  elements_[static_cast<size_t>(position_[static_cast<size_t>(e)])].fiber = unit_fiber;
}

}  // namespace fiberfem::core
