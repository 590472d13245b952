#pragma once
/// @file The simulator's state between steps (what a checkpoint saves), plain data.

#include "core/circulation/circulation.hpp"
#include "core/linear_solver.hpp"
#include "core/types.hpp"

#include <Eigen/Geometry>

#include <vector>

namespace fiberfem::core {

/// Everything later steps depend on besides the model, the settings and the solver's
/// memory: the Simulator keeps its state in exactly this struct, so a checkpoint copies it
/// whole and a restore assigns it whole (a new field cannot be left out of one of them).
/// Plain data, no I/O.
struct SimulatorState {
  double time_s = 0;                 ///< Simulation time, s.
  long step_count = 0;               ///< Accepted steps so far.
  Eigen::VectorXd x;                 ///< Positions, 3N, m.
  Eigen::VectorXd v;                 ///< Velocities, 3N, m/s.
  Eigen::VectorXd vfree;             ///< Last solution over the free DOFs, m/s.
  Eigen::VectorXd vfree_prev;        ///< The one before (warm-start extrapolation), m/s.
  double last_h_s = -1;              ///< Step size of the last solve, s (-1: none yet).
  /// Warm-start polar rotation per element, by the element loop's position
  /// (SparseSystem::element_order(); checkpoints keep them by element).
  std::vector<Eigen::Quaterniond> q;
  std::vector<Mat3> R;               ///< Rotation per element, by loop position as q.
  bool rotations_current = false;    ///< R belongs to x (computed by the last step's checks).
  int inverted_current = 0;          ///< Inverted elements counted with R.
  std::vector<Eigen::Quaterniond> block_q;  ///< Warm-start rotation per free node block.
  std::vector<Mat3> block_R;         ///< Rotation per free node block.
  std::vector<double> active_tension_pa;   ///< Per element, Pa (empty: contraction off).
  Eigen::VectorXd f_ext;             ///< External force of the current (sub)step, 3N, N.
  double energy_floor_j = 0;         ///< Round-off scale of the energy check, J.
  double contraction_origin_s = 0;   ///< Where beats are counted from (set_contraction), s.
  circulation::State circulation;    ///< The lumped circulation's state (Model::circulation).
  /// Free-DOF velocity response to unit pressure in each coupled cavity (warm starts), m/s/Pa.
  std::vector<Eigen::VectorXd> cavity_response;
  /// Volume of each coupled cavity after the last step, m^3.
  std::vector<double> cavity_volume_m3;
  int circulation_iterations = 0;    ///< Newton iterations on the pressures in the last step.
};

/// A SimulatorState with what a restore checks it against and the linear solver's memory:
/// restoring it into a Simulator built from the same model and settings continues the run
/// bit-for-bit (Simulator::checkpoint, Simulator::restore).
struct SimulatorCheckpoint : SimulatorState {
  double dt_s = 0;                   ///< The time step when saved, s (restore checks it).
  int num_nodes = 0;                 ///< Nodes of the model (restore checks it).
  int num_elements = 0;              ///< Elements of the model (restore checks it).
  LinearSolverState solver;          ///< Recycled solutions and lagged factors.
};

}  // namespace fiberfem::core
