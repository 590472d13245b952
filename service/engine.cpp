// The real-time tier as the service's engine, and the choice of engine by the scene's tier.

#include "service/engine.hpp"

#include "service/engine_accurate.hpp"

#include <stdexcept>

namespace fiberfem::service {

namespace {

// core::Simulator as it is: every call forwards.
class RealTimeEngine final : public Engine {
 public:
  explicit RealTimeEngine(const io::Scene& scene) : sim_(scene.model, scene.settings) {}
  core::StepReport step() override { return sim_.step(); }
  double time_s() const override { return sim_.time_s(); }
  long step_count() const override { return sim_.step_count(); }
  double dt_s() const override { return sim_.settings().dt_s; }
  Eigen::Map<const core::Positions> positions() const override { return sim_.positions(); }
  Eigen::Map<const core::Positions> velocities() const override { return sim_.velocities(); }
  const core::Model& model() const override { return sim_.model(); }
  const std::vector<double>& active_tension() const override { return sim_.active_tension(); }
  EngineCheckpoint checkpoint() const override { return sim_.checkpoint(); }
  void restore(const EngineCheckpoint& c) override {
    const auto* s = std::get_if<core::SimulatorCheckpoint>(&c);
    if (s == nullptr) throw std::invalid_argument("checkpoint of the accurate tier: this run is on the real-time tier");
    sim_.restore(*s);
  }
  void reset() override { sim_.reset(); }
  core::Simulator* real_time() override { return &sim_; }

 private:
  core::Simulator sim_;
};

}  // namespace

std::unique_ptr<Engine> make_engine(const io::Scene& scene) {
  if (scene.accurate()) return std::make_unique<AccurateEngine>(scene);
  return std::make_unique<RealTimeEngine>(scene);
}

}  // namespace fiberfem::service
