// The Simulator's coupling to the lumped circulation (Model::circulation,
// docs/circulation.md): per step, the cavity pressures are solved with the velocities so
// that every coupled cavity's volume at the step's end equals the loop's.
#include "core/simulator.hpp"

#include <Eigen/LU>

#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::core {
namespace {

using PressureVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 2, 1>;
using PressureMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 2, 2>;

// Slot of a chamber in circulation::step's external pressures.
size_t external_slot(circulation::ChamberId c) { return c == circulation::lv ? 0 : 1; }

}  // namespace

void Simulator::setup_circulation() {
  circulation::Coupling& c = model_.circulation;
  const auto fail = [](const std::string& what) { throw std::invalid_argument("circulation: " + what); };
  if (c.cavities.size() > 2) fail("at most two cavities (the ventricles) can be coupled");
  if (c.cavities.size() == 2 && c.cavities[0].chamber == c.cavities[1].chamber) fail("both cavities are coupled to one ventricle");
  if (!(c.volume_tolerance > 0 && c.volume_tolerance <= 1e-3))
    fail("volume_tolerance must be in (0, 1e-3], got " + std::to_string(c.volume_tolerance));
  if (c.max_iterations < 1 || c.max_iterations > 200) fail("max_iterations must be in [1, 200]");
  for (const circulation::CoupledCavity& cav : c.cavities) {
    if (cav.chamber != circulation::lv && cav.chamber != circulation::rv) fail("cavity " + cav.name + " is not a ventricle");
    c.parameters.chambers[static_cast<size_t>(cav.chamber)].kind = circulation::ChamberKind::external;
    // The pressure does work on the cavity's volume only if the lid across its rim stays
    // put: every rim node must be fixed.
    const int open = open_rim_nodes(cav.surface, model_.fixed_dofs);
    if (open > 0)
      fail("cavity " + cav.name + " is not closed: " + std::to_string(open) + " of the " +
           std::to_string(cav.surface.rim_nodes.size()) + " nodes of its rim are not fixed (fix the base)");
    cavity_rest_volume_.push_back(cavity_volume(cav.surface, model_.mesh.rest_positions()));
    SurfaceLoad unit;
    unit.faces = cav.surface.faces;
    unit.pressure_pa = 1.0;
    unit.follower = true;
    cavity_loads_.push_back(std::move(unit));
  }
  c.parameters.validate();
  const size_t m = c.cavities.size();
  cavity_force_.resize(m);
  cavity_rhs_.resize(m);
  cavity_shift_.resize(m);
}

void Simulator::reset_circulation() {
  const circulation::Coupling& c = model_.circulation;
  st_.circulation = c.initial;
  st_.circulation.time_s = 0;
  st_.circulation.external_pa = {0, 0};  // the rest shape carries no pressure
  st_.cavity_response.assign(c.cavities.size(), Eigen::VectorXd::Zero(sys_.num_free()));
  st_.cavity_volume_m3.clear();
  for (const circulation::CoupledCavity& cav : c.cavities) {
    const double v = cavity_volume(cav.surface, model_.mesh.rest_positions());
    st_.circulation.volume_m3[static_cast<size_t>(cav.chamber)] = v;
    st_.cavity_volume_m3.push_back(v);
  }
  st_.circulation_iterations = 0;
}

void Simulator::set_circulation_parameters(circulation::Parameters p) {
  circulation::Coupling& c = model_.circulation;
  if (!c.enabled()) throw std::invalid_argument("circulation: this model has no circulation (scene key circulation)");
  for (const circulation::CoupledCavity& cav : c.cavities) p.chambers[static_cast<size_t>(cav.chamber)].kind = circulation::ChamberKind::external;
  p.validate();
  if (p.period_s != c.parameters.period_s) circulation::keep_beat_phase(st_.circulation, c.parameters.period_s);
  c.parameters = std::move(p);
}

// The step is affine in the cavity pressures p (the follower loads are taken at the step's
// start): v(p) = v(p*) + sum_k (p_k - p*_k) s_k with A s_k = h g_k, g_k the forces of a unit
// pressure on cavity k. One solve at the predicted pressures p* (the last step's) and one
// per cavity give every v(p); Newton then solves V_3D(x_n + h v(p)) = V_0D(p) for p, where
// V_0D is the loop's backward-Euler step with those ventricle pressures. Each iteration
// costs volume sums and a 12-unknown 0D step, no linear solve.
bool Simulator::solve_coupled(double h, StepReport& r, std::string& why) {
  const circulation::Coupling& c = model_.circulation;
  const int m = static_cast<int>(c.cavities.size());
  const Positions& rest = model_.mesh.rest_positions();
  const std::array<double, 2> predicted = st_.circulation.external_pa;
  for (int k = 0; k < m; ++k) {
    const size_t kk = static_cast<size_t>(k);
    cavity_force_[kk].setZero(st_.x.size());
    add_surface_load_at(rest, positions(), cavity_loads_[kk], st_.time_s + h, cavity_force_[kk]);
    cavity_rhs_[kk] = h * sys_.restrict_to_free(cavity_force_[kk]);
    rhs_ += predicted[external_slot(c.cavities[kk].chamber)] * cavity_rhs_[kk];
  }
  if (!solve_free(h, r, why)) return false;
  coupled_v_ = st_.vfree;
  // Responses to unit pressures: the same matrix, warm-started from the last step's.
  for (int k = 0; k < m; ++k) {
    const size_t kk = static_cast<size_t>(k);
    const SolveStats s = solver_->solve_same_matrix(sys_.matrix(), cavity_rhs_[kk], st_.cavity_response[kk]);
    r.solver_iterations += s.iterations;
    r.solver_factorizations += s.factorizations;
    r.solver_residual = std::max(r.solver_residual, s.relative_residual);
    if (!st_.cavity_response[kk].allFinite() || !(s.relative_residual <= settings_.solver.failure_residual)) {
      why = "cavity " + c.cavities[kk].name + ": pressure response solve failed";
      return false;
    }
    st_.v.setZero();
    sys_.scatter_free(st_.cavity_response[kk], st_.v);
    cavity_shift_[kk] = h * st_.v;
  }
  sys_.scatter_free(coupled_v_, st_.v);
  const Eigen::VectorXd x_star = st_.x + h * st_.v;
  const int nn = model_.mesh.num_nodes();

  // Residual V_3D - V_0D at pressure shifts dp from the predicted ones.
  struct Eval {
    PressureVec volume, residual;
    circulation::State loop;
    Eigen::Matrix2d dloop;
  };
  const auto evaluate = [&](const PressureVec& dp, bool with_slope) {
    Eval e;
    coupled_x_ = x_star;
    for (int k = 0; k < m; ++k) coupled_x_ += dp(k) * cavity_shift_[static_cast<size_t>(k)];
    std::array<double, 2> ext = predicted;
    e.volume.resize(m);
    e.residual.resize(m);
    for (int k = 0; k < m; ++k) {
      const auto& cav = c.cavities[static_cast<size_t>(k)];
      ext[external_slot(cav.chamber)] += dp(k);
      e.volume(k) = cavity_volume(cav.surface, Eigen::Map<const Positions>(coupled_x_.data(), 3, nn));
    }
    e.loop = circulation::step(c.parameters, st_.circulation, h, ext, with_slope ? &e.dloop : nullptr);
    for (int k = 0; k < m; ++k)
      e.residual(k) = e.volume(k) - e.loop.volume_m3[static_cast<size_t>(c.cavities[static_cast<size_t>(k)].chamber)];
    return e;
  };
  // Largest residual as a fraction of its cavity's rest volume.
  const auto size_of = [&](const PressureVec& res) {
    double n = 0;
    for (int k = 0; k < m; ++k) n = std::max(n, std::abs(res(k)) / cavity_rest_volume_[static_cast<size_t>(k)]);
    return n;
  };
  PressureVec dp = PressureVec::Zero(m);
  Eval e = evaluate(dp, true);
  double size = size_of(e.residual);
  int it = 0;
  for (; size > c.volume_tolerance && it < c.max_iterations; ++it) {
    // Jacobian: the cavities' volume slopes (central differences of the exact polyhedral
    // volume along the affine path, whose curvature is tiny) minus the loop's.
    PressureMat J(m, m);
    for (int j = 0; j < m; ++j) {
      const double eps = 1e-3 * (std::abs(predicted[external_slot(c.cavities[static_cast<size_t>(j)].chamber)] + dp(j)) + 100.0);
      PressureVec hi = dp, lo = dp;
      hi(j) += eps;
      lo(j) -= eps;
      const Eval a = evaluate(hi, false), b = evaluate(lo, false);
      for (int k = 0; k < m; ++k) {
        const size_t ck = external_slot(c.cavities[static_cast<size_t>(k)].chamber);
        const size_t cj = external_slot(c.cavities[static_cast<size_t>(j)].chamber);
        J(k, j) = (a.volume(k) - b.volume(k)) / (2 * eps) - e.dloop(static_cast<Eigen::Index>(ck), static_cast<Eigen::Index>(cj));
      }
    }
    const PressureVec step = J.partialPivLu().solve(-e.residual);
    // Backtracking: the valves switch within a fraction of a mmHg.
    double alpha = 1;
    for (int b = 0; b < 30; ++b, alpha *= 0.5) {
      Eval t = evaluate(dp + alpha * step, true);
      const double ts = size_of(t.residual);
      if (ts < size || b == 29) {
        dp += alpha * step;
        e = std::move(t);
        size = ts;
        break;
      }
    }
  }
  r.circulation_iterations += it;
  st_.circulation_iterations = it;
  if (!(size <= c.volume_tolerance)) {
    why = "circulation: cavity pressures did not converge in " + std::to_string(it) + " iterations (volume mismatch " +
          std::to_string(size) + " of the rest volume)";
    return false;
  }
  st_.vfree = coupled_v_;
  for (int k = 0; k < m; ++k) {
    const size_t kk = static_cast<size_t>(k);
    st_.vfree += dp(k) * st_.cavity_response[kk];
    // The loads' work in the energy check includes the cavity pressures.
    st_.f_ext += e.loop.external_pa[external_slot(c.cavities[kk].chamber)] * cavity_force_[kk];
    st_.cavity_volume_m3[kk] = e.volume(k);
  }
  st_.circulation = e.loop;
  return take_velocity(h, why);
}

}  // namespace fiberfem::core
