#pragma once
/// @file The accurate tier as the service's engine: the hyperelastic backward-Euler stepper
/// (core/hyperelastic/dynamic.hpp) on the problem io::accurate_problem builds from the
/// scene, the loads at each step's end time as `fiberfem run` takes them, plus the
/// commands' point forces on corner nodes.

#include "io/scene_accurate.hpp"
#include "service/engine.hpp"

namespace fiberfem::service {

class AccurateEngine final : public Engine {
 public:
  /// @throws std::invalid_argument (io::SceneError) for what the accurate tier does not take.
  explicit AccurateEngine(const io::Scene& scene);

  core::StepReport step() override;
  double time_s() const override { return solver_->time_s(); }
  long step_count() const override { return solver_->steps(); }
  double dt_s() const override { return solver_->settings().dt_s; }
  Eigen::Map<const core::Positions> positions() const override { return corner(solver_->positions()); }
  Eigen::Map<const core::Positions> velocities() const override { return corner(solver_->velocities()); }
  const core::Model& model() const override { return scene_.model; }
  const std::vector<double>& active_tension() const override { return tension_pa_; }
  /// The point forces on corner nodes (the commands' forces), replacing those set before.
  /// @throws std::invalid_argument for a node out of range or a non-finite force.
  void set_point_forces(const std::vector<core::PointForce>& forces);
  EngineCheckpoint checkpoint() const override;
  void restore(const EngineCheckpoint& c) override;
  void reset() override;
  const core::circulation::State* circulation_state() const override { return coupled_ ? &coupled_->state() : nullptr; }
  const std::vector<double>& coupled_cavity_volumes() const override {
    return coupled_ ? coupled_->volumes() : Engine::coupled_cavity_volumes();
  }
  int circulation_iterations() const override { return coupled_ ? coupled_->last_pressure_iterations() : 0; }
  AccurateEngine* accurate() override { return this; }

  /// Builds the engine of `running` (the same scene with changed parameters) and carries
  /// this one's state over: positions, velocities, pressures, time, steps, point forces and
  /// the lagged factor, taken over without factorising again (this engine is left without
  /// it); the parameters change the answer from the next step on. A new heart rate keeps
  /// the phase of the beat under way (core::Contraction::continued_origin).
  /// @throws std::invalid_argument as the constructor, or when the state does not fit the
  /// new problem (another mesh); this engine is unchanged then.
  std::unique_ptr<AccurateEngine> rebuilt(const io::Scene& running);

  /// The element mesh (corner nodes first) and the full state on it.
  const core::hyperelastic::ElementMesh& element_mesh() const { return *problem_.mesh; }
  const core::Positions& element_positions() const { return solver_->positions(); }
  const core::Positions& element_velocities() const { return solver_->velocities(); }
  const Eigen::VectorXd& pressures() const { return solver_->pressures(); }
  const core::hyperelastic::DynamicSettings& settings() const { return solver_->settings(); }
  /// Newton's totals over the steps of this engine (since it was built or rebuilt).
  core::hyperelastic::NewtonReport totals() const { return solver_->totals(); }

 private:
  Eigen::Map<const core::Positions> corner(const core::Positions& x) const {
    return {x.data(), 3, problem_.mesh->num_corner_nodes()};
  }
  void update_tension();
  core::StepReport attempt(int substeps);
  void restore_state(const EngineCheckpoint& c);  // restore() without touching the tension
  static constexpr int kMaxSubsteps = 8;
  // A solver (and its coupling to the circulation, when the scene has one) at rest.
  void start(const core::hyperelastic::DynamicSettings& settings);

  io::Scene scene_;
  io::AccurateProblem problem_;
  std::unique_ptr<core::hyperelastic::DynamicSolver> solver_;
  std::vector<core::hyperelastic::CoupledCavity> cavities_;  // empty: no circulation
  std::unique_ptr<core::hyperelastic::CirculationCoupledDynamics> coupled_;
  core::Positions nodal_forces_n_;  // 3 x element-mesh nodes; empty: none
  std::vector<double> tension_pa_;
  double contraction_origin_s_ = 0;  // the contraction's beats count from here (a steered rate moves it)
};

}  // namespace fiberfem::service
