#include "core/simulator.hpp"

namespace fiberfem::core {

Energies Simulator::energies() const {
  Energies en;
  en.elastic_j = elements_->elastic_energy(st_.x, settings_.corotation);
  for (int n = 0; n < model_.mesh.num_nodes(); ++n) {
    en.kinetic_j += 0.5 * mass_(n) * st_.v.segment<3>(3 * n).squaredNorm();
    en.gravity_j -= mass_(n) * model_.loads.gravity_m_s2.dot(st_.x.segment<3>(3 * n));
  }
  return en;
}

int Simulator::count_inverted() const { return elements_->count_inverted(st_.x); }

}  // namespace fiberfem::core
