#include "core/hyperelastic/circulation_coupling.hpp"

#include <Eigen/LU>

#include <cmath>
#include <stdexcept>

namespace fiberfem::core::hyperelastic {
namespace {

size_t slot(circulation::ChamberId c) { return c == circulation::lv ? 0 : 1; }

}  // namespace

CirculationCoupledDynamics::CirculationCoupledDynamics(DynamicSolver& solver, const Problem& problem,
                                                       circulation::Parameters parameters, circulation::State initial,
                                                       std::vector<CoupledCavity> cavities, double volume_tolerance,
                                                       int max_iterations)
    : solver_(solver),
      parameters_(std::move(parameters)),
      state_(initial),
      cavities_(std::move(cavities)),
      tolerance_(volume_tolerance),
      max_iterations_(max_iterations),
      num_loads_(static_cast<int>(problem.pressures.size())) {
  if (cavities_.empty() || cavities_.size() > 2) throw std::invalid_argument("circulation: one or two cavities");
  for (const CoupledCavity& c : cavities_) {
    if (c.pressure_load < 0 || c.pressure_load >= static_cast<int>(problem.pressures.size()))
      throw std::invalid_argument("circulation: cavity pressure load index out of range");
    if (problem.pressures[static_cast<size_t>(c.pressure_load)].pressure_pa != 1.0)
      throw std::invalid_argument("circulation: a cavity's pressure load must be 1 Pa (scaled per step)");
    parameters_.chambers[static_cast<size_t>(c.chamber)].kind = circulation::ChamberKind::external;
  }
  parameters_.validate();
  state_.external_pa = {0, 0};
  for (int k = 0; k < static_cast<int>(cavities_.size()); ++k) {
    const double v = volume(k, solver_.positions());
    rest_volumes_.push_back(v);
    volumes_.push_back(v);
    state_.volume_m3[static_cast<size_t>(cavities_[static_cast<size_t>(k)].chamber)] = v;
  }
}

CoupledStepReport CirculationCoupledDynamics::step(Loading loading) {
  const int m = static_cast<int>(cavities_.size());
  const double h = solver_.dt_s();
  CoupledStepReport rep;
  // The caller's factors for its own loads (ramps) are kept; the cavities' are set below.
  loading.pressure_factors.resize(static_cast<size_t>(num_loads_), 1.0);
  struct Eval {
    Positions x;
    Eigen::VectorXd p, residual, volume;
    circulation::State loop;
    Eigen::Matrix2d dloop;
    bool ok = false;
  };
  Positions guess = solver_.predicted_positions();
  Eigen::VectorXd guess_p = solver_.pressures();
  const auto evaluate = [&](const Eigen::VectorXd& pressures) {
    Eval e;
    std::array<double, 2> ext = state_.external_pa;
    for (int k = 0; k < m; ++k) {
      const CoupledCavity& c = cavities_[static_cast<size_t>(k)];
      loading.pressure_factors[static_cast<size_t>(c.pressure_load)] = pressures(k);
      ext[slot(c.chamber)] = pressures(k);
    }
    e.x = guess;
    e.p = guess_p;
    const DynamicStepReport s = solver_.solve_step(loading, e.x, e.p);
    rep.newton_iterations += s.iterations;
    ++rep.pressure_iterations;
    if (!s.converged) {
      rep.message = s.message;
      return e;
    }
    e.loop = circulation::step(parameters_, state_, h, ext, &e.dloop);
    e.volume.resize(m);
    e.residual.resize(m);
    for (int k = 0; k < m; ++k) {
      e.volume(k) = volume(k, e.x);
      e.residual(k) = e.volume(k) - e.loop.volume_m3[static_cast<size_t>(cavities_[static_cast<size_t>(k)].chamber)];
    }
    e.ok = true;
    guess = e.x;  // the next iteration starts from here
    guess_p = e.p;
    return e;
  };
  const auto size_of = [&](const Eigen::VectorXd& r) {
    double s = 0;
    for (int k = 0; k < m; ++k) s = std::max(s, std::abs(r(k)) / rest_volumes_[static_cast<size_t>(k)]);
    return s;
  };
  const auto loop_slope = [&](const Eval& e) {
    Eigen::MatrixXd J(m, m);
    for (int k = 0; k < m; ++k)
      for (int j = 0; j < m; ++j)
        J(k, j) = e.dloop(static_cast<Eigen::Index>(slot(cavities_[static_cast<size_t>(k)].chamber)),
                          static_cast<Eigen::Index>(slot(cavities_[static_cast<size_t>(j)].chamber)));
    return J;
  };
  Eigen::VectorXd p(m);
  for (int k = 0; k < m; ++k) p(k) = state_.external_pa[slot(cavities_[static_cast<size_t>(k)].chamber)];
  Eval e = evaluate(p);
  if (!e.ok) return rep;
  if (!have_slope_) {  // the cavities' volume slope by finite differences, once
    slope_.resize(m, m);
    for (int j = 0; j < m; ++j) {
      Eigen::VectorXd q = p;
      const double dp = 1e-3 * std::abs(p(j)) + 10.0;
      q(j) += dp;
      const Eval f = evaluate(q);
      if (!f.ok) return rep;
      slope_.col(j) = (f.volume - e.volume) / dp;
    }
    have_slope_ = true;
    guess = e.x;
    guess_p = e.p;
  }
  double size = size_of(e.residual);
  while (size > tolerance_ && rep.pressure_iterations < max_iterations_) {
    const Eigen::VectorXd dp = (slope_ - loop_slope(e)).partialPivLu().solve(-e.residual);
    const Eval f = evaluate(p + dp);
    if (!f.ok) return rep;
    // Broyden's update of the cavities' slope from the volumes' change, unless the change
    // is within the body's Newton tolerance (a tiny pressure step: the solve may not move).
    const Eigen::VectorXd dv = f.volume - e.volume;
    const Eigen::MatrixXd updated = slope_ + (dv - slope_ * dp) * dp.transpose() / dp.squaredNorm();
    const bool meaningful = updated.diagonal().minCoeff() > 0.2 * slope_.diagonal().minCoeff() &&
                            updated.diagonal().maxCoeff() < 5 * slope_.diagonal().maxCoeff();
    if (meaningful) slope_ = updated;
    p += dp;
    e = f;
    size = size_of(e.residual);
  }
  if (!(size <= tolerance_)) {
    rep.message = "circulation: cavity pressures did not converge (volume mismatch " + std::to_string(size) + " of the rest volume)";
    return rep;
  }
  solver_.accept_step(e.x, e.p);
  state_ = e.loop;
  for (int k = 0; k < m; ++k) volumes_[static_cast<size_t>(k)] = e.volume(k);
  last_iterations_ = rep.pressure_iterations;
  rep.converged = true;
  return rep;
}

DynamicState CirculationCoupledDynamics::checkpoint() const {
  DynamicState s = solver_.state();
  s.circulation = state_;
  s.cavity_volume_m3 = volumes_;
  if (have_slope_) s.cavity_slope = slope_;
  return s;
}

void CirculationCoupledDynamics::restore(const DynamicState& s) {
  if (s.cavity_volume_m3.size() != cavities_.size())
    throw std::invalid_argument("dynamic state: " + std::to_string(s.cavity_volume_m3.size()) + " coupled cavities, the run has " +
                                std::to_string(cavities_.size()));
  const auto n = static_cast<Eigen::Index>(cavities_.size());
  if (s.cavity_slope.size() != 0 && (s.cavity_slope.rows() != n || s.cavity_slope.cols() != n))
    throw std::invalid_argument("dynamic state: a cavity volume slope of the wrong size");
  solver_.restore(s);
  state_ = s.circulation;
  volumes_ = s.cavity_volume_m3;
  have_slope_ = s.cavity_slope.size() != 0;
  slope_ = s.cavity_slope;
  last_iterations_ = 0;
}

void CirculationCoupledDynamics::continue_from(const CirculationCoupledDynamics& previous) {
  if (previous.cavities_.size() != cavities_.size()) throw std::invalid_argument("circulation: another set of coupled cavities");
  state_ = previous.state_;
  volumes_ = previous.volumes_;
  slope_ = previous.slope_;
  have_slope_ = previous.have_slope_;
}

}  // namespace fiberfem::core::hyperelastic
