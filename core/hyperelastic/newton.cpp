// Newton's method for the static problem (ACCURATE.md section 4).

#include "core/hyperelastic/newton.hpp"

#include "core/hyperelastic/tangent_solver.hpp"

#include <algorithm>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace fiberfem::core::hyperelastic {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }


}  // namespace

void NewtonSettings::validate() const {
  if (load_steps < 1) throw std::invalid_argument("solver.load_steps must be >= 1");
  if (!(tolerance > 0 && tolerance < 1)) throw std::invalid_argument("solver.newton.tolerance must be in (0, 1)");
  if (max_iterations < 1) throw std::invalid_argument("solver.newton.max_iterations must be >= 1");
  if (max_cutbacks < 0) throw std::invalid_argument("solver.newton.max_cutbacks must be >= 0");
  if (threads < 0) throw std::invalid_argument("solver.threads must be >= 0");
}

NewtonReport solve_static(const Problem& problem, Positions& x_io, Eigen::VectorXd& p_io, const NewtonSettings& s) {
  s.validate();
  Assembler assembler(problem);
  assembler.set_threads(s.threads);
  const ElementMesh& mesh = *problem.mesh;
  if (x_io.cols() == 0) x_io = mesh.rest_positions();
  if (x_io.cols() != mesh.num_nodes()) throw std::invalid_argument("static: initial positions have the wrong node count");
  if (p_io.size() != assembler.num_pressures()) p_io = Eigen::VectorXd::Zero(assembler.num_pressures());
  // Fixed components sit at rest.
  for (size_t d = 0; d < problem.fixed_dofs.size(); ++d)
    if (problem.fixed_dofs[d]) x_io.data()[d] = mesh.rest_positions().data()[d];

  NewtonReport rep;
  rep.equations = assembler.num_equations();
  const double fref = assembler.reference_load_norm();
  const double volume = assembler.volume_m3();
  const double length = std::cbrt(volume);
  constexpr double kRoundOff = 1e-13;
  // One merit for both kinds of rows: the force rows against the load, the volume rows
  // against the body's volume.
  auto merit = [&](const Eigen::VectorXd& R) {
    return assembler.displacement_norm(R) / fref + (assembler.num_pressures() > 0 ? R.tail(assembler.num_pressures()).lpNorm<1>() / volume : 0.0);
  };
  auto converged_at = [&](const Eigen::VectorXd& R) {
    return assembler.displacement_norm(R) <= s.tolerance * fref &&
           (assembler.num_pressures() == 0 || R.tail(assembler.num_pressures()).lpNorm<1>() <= s.tolerance * volume);
  };

  TangentSolver linear;
  SparseMatrix K;
  Eigen::VectorXd R, Rn, delta;
  Positions x = x_io;
  Eigen::VectorXd p = p_io;
  // The last converged increment, for the predictor.
  Positions dx_last;
  Eigen::VectorXd dp_last;
  double dlambda_last = 0;
  double lambda = 0, dlambda = 1.0 / s.load_steps;
  bool singular = false;  // a tangent that could not be factorised
  while (lambda < 1.0 - 1e-14) {
    const double target = std::min(1.0, lambda + dlambda);
    // Predictor: the last increment extrapolated linearly in the load factor (the state
    // itself when that inverts an element).
    Positions xt = x;
    Eigen::VectorXd pt = p;
    auto t0 = Clock::now();
    Evaluation ev;
    if (dlambda_last > 0) {
      const double f = (target - lambda) / dlambda_last;
      xt = x + f * dx_last;
      pt = p + f * dp_last;
      ev = assembler.evaluate(xt, pt, target, R, &K);
      if (!ev.finite || ev.inverted_elements > 0) xt = x, pt = p;
    }
    if (dlambda_last == 0 || !ev.finite || ev.inverted_elements > 0) ev = assembler.evaluate(xt, pt, target, R, &K);
    rep.assembly_s += since(t0);
    bool converged = false;
    std::vector<double> history;
    for (int it = 0; it < s.max_iterations && ev.finite && ev.inverted_elements == 0; ++it) {
      if (converged_at(R)) {
        converged = true;
        break;
      }
      // Inexact Newton: the linear solve to a forcing tolerance that tightens with the
      // residual keeps the convergence superlinear (Eisenstat and Walker's choice 1 bound).
      const double forcing = std::clamp(merit(R), 1e-12, 1e-2);
      if (!linear.solve(K, R, forcing, false, delta)) {
        singular = true;
        break;
      }
      // Backtracking: halve while the step inverts an element, gives a non-finite residual,
      // or multiplies the merit by more than kMaxGrowth (a safeguard, not a descent test:
      // Newton across a large rotation passes through larger residuals on its way).
      constexpr double kMaxGrowth = 1e3;
      const double m0 = merit(R);
      double alpha = 1.0;
      Positions xn;
      Eigen::VectorXd pn;
      bool accepted = false;
      for (int l = 0; l < (s.line_search ? 20 : 1); ++l, alpha *= 0.5) {
        xn = xt;
        pn = pt;
        assembler.add_increment(delta, -alpha, xn, pn);
        t0 = Clock::now();
        ev = assembler.evaluate(xn, pn, target, Rn, nullptr);
        rep.assembly_s += since(t0);
        if (ev.finite && ev.inverted_elements == 0 && merit(Rn) < kMaxGrowth * m0) {
          accepted = true;
          break;
        }
      }
      ++rep.iterations;
      if (!accepted) break;
      xt = xn;
      pt = pn;
      t0 = Clock::now();
      ev = assembler.evaluate(xt, pt, target, R, &K);
      rep.assembly_s += since(t0);
      history.push_back(assembler.displacement_norm(R) / fref);
      // Round-off floor: the update moved no node by more than round-off of the body's
      // size and the residual stopped falling. No iteration can do better; accept it.
      const double moved = alpha * delta.head(assembler.num_free_displacements()).lpNorm<Eigen::Infinity>();
      if (moved <= kRoundOff * length && merit(R) > 0.5 * m0) {
        converged = true;
        rep.message = "stopped at the round-off floor (relative residual " + std::to_string(history.back()) + ")";
        break;
      }
    }
    if (!converged && ev.finite && ev.inverted_elements == 0 && converged_at(R)) converged = true;
    ++rep.load_steps;
    rep.residual_history = history;
    if (converged) {
      dx_last = xt - x;
      dp_last = pt - p;
      dlambda_last = target - lambda;
      x = xt;
      p = pt;
      lambda = target;
      rep.relative_residual = assembler.displacement_norm(R) / fref;
      continue;
    }
    if (rep.cutbacks >= s.max_cutbacks) {
      char msg[256];
      std::snprintf(msg, sizeof msg,
                    "the load cannot be carried: Newton did not converge beyond load factor %.4g (increment %.3g, %d "
                    "cut-backs); use more solver.load_steps or a smaller load",
                    lambda, dlambda, rep.cutbacks);
      rep.message = msg;
      if (singular && lambda == 0)
        rep.message = "the tangent is singular at the rest state: the body is not held against rigid motion, or "
                      "linear tetrahedra with material.incompressible (one pressure per element locks them, with about "
                      "as many pressures as free displacements); use mesh.order 2 or a material.bulk_modulus";
      break;
    }
    dlambda *= 0.5;
    ++rep.cutbacks;
  }
  rep.converged = lambda >= 1.0 - 1e-14;
  rep.load_factor = rep.converged ? 1.0 : lambda;
  rep.factorisations = linear.factorisations();
  rep.krylov_iterations = linear.krylov_iterations();
  rep.factor_s = linear.seconds();
  x_io = x;
  p_io = p;
  return rep;
}

}  // namespace fiberfem::core::hyperelastic
