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
      max_iterations_(max_iterations) {
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
  std::vector<int> loads;
  Eigen::VectorXd P(m), tolerance(m);
  for (int k = 0; k < m; ++k) {
    const CoupledCavity& c = cavities_[static_cast<size_t>(k)];
    loads.push_back(c.pressure_load);
    P(k) = state_.external_pa[slot(c.chamber)];
    tolerance(k) = tolerance_ * rest_volumes_[static_cast<size_t>(k)];
  }
  circulation::State loop;
  Border border;
  border.tolerance = tolerance;
  // g_k = V_k(x) - V_loop,k(P): the cavity's volume against the loop's after its step with
  // the ventricle pressures P.
  border.constraints = [&](const Positions& x, const Eigen::VectorXd& pressures, Eigen::VectorXd& g,
                           std::vector<Eigen::VectorXd>& G, Eigen::MatrixXd& dg_dP) {
    std::array<double, 2> ext = state_.external_pa;
    for (int k = 0; k < m; ++k) ext[slot(cavities_[static_cast<size_t>(k)].chamber)] = pressures(k);
    Eigen::Matrix2d dloop;
    loop = circulation::step(parameters_, state_, h, ext, &dloop);
    g.resize(m);
    G.resize(static_cast<size_t>(m));
    dg_dP.resize(m, m);
    for (int k = 0; k < m; ++k) {
      const CoupledCavity& c = cavities_[static_cast<size_t>(k)];
      g(k) = volume(k, x) - loop.volume_m3[static_cast<size_t>(c.chamber)];
      G[static_cast<size_t>(k)] = solver_.assembler().equation_rows(cavity_volume_gradient(c.surface, x));
      for (int j = 0; j < m; ++j)
        dg_dP(k, j) = -dloop(static_cast<Eigen::Index>(slot(c.chamber)),
                             static_cast<Eigen::Index>(slot(cavities_[static_cast<size_t>(j)].chamber)));
    }
  };
  Positions x = solver_.predicted_positions();
  Eigen::VectorXd p = solver_.pressures();
  const DynamicStepReport r = solver_.solve_step_bordered(std::move(loading), loads, border, x, p, P);
  rep.newton_iterations = r.iterations;
  rep.pressure_iterations = r.iterations;
  if (!r.converged) {
    rep.message = r.message;
    return rep;
  }
  std::vector<Eigen::VectorXd> G;
  Eigen::VectorXd g;
  Eigen::MatrixXd dg;
  border.constraints(x, P, g, G, dg);  // the loop's state at the converged pressures
  solver_.accept_step(x, p);
  state_ = loop;
  for (int k = 0; k < m; ++k) volumes_[static_cast<size_t>(k)] = volume(k, x);
  last_iterations_ = rep.pressure_iterations;
  rep.converged = true;
  return rep;
}

DynamicState CirculationCoupledDynamics::checkpoint() const {
  DynamicState s = solver_.state();
  s.circulation = state_;
  s.cavity_volume_m3 = volumes_;
  return s;
}

void CirculationCoupledDynamics::restore(const DynamicState& s) {
  if (s.cavity_volume_m3.size() != cavities_.size())
    throw std::invalid_argument("dynamic state: " + std::to_string(s.cavity_volume_m3.size()) + " coupled cavities, the run has " +
                                std::to_string(cavities_.size()));
  solver_.restore(s);
  state_ = s.circulation;
  volumes_ = s.cavity_volume_m3;
  last_iterations_ = 0;
}

void CirculationCoupledDynamics::continue_from(const CirculationCoupledDynamics& previous) {
  if (previous.cavities_.size() != cavities_.size()) throw std::invalid_argument("circulation: another set of coupled cavities");
  state_ = previous.state_;
  // A new heart rate: the beat under way keeps its time (as the real-time tier's).
  if (parameters_.period_s != previous.parameters_.period_s) circulation::keep_beat_phase(state_, previous.parameters_.period_s);
  volumes_ = previous.volumes_;
}

}  // namespace fiberfem::core::hyperelastic
