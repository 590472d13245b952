#include "core/simulator.hpp"

#include "core/corotation.hpp"
#include "core/element.hpp"
#include "core/parallel.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace fiberfem::core {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}


}  // namespace

const char* to_string(StepStatus s) {
  switch (s) {
    case StepStatus::ok: return "ok";
    case StepStatus::recovered: return "recovered";
    case StepStatus::failed: return "failed";
  }
  return "?";
}

void SimulatorSettings::validate() const {
  if (!(dt_s > 0 && dt_s <= 10))
    throw std::invalid_argument("simulator: dt_s must be in (0, 10] s, got " + std::to_string(dt_s));
  solver.validate();
  if (max_substep_halvings < 0 || max_substep_halvings > 12)
    throw std::invalid_argument("simulator: max_substep_halvings must be in [0, 12], got " +
                                std::to_string(max_substep_halvings));
  if (!(max_inverted_fraction > 0 && max_inverted_fraction <= 1))
    throw std::invalid_argument("simulator: max_inverted_fraction must be in (0, 1], got " +
                                std::to_string(max_inverted_fraction));
  if (!(max_energy_gain >= 0))
    throw std::invalid_argument("simulator: max_energy_gain must be >= 0 (infinity turns the check off), got " +
                                std::to_string(max_energy_gain));
  if (!(polar_tolerance_rad > 0 && polar_tolerance_rad <= 0.1))
    throw std::invalid_argument("simulator: polar_tolerance_rad must be in (0, 0.1], got " +
                                std::to_string(polar_tolerance_rad));
  if (threads < 0) throw std::invalid_argument("simulator: threads must be >= 0, got " + std::to_string(threads));
}

Simulator::Simulator(Model model, SimulatorSettings settings)
    : model_((model.validate(), std::move(model))),
      settings_((settings.validate(), settings)),
      sys_(model_.mesh, model_.fixed_dofs) {
  // The governor's ceiling: the count OpenMP gave this process (OMP_NUM_THREADS, or every
  // core), taken once, before any simulator here set its own.
  static const int process_threads = std::max(1, omp_get_max_threads());
  governor_ = ThreadGovernor(process_threads);
  if (settings_.threads > 0) omp_set_num_threads(settings_.threads);
  caches_.build(model_, /*with_stiffness=*/false);
  const int ne = model_.mesh.num_elements();
  elements_.resize(static_cast<size_t>(ne));
  parallel_for(ne, [&](int e) {
    const size_t i = static_cast<size_t>(e);
    elements_[i].Dm_inv = caches_.Dm_inv[i];
    for (int j = 0; j < 3; ++j) elements_[i].Dm.col(j) = caches_.X[i].segment<3>(3 * (j + 1)) - caches_.X[i].segment<3>(0);
    elements_[i].fiber = model_.fibers[i];
    elements_[i].volume = model_.mesh.rest_volume(e);
  });
  for (const Material& m : model_.region_materials) region_law_.push_back(SpencerConstants::of(m));
  beta_e_.assign(static_cast<size_t>(ne), 0.0);
  if (!model_.region_damping.empty())
    for (int e = 0; e < ne; ++e)
      beta_e_[static_cast<size_t>(e)] =
          model_.region_damping[static_cast<size_t>(model_.mesh.regions()[static_cast<size_t>(e)])].stiffness_s;
  update_node_masses();
  refresh_external_forces();
  check_solver_fits(settings_.solver);
  solver_ = make_linear_solver(settings_.solver);
  solver_->set_blocks(sys_.node_block_starts());
  solver_->set_system(&sys_);
  const int nn = model_.mesh.num_nodes();
  for (int n = 0; n < nn; ++n)
    for (int c = 0; c < 3; ++c)
      if (sys_.free_index()[static_cast<size_t>(3 * n + c)] >= 0) {
        block_node_.push_back(n);
        break;
      }
  node_elem_start_.assign(static_cast<size_t>(nn) + 1, 0);
  for (const Tet& t : model_.mesh.tets())
    for (int n : t) ++node_elem_start_[static_cast<size_t>(n) + 1];
  for (int n = 0; n < nn; ++n) node_elem_start_[static_cast<size_t>(n) + 1] += node_elem_start_[static_cast<size_t>(n)];
  node_elems_.resize(static_cast<size_t>(node_elem_start_.back()));
  {
    std::vector<int> fill(node_elem_start_.begin(), node_elem_start_.end() - 1);
    for (int e = 0; e < ne; ++e)
      for (int n : model_.mesh.tets()[static_cast<size_t>(e)]) node_elems_[static_cast<size_t>(fill[static_cast<size_t>(n)]++)] = e;
  }
  st_.R.assign(static_cast<size_t>(ne), Mat3::Identity());
  st_.q.assign(static_cast<size_t>(ne), Eigen::Quaterniond::Identity());
  if (model_.contraction.enabled()) {  // per-step tensions come from the schedule
    st_.active_tension_pa.assign(static_cast<size_t>(ne), 0.0);
    tension_table_ = model_.contraction.tabulate();
  }
  reset();
}

void Simulator::refresh_external_forces() {
  f_ext_const_ = model_.constant_external_forces();
  varying_loads_.clear();
  for (const SurfaceLoad& s : model_.loads.surface_loads)
    if (s.varies()) varying_loads_.push_back(&s);
  st_.f_ext = f_ext_const_;
  const Positions& rest = model_.mesh.rest_positions();
  const bool have_state = st_.x.size() == rest.size();  // not yet in the constructor
  for (const SurfaceLoad* s : varying_loads_)
    if (have_state)
      add_surface_load_at(rest, positions(), *s, st_.time_s, st_.f_ext);
    else
      add_surface_load_at(rest, rest, *s, 0.0, st_.f_ext);
}

void Simulator::update_node_masses() {
  mass_ = model_.lumped_node_masses();
  st_.energy_floor_j = 0;
  for (int e = 0; e < model_.mesh.num_elements(); ++e) {
    const Material& m = model_.region_materials[static_cast<size_t>(model_.mesh.regions()[static_cast<size_t>(e)])];
    st_.energy_floor_j += 0.5 * model_.mesh.rest_volume(e) * m.stiffness().diagonal().maxCoeff() * 1e-16;
  }
  mass_alpha_ = Eigen::VectorXd::Zero(model_.mesh.num_nodes());
  if (model_.region_damping.empty()) return;
  for (int e = 0; e < model_.mesh.num_elements(); ++e) {
    const int r = model_.mesh.regions()[static_cast<size_t>(e)];
    const double me = model_.region_materials[static_cast<size_t>(r)].density_kg_m3() * model_.mesh.rest_volume(e);
    const double alpha = model_.region_damping[static_cast<size_t>(r)].mass_1_s;
    for (int n : model_.mesh.tets()[static_cast<size_t>(e)]) mass_alpha_(n) += 0.25 * alpha * me;
  }
}

void Simulator::reset() {
  const int n = model_.mesh.num_nodes();
  st_.x = Eigen::Map<const Eigen::VectorXd>(model_.mesh.rest_positions().data(), 3 * n);
  st_.v = Eigen::VectorXd::Zero(3 * n);
  std::fill(st_.R.begin(), st_.R.end(), Mat3::Identity());
  std::fill(st_.q.begin(), st_.q.end(), Eigen::Quaterniond::Identity());
  st_.rotations_current = false;
  assembled_ahead_ = false;
  st_.block_q.assign(block_node_.size(), Eigen::Quaterniond::Identity());
  st_.block_R.assign(block_node_.size(), Mat3::Identity());
  solver_->invalidate();
  solver_->forget_solutions();
  st_.vfree = Eigen::VectorXd::Zero(sys_.num_free());
  st_.vfree_prev = st_.vfree;
  st_.time_s = 0;
  st_.step_count = 0;
  st_.contraction_origin_s = 0;
}

SimulatorCheckpoint Simulator::checkpoint() const {
  SimulatorCheckpoint c;
  static_cast<SimulatorState&>(c) = st_;
  c.dt_s = settings_.dt_s;
  c.num_nodes = model_.mesh.num_nodes();
  c.num_elements = model_.mesh.num_elements();
  c.solver = solver_->save_state();
  return c;
}

void Simulator::restore(const SimulatorCheckpoint& c) {
  const int nn = model_.mesh.num_nodes(), ne = model_.mesh.num_elements();
  const auto fail = [](const std::string& what) { throw std::invalid_argument("restore: " + what); };
  if (c.num_nodes != nn || c.num_elements != ne)
    fail("checkpoint of a mesh with " + std::to_string(c.num_nodes) + " nodes and " + std::to_string(c.num_elements) +
         " elements, this model has " + std::to_string(nn) + " and " + std::to_string(ne));
  if (c.dt_s != settings_.dt_s)
    fail("checkpoint time step " + std::to_string(c.dt_s) + " s, this simulator's " + std::to_string(settings_.dt_s) + " s");
  const Eigen::Index n3 = 3 * static_cast<Eigen::Index>(nn);
  if (c.x.size() != n3 || c.v.size() != n3 || c.f_ext.size() != n3) fail("state vectors of the wrong size");
  if (!c.x.allFinite() || !c.v.allFinite()) fail("non-finite positions or velocities");
  if (c.vfree.size() != sys_.num_free() || c.vfree_prev.size() != sys_.num_free()) fail("free-DOF vectors of the wrong size");
  if (c.q.size() != st_.q.size() || c.R.size() != st_.R.size()) fail("per-element rotations of the wrong size");
  if (c.block_q.size() != st_.block_q.size() || c.block_R.size() != st_.block_R.size()) fail("node-block rotations of the wrong size");
  if (!(c.active_tension_pa.empty() || static_cast<int>(c.active_tension_pa.size()) == ne))
    fail("active tension of the wrong size");
  if (model_.contraction.enabled() && c.active_tension_pa.empty()) fail("no active tension for a contracting model");
  if (!(std::isfinite(c.time_s) && c.step_count >= 0)) fail("bad time or step count");
  solver_->load_state(c.solver, sys_.matrix());  // throws before anything else changes
  st_ = c;  // the state part (SimulatorState), whole
  assembled_ahead_ = false;  // not in the checkpoint: the next step makes its element pass
}

void Simulator::apply_fixed() {
  if (model_.fixed_dofs.empty()) return;
  const auto& rest = model_.mesh.rest_positions();
  for (int d = 0; d < sys_.num_dofs(); ++d)
    if (model_.fixed_dofs[static_cast<size_t>(d)]) {
      st_.x(d) = rest.data()[d];
      st_.v(d) = 0;
    }
}

void Simulator::set_state(const Positions& x, const Positions& v) {
  const int n = model_.mesh.num_nodes();
  if (x.cols() != n || v.cols() != n)
    throw std::invalid_argument("set_state: expected " + std::to_string(n) + " nodes");
  if (!x.allFinite() || !v.allFinite()) throw std::invalid_argument("set_state: non-finite values");
  st_.x = Eigen::Map<const Eigen::VectorXd>(x.data(), 3 * n);
  st_.v = Eigen::Map<const Eigen::VectorXd>(v.data(), 3 * n);
  apply_fixed();
  st_.vfree = sys_.restrict_to_free(st_.v);
  st_.vfree_prev = st_.vfree;
  solver_->forget_solutions();
  // Re-seed the warm-started rotations from the new shape (exact, by SVD).
  const int ne = model_.mesh.num_elements();
  parallel_for(ne, [&](int e) {
    const size_t i = static_cast<size_t>(e);
    const Mat3 F = element_gradient(e);
    st_.R[i] = settings_.corotation ? rotation_svd(F) : Mat3::Identity();
    st_.q[i] = Eigen::Quaterniond(st_.R[i]);
  });
  st_.rotations_current = false;
  assembled_ahead_ = false;
  solver_->invalidate();
}

// Ds - Dm of element e at the current positions (its edges' displacements), m.
Mat3 Simulator::element_edges(int e) const {
  const size_t i = static_cast<size_t>(e);
  const Tet& t = model_.mesh.tets()[i];
  const Mat3& Dm = elements_[i].Dm;
  Mat3 D;
  const Vec3 x0 = st_.x.segment<3>(3 * t[0]);
  for (int j = 0; j < 3; ++j) D.col(j) = (st_.x.segment<3>(3 * t[static_cast<size_t>(j + 1)]) - x0) - Dm.col(j);
  return D;
}

// Deformation gradient of element e at the current positions, as F = I + (Ds - Dm) Dm^-1:
// the round-off is relative to the displacement (F is exactly I at rest, where Ds Dm^-1
// would leave 1e-16 of strain and a non-zero energy).
Mat3 Simulator::element_gradient(int e) const {
  Mat3 F = element_edges(e) * elements_[static_cast<size_t>(e)].Dm_inv;
  F.diagonal().array() += 1.0;
  return F;
}

// Rotations of elements elems[0..n-1] (n <= 4) from their F into st_.R (and the warm-start
// st_.q); returns how many are inverted (det F <= 0).
int Simulator::rotate_elements(const int* elems, int n, const Mat3* F) {
  int inverted = 0;
  for (int l = 0; l < n; ++l) inverted += F[l].determinant() <= 0 ? 1 : 0;
  if (!settings_.corotation) {
    for (int l = 0; l < n; ++l) st_.R[static_cast<size_t>(elems[l])] = Mat3::Identity();
  } else if (settings_.rotation == RotationMethod::polar) {
    Eigen::Quaterniond* q[4];
    Mat3* R[4];
    for (int l = 0; l < n; ++l) {
      q[l] = &st_.q[static_cast<size_t>(elems[l])];
      R[l] = &st_.R[static_cast<size_t>(elems[l])];
    }
    rotation_polar_batch(F, q, R, n, settings_.polar_tolerance_rad);
  } else {
    for (int l = 0; l < n; ++l) st_.R[static_cast<size_t>(elems[l])] = rotation_svd(F[l]);
  }
  return inverted;
}

// The element pass of a (sub)step of size h ending at time t_end_s: rotations of the
// current positions (unless st_.rotations_current), the active tension at t_end_s, and the
// elastic and active forces, energy and warped blocks of every element into sys_ (without
// the mass terms), f_ and f_active_. Returns the elastic energy of the current state;
// counts inverted elements into st_.inverted_current when it computes the rotations.
double Simulator::assemble_elements(double h, double t_end_s) {
  const int ne = model_.mesh.num_elements();
  // Sums per chunk of the loop, added in chunk order below: the same bits on any thread count.
  acc_.resize(static_cast<size_t>(sys_.num_chunks()));  // no allocation after the first step
  std::fill(acc_.begin(), acc_.end(), ChunkAcc{});
  std::vector<ChunkAcc>& acc = acc_;
  const Contraction& con = model_.contraction;
  if (con.enabled()) {
    // The tension at the end of the (sub)step, as backward Euler evaluates forces there,
    // from the tabulated beat (Contraction::tabulate).
    const double t_end = t_end_s - st_.contraction_origin_s;
    const auto& regions = model_.mesh.regions();
    const bool delays = !con.element_delay_s.empty();
    const double shared = tension_table_.value(t_end);
    parallel_for(ne, [&](int e) {
      const size_t i = static_cast<size_t>(e);
      const double peak = con.region_peak_pa[static_cast<size_t>(regions[i])];
      st_.active_tension_pa[i] = peak * (delays ? tension_table_.value(t_end - con.element_delay_s[i]) : shared);
    });
  }
  const bool rest_frame_active = con.enabled() && con.mode == ContractionMode::nodal_forces;
  f_.setZero(sys_.num_dofs());  // (assemble_batched replaces the matrix values)
  const bool active = !st_.active_tension_pa.empty();
  // The active forces' own vector is needed only for the energy check's work balance.
  const bool track_active_work = active && settings_.max_energy_gain < std::numeric_limits<double>::infinity();
  if (track_active_work) f_active_.setZero(sys_.num_dofs());
  // One pass per element (rotations fused in unless the last step's check computed them):
  // F, R, the corotated strain's stress, forces, energy and the warped blocks in closed
  // form (core/spencer_element.hpp: no stored 12 x 12 K^e is read).
  const bool need_rotations = !st_.rotations_current;
  const auto& regions = model_.mesh.regions();
  constexpr int W = ElementBatch::kWidth;
  static_assert(W <= 4, "rotate_elements takes at most four elements");
  using Lanes = double __attribute__((vector_size(W * sizeof(double))));
  sys_.assemble_batched(
      [&](const int* elems, int n, ElementBatch& batch) {
        ChunkAcc& my = acc[static_cast<size_t>(batch.chunk)];
        // Lanes past n repeat the last element (computed, never scattered).
        int lane_elem[W];
        for (int l = 0; l < W; ++l) lane_elem[l] = elems[std::min(l, n - 1)];
        Mat3 D[W], F[W];
        for (int l = 0; l < W; ++l) {
          const int e = lane_elem[l];
          D[l] = element_edges(e);
          if (l < n) {
            F[l].noalias() = D[l] * elements_[static_cast<size_t>(e)].Dm_inv;
            F[l].diagonal().array() += 1.0;
          }
        }
        if (need_rotations) my.inverted += rotate_elements(elems, n, F);
        Lanes kv[5], cl, Rl[9], Dil[9], Dl[9], fl[3];
        for (int l = 0; l < W; ++l) {
          const size_t i = static_cast<size_t>(lane_elem[l]);
          const SpencerElement& el = elements_[i];
          const SpencerConstants& law = region_law_[static_cast<size_t>(regions[i])];
          kv[0][l] = el.volume * law.lambda;
          kv[1][l] = el.volume * law.mu_t;
          kv[2][l] = el.volume * law.alpha;
          kv[3][l] = el.volume * law.gamma;
          kv[4][l] = el.volume * law.beta;
          cl[l] = h * beta_e_[i] + h * h;
          const Mat3& R = st_.R[i];
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
            const size_t i = static_cast<size_t>(elems[l]);
            const SpencerElement& el = elements_[i];
            Vec12& fe = batch.force[l];
            const Vec3 dir = rest_frame_active ? el.fiber : Vec3(st_.R[i] * el.fiber);
            const Vec3 s123 = el.Dm_inv * el.fiber;  // f . g_a, a = 1..3
            const double sa[4] = {-(s123(0) + s123(1) + s123(2)), s123(0), s123(1), s123(2)};
            const double tv = st_.active_tension_pa[i] * el.volume;
            const Tet& t = model_.mesh.tets()[i];
            for (int a = 0; a < 4; ++a) {
              const Vec3 fa = (-tv * sa[a]) * dir;
              fe.segment<3>(3 * a) += fa;
              if (track_active_work) f_active_.segment<3>(3 * t[static_cast<size_t>(a)]) += fa;
            }
          }
        // The warped stiffness of all lanes at once: c R K^e R^T (core/spencer_element.hpp).
        Lanes k[5];
        for (int j = 0; j < 5; ++j) k[j] = cl * kv[j];
        Lanes out[90];
        spencer_upper_blocks(k, Rl, Dil, fl, out);
        std::memcpy(batch.upper, out, sizeof out);
      },
      f_);
  if (need_rotations) {
    int inverted_sum = 0;
    for (const ChunkAcc& a : acc) inverted_sum += a.inverted;
    st_.inverted_current = inverted_sum;
  }
  st_.rotations_current = true;
  double elastic = 0;
  for (const ChunkAcc& c : acc) elastic += c.energy;
  return elastic;
}

// Linearised backward Euler in velocity form (PHYSICS.md section 5), per element e:
//   A = sum_e [(1 + h alpha_e) M_e + (h beta_e + h^2) R K^e R^T]
//   b = M v_n + h (f_ext + f_el(x_n) + f_active),  f_el = -R K^e (R^T x - X),
//   f_active = -T_a R g^e (section 6); then st_.x{n+1} = x_n + h st_.v{n+1}.
bool Simulator::advance(double h, bool last_chance, StepReport& r, std::string& why) {
  const int ne = model_.mesh.num_elements();

  // Phase 1 and 2: rotations fused with the assembly of A and of the elastic and active
  // forces, unless the checks of the last (sub)step already made this pass for this state
  // and step size (assembled_ahead_).
  auto t0 = Clock::now();
  if (!varying_loads_.empty()) {  // ramped and follower loads at the end of the (sub)step
    st_.f_ext = f_ext_const_;
    for (const SurfaceLoad* s : varying_loads_) add_surface_load_at(model_.mesh.rest_positions(), positions(), *s, st_.time_s + h, st_.f_ext);
  }
  double elastic;
  if (assembled_ahead_ && ahead_h_ == h) {
    elastic = ahead_elastic_j_;
  } else {
    elastic = assemble_elements(h, st_.time_s + h);
  }
  assembled_ahead_ = false;
  const bool active = !st_.active_tension_pa.empty();
  r.inverted_elements = st_.inverted_current;
  const auto& fi = sys_.free_index();
  const int nn = model_.mesh.num_nodes();
  rhs_.resize(sys_.num_free());
  for (int n = 0; n < nn; ++n) {
    const double md = mass_(n) + h * mass_alpha_(n);
    for (int c = 0; c < 3; ++c) {
      const int k = fi[static_cast<size_t>(3 * n + c)];
      if (k < 0) continue;
      sys_.add_to_diagonal(k, md);
      rhs_(k) = mass_(n) * st_.v(3 * n + c) + h * (st_.f_ext(3 * n + c) + f_(3 * n + c));
    }
  }
  r.elastic_energy_j = elastic;
  double kinetic = 0;
  for (int n = 0; n < nn; ++n) kinetic += 0.5 * mass_(n) * st_.v.segment<3>(3 * n).squaredNorm();
  r.kinetic_energy_j = kinetic;
  // (kinetic and elastic are the energies of the state the step starts from.)
  r.time.assembly_s += seconds_since(t0);

  // Phase 3: solve for the new velocity.
  t0 = Clock::now();
  // Initial guess: the last velocity extrapolated linearly (v_n + (v_n - st_.v{n-1})), which
  // follows smooth motion to second order; PCG ignores it when warm_start is off.
  if (!settings_.solver.warm_start || st_.vfree.size() != sys_.num_free()) {
    st_.vfree = sys_.restrict_to_free(st_.v);
  } else if (h == st_.last_h_s) {
    guess_ = 2.0 * st_.vfree - st_.vfree_prev;
    st_.vfree_prev = st_.vfree;
    st_.vfree.swap(guess_);
  } else {
    st_.vfree_prev = st_.vfree;
  }
  st_.last_h_s = h;
  solver_->set_matrix_key(h);
  if (solver_->uses_block_rotations()) {
    update_block_rotations();
    solver_->set_block_rotations(st_.block_R);
  }
  if (solver_->uses_block_positions()) {
    block_x_.resize(3 * static_cast<Eigen::Index>(block_node_.size()));
    for (size_t k = 0; k < block_node_.size(); ++k)
      block_x_.segment<3>(3 * static_cast<Eigen::Index>(k)) = st_.x.segment<3>(3 * static_cast<Eigen::Index>(block_node_[k]));
    solver_->set_block_positions(block_x_);
  }
  if (!solver_->reads_blocks()) sys_.sync_matrix();
  const SolveStats st = solver_->solve(sys_.matrix(), rhs_, st_.vfree);
  r.solver_factorizations += st.factorizations;
  r.time.solve_s += seconds_since(t0);
  r.solver_iterations += st.iterations;
  r.solver_residual = std::max(r.solver_residual, st.relative_residual);
  if (!st_.vfree.allFinite()) {
    why = "linear solve produced NaN/Inf";
    return false;
  }
  if (!(st.relative_residual <= settings_.solver.failure_residual)) {
    why = "linear solve residual " + std::to_string(st.relative_residual) + " above failure_residual";
    return false;
  }
  sys_.scatter_free(st_.vfree, st_.v);
  st_.x += h * st_.v;
  st_.rotations_current = false;
  if (!st_.x.allFinite()) {
    why = "positions became NaN/Inf";
    return false;
  }
  // Checks on the state the step leaves. They need its rotations and elastic energy, which
  // the next (sub)step's element pass computes anyway: that pass is made here, for a next
  // step of the same size, and kept for it (assembled_ahead_) unless a check fails or
  // something changes the model in between. The work of the loads and of the active
  // stress is summed first, as the pass overwrites f_active_ with the next step's.
  const bool guard = settings_.max_energy_gain < std::numeric_limits<double>::infinity();
  if (guard || settings_.max_inverted_fraction < 1.0) {
    t0 = Clock::now();
    double kinetic1 = 0, work = 0;
    if (guard)
      for (int n = 0; n < nn; ++n) {
        kinetic1 += 0.5 * mass_(n) * st_.v.segment<3>(3 * n).squaredNorm();
        Vec3 f = st_.f_ext.segment<3>(3 * n);
        if (active) f += f_active_.segment<3>(3 * n);
        work += h * f.dot(st_.v.segment<3>(3 * n));
      }
    const double t_next = st_.time_s + h;  // the time this step ends, as the next one sees it
    const double elastic1 = assemble_elements(h, t_next + h);
    assembled_ahead_ = true;
    ahead_h_ = h;
    ahead_elastic_j_ = elastic1;
    r.time.assembly_s += seconds_since(t0);
    r.inverted_elements = st_.inverted_current;
    if (st_.inverted_current > settings_.max_inverted_fraction * ne) {
      why = std::to_string(st_.inverted_current) + " inverted elements after the step, above max_inverted_fraction";
      st_.rotations_current = false;
      assembled_ahead_ = false;
      return false;
    }
    if (guard) {
      // Backward Euler with damping dissipates: the kinetic plus elastic energy may grow
      // only by the work of the loads and of the active stress, h (f_ext + f_active) . v.
      const double gain = (kinetic1 + elastic1) - (kinetic + elastic) - work;
      // st_.energy_floor_j: the energy of a uniform strain of 1e-8, below which energy
      // changes are round-off (and polar tolerance), not dynamics. At the finest substep
      // the step is accepted whatever the gain (refinement, not failure).
      const double allowed = settings_.max_energy_gain * (kinetic + elastic + std::abs(work));
      if (gain > allowed + st_.energy_floor_j && !last_chance) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "energy grew by %.3g J without external work (%.3g of the state's energy)",
                      gain, gain / (kinetic + elastic + std::abs(work) + 1e-300));
        why = buf;
        st_.rotations_current = false;
        assembled_ahead_ = false;
        return false;
      }
    }
  }
  st_.time_s += h;
  return true;
}

// Rotation of each node block: the rotation nearest the sum of the rotations of the
// elements around the node (warm-started polar extraction). Only the warp preconditioner
// uses it.
void Simulator::update_block_rotations() {
  const int nb = static_cast<int>(block_node_.size());
  if (!settings_.corotation) {
    std::fill(st_.block_R.begin(), st_.block_R.end(), Mat3::Identity());
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
        sum[l] += st_.R[static_cast<size_t>(node_elems_[static_cast<size_t>(j)])];
      q[l] = &st_.block_q[k];
      R[l] = &st_.block_R[k];
    }
    rotation_polar_batch(sum, q, R, n4, 1e-6);
  });
}

StepReport Simulator::step() {
  // The thread count of this step: the user's, or the governor's (core/thread_governor.hpp).
  // Set on every step: the count is per calling thread in OpenMP, and another simulator
  // stepped on this thread may have set its own.
  const int nthreads = settings_.threads > 0 ? settings_.threads : governor_.threads();
  omp_set_num_threads(nthreads);
  const auto t0 = Clock::now();
  StepReport r;
  // Rollback copies into members sized once: a step allocates nothing in steady state.
  x0_ = st_.x;
  v0_ = st_.v;
  vfree0_ = st_.vfree;
  vprev0_ = st_.vfree_prev;
  const Eigen::VectorXd &x0 = x0_, &v0 = v0_, &vfree0 = vfree0_, &vprev0 = vprev0_;
  const double last_h0 = st_.last_h_s;
  const bool keep_q = settings_.rotation == RotationMethod::polar;
  if (keep_q) q0_ = st_.q;
  const double t_start = st_.time_s;
  std::string why;
  for (int level = 0; level <= settings_.max_substep_halvings; ++level) {
    const int nsub = 1 << level;
    const double h = settings_.dt_s / nsub;
    StepReport attempt;
    attempt.time = r.time;
    bool ok = true;
    for (int s = 0; s < nsub && ok; ++s) {
      StepReport sub;
      sub.time = attempt.time;
      ok = advance(h, level == settings_.max_substep_halvings, sub, why);
      attempt.time = sub.time;
      attempt.solver_iterations += sub.solver_iterations;
      r.solver_factorizations += sub.solver_factorizations;
      attempt.solver_residual = std::max(attempt.solver_residual, sub.solver_residual);
      attempt.inverted_elements = sub.inverted_elements;
      if (s == 0) {
        attempt.kinetic_energy_j = sub.kinetic_energy_j;
        attempt.elastic_energy_j = sub.elastic_energy_j;
      }
    }
    r.time = attempt.time;
    if (ok) {
      const PhaseTimes times = r.time;
      const std::string msg = r.message;
      const int factorizations = r.solver_factorizations;
      r = attempt;
      r.time = times;
      r.message = msg;
      r.solver_factorizations = factorizations;
      r.substeps = nsub;
      r.attempts = level + 1;
      r.status = level == 0 ? StepStatus::ok : StepStatus::recovered;
      break;
    }
    // Roll back and retry with twice the substeps.
    r.message += (r.message.empty() ? "" : "; ") + std::string("dt/") + std::to_string(nsub) + ": " + why;
    st_.x = x0;
    st_.v = v0;
    st_.vfree = vfree0;
    st_.vfree_prev = vprev0;
    st_.rotations_current = false;
    assembled_ahead_ = false;
    st_.last_h_s = last_h0;
    if (keep_q) st_.q = q0_;
    st_.time_s = t_start;
    r.attempts = level + 1;
    r.status = StepStatus::failed;
  }
  if (r.status != StepStatus::failed) ++st_.step_count;
  double vmax2 = 0;
  for (int n = 0; n < model_.mesh.num_nodes(); ++n) vmax2 = std::max(vmax2, st_.v.segment<3>(3 * n).squaredNorm());
  r.max_speed_m_s = std::sqrt(vmax2);
  r.time_s = st_.time_s;
  r.time.total_s = seconds_since(t0);
  r.threads = nthreads;
  // Steps that did other work than the usual step (a retry; a factorisation, except with
  // the direct solver, which factorises every step) are not compared.
  if (settings_.threads == 0)
    governor_.record(r.time.total_s, r.attempts == 1 && (r.solver_factorizations == 0 ||
                                                         settings_.solver.method == LinearSolverKind::direct));
  return r;
}

Energies Simulator::energies() const {
  Energies en;
  const int ne = model_.mesh.num_elements();
  en.elastic_j = fixed_sum(ne, true, [&](int e) {
    const size_t i = static_cast<size_t>(e);
    const Mat3 F = element_gradient(e);
    const Mat3 R = settings_.corotation ? rotation_svd(F) : Mat3::Identity();
    return spencer_energy(region_law_[static_cast<size_t>(model_.mesh.regions()[i])], elements_[i], R, F);
  });
  for (int n = 0; n < model_.mesh.num_nodes(); ++n) {
    en.kinetic_j += 0.5 * mass_(n) * st_.v.segment<3>(3 * n).squaredNorm();
    en.gravity_j -= mass_(n) * model_.loads.gravity_m_s2.dot(st_.x.segment<3>(3 * n));
  }
  return en;
}

int Simulator::count_inverted() const {
  int count = 0;
  for (int e = 0; e < model_.mesh.num_elements(); ++e) {
    const size_t i = static_cast<size_t>(e);
    if (element_gradient(static_cast<int>(i)).determinant() <= 0) ++count;
  }
  return count;
}

void Simulator::set_region_material(int region, const Material& material) {
  if (region < 0 || region >= static_cast<int>(model_.region_materials.size()))
    throw std::invalid_argument("set_region_material: no region " + std::to_string(region));
  model_.region_materials[static_cast<size_t>(region)] = material;
  region_law_[static_cast<size_t>(region)] = SpencerConstants::of(material);
  assembled_ahead_ = false;
  update_node_masses();
  solver_->invalidate();
  refresh_external_forces();
}

void Simulator::set_region_damping(int region, const RayleighDamping& damping) {
  damping.validate();
  if (region < 0 || region >= model_.mesh.num_regions())
    throw std::invalid_argument("set_region_damping: no region " + std::to_string(region));
  if (model_.region_damping.empty()) model_.region_damping.assign(static_cast<size_t>(model_.mesh.num_regions()), {});
  model_.region_damping[static_cast<size_t>(region)] = damping;
  for (int e = 0; e < model_.mesh.num_elements(); ++e)
    if (model_.mesh.regions()[static_cast<size_t>(e)] == region) beta_e_[static_cast<size_t>(e)] = damping.stiffness_s;
  assembled_ahead_ = false;
  update_node_masses();
  solver_->invalidate();
}

void Simulator::set_fibers(std::vector<Vec3> fibers) {
  const int ne = model_.mesh.num_elements();
  if (static_cast<int>(fibers.size()) != ne)
    throw std::invalid_argument("set_fibers: " + std::to_string(fibers.size()) + " fibers for " +
                                std::to_string(ne) + " elements");
  for (int e = 0; e < ne; ++e) {
    const double n = fibers[static_cast<size_t>(e)].norm();
    if (!(std::isfinite(n) && n > 1e-12))
      throw std::invalid_argument("set_fibers: element " + std::to_string(e) + " has a zero or non-finite fiber");
    fibers[static_cast<size_t>(e)] /= n;
  }
  // The step reads the fiber from elements_ (stiffness and active stress alike): a changed
  // fiber of an anisotropic region changes the matrix, so lagged factors are refreshed.
  bool matrix_changed = false;
  for (int e = 0; e < ne; ++e) {
    const size_t i = static_cast<size_t>(e);
    if (fibers[i] == model_.fibers[i]) continue;
    model_.fibers[i] = fibers[i];
    elements_[i].fiber = fibers[i];
    assembled_ahead_ = false;  // the active stress follows the fiber, isotropic or not
    if (!model_.region_materials[static_cast<size_t>(model_.mesh.regions()[i])].is_isotropic()) matrix_changed = true;
  }
  if (matrix_changed) solver_->invalidate();
}

void Simulator::set_time_step(double dt_s) {
  SimulatorSettings s = settings_;
  s.dt_s = dt_s;
  s.validate();
  if (s.dt_s != settings_.dt_s) solver_->invalidate();
  settings_ = s;
  assembled_ahead_ = false;
}

void Simulator::set_gravity(const Vec3& g) {
  if (!g.allFinite()) throw std::invalid_argument("set_gravity: gravity must be finite");
  model_.loads.gravity_m_s2 = g;
  refresh_external_forces();
}

void Simulator::set_loads(const Loads& loads) {
  Model probe = model_;
  probe.loads = loads;
  probe.validate();
  model_.loads = loads;
  refresh_external_forces();
}

void Simulator::check_solver_fits(const SolverSettings& s) const {
  // The amg hierarchy is built on 3 x 3 node blocks (the rigid-body modes are per node).
  if (s.method == LinearSolverKind::pcg && s.preconditioner == PreconditionerKind::amg && !sys_.has_blocks())
    throw std::invalid_argument(
        "solver: preconditioner amg needs every node wholly free or wholly fixed, and this model fixes single "
        "components of some nodes: use preconditioner cholesky");
}

void Simulator::set_solver_settings(const SolverSettings& s) {
  s.validate();
  check_solver_fits(s);
  settings_.solver = s;
  assembled_ahead_ = false;
  solver_ = make_linear_solver(s);
  solver_->set_blocks(sys_.node_block_starts());
  solver_->set_system(&sys_);
}

void Simulator::set_rotation_method(RotationMethod m) {
  if (m == RotationMethod::polar && settings_.rotation != RotationMethod::polar)
    for (size_t i = 0; i < st_.R.size(); ++i) st_.q[i] = Eigen::Quaterniond(st_.R[i]);
  settings_.rotation = m;
  st_.rotations_current = false;
  assembled_ahead_ = false;
}

void Simulator::set_corotation(bool on) {
  st_.rotations_current = false;
  assembled_ahead_ = false;
  if (on != settings_.corotation) solver_->invalidate();
  settings_.corotation = on;
}

void Simulator::set_active_tension(std::vector<double> tension_pa) {
  if (model_.contraction.enabled())
    throw std::invalid_argument("set_active_tension: the model's contraction schedule sets the tension");
  assembled_ahead_ = false;
  if (tension_pa.empty()) {
    st_.active_tension_pa.clear();
    return;
  }
  if (static_cast<int>(tension_pa.size()) != model_.mesh.num_elements())
    throw std::invalid_argument("set_active_tension: " + std::to_string(tension_pa.size()) +
                                " values for " + std::to_string(model_.mesh.num_elements()) + " elements");
  for (size_t e = 0; e < tension_pa.size(); ++e)
    if (!std::isfinite(tension_pa[e]))
      throw std::invalid_argument("set_active_tension: element " + std::to_string(e) + " is not finite");
  st_.active_tension_pa = std::move(tension_pa);
}

void Simulator::set_contraction(Contraction contraction) {
  contraction.validate(model_.mesh.num_regions(), model_.mesh.num_elements());
  assembled_ahead_ = false;
  const bool was_on = model_.contraction.enabled();
  const bool on = contraction.enabled();
  if (on) {
    // Keep the phase of the beat under way (a rate change must not jump the twitch):
    // phase = time since the current beat began. The new origin puts the current beat
    // at the same phase, one whole new period (or more) after the origin so the table's
    // first-beat branch (no previous tail) is not taken again.
    double origin = st_.time_s;
    if (was_on) {
      const double since = st_.time_s - st_.contraction_origin_s;
      const double old_period = model_.contraction.period_s;
      if (since >= old_period) {
        const double phase = since - std::floor(since / old_period) * old_period;
        origin = st_.time_s - phase - contraction.period_s;
      } else {
        origin = st_.contraction_origin_s;  // still in the first beat
      }
    }
    TwitchTable table = contraction.tabulate();
    tension_table_ = std::move(table);
    st_.contraction_origin_s = origin;
    st_.active_tension_pa.assign(static_cast<size_t>(model_.mesh.num_elements()), 0.0);
  } else {
    st_.active_tension_pa.clear();
  }
  model_.contraction = std::move(contraction);
}

}  // namespace fiberfem::core
