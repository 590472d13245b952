#pragma once
/// @file The accurate tier's time steps coupled to the lumped circulation
/// (docs/circulation.md): the problem's pressure load k is cavity k's blood pressure (its
/// PressureLoad::pressure_pa must be 1 Pa, scaled each step by Loading::pressure_factors).
/// Each step solves the body and the cavity pressures together: the pressures are unknowns
/// bordered onto the step's Newton iteration with one constraint per cavity, its volume at
/// the step's end equal to the loop's after the loop's backward-Euler step with those
/// pressures (newton_iterate_bordered: per iteration one solve for the body's residual and
/// one per cavity with the same tangent, then the 1 x 1 or 2 x 2 Schur complement). The
/// volumes are as exact as the body's Newton solve (NewtonSettings::tolerance): the volume
/// tolerance must be above what that leaves (about 1e-8 of the cavity at the default 1e-9).

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
  int pressure_iterations = 0;  ///< Newton iterations updating the pressures (all of the step's).
  int newton_iterations = 0;    ///< Newton iterations of the step.
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
  /// Newton iterations on the pressures (with the body) of the last step.
  int last_pressure_iterations() const { return last_iterations_; }

  /// The solver's state() with the coupling's (the loop, the volumes).
  DynamicState checkpoint() const;
  /// Restores the solver and the coupling from a checkpoint() of the same problem; a state
  /// without cavity volumes (of an uncoupled run) is refused.
  /// @throws std::invalid_argument naming what does not fit (nothing changes then).
  void restore(const DynamicState& s);
  /// Carries `previous`'s loop state and volumes over, under this coupling's parameters
  /// (a changed beat period keeps the beat under way: circulation::keep_beat_phase); its
  /// solver's state is the caller's to carry (DynamicSolver::continue_from).
  void continue_from(const CirculationCoupledDynamics& previous);

 private:
  double volume(int k, const Positions& x) const { return cavity_volume(cavities_[static_cast<size_t>(k)].surface, x); }
  DynamicSolver& solver_;
  circulation::Parameters parameters_;
  circulation::State state_;
  std::vector<CoupledCavity> cavities_;
  double tolerance_;
  int max_iterations_;
  std::vector<double> volumes_, rest_volumes_;
  int last_iterations_ = 0;
};

}  // namespace fiberfem::core::hyperelastic
