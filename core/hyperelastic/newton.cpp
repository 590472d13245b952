// Newton's method for the static problem (ACCURATE.md section 4).

#include "core/hyperelastic/newton.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace fiberfem::core::hyperelastic {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

double residual_merit(const Assembler& a, const Eigen::VectorXd& R) {
  return a.displacement_norm(R) / a.reference_load_norm() +
         (a.num_pressures() > 0 ? R.tail(a.num_pressures()).lpNorm<1>() / a.volume_m3() : 0.0);
}

void NewtonSettings::validate() const {
  if (load_steps < 1) throw std::invalid_argument("solver.load_steps must be >= 1");
  if (!(tolerance > 0 && tolerance < 1)) throw std::invalid_argument("solver.newton.tolerance must be in (0, 1)");
  if (!(increment_tolerance > 0 && increment_tolerance < 1))
    throw std::invalid_argument("solver.newton.increment_tolerance must be in (0, 1)");
  if (max_iterations < 1) throw std::invalid_argument("solver.newton.max_iterations must be >= 1");
  if (max_cutbacks < 0) throw std::invalid_argument("solver.newton.max_cutbacks must be >= 0");
  if (give_up_after < 0) throw std::invalid_argument("Newton's give_up_after must be >= 0");
  if (threads < 0) throw std::invalid_argument("solver.threads must be >= 0");
}

namespace {

constexpr double kRoundOff = 1e-13;
// Backtracking's bound on the merit's growth: a safeguard, not a descent test (Newton
// across a large rotation passes through larger residuals on its way).
constexpr double kMaxGrowth = 1e3;
// The load predictor's bound on the residual's growth over the unextrapolated state's.
constexpr double kMaxPredictorGrowth = 1e3;

// Backtracking from a full step: halves alpha (20 times at most; once without the line
// search) until `admissible(alpha)` holds. @return that alpha, or 0 when none did.
template <class Admissible>
double backtrack(const NewtonSettings& s, Admissible&& admissible) {
  double alpha = 1.0;
  for (int l = 0; l < (s.line_search ? 20 : 1); ++l, alpha *= 0.5)
    if (admissible(alpha)) return alpha;
  return 0.0;
}

// Whether a solve should give up at iteration `it` with merit `m` (`first`: its merit at
// iteration 0): with s.give_up_after set, Newton that has not got below where it started
// in that many iterations. On the coupled heart (heart-circulation.yaml) such a step went
// on to fail at the 30th iteration nearly always, refactorising at most of them; given
// up at the 4th and retried in substeps, a beat took 549 -> 315 Newton iterations and
// 302 -> 67 factorisations.
bool no_progress(const NewtonSettings& s, int it, double m, double first) {
  return s.give_up_after > 0 && it >= s.give_up_after && m >= first;
}

// Inexact Newton's forcing term: the linear solve to a relative residual that tightens
// with the residual keeps the convergence superlinear (Eisenstat and Walker's choice eta =
// merit), but never tighter than where the iteration ends: from merit m a solve to
// 0.5 tolerance / m already takes the residual below the tolerance, and asking for the
// full eta = m there (about 1e-9) outran the lagged factor on most last iterations and made
// them factorise the tangent afresh (Eisenstat and Walker's safeguard, as Kelley writes it).
// Only while it works: where the residual cannot fall to the tolerance (a stiff penalty
// leaves a round-off floor above it: Land's beam at 500 times the shear modulus stalls at
// 2.6e-9), the looser solve moves the nodes by more than round-off without lowering the
// residual, so the floor's test below never holds and Newton ran on to its cut-backs. So a
// loosened iteration whose merit does not halve turns the floor off for the rest of the
// solve, and the next exact solve stops at the round-off floor as before. The floor is on
// only where NewtonSettings::forcing_floor asks for it (the time steps): on the static
// load increments it cost factorisations instead of saving them.
class Forcing {
 public:
  explicit Forcing(bool floor) : floor_(floor) {}
  double operator()(double m, double tolerance) {
    loosened_ = floor_ && 0.5 * tolerance / m > m;
    m_ = m;
    return std::clamp(floor_ ? std::max(m, 0.5 * tolerance / m) : m, 1e-12, 1e-2);
  }
  /// After the iteration: its merit now.
  void after(double m) {
    if (loosened_ && m > 0.5 * m_) floor_ = false;
  }

 private:
  bool floor_, loosened_ = false;
  double m_ = 0;
};

bool converged_at(const Assembler& a, const Eigen::VectorXd& R, double tolerance) {
  return a.displacement_norm(R) <= tolerance * a.reference_load_norm() &&
         (a.num_pressures() == 0 || R.tail(a.num_pressures()).lpNorm<1>() <= tolerance * a.volume_m3());
}

}  // namespace

bool newton_iterate(const Assembler& assembler, TangentSolver& linear, const ResidualFn& residual, const NewtonSettings& s,
                    Positions& xt, Eigen::VectorXd& pt, Eigen::VectorXd& R, SparseMatrix& K, Evaluation& ev,
                    NewtonReport& rep, bool& singular) {
  const double fref = assembler.reference_load_norm();
  const double length = std::cbrt(assembler.volume_m3());
  Eigen::VectorXd Rn, delta;
  rep.residual_history.clear();
  double first = 0;
  Forcing forcing(s.forcing_floor);
  for (int it = 0; it < s.max_iterations && ev.finite && ev.inverted_elements == 0; ++it) {
    if (converged_at(assembler, R, s.tolerance)) return true;
    // Inexact Newton: the linear solve to a forcing tolerance that tightens with the
    // residual keeps the convergence superlinear (Eisenstat and Walker's choice 1 bound).
    const double m0 = residual_merit(assembler, R);
    if (it == 0) first = m0;
    if (no_progress(s, it, m0, first)) {
      rep.message = "Newton made no progress in " + std::to_string(it) + " iterations";
      return false;
    }
    linear.set_threads(assembler.threads());
    if (!linear.solve(K, R, forcing(m0, s.tolerance), false, delta)) {
      singular = true;
      return false;
    }
    // Backtracking: halve while the step inverts an element, gives a non-finite residual,
    // or multiplies the merit by more than kMaxGrowth. The full step, nearly always taken,
    // is evaluated with its tangent, which the next iteration then needs; a shorter one
    // has its tangent made once it is accepted.
    Positions xn;
    Eigen::VectorXd pn;
    const double alpha = backtrack(s, [&](double a) {
      xn = xt;
      pn = pt;
      assembler.add_increment(delta, -a, xn, pn);
      const auto t0 = Clock::now();
      ev = residual(xn, pn, Rn, a == 1.0 ? &K : nullptr);
      rep.assembly_s += since(t0);
      return ev.finite && ev.inverted_elements == 0 && residual_merit(assembler, Rn) < kMaxGrowth * m0;
    });
    ++rep.iterations;
    if (alpha == 0) return false;
    xt = xn;
    pt = pn;
    if (alpha == 1.0) {
      R.swap(Rn);
    } else {
      const auto t0 = Clock::now();
      ev = residual(xt, pt, R, &K);
      rep.assembly_s += since(t0);
    }
    rep.residual_history.push_back(assembler.displacement_norm(R) / fref);
    forcing.after(residual_merit(assembler, R));
    // Round-off floor: the update moved no node by more than round-off of the body's
    // size and the residual stopped falling. No iteration can do better; accept it.
    const double moved = alpha * delta.head(assembler.num_free_displacements()).lpNorm<Eigen::Infinity>();
    if (moved <= kRoundOff * length && residual_merit(assembler, R) > 0.5 * m0) {
      rep.message = "stopped at the round-off floor (relative residual " + std::to_string(rep.residual_history.back()) + ")";
      return true;
    }
  }
  return ev.finite && ev.inverted_elements == 0 && converged_at(assembler, R, s.tolerance);
}

bool newton_iterate_bordered(const Assembler& assembler, TangentSolver& linear, const Border& border, const NewtonSettings& s,
                             Positions& xt, Eigen::VectorXd& pt, Eigen::VectorXd& Pt, NewtonReport& rep, bool& singular) {
  const double length = std::cbrt(assembler.volume_m3());
  const Eigen::Index m = Pt.size();
  Eigen::VectorXd R, Rn, delta, g, gn;
  SparseMatrix K;
  std::vector<Eigen::VectorXd> G, u, z(static_cast<size_t>(m));
  Eigen::MatrixXd dg_dP;
  // The border's constraints scaled by their tolerances, added to the force merit.
  const auto merit_of = [&](const Eigen::VectorXd& r, const Eigen::VectorXd& gg) {
    return residual_merit(assembler, r) + s.tolerance * gg.cwiseQuotient(border.tolerance).cwiseAbs().sum();
  };
  auto t0 = Clock::now();
  Evaluation ev = border.residual(xt, pt, Pt, R, &K);
  rep.assembly_s += since(t0);
  rep.residual_history.clear();
  double first = 0;
  Forcing force(s.forcing_floor);
  for (int it = 0; it < s.max_iterations && ev.finite && ev.inverted_elements == 0; ++it) {
    border.constraints(xt, Pt, g, G, dg_dP);
    const bool border_met = (g.cwiseAbs().array() <= border.tolerance.array()).all();
    if (border_met && converged_at(assembler, R, s.tolerance)) return true;
    const double m0 = merit_of(R, g);
    if (it == 0) first = m0;
    if (no_progress(s, it, m0, first)) {
      rep.message = "Newton made no progress in " + std::to_string(it) + " iterations";
      return false;
    }
    const double forcing = force(residual_merit(assembler, R), s.tolerance);
    linear.set_threads(assembler.threads());
    if (!linear.solve(K, R, forcing, false, delta)) {
      singular = true;
      return false;
    }
    // The responses to each bordered unknown, to the same forcing (an inexact Schur
    // complement slows Newton less than refactorising for tighter solves), each from its
    // value at the last iteration: the tangent and u_k move little between iterations.
    border.unit_residuals(xt, u);
    for (Eigen::Index k = 0; k < m; ++k)
      if (!linear.solve(K, u[static_cast<size_t>(k)], forcing, false, z[static_cast<size_t>(k)], /*warm=*/it > 0)) {
        singular = true;
        return false;
      }
    // R + K dx + U dP = 0 and g + G.dx + dg/dP dP = 0, with dx = -delta - Z dP:
    // (dg/dP - G^T Z) dP = -g + G^T delta.
    Eigen::MatrixXd S = dg_dP;
    Eigen::VectorXd rhs = -g;
    for (Eigen::Index k = 0; k < m; ++k) {
      rhs(k) += G[static_cast<size_t>(k)].dot(delta);
      for (Eigen::Index j = 0; j < m; ++j) S(k, j) -= G[static_cast<size_t>(k)].dot(z[static_cast<size_t>(j)]);
    }
    const Eigen::VectorXd dP = S.fullPivLu().solve(rhs);
    Eigen::VectorXd increment = -delta;
    for (Eigen::Index j = 0; j < m; ++j) increment -= dP(j) * z[static_cast<size_t>(j)];
    if (!increment.allFinite() || !dP.allFinite()) return false;
    Positions xn;
    Eigen::VectorXd pn, Pn;
    const double alpha = backtrack(s, [&](double a) {
      xn = xt;
      pn = pt;
      Pn = Pt + a * dP;
      assembler.add_increment(increment, a, xn, pn);
      t0 = Clock::now();
      ev = border.residual(xn, pn, Pn, Rn, a == 1.0 ? &K : nullptr);  // the full step with its tangent
      rep.assembly_s += since(t0);
      if (!ev.finite || ev.inverted_elements > 0) return false;
      try {
        std::vector<Eigen::VectorXd> Gn;
        Eigen::MatrixXd dn;
        border.constraints(xn, Pn, gn, Gn, dn);
      } catch (const std::runtime_error&) {
        return false;
      }
      return merit_of(Rn, gn) < kMaxGrowth * m0;
    });
    ++rep.iterations;
    if (alpha == 0) return false;
    xt = xn;
    pt = pn;
    Pt = Pn;
    if (alpha == 1.0) {
      R.swap(Rn);
    } else {
      t0 = Clock::now();
      ev = border.residual(xt, pt, Pt, R, &K);
      rep.assembly_s += since(t0);
    }
    rep.residual_history.push_back(assembler.displacement_norm(R) / assembler.reference_load_norm());
    force.after(residual_merit(assembler, R));
    const double moved = alpha * increment.head(assembler.num_free_displacements()).lpNorm<Eigen::Infinity>();
    if (moved <= kRoundOff * length && merit_of(R, gn) > 0.5 * m0) {
      rep.message = "stopped at the round-off floor (relative residual " + std::to_string(rep.residual_history.back()) + ")";
      return (gn.cwiseAbs().array() <= border.tolerance.array()).all();
    }
  }
  if (!ev.finite || ev.inverted_elements > 0) return false;
  border.constraints(xt, Pt, g, G, dg_dP);
  return (g.cwiseAbs().array() <= border.tolerance.array()).all() && converged_at(assembler, R, s.tolerance);
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
  TangentSolver linear;
  SparseMatrix K;
  Eigen::VectorXd R;
  Positions x = x_io;
  Eigen::VectorXd p = p_io;
  // The last converged increment, for the predictor.
  Positions dx_last;
  Eigen::VectorXd dp_last;
  double dlambda_last = 0;
  double lambda = 0, dlambda = 1.0 / s.load_steps;
  bool singular = false;  // a tangent that could not be factorised
  bool loose = s.increment_tolerance > s.tolerance;  // increments before the last to increment_tolerance
  while (lambda < 1.0 - 1e-14) {
    const double target = std::min(1.0, lambda + dlambda);
    const ResidualFn residual = [&](const Positions& xa, const Eigen::VectorXd& pa, Eigen::VectorXd& Ra, SparseMatrix* Ka) {
      return assembler.evaluate(xa, pa, target, Ra, Ka);
    };
    // Predictor: the last increment extrapolated linearly in the load factor, unless that
    // inverts an element or has left the region where the linearisation holds: a residual
    // more than kMaxPredictorGrowth times the state's own at the new load. Extrapolating
    // starts an increment nearer equilibrium even where its residual is several times the
    // state's (Land problem 2: 4 to 33 times, and 45 Newton iterations against 53 from the
    // state), but not after an increment that was mostly the body settling into its first
    // loaded shape (Land problem 3's first increment, doubled: 6,500 times, and 15
    // iterations instead of 6). The state's residual costs one evaluation without the
    // tangent.
    Positions xt = x;
    Eigen::VectorXd pt = p;
    const auto t0 = Clock::now();
    Evaluation ev;
    bool extrapolated = false;  // then R, K and ev are already the predictor's
    if (dlambda_last > 0) {
      const double f = (target - lambda) / dlambda_last;
      const Positions xe = x + f * dx_last;
      const Eigen::VectorXd pe = p + f * dp_last;
      const Evaluation ee = residual(xe, pe, R, &K);
      if (ee.finite && ee.inverted_elements == 0) {
        Eigen::VectorXd Rs;
        const Evaluation es = residual(x, p, Rs, nullptr);
        if (!(es.finite && es.inverted_elements == 0) || residual_merit(assembler, R) <= kMaxPredictorGrowth * residual_merit(assembler, Rs)) {
          xt = xe;
          pt = pe;
          ev = ee;
          extrapolated = true;
        }
      }
    }
    if (!extrapolated) ev = residual(xt, pt, R, &K);
    rep.assembly_s += since(t0);
    // Only the last increment's state is the answer: the ones before it need only be near
    // enough for the next to start from (Land problem 3: 41 -> 19 Newton iterations, 3 ->
    // 2 factorisations, the final probes equal to 1e-9 of their value).
    NewtonSettings increment = s;
    if (loose && target < 1.0 - 1e-14) increment.tolerance = s.increment_tolerance;
    const bool converged = newton_iterate(assembler, linear, residual, increment, xt, pt, R, K, ev, rep, singular);
    ++rep.load_steps;
    if (!converged && loose && !singular) {
      // An increment that fails from a loosely converged state may need a better start (a
      // stiff penalty on Land problem 3 could not go on from one): the state is solved to
      // the full tolerance at its own load, every later increment too, and the increment
      // is tried again.
      loose = false;
      if (lambda > 0) {
        Positions xs = x;
        Eigen::VectorXd ps = p, Rs;
        const ResidualFn at_state = [&](const Positions& xa, const Eigen::VectorXd& pa, Eigen::VectorXd& Ra, SparseMatrix* Ka) {
          return assembler.evaluate(xa, pa, lambda, Ra, Ka);
        };
        const auto t1 = Clock::now();
        Evaluation es = at_state(xs, ps, Rs, &K);
        rep.assembly_s += since(t1);
        if (newton_iterate(assembler, linear, at_state, s, xs, ps, Rs, K, es, rep, singular)) {
          x = xs;
          p = ps;
        }
      }
      if (!singular) continue;
    }
    if (converged) {
      rep.relative_residual = assembler.displacement_norm(R) / assembler.reference_load_norm();
      dx_last = xt - x;
      dp_last = pt - p;
      dlambda_last = target - lambda;
      x = xt;
      p = pt;
      lambda = target;
      continue;
    }
    if (rep.cutbacks >= s.max_cutbacks || singular) {
      char msg[256];
      std::snprintf(msg, sizeof msg,
                    "the load cannot be carried: Newton did not converge beyond load factor %.4g (increment %.3g, %d "
                    "cut-backs); use more solver.load_steps or a smaller load",
                    lambda, dlambda, rep.cutbacks);
      rep.message = msg;
      if (singular && lambda == 0)
        rep.message = "the tangent could not be factorised at the rest state (the sparse LU found it singular or ran "
                      "out of memory): the body is not held against rigid motion; or linear tetrahedra with "
                      "material.incompressible (one pressure per element locks them, with about as many pressures as "
                      "free displacements: use mesh.order 2 or a material.bulk_modulus); or the mesh is beyond what the "
                      "direct solver handles here";
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
