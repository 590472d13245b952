#pragma once
/// @file What the service steps: the engine of a scene's tier behind one interface, so the
/// run control, the service loop, its status, recording and replay run both tiers alike.
/// The real-time tier is core::Simulator itself (its step untouched: one virtual call per
/// step); the accurate tier (material.law, mesh.order 2) is the hyperelastic time stepper
/// (service/engine_accurate.hpp). positions() are those of the scene's corner mesh
/// (model().mesh), what the service publishes: the first columns of an order-2 state, since
/// the element mesh numbers corner nodes first (its archive frames hold every node:
/// AccurateEngine::element_positions).

#include "core/hyperelastic/dynamic.hpp"
#include "core/simulator.hpp"
#include "io/scene.hpp"

#include <memory>
#include <variant>
#include <vector>

namespace fiberfem::service {

class AccurateEngine;

/// The complete state of either engine between steps (a checkpoint restores it bit for bit
/// into an engine built from the same scene and parameters).
using EngineCheckpoint = std::variant<core::SimulatorCheckpoint, core::hyperelastic::DynamicState>;

class Engine {
 public:
  virtual ~Engine() = default;

  /// Advances by one time step. Never throws for numerical trouble: a step that fails
  /// leaves the state as it was and says so (StepReport::status failed, message).
  virtual core::StepReport step() = 0;
  virtual double time_s() const = 0;
  virtual long step_count() const = 0;
  /// The time step, s.
  virtual double dt_s() const = 0;
  /// Positions and velocities of the corner mesh's nodes (model().mesh), 3 x N, m and m/s.
  virtual Eigen::Map<const core::Positions> positions() const = 0;
  virtual Eigen::Map<const core::Positions> velocities() const = 0;
  /// The scene's model: corner mesh, fibers, fixed components, contraction, loads (on the
  /// accurate tier its materials are the laws' small-strain limits, for display only).
  virtual const core::Model& model() const = 0;
  /// Active tension per element along its fiber as the last step applied it, Pa; empty when
  /// contraction is off.
  virtual const std::vector<double>& active_tension() const = 0;

  virtual EngineCheckpoint checkpoint() const = 0;
  /// @throws std::invalid_argument when the checkpoint is of the other tier or does not fit
  /// (the engine is unchanged then).
  virtual void restore(const EngineCheckpoint& c) = 0;
  /// Back to rest, time zero.
  virtual void reset() = 0;

  /// The lumped circulation after the last step (scene key `circulation`), or nullptr when
  /// the scene has none. Its parameters are model().circulation.parameters.
  virtual const core::circulation::State* circulation_state() const { return nullptr; }
  /// Volume of each coupled cavity (model().circulation.cavities order) after the last
  /// step, m^3; empty without a circulation.
  virtual const std::vector<double>& coupled_cavity_volumes() const;
  /// Newton iterations on the cavity pressures in the last step; 0 without a circulation.
  virtual int circulation_iterations() const { return 0; }
  /// Replaces the circulation's parameters between steps, the loop's state carried over
  /// (core::Simulator::set_circulation_parameters: pressures, volumes and flows go on from
  /// where they are; a new heart rate keeps the beat under way).
  /// @throws std::invalid_argument, changing nothing: without a circulation, for invalid
  /// parameters, and on an engine that cannot steer one (the default).
  virtual void set_circulation_parameters(const core::circulation::Parameters& p);

  /// The real-time simulator, or nullptr on the accurate tier.
  virtual core::Simulator* real_time() { return nullptr; }
  const core::Simulator* real_time() const { return const_cast<Engine*>(this)->real_time(); }
  /// The accurate engine, or nullptr on the real-time tier.
  virtual AccurateEngine* accurate() { return nullptr; }
  const AccurateEngine* accurate() const { return const_cast<Engine*>(this)->accurate(); }
};

/// The real-time tier: core::Simulator as it is, every call forwarded.
class RealTimeEngine final : public Engine {
 public:
  /// Owns a simulator of `scene` at rest. @throws std::invalid_argument as Simulator does.
  explicit RealTimeEngine(const io::Scene& scene);
  /// Steps `sim`, which the caller owns and keeps alive (a test or benchmark that drives
  /// its own simulator and records it).
  explicit RealTimeEngine(core::Simulator& sim) : sim_(sim) {}
  core::StepReport step() override { return sim_.step(); }
  double time_s() const override { return sim_.time_s(); }
  long step_count() const override { return sim_.step_count(); }
  double dt_s() const override { return sim_.settings().dt_s; }
  Eigen::Map<const core::Positions> positions() const override { return sim_.positions(); }
  Eigen::Map<const core::Positions> velocities() const override { return sim_.velocities(); }
  const core::Model& model() const override { return sim_.model(); }
  const std::vector<double>& active_tension() const override { return sim_.active_tension(); }
  EngineCheckpoint checkpoint() const override { return sim_.checkpoint(); }
  void restore(const EngineCheckpoint& c) override;
  void reset() override { sim_.reset(); }
  const core::circulation::State* circulation_state() const override {
    return sim_.model().circulation.enabled() ? &sim_.circulation_state() : nullptr;
  }
  const std::vector<double>& coupled_cavity_volumes() const override { return sim_.coupled_cavity_volumes(); }
  int circulation_iterations() const override { return sim_.circulation_iterations(); }
  void set_circulation_parameters(const core::circulation::Parameters& p) override { sim_.set_circulation_parameters(p); }
  core::Simulator* real_time() override { return &sim_; }

 private:
  std::unique_ptr<core::Simulator> owned_;
  core::Simulator& sim_;
};

/// The engine of a scene's tier, at rest. @throws std::invalid_argument (io::SceneError)
/// naming what the tier cannot take.
std::unique_ptr<Engine> make_engine(const io::Scene& scene);

}  // namespace fiberfem::service
