#pragma once
/// @file The dynamic engine: corotated, linearised implicit backward Euler
/// (PHYSICS.md sections 4 and 5) with rollback and substepping on failure.

#include "core/element_model.hpp"
#include "core/linear_solver.hpp"
#include "core/model.hpp"
#include "core/rotation.hpp"
#include "core/simulator_state.hpp"
#include "core/sparse_system.hpp"
#include "core/thread_governor.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <string>
#include <vector>

namespace fiberfem::core {

/// Settings of the time stepper. Every field has a default; `validate()` names a bad one.
struct SimulatorSettings {
  double dt_s = 1.0 / 60.0;  ///< Time step, s, in (0, 10]. Default 1/60.
  SolverSettings solver;     ///< Linear solver; see SolverSettings.
  RotationMethod rotation = RotationMethod::polar;  ///< polar | svd. Default polar (5x cheaper, agrees to polar_tolerance_rad).
  bool corotation = true;    ///< false: plain linear FEM (R = I), the baseline. Default true.
  /// On failure a step is retried with 2, 4, ... 2^k substeps, k up to this, in [0, 12].
  /// Default 4 (16 substeps).
  int max_substep_halvings = 4;
  /// A step that leaves more than this fraction of elements inverted counts as failed,
  /// in (0, 1]. Default 1 (inversion alone never fails a step; it is always counted).
  double max_inverted_fraction = 1.0;
  /// Energy check: a step whose kinetic plus elastic energy grows by more than this
  /// fraction of the state's energy beyond the work of the loads and the active stress
  /// counts as failed and is retried with substeps, in [0, inf]; infinity turns the
  /// check off (saves one pass of energy sums). The linearised step can gain energy when
  /// one step spans a large rotation (huge steps, huge loads, fast spin). Default 1e-3.
  double max_energy_gain = 1e-3;
  /// What a substep may gain at the finest substep level (max_substep_halvings), as a
  /// multiple of the state's energy (with the loads' work), beyond which the step fails
  /// rather than being accepted. There the check refines no further and accepts a gain
  /// above max_energy_gain (at a fiber ratio of 1,000 a few steps gain 4%), but not a
  /// doubling: a model that cannot carry its load blows up from there (Land problem 3's
  /// loads on the real-time tier: 1.7 times in one substep, then 1e291 J within the same
  /// step, the follower pressure's work growing with it, so no larger bound would catch
  /// it). With max_substep_halvings 0 the 1,000 g beam's first step from rest, which gains
  /// 18 times its energy, fails too: it needs substeps.
  static constexpr double kFinestEnergyGain = 1.0;
  /// Convergence of the warm-started polar rotation (rotation = polar), rad, in (0, 0.1].
  /// Default 1e-9.
  double polar_tolerance_rad = 1e-9;
  /// OpenMP threads of the engine, >= 0. 0 (default): chosen step by step from measured
  /// step times, up to every core (core/thread_governor.hpp): fewer where more do not pay
  /// (small meshes) or where another process keeps a core busy. N > 0: always N. Results do
  /// not depend on the count (core/parallel.hpp).
  int threads = 0;
  /// Numbering of the free DOFs (core/sparse_system.hpp). Default bandwidth: a mesh
  /// generator's node numbering is replaced by a local one inside the engine; positions,
  /// velocities, forces and checkpoints stay in the mesh's node order either way.
  DofOrder dof_order = DofOrder::bandwidth;
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

enum class StepStatus {
  ok,         ///< Advanced by one step as asked.
  recovered,  ///< The full step failed; advanced with substeps.
  failed,     ///< Every retry failed; the state is rolled back to before the step.
};
const char* to_string(StepStatus s);

/// Wall time of the phases of one step, seconds.
struct PhaseTimes {
  /// Rotation extraction outside the element pass: 0 since the rotations are part of
  /// that pass (kept for the report and status formats).
  double rotations_s = 0;
  /// The element pass (deformation gradients, rotations, warped stiffness, forces and
  /// energy, including the one the checks make ahead for the next step), the mass terms
  /// and the right-hand side.
  double assembly_s = 0;
  double solve_s = 0;      ///< Linear solve.
  double total_s = 0;      ///< Whole step, including retries.
};

/// What one step did. Energies are those of the state the step started from (they come
/// free with the assembly); `Simulator::energies()` computes the current state's.
struct StepReport {
  StepStatus status = StepStatus::ok;
  int substeps = 1;               ///< Substeps of the accepted attempt.
  int attempts = 1;               ///< Attempts made (1 + retries).
  int solver_iterations = 0;      ///< Summed over the accepted attempt's substeps.
  int solver_factorizations = 0;  ///< Cholesky factorisations, summed over all attempts.
  int threads = 1;                ///< OpenMP threads the step ran on.
  double solver_residual = 0;     ///< Largest relative residual of the accepted attempt.
  /// Newton iterations on the cavity pressures (Model::circulation), summed over the
  /// accepted attempt's substeps; 0 without a circulation.
  int circulation_iterations = 0;
  double kinetic_energy_j = 0;
  double elastic_energy_j = 0;
  int inverted_elements = 0;      ///< Elements with det F <= 0 at the last substep.
  double max_speed_m_s = 0;       ///< Largest node speed after the step.
  double time_s = 0;              ///< Simulation time after the step.
  PhaseTimes time;
  std::string message;            ///< Why a retry happened or the step failed.
};

/// Energies of a state, joules.
struct Energies {
  double kinetic_j = 0;
  double elastic_j = 0;
  double gravity_j = 0;  ///< -sum m g.x (relative to the origin).
};

/// The integrator: each step asks the element model (core/element_model.hpp) for one
/// element pass, adds the mass terms, solves for the new velocity and checks the result.
/// Files by job: construction and state (simulator.cpp), the step and its retries
/// (simulator_step.cpp), checkpoints (simulator_checkpoint.cpp), energies
/// (simulator_energy.cpp), changes between steps (simulator_setters.cpp).
class Simulator {
 public:
  /// Validates the model and settings and precomputes every element cache.
  /// @throws std::invalid_argument naming what is wrong.
  Simulator(Model model, SimulatorSettings settings = {});
  /// Not movable: the element model and the varying loads point into the owned model.
  /// Hold a Simulator where it is made (or through a unique_ptr).
  Simulator(Simulator&&) = delete;
  Simulator& operator=(Simulator&&) = delete;

  /// Advances by dt. Never throws for numerical trouble: see StepReport::status.
  StepReport step();

  /// Current positions (3 x N), metres, and velocities (3 x N), m/s.
  Eigen::Map<const Positions> positions() const { return {st_.x.data(), 3, model_.mesh.num_nodes()}; }
  Eigen::Map<const Positions> velocities() const { return {st_.v.data(), 3, model_.mesh.num_nodes()}; }
  /// Replaces the state (e.g. to start deformed). Fixed DOFs keep their rest position and
  /// zero velocity. @throws std::invalid_argument on size mismatch or non-finite values.
  void set_state(const Positions& x, const Positions& v);
  /// Back to rest, zero velocity, time zero.
  void reset();
  double time_s() const { return st_.time_s; }
  long step_count() const { return st_.step_count; }

  /// The complete state between steps (see SimulatorCheckpoint). Cost: copies of the
  /// state vectors and of the lagged factors' matrices.
  SimulatorCheckpoint checkpoint() const;
  /// Restores a checkpoint() taken from a Simulator with the same model and settings
  /// (after the same parameter changes): the following steps equal those after the
  /// checkpoint bit-for-bit. Refactorises the lagged preconditioner factors from their
  /// saved matrices (CHOLMOD is deterministic for the same matrix).
  /// @throws std::invalid_argument on a size, time-step or solver mismatch or
  /// non-finite positions or velocities (the simulator is unchanged then).
  void restore(const SimulatorCheckpoint& c);

  /// External force of the last step (3N, newtons): gravity, point forces and surface
  /// loads, with ramped and follower loads as that step applied them.
  const Eigen::VectorXd& external_force() const { return st_.f_ext; }
  /// Exact energies of the current state (one pass over the elements).
  Energies energies() const;
  /// Elements with det F <= 0 in the current state.
  int count_inverted() const;
  /// Active tension per element along its fiber, Pa, as the last step applied it (the
  /// contraction schedule or set_active_tension); empty when contraction is off.
  const std::vector<double>& active_tension() const { return st_.active_tension_pa; }
  /// The lumped circulation's state after the last step (Model::circulation); its
  /// external_pa are the coupled cavities' pressures (lv, rv), Pa.
  const circulation::State& circulation_state() const { return st_.circulation; }
  /// Volume of each coupled cavity (Model::circulation.cavities order) after the last step, m^3.
  const std::vector<double>& coupled_cavity_volumes() const { return st_.cavity_volume_m3; }
  /// Newton iterations on the cavity pressures in the last (sub)step.
  int circulation_iterations() const { return st_.circulation_iterations; }

  const Model& model() const { return model_; }
  const SimulatorSettings& settings() const { return settings_; }
  const SparseSystem& system() const { return sys_; }
  /// The linear solver (its factor_info() for reports and benchmarks).
  const LinearSolver& linear_solver() const { return *solver_; }
  /// The thread count the engine has settled on (settings().threads when that is set).
  int threads() const { return settings_.threads > 0 ? settings_.threads : governor_.settled(); }

  // Changes between steps. Each rebuilds only the caches it touches and validates first.
  void set_region_material(int region, const Material& material);
  void set_region_damping(int region, const RayleighDamping& damping);
  /// Fibers per element (non-zero; normalised here). Rebuilds K^e and g^e of the elements
  /// whose fiber changed (none for isotropic regions' K^e).
  void set_fibers(std::vector<Vec3> fibers);
  void set_time_step(double dt_s);
  void set_gravity(const Vec3& g_m_s2);
  void set_loads(const Loads& loads);
  void set_solver_settings(const SolverSettings& s);
  void set_rotation_method(RotationMethod m);
  void set_corotation(bool on);
  /// Active tension per element (Pa) along the current fiber (PHYSICS.md section 6);
  /// an empty vector turns contraction off (no per-step cost). For models without a
  /// contraction schedule (Model::contraction): with one, the schedule sets the tension
  /// at the end of every (sub)step and this throws.
  void set_active_tension(std::vector<double> tension_pa);
  /// Replaces the contraction schedule (heart rate, peak tensions, twitch, pacing delays,
  /// mode) between steps. A beat under way keeps its phase: when only the period changes,
  /// the current beat goes on and the next one starts one new period after it began. A
  /// schedule switched on starts its first beat now; switched off, the tension drops to
  /// zero. @throws std::invalid_argument (Contraction::validate) and changes nothing.
  void set_contraction(Contraction contraction);
  /// Time the contraction schedule counts beats from, s (0 unless set_contraction moved it).
  double contraction_origin_s() const { return st_.contraction_origin_s; }
  /// Replaces the lumped circulation's parameters (Model::circulation.parameters) between
  /// steps. The loop's state carries over as it is (chamber volumes, compartment pressures
  /// and flows), so the next step starts from the pressures the last one reached. A new
  /// beat period keeps the beat under way (circulation::continued_beat_origin). The chambers
  /// of the coupled cavities stay the mesh's (their entries in `p` are not used).
  /// @throws std::invalid_argument without a circulation or when `p` is invalid
  /// (Parameters::validate); nothing changes then.
  void set_circulation_parameters(circulation::Parameters p);

 private:
  // The step (simulator_step.cpp).
  bool advance(double h, bool last_chance, StepReport& r, std::string& why);
  void assemble_step(double h, StepReport& r);
  bool solve_velocity(double h, StepReport& r, std::string& why);
  bool solve_free(double h, StepReport& r, std::string& why);
  void free_flight_guess(double h);
  bool take_velocity(double h, std::string& why);
  // The circulation coupling (simulator_circulation.cpp).
  void setup_circulation();
  void reset_circulation();
  bool solve_coupled(double h, StepReport& r, std::string& why);
  bool check_step(double h, double kinetic, double elastic, bool last_chance, StepReport& r, std::string& why);
  double assemble_elements(double h, double t_end_s);
  void update_active_tension(double t_end_s);
  // Construction and state (simulator.cpp).
  void update_node_masses();
  void apply_fixed();
  void refresh_external_forces();
  /// @throws std::invalid_argument when `s` cannot work on this system (amg needs whole node blocks).
  void check_solver_fits(const SolverSettings& s) const;
  void install_solver(const SolverSettings& s);

  Model model_;
  SimulatorState st_;  // everything a checkpoint saves besides the solver's memory
  SimulatorSettings settings_;
  SparseSystem sys_;
  // What the elements contribute (forces, tangent blocks, energy, rotations): the
  // corotated linear tetrahedron. Reads model_.mesh.
  std::unique_ptr<ElementModel> elements_;
  std::unique_ptr<LinearSolver> solver_;
  Eigen::VectorXd mass_;            // per node, kg
  Eigen::VectorXd mass_alpha_;      // per node, sum alpha_e m_e / 4, kg/s
  Eigen::VectorXd f_ext_const_;     // 3N, its part that never changes
  std::vector<const SurfaceLoad*> varying_loads_;  // ramped or follower (into model_.loads)
  TwitchTable tension_table_;       // the contraction's normalised beat, tabulated
  Eigen::VectorXd block_x_;  // node-block positions for the amg preconditioner
  // work
  Eigen::VectorXd f_, rhs_;
  Eigen::VectorXd guess_;  // warm start extrapolated from st_.vfree and st_.vfree_prev
  Eigen::VectorXd flight_, flight_Av_, guess_Av_;  // free_flight_guess's work vectors
  Eigen::VectorXd f_active_;        // 3N, active-stress forces of the step (when active)
  // The checks of the last (sub)step made the next step's element pass (assemble_elements)
  // for step size ahead_h_: sys_ (without the mass terms), f_, f_active_ and st_.active_tension_pa belong
  // to st_.x, and ahead_elastic_j_ is its elastic energy. Anything that changes what the pass
  // reads (material, damping, fibers, tension, contraction, state) clears it.
  bool assembled_ahead_ = false;
  double ahead_h_ = 0;
  double ahead_elastic_j_ = 0;
  ThreadGovernor governor_;  // threads of each step when settings_.threads is 0
  Eigen::VectorXd x0_, v0_, vfree0_, vprev0_;  // state at the start of a step (rollback)
  std::vector<Eigen::Quaterniond> q0_;       // warm-start rotations at the start of a step (rollback)
  // The circulation coupling: a unit follower pressure on each coupled cavity's wall, its
  // forces (3N) and free-DOF right-hand side of a step, and work vectors of the pressures' Newton.
  std::vector<SurfaceLoad> cavity_loads_;
  std::vector<Eigen::VectorXd> cavity_force_, cavity_rhs_, cavity_shift_;
  Eigen::VectorXd coupled_v_, coupled_x_;
  std::vector<double> cavity_rest_volume_;   // m^3, per coupled cavity
  circulation::State circulation0_;          // at the start of a step (rollback)
};

}  // namespace fiberfem::core
