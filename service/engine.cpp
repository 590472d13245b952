// The real-time tier as the service's engine, and the choice of engine by the scene's tier.

#include "service/engine.hpp"

#include "service/engine_accurate.hpp"

#include <stdexcept>

namespace fiberfem::service {

const std::vector<double>& Engine::coupled_cavity_volumes() const {
  static const std::vector<double> none;
  return none;
}

void Engine::set_circulation_parameters(const core::circulation::Parameters&) {
  throw std::invalid_argument("this run's tier cannot steer a circulation (the real-time tier can)");
}

RealTimeEngine::RealTimeEngine(const io::Scene& scene)
    : owned_(std::make_unique<core::Simulator>(scene.model, scene.settings)), sim_(*owned_) {}

void RealTimeEngine::restore(const EngineCheckpoint& c) {
  const auto* s = std::get_if<core::SimulatorCheckpoint>(&c);
  if (s == nullptr) throw std::invalid_argument("checkpoint of the accurate tier: this run is on the real-time tier");
  sim_.restore(*s);
}

std::unique_ptr<Engine> make_engine(const io::Scene& scene) {
  if (scene.accurate()) return std::make_unique<AccurateEngine>(scene);
  return std::make_unique<RealTimeEngine>(scene);
}

}  // namespace fiberfem::service
