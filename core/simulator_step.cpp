#include "core/simulator.hpp"

#include "core/parallel.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

namespace fiberfem::core {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

// The tension of each element at t_end_s (the end of the (sub)step, as backward Euler
// evaluates forces there) from the tabulated beat (Contraction::tabulate).
void Simulator::update_active_tension(double t_end_s) {
  const Contraction& con = model_.contraction;
  if (!con.enabled()) return;
  const int ne = model_.mesh.num_elements();
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

// The element pass of a (sub)step of size h ending at time t_end_s: the active tension at
// t_end_s, then one call of the element model (core/element_model.hpp), which fills sys_
// (without the mass terms), f_ and f_active_, updates the element rotations unless
// st_.rotations_current, and returns the elastic energy of the current state.
double Simulator::assemble_elements(double h, double t_end_s) {
  update_active_tension(t_end_s);
  ElementPass pass;
  pass.h_s = h;
  pass.corotation = settings_.corotation;
  pass.rotation = settings_.rotation;
  pass.polar_tolerance_rad = settings_.polar_tolerance_rad;
  pass.rest_frame_active = model_.contraction.enabled() && model_.contraction.mode == ContractionMode::nodal_forces;
  pass.track_active_work = settings_.max_energy_gain < std::numeric_limits<double>::infinity();
  return elements_->assemble(pass, st_, sys_, f_, f_active_);
}

// Linearised backward Euler in velocity form (PHYSICS.md section 5), per element e:
//   A = sum_e [(1 + h alpha_e) M_e + (h beta_e + h^2) R K^e R^T]
//   b = M v_n + h (f_ext + f_el(x_n) + f_active),  f_el = -R K^e (R^T x - X),
//   f_active = -T_a R g^e (section 6); then st_.x{n+1} = x_n + h st_.v{n+1}.
// The element terms come from the element model, the mass terms are added here.
bool Simulator::advance(double h, bool last_chance, StepReport& r, std::string& why) {
  assemble_step(h, r);
  if (model_.circulation.enabled() ? !solve_coupled(h, r, why) : !solve_velocity(h, r, why)) return false;
  if (!check_step(h, r.kinetic_energy_j, r.elastic_energy_j, last_chance, r, why)) return false;
  st_.time_s += h;
  return true;
}

// A and b of the (sub)step; the energies of the state it starts from into r.
void Simulator::assemble_step(double h, StepReport& r) {
  // Phase 1 and 2: rotations fused with the assembly of A and of the elastic and active
  // forces, unless the checks of the last (sub)step already made this pass for this state
  // and step size (assembled_ahead_).
  auto t0 = Clock::now();
  // Ramped and follower loads at the end of the (sub)step; the cavity pressures of a
  // circulation (solve_coupled) are added to it afresh every step.
  if (!varying_loads_.empty() || model_.circulation.enabled()) {
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
  r.inverted_elements = st_.inverted_current;
  const auto& fi = sys_.free_index();
  const int nn = model_.mesh.num_nodes();
  rhs_.resize(sys_.num_free());
  // Node by node on the threads (each node's own entries): the mass terms of A and b, and
  // the kinetic energy, summed in a fixed partition.
  r.kinetic_energy_j = fixed_sum(nn, true, [&](int n) {
    const double md = mass_(n) + h * mass_alpha_(n);
    for (int c = 0; c < 3; ++c) {
      const int k = fi[static_cast<size_t>(3 * n + c)];
      if (k < 0) continue;
      sys_.add_to_diagonal(k, md);
      rhs_(k) = mass_(n) * st_.v(3 * n + c) + h * (st_.f_ext(3 * n + c) + f_(3 * n + c));
    }
    return 0.5 * mass_(n) * st_.v.segment<3>(3 * n).squaredNorm();
  });
  r.elastic_energy_j = elastic;
  // (kinetic and elastic are the energies of the state the step starts from.)
  r.time.assembly_s += seconds_since(t0);
}

// The new velocity (and positions) from A and b; false with `why` when the solve fails.
bool Simulator::solve_velocity(double h, StepReport& r, std::string& why) {
  return solve_free(h, r, why) && take_velocity(h, why);
}

// st_.vfree from A and b (rhs_), warm-started; false with `why` when the solve fails.
bool Simulator::solve_free(double h, StepReport& r, std::string& why) {
  auto t0 = Clock::now();
  // Phase 3: solve for the new velocity.
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
  if (solver_->takes_guess()) free_flight_guess(h);
  solver_->set_matrix_key(h);
  if (solver_->uses_block_rotations()) {
    elements_->update_node_rotations(st_, settings_.corotation);
    solver_->set_block_rotations(st_.block_R);
  }
  if (solver_->uses_block_positions()) {
    const std::vector<int>& block_node = sys_.block_nodes();
    block_x_.resize(3 * static_cast<Eigen::Index>(block_node.size()));
    for (size_t k = 0; k < block_node.size(); ++k)
      block_x_.segment<3>(3 * static_cast<Eigen::Index>(k)) = st_.x.segment<3>(3 * static_cast<Eigen::Index>(block_node[k]));
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
  return true;
}

// A solver that remembers no solutions yet (the first solve of a run, or the first after
// a reset) starts from st_.vfree as given: that guess becomes the best combination, the
// least A-norm error, of it and the free-flight velocity D^-1 b, D the mass diagonal
// (1 + h alpha) M, the velocity the step would give if the stiffness were dropped. From
// rest under a body force the free flight is exact away from the supports; block Jacobi
// would build it over about as many iterations as the body is elements long (133 on the
// 252,368-tet beam of docs/vega-comparison.md, whose step matrix the stiffness dominates
// at the element scale). Where the stiffness dominates the motion (an active contraction)
// the projection keeps the given guess: it is in the span, so never a worse start. Two
// products with A, once.
void Simulator::free_flight_guess(double h) {
  const auto& fi = sys_.free_index();
  const int nn = model_.mesh.num_nodes();
  const Eigen::Index nf = sys_.num_free();
  if (rhs_.size() != nf || st_.vfree.size() != nf) return;
  flight_.resize(nf);
  for (int n = 0; n < nn; ++n) {
    const double md = mass_(n) + h * mass_alpha_(n);
    for (int c = 0; c < 3; ++c) {
      const int k = fi[static_cast<size_t>(3 * n + c)];
      if (k >= 0) flight_(k) = md > 0 ? rhs_(k) / md : 0.0;
    }
  }
  const bool par = nf > 20000;
  const auto product = [&](const Eigen::VectorXd& v, Eigen::VectorXd& Av) {
    if (sys_.blocks_current()) {
      sys_.block_product(v, Av, par);
    } else {
      Av.resize(nf);
      Av.noalias() = sys_.matrix() * v;  // both triangles stored
    }
  };
  const Eigen::VectorXd& given = st_.vfree;
  product(flight_, flight_Av_);
  const double ff = flight_.dot(flight_Av_), fb = flight_.dot(rhs_);
  if (!(ff > 0) || !std::isfinite(fb)) return;
  Eigen::Vector2d c(0.0, fb / ff);
  if (given.squaredNorm() > 0) {
    product(given, guess_Av_);
    Eigen::Matrix2d G;
    G << given.dot(guess_Av_), given.dot(flight_Av_), flight_.dot(guess_Av_), ff;
    const Eigen::Vector2d g(given.dot(rhs_), fb);
    // Nearly parallel: keep the given guess (the 2 x 2 system says nothing new).
    const double det = G(0, 0) * G(1, 1) - G(0, 1) * G(1, 0);
    if (!(G(0, 0) > 0) || !(det > 1e-12 * G(0, 0) * G(1, 1))) return;
    c = G.ldlt().solve(g);
  }
  if (!c.allFinite()) return;
  guess_ = c(0) * given + c(1) * flight_;
  if (guess_.allFinite()) st_.vfree.swap(guess_);
}

// The velocity st_.vfree becomes the state's, and the positions move by h v.
bool Simulator::take_velocity(double h, std::string& why) {
  sys_.scatter_free(st_.vfree, st_.v);
  st_.x += h * st_.v;
  st_.rotations_current = false;
  if (!st_.x.allFinite()) {
    why = "positions became NaN/Inf";
    return false;
  }
  return true;
}

bool Simulator::check_step(double h, double kinetic, double elastic, bool last_chance, StepReport& r, std::string& why) {
  const int ne = model_.mesh.num_elements();
  const int nn = model_.mesh.num_nodes();
  const bool active = !st_.active_tension_pa.empty();
  // Checks on the state the step leaves. They need its rotations and elastic energy, which
  // the next (sub)step's element pass computes anyway: that pass is made here, for a next
  // step of the same size, and kept for it (assembled_ahead_) unless a check fails or
  // something changes the model in between. The work of the loads and of the active
  // stress is summed first, as the pass overwrites f_active_ with the next step's.
  const bool guard = settings_.max_energy_gain < std::numeric_limits<double>::infinity();
  if (guard || settings_.max_inverted_fraction < 1.0) {
    const auto t0 = Clock::now();
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
      // the step is accepted with a gain beyond the allowance (refinement, not failure),
      // up to kFinestEnergyGain times the state's energy: a substep that gains more even
      // there is blowing up (a load the linearised model cannot carry), and the step fails
      // instead of handing on a state of 1e140 m.
      const double state = kinetic + elastic + std::abs(work);
      const double allowed = settings_.max_energy_gain * state;
      const double limit = last_chance ? std::max(allowed, SimulatorSettings::kFinestEnergyGain * state) : allowed;
      if (gain > limit + st_.energy_floor_j) {
        char buf[200];
        std::snprintf(buf, sizeof buf, "energy grew by %.3g J without external work (%.3g of the state's energy%s)",
                      gain, gain / (state + 1e-300), last_chance ? ", at the finest substep level" : "");
        why = buf;
        st_.rotations_current = false;
        assembled_ahead_ = false;
        return false;
      }
    }
  }
  return true;
}

StepReport Simulator::step() {
  // The thread count of this step: the user's, or the governor's (core/thread_governor.hpp).
  // Set on every step: the count is per calling thread in OpenMP, and another simulator
  // stepped on this thread may have set its own.
  // Fewer by the threads of factorisations running beside the steps: a parallel loop
  // whose threads outnumber the cores waits at each barrier for a descheduled one.
  const int beside = solver_->threads_beside();
  const int nthreads = std::max(1, (settings_.threads > 0 ? settings_.threads : governor_.threads()) - beside);
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
  if (model_.circulation.enabled()) circulation0_ = st_.circulation;
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
      attempt.circulation_iterations += sub.circulation_iterations;
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
    if (model_.circulation.enabled()) st_.circulation = circulation0_;
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
  // the direct solver, which factorises every step; one beside them) are not compared.
  if (settings_.threads == 0)
    governor_.record(r.time.total_s, r.attempts == 1 && beside == 0 &&
                                         (r.solver_factorizations == 0 || settings_.solver.method == LinearSolverKind::direct));
  return r;
}

}  // namespace fiberfem::core
