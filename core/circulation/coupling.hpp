#pragma once
/// @file What couples the lumped circulation to the 3D model: which cavity is which
/// ventricle, the circulation's parameters and initial state, and how tightly the cavity
/// volumes are matched (docs/circulation.md). Plain data held by core::Model.

#include "core/cavity.hpp"
#include "core/circulation/circulation.hpp"

#include <string>
#include <vector>

namespace fiberfem::core::circulation {

/// A cavity of the mesh standing for one ventricle of the loop: its endocardial pressure
/// loads the cavity wall as a follower pressure, its volume is the cavity's.
struct CoupledCavity {
  ChamberId chamber = lv;   ///< lv or rv.
  std::string name;         ///< The cavity's name (scene key measure.cavities), for messages.
  CavitySurface surface;    ///< Its wall; its rim must be fixed (the cavity is closed).
};

struct Coupling {
  /// The loop; the chambers of the coupled cavities are ChamberKind::external, the other
  /// ventricle (if only one cavity is coupled) keeps its elastance.
  Parameters parameters;
  /// The loop's state at time zero; the coupled ventricles' volumes are replaced by the
  /// cavities' rest volumes.
  State initial = State::regazzoni_initial();
  std::vector<CoupledCavity> cavities;  ///< One or two, distinct chambers.
  /// The step's cavity pressures are converged until every cavity's volume agrees with
  /// the loop's within this fraction of its rest volume, in (0, 1e-3]. Default 1e-9.
  double volume_tolerance = 1e-9;
  /// Newton iterations on the pressures before the step counts as failed (retried with
  /// substeps), in [1, 200]. Default 30.
  int max_iterations = 30;
  bool enabled() const { return !cavities.empty(); }
};

}  // namespace fiberfem::core::circulation
