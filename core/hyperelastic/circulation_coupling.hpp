#pragma once
/// @file The accurate tier's time steps coupled to the lumped circulation
/// (docs/circulation.md): the problem's pressure load k is cavity k's blood pressure (its
/// PressureLoad::pressure_pa must be 1 Pa, scaled each step by Loading::pressure_factors),
/// and every step the cavity pressures are iterated until each cavity's volume at the end
/// of the converged Newton step equals the loop's. Each iteration is a full (not committed)
/// Newton step warm-started from the previous one; the pressures' Jacobian is the loop's
/// exact one minus the cavities' volume slope, estimated by finite differences at the first
/// step and kept up to date by Broyden's secant updates. The volumes are as exact as the
/// body's Newton solves (NewtonSettings::tolerance): the volume tolerance must be above
/// what that leaves (about 1e-9 of the cavity at the default 1e-9).

#include "core/cavity.hpp"
#include "core/circulation/circulation.hpp"
#include "core/hyperelastic/dynamic.hpp"

#include <string>
#include <vector>

namespace fiberfem::core::hyperelastic {

struct CoupledCavity {
  circulation::ChamberId chamber = circulation::lv;  ///< lv or rv (ChamberKind::external).
  int pressure_load = 0;                             ///< Index into Problem::pressures.
  CavitySurface surface;                             ///< Its wall on the corner nodes (rim fixed).
};

struct CoupledStepReport {
  bool converged = false;
  int pressure_iterations = 0;  ///< Newton steps of the body solved (each one converged).
  int newton_iterations = 0;    ///< Summed over them.
  std::string message;
};

class CirculationCoupledDynamics {
 public:
  /// `solver` (at rest) steps the problem; the coupled chambers of `parameters` must be
  /// ChamberKind::external. @throws std::invalid_argument for a bad cavity or load index.
  CirculationCoupledDynamics(DynamicSolver& solver, const Problem& problem, circulation::Parameters parameters,
                             circulation::State initial, std::vector<CoupledCavity> cavities, double volume_tolerance = 1e-8,
                             int max_iterations = 30);
  /// One step; `loading`'s other loads (active tension, gravity) as the caller sets them.
  /// A step that does not converge changes nothing.
  CoupledStepReport step(Loading loading);
  const circulation::State& state() const { return state_; }
  /// The cavities' volumes at the current state, m^3.
  const std::vector<double>& volumes() const { return volumes_; }
  const circulation::Parameters& parameters() const { return parameters_; }
  /// Newton iterations on the pressures (converged body solves) of the last step.
  int last_pressure_iterations() const { return last_iterations_; }

  /// The solver's state() with the coupling's (the loop, the volumes, the slope).
  DynamicState checkpoint() const;
  /// Restores the solver and the coupling from a checkpoint() of the same problem; a state
  /// without cavity volumes (of an uncoupled run) is refused.
  /// @throws std::invalid_argument naming what does not fit (nothing changes then).
  void restore(const DynamicState& s);
  /// Carries `previous`'s loop state, volumes and slope over (its solver's state is the
  /// caller's to carry: DynamicSolver::continue_from).
  void continue_from(const CirculationCoupledDynamics& previous);

 private:
  double volume(int k, const Positions& x) const { return cavity_volume(cavities_[static_cast<size_t>(k)].surface, x); }
  DynamicSolver& solver_;
  circulation::Parameters parameters_;
  circulation::State state_;
  std::vector<CoupledCavity> cavities_;
  double tolerance_;
  int max_iterations_;
  int num_loads_;
  std::vector<double> volumes_, rest_volumes_;
  Eigen::MatrixXd slope_;  // d V_cavity / d p, m^3/Pa (secant estimate)
  bool have_slope_ = false;
  int last_iterations_ = 0;
};

}  // namespace fiberfem::core::hyperelastic
