// Backward-Euler steps with Newton's method (ACCURATE.md section 4).

#include "core/hyperelastic/dynamic.hpp"

#include <cmath>
#include <stdexcept>

namespace fiberfem::core::hyperelastic {

void DynamicSettings::validate() const {
  if (!(dt_s > 0) || !std::isfinite(dt_s)) throw std::invalid_argument("solver.dt must be > 0 s");
  if (!(mass_damping_1_s >= 0) || !std::isfinite(mass_damping_1_s))
    throw std::invalid_argument("regions[].damping.mass must be finite and >= 0");
  newton.validate();
  if (give_up_after < 0) throw std::invalid_argument("dynamic: give_up_after must be >= 0");
}

DynamicSolver::DynamicSolver(const Problem& problem, const DynamicSettings& settings)
    : problem_(problem), settings_(settings), assembler_(problem), linear_(/*keeps_state=*/true) {
  settings_.validate();
  settings_.newton.give_up_after = settings_.give_up_after;
  settings_.newton.forcing_floor = true;
  if (problem.region_density_kg_m3.empty())
    throw std::invalid_argument("dynamic: every region needs a density > 0");
  for (double rho : problem.region_density_kg_m3)
    if (!(rho > 0)) throw std::invalid_argument("dynamic: every region needs a density > 0");
  assembler_.set_threads(settings_.newton.threads);
  x_ = problem.mesh->rest_positions();
  v_ = Positions::Zero(3, x_.cols());
  p_ = Eigen::VectorXd::Zero(assembler_.num_pressures());
  totals_.equations = assembler_.num_equations();
}

DynamicStepReport DynamicSolver::step(const Loading& loading) {
  // Predictor: the last velocity carried over the step (free components only move).
  Positions x = predicted_positions();
  Eigen::VectorXd p = p_;
  DynamicStepReport rep = solve_step(loading, x, p);
  if (rep.converged) accept_step(x, p);
  return rep;
}

DynamicStepReport DynamicSolver::solve_step(const Loading& loading, Positions& x, Eigen::VectorXd& p) {
  const double h = dt_s();
  const ResidualFn residual = [&](const Positions& xx, const Eigen::VectorXd& pp, Eigen::VectorXd& R, SparseMatrix* K) {
    const Evaluation ev = assembler_.evaluate(xx, pp, loading, R, K);
    assembler_.add_inertia(xx, x_, v_, h, settings_.mass_damping_1_s, R, K);
    return ev;
  };
  Eigen::VectorXd R;
  Evaluation ev = residual(x, p, R, &K_);
  if (start_is_better(residual, x, p, ev, R)) {
    x = x_;
    ev = residual(x, p, R, &K_);
  }
  NewtonReport counters;
  bool singular = false;
  const bool converged = newton_iterate(assembler_, linear_, residual, settings_.newton, x, p, R, K_, ev, counters, singular);
  if (converged) solved_energy_j_ = ev.energy_j;  // newton_iterate's last evaluation is at x
  return finish_solve(counters, converged, singular);
}

// The predictor x + h v carries the last step's velocity over the step. Where the last
// step was a jolt (the heart's first steps, filling from rest; the onset of a contraction)
// that leaves Newton farther from the answer than the step's start: on the coupled heart
// (heart-circulation.yaml) starting each step from the smaller of the two residuals took
// a beat in 549 Newton iterations instead of 750 (476 -> 302 factorisations). The start's residual costs one evaluation
// without the tangent.
bool DynamicSolver::start_is_better(const ResidualFn& residual, const Positions& x, const Eigen::VectorXd& p,
                                    const Evaluation& ev, const Eigen::VectorXd& R) const {
  if (!ev.finite || ev.inverted_elements > 0) return true;
  if (x.data() == x_.data() || x == x_) return false;
  Eigen::VectorXd Rs;
  const Evaluation es = residual(x_, p, Rs, nullptr);
  return es.finite && es.inverted_elements == 0 && residual_merit(assembler_, Rs) < residual_merit(assembler_, R);
}

DynamicStepReport DynamicSolver::finish_solve(const NewtonReport& counters, bool converged, bool singular) {
  totals_.iterations += counters.iterations;
  totals_.assembly_s += counters.assembly_s;
  DynamicStepReport rep;
  rep.iterations = counters.iterations;
  rep.converged = converged;
  if (converged) return rep;
  // Newton's own message says why where it has one (not the round-off floor's note).
  if (singular) rep.message = "the step's tangent is singular";
  else if (!counters.message.empty() && counters.message.find("round-off") == std::string::npos) rep.message = counters.message;
  else
    rep.message = "Newton did not converge in " + std::to_string(settings_.newton.max_iterations) +
                  " iterations (a smaller solver.dt, or a softer load)";
  return rep;
}

DynamicStepReport DynamicSolver::solve_step_bordered(Loading loading, const std::vector<int>& loads, Border border, Positions& x,
                                                     Eigen::VectorXd& p, Eigen::VectorXd& P) {
  const double h = dt_s();
  loading.pressure_factors.resize(problem_.pressures.size(), 1.0);
  // The tangent evaluations are at the iterates taken: the last is at the converged end.
  double energy_at_iterate = 0;
  border.residual = [&](const Positions& xx, const Eigen::VectorXd& pp, const Eigen::VectorXd& PP, Eigen::VectorXd& R,
                        SparseMatrix* K) {
    for (size_t k = 0; k < loads.size(); ++k) loading.pressure_factors[static_cast<size_t>(loads[k])] = PP(static_cast<Eigen::Index>(k));
    const Evaluation ev = assembler_.evaluate(xx, pp, loading, R, K);
    assembler_.add_inertia(xx, x_, v_, h, settings_.mass_damping_1_s, R, K);
    if (K != nullptr) energy_at_iterate = ev.energy_j;
    return ev;
  };
  border.unit_residuals = [&](const Positions& xx, std::vector<Eigen::VectorXd>& u) {
    u.resize(loads.size());
    for (size_t k = 0; k < loads.size(); ++k) u[k] = assembler_.unit_pressure_residual(xx, loads[k]);
  };
  Eigen::VectorXd R;
  const Evaluation ev = border.residual(x, p, P, R, nullptr);
  const ResidualFn at_P = [&](const Positions& xx, const Eigen::VectorXd& pp, Eigen::VectorXd& RR, SparseMatrix* K) {
    return border.residual(xx, pp, P, RR, K);
  };
  if (start_is_better(at_P, x, p, ev, R)) x = x_;
  NewtonReport counters;
  bool singular = false;
  bool converged = false;
  try {
    converged = newton_iterate_bordered(assembler_, linear_, border, settings_.newton, x, p, P, counters, singular);
  } catch (const std::runtime_error& e) {  // the constraints could not be evaluated
    counters.message = e.what();
  }
  if (converged) solved_energy_j_ = energy_at_iterate;
  return finish_solve(counters, converged, singular);
}

void DynamicSolver::accept_step(const Positions& x, const Eigen::VectorXd& p) {
  v_ = (x - x_) / dt_s();
  x_ = x;
  p_ = p;
  energy_j_ = solved_energy_j_;
  t_s_ += dt_s();
  if (++substep_ == substeps_) {
    substep_ = 0;
    ++steps_;
  }
}

void DynamicSolver::set_substeps(int n) {
  if (n < 1) throw std::invalid_argument("dynamic: substeps must be >= 1");
  if (substep_ != 0) throw std::invalid_argument("dynamic: substeps changed in the middle of a step");
  substeps_ = n;
}

DynamicState DynamicSolver::state() const { return {x_, v_, p_, t_s_, steps_, linear_.state(), {}, {}}; }

void DynamicSolver::continue_from(DynamicSolver& previous) {
  DynamicState s{previous.x_, previous.v_, previous.p_, previous.t_s_, previous.steps_, {}, {}, {}};
  restore(s);  // checks the sizes; no factor yet
  linear_.take_memory(previous.linear_);
}

void DynamicSolver::restore(const DynamicState& s) {
  const auto bad = [](const std::string& m) { throw std::invalid_argument("dynamic state: " + m); };
  if (s.x.cols() != x_.cols() || s.v.cols() != x_.cols() || s.x.rows() != 3 || s.v.rows() != 3)
    bad("positions and velocities for " + std::to_string(s.x.cols()) + " nodes, the problem has " + std::to_string(x_.cols()));
  if (s.p.size() != p_.size())
    bad(std::to_string(s.p.size()) + " pressures, the problem has " + std::to_string(p_.size()));
  if (!s.x.allFinite() || !s.v.allFinite() || !s.p.allFinite() || !std::isfinite(s.time_s)) bad("a value is not finite");
  const int n = assembler_.num_equations();
  for (const SparseMatrix* m : {&s.linear.analysed, &s.linear.factored})
    if (m->rows() != 0 && (m->rows() != n || m->cols() != n))
      bad("a lagged factor of " + std::to_string(m->rows()) + " equations, the problem has " + std::to_string(n));
  linear_.restore(s.linear);
  x_ = s.x;
  v_ = s.v;
  p_ = s.p;
  t_s_ = s.time_s;
  steps_ = s.steps;
  substep_ = 0;
  Eigen::VectorXd R;
  energy_j_ = assembler_.evaluate(x_, p_, Loading{}, R, nullptr).energy_j;  // this problem's laws
}

NewtonReport DynamicSolver::totals() const {
  NewtonReport r = totals_;
  r.factorisations = linear_.factorisations();
  r.krylov_iterations = linear_.krylov_iterations();
  r.factor_s = linear_.seconds();
  r.converged = true;
  return r;
}

}  // namespace fiberfem::core::hyperelastic
