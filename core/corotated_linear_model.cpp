#include "core/corotated_linear_model.hpp"

#include "core/element.hpp"
#include "core/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <utility>

#ifdef __AVX512F__
#include <immintrin.h>
#endif

namespace fiberfem::core {

namespace {

// Eight doubles, one per lane; may alias doubles (the pass writes a batch's blocks in place).
using Lanes8 = double __attribute__((vector_size(8 * sizeof(double)), __may_alias__));

// xa[a][r] = coordinate r of corner a of each lane (x at node3[a][lane] + r).
void gather_corners(const double* x, const int (*node3)[8], Lanes8 (&xa)[4][3]) {
  for (int a = 0; a < 4; ++a) {
#ifdef __AVX512F__
    const __m256i idx = _mm256_load_si256(reinterpret_cast<const __m256i*>(node3[a]));
    for (int r = 0; r < 3; ++r) {
      const __m512d v = _mm512_i32gather_pd(idx, x + r, 8);
      std::memcpy(&xa[a][r], &v, sizeof v);
    }
#else
    for (int r = 0; r < 3; ++r)
      for (int l = 0; l < 8; ++l) xa[a][r][l] = x[node3[a][l] + r];
#endif
  }
}

// Rl[3 r + c] = R(r, c) of each lane's rotation: R0 points at lane 0's (column-major 3 x 3
// matrices in sequence); lanes past n repeat lane n - 1's.
void gather_rotations(const double* R0, int n, Lanes8 (&Rl)[9]) {
  alignas(32) int base[8];
  for (int l = 0; l < 8; ++l) base[l] = 9 * std::min(l, n - 1);
#ifdef __AVX512F__
  const __m256i idx = _mm256_load_si256(reinterpret_cast<const __m256i*>(base));
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      const __m512d v = _mm512_i32gather_pd(idx, R0 + 3 * c + r, 8);
      std::memcpy(&Rl[3 * r + c], &v, sizeof v);
    }
#else
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      for (int l = 0; l < 8; ++l) Rl[3 * r + c][l] = R0[base[l] + 3 * c + r];
#endif
}

// (The helpers take and give lanes through references: passed by value, a vector of eight
// doubles changes the calling convention between builds with and without AVX-512.)

// out = a * b + c, rounded once.
void fma8(const Lanes8& a, const Lanes8& b, const Lanes8& c, Lanes8& out) {
#ifdef __AVX512F__
  out = reinterpret_cast<Lanes8>(
      _mm512_fmadd_pd(reinterpret_cast<__m512d>(a), reinterpret_cast<__m512d>(b), reinterpret_cast<__m512d>(c)));
#else
  for (int l = 0; l < 8; ++l) out[l] = std::fma(a[l], b[l], c[l]);
#endif
}

// out = a * b rounded on its own (never fused into a sum that uses it).
void product8(const Lanes8& a, const Lanes8& b, Lanes8& out) {
#ifdef __AVX512F__
  out = a * b;
  asm("" : "+v"(out));
#else
  for (int l = 0; l < 8; ++l) {
    volatile double p = a[l] * b[l];
    out[l] = p;
  }
#endif
}

// out = row r of a 3 x 3 product, the sum over k of m[k] v[k], fused in the order GCC
// compiles Eigen's fixed-size 3 x 3 products for AVX-512 (k = 0, 1, 2 in rows 0 and 1;
// k = 1, 2, 0 in row 2): there the pass's lanes round as the scalar code's Eigen products
// (element_gradient's F, the active force's R f and Dm^-1 f), bit for bit.
void row3(int r, const Lanes8* m, const Lanes8* v, Lanes8& out) {
  Lanes8 t;
  if (r < 2) {
    fma8(m[1], v[1], m[0] * v[0], t);
    fma8(m[2], v[2], t, out);
  } else {
    fma8(m[2], v[2], m[1] * v[1], t);
    fma8(m[0], v[0], t, out);
  }
}

// F = I + D Dm^-1 of lanes 0..n-1 (D and Dm^-1 row-major, lanes).
void gradients(const Lanes8 (&D)[9], const Lanes8 (&Dinv)[9], int n, Mat3* F) {
  for (int c = 0; c < 3; ++c) {
    const Lanes8 col[3] = {Dinv[c], Dinv[3 + c], Dinv[6 + c]};
    for (int r = 0; r < 3; ++r) {
      Lanes8 v;
      row3(r, D + 3 * r, col, v);
      if (r == c) v += 1.0;
      for (int l = 0; l < n; ++l) F[l](r, c) = v[l];
    }
  }
}

// out = M v for M row-major (lanes).
void matvec3(const Lanes8 (&M)[9], const Lanes8 (&v)[3], Lanes8 (&out)[3]) {
  for (int r = 0; r < 3; ++r) row3(r, M + 3 * r, v, out[r]);
}

}  // namespace

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
  });
  for (const Material& m : model.region_materials) region_law_.push_back(SpencerConstants::of(m));
  static_assert(ElementBatch::kWidth == 8, "ElementLanes holds eight lanes");
  lanes_.resize(static_cast<size_t>((ne + 7) / 8));
  for (size_t k = 0; k < static_cast<size_t>(ne); ++k) {
    const SpencerElement& el = elements_[k];
    const double beta =
        model.region_damping.empty() ? 0.0 : model.region_damping[static_cast<size_t>(region_[k])].stiffness_s;
    for_each_slot(k, [&](ElementLanes& L, size_t l) {
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          L.Dm[3 * r + c][l] = el.Dm(r, c);
          L.Dm_inv[3 * r + c][l] = el.Dm_inv(r, c);
        }
      for (int c = 0; c < 3; ++c) L.fiber[c][l] = el.fiber(c);
      L.volume[l] = el.volume;
      L.beta[l] = beta;
      for (int a = 0; a < 4; ++a) L.node3[a][l] = 3 * tets_[k][static_cast<size_t>(a)];
    });
  }
  refresh_lane_laws();
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
  using Lanes = Lanes8;
  const int ne = static_cast<int>(elements_.size());
  sys.assemble_batched(
      [&](const int* elems, int n, ElementBatch& batch) {
        ChunkAcc& my = acc[static_cast<size_t>(batch.chunk)];
        // Lanes past n repeat the last element (computed, never scattered). The model's
        // per-element data and the state's rotations are read at the loop position (in
        // sequence), the active tension at the element.
        size_t lane_pos[W];
        for (int l = 0; l < W; ++l) lane_pos[l] = static_cast<size_t>(batch.first + std::min(l, n - 1));
        // The lanes of this batch as stored (a batch at a multiple of eight, whole or the
        // last), else copied lane by lane (a loop with chunks of another size).
        ElementLanes copy;
        const bool stored = batch.first % W == 0 && (n == W || batch.first + n == ne);
        if (!stored) lanes_copy(lane_pos, copy);
        const ElementLanes& L = stored ? lanes_[static_cast<size_t>(batch.first / W)] : copy;
        // The next batch's lanes on their way to the cache while this one computes.
        if (stored && batch.first + W < ne) {
          const char* next = reinterpret_cast<const char*>(&lanes_[static_cast<size_t>(batch.first / W) + 1]);
          for (size_t b = 0; b < sizeof(ElementLanes); b += 64) __builtin_prefetch(next + b);
        }
        Lanes Dil[9], Dl[9], fl[3], kv[5], cl;
        std::memcpy(Dil, L.Dm_inv, sizeof Dil);
        std::memcpy(fl, L.fiber, sizeof fl);
        std::memcpy(kv, L.law, sizeof kv);
        {
          Lanes beta;
          std::memcpy(&beta, L.beta, sizeof beta);
          cl = h * beta + h * h;
        }
        // D = Ds - Dm: the corners' positions gathered lane by lane.
        {
          Lanes xa[4][3];
          gather_corners(x.data(), L.node3, xa);
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) {
              Lanes dm;
              std::memcpy(&dm, L.Dm[3 * r + c], sizeof dm);
              Dl[3 * r + c] = (xa[c + 1][r] - xa[0][r]) - dm;
            }
        }
        if (need_rotations) {
          // F = I + D Dm^-1 (the same operations, in the same order, as one element's).
          Mat3 F[W];
          gradients(Dl, Dil, n, F);
          my.inverted += rotate_elements(pass, st, batch.first, n, F);
        }
        Lanes Rl[9];
        gather_rotations(st.R[static_cast<size_t>(batch.first)].data(), n, Rl);
        // Forces -V R sigma g_a and energies of all lanes at once.
        Lanes fel[12], energy;
        spencer_force_lanes(kv, Rl, Dil, Dl, fl, fel, energy);
        if (active) {
          // g^e_a = V f (f . g_a) (PHYSICS.md section 6): the active force is
          // -T_a V (R f)(f . g_a), or along the rest fiber f in the paper's nodal mode.
          Lanes tv, vol, s[3], dir[3], fa[4][3];
          for (int l = 0; l < W; ++l) tv[l] = st.active_tension_pa[static_cast<size_t>(elems[std::min(l, n - 1)])];
          std::memcpy(&vol, L.volume, sizeof vol);
          tv *= vol;
          matvec3(Dil, fl, s);  // f . g_a, a = 1..3
          if (rest_frame_active)
            std::memcpy(dir, fl, sizeof dir);
          else
            matvec3(Rl, fl, dir);
          const Lanes sa[4] = {-((s[0] + s[1]) + s[2]), s[0], s[1], s[2]};
          for (int a = 0; a < 4; ++a) {
            const Lanes ka = -tv * sa[a];
            for (int c = 0; c < 3; ++c) {
              product8(ka, dir[c], fa[a][c]);
              fel[3 * a + c] += fa[a][c];
            }
          }
          if (track_active_work)
            for (int l = 0; l < n; ++l) {
              const Tet& t = tets_[lane_pos[l]];
              for (int a = 0; a < 4; ++a)
                f_active.segment<3>(3 * t[static_cast<size_t>(a)]) += Vec3(fa[a][0][l], fa[a][1][l], fa[a][2][l]);
            }
        }
        for (int l = 0; l < n; ++l) {
          Vec12& fe = batch.force[l];
          for (int c = 0; c < 12; ++c) fe(c) = fel[c][l];
          my.energy += energy[l];
        }
        // The warped stiffness of all lanes at once: c R K^e R^T (core/spencer_element.hpp).
        Lanes k[5];
        for (int j = 0; j < 5; ++j) k[j] = cl * kv[j];
        // Written in place: batch.upper[q] is one vector of lanes (Lanes8 may alias doubles).
        static_assert(sizeof batch.upper == 90 * sizeof(Lanes) && alignof(ElementBatch) >= alignof(Lanes));
        spencer_upper_blocks(k, Rl, Dil, fl, reinterpret_cast<Lanes*>(batch.upper));
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

void CorotatedLinearModel::lanes_copy(const size_t* pos, ElementLanes& out) const {
  for (int l = 0; l < 8; ++l) {
    const ElementLanes& from = lanes_[pos[l] / 8];
    const int m = static_cast<int>(pos[l] % 8);
    for (int q = 0; q < 9; ++q) {
      out.Dm[q][l] = from.Dm[q][m];
      out.Dm_inv[q][l] = from.Dm_inv[q][m];
    }
    for (int c = 0; c < 3; ++c) out.fiber[c][l] = from.fiber[c][m];
    for (int j = 0; j < 5; ++j) out.law[j][l] = from.law[j][m];
    out.volume[l] = from.volume[m];
    out.beta[l] = from.beta[m];
    for (int a = 0; a < 4; ++a) out.node3[a][l] = from.node3[a][m];
  }
}

void CorotatedLinearModel::refresh_lane_laws() {
  for (size_t k = 0; k < elements_.size(); ++k) {
    const double v = elements_[k].volume;
    const SpencerConstants& law = region_law_[static_cast<size_t>(region_[k])];
    for_each_slot(k, [&](ElementLanes& L, size_t l) {
      L.law[0][l] = v * law.lambda;
      L.law[1][l] = v * law.mu_t;
      L.law[2][l] = v * law.alpha;
      L.law[3][l] = v * law.gamma;
      L.law[4][l] = v * law.beta;
    });
  }
}

void CorotatedLinearModel::set_region_material(int region, const Material& material) {
  region_law_[static_cast<size_t>(region)] = SpencerConstants::of(material);
  refresh_lane_laws();
}

void CorotatedLinearModel::set_region_stiffness_damping(int region, double beta_s) {
  for (size_t k = 0; k < region_.size(); ++k)
    if (region_[k] == region) for_each_slot(k, [&](ElementLanes& L, size_t l) { L.beta[l] = beta_s; });
}

void CorotatedLinearModel::set_fiber(int e, const Vec3& unit_fiber) {
  const size_t k = static_cast<size_t>(position_[static_cast<size_t>(e)]);
  elements_[k].fiber = unit_fiber;
  for_each_slot(k, [&](ElementLanes& L, size_t l) {
    for (int c = 0; c < 3; ++c) L.fiber[c][l] = unit_fiber(c);
  });
}

}  // namespace fiberfem::core
