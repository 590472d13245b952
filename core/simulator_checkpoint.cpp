#include "core/simulator.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::core {

SimulatorCheckpoint Simulator::checkpoint() const {
  SimulatorCheckpoint c;
  static_cast<SimulatorState&>(c) = st_;
  c.dt_s = settings_.dt_s;
  c.num_nodes = model_.mesh.num_nodes();
  c.num_elements = model_.mesh.num_elements();
  c.solver = solver_->save_state();
  return c;
}

void Simulator::restore(const SimulatorCheckpoint& c) {
  const int nn = model_.mesh.num_nodes(), ne = model_.mesh.num_elements();
  const auto fail = [](const std::string& what) { throw std::invalid_argument("restore: " + what); };
  if (c.num_nodes != nn || c.num_elements != ne)
    fail("checkpoint of a mesh with " + std::to_string(c.num_nodes) + " nodes and " + std::to_string(c.num_elements) +
         " elements, this model has " + std::to_string(nn) + " and " + std::to_string(ne));
  if (c.dt_s != settings_.dt_s)
    fail("checkpoint time step " + std::to_string(c.dt_s) + " s, this simulator's " + std::to_string(settings_.dt_s) + " s");
  const Eigen::Index n3 = 3 * static_cast<Eigen::Index>(nn);
  if (c.x.size() != n3 || c.v.size() != n3 || c.f_ext.size() != n3) fail("state vectors of the wrong size");
  if (!c.x.allFinite() || !c.v.allFinite()) fail("non-finite positions or velocities");
  if (c.vfree.size() != sys_.num_free() || c.vfree_prev.size() != sys_.num_free()) fail("free-DOF vectors of the wrong size");
  if (c.q.size() != st_.q.size() || c.R.size() != st_.R.size()) fail("per-element rotations of the wrong size");
  if (c.block_q.size() != st_.block_q.size() || c.block_R.size() != st_.block_R.size()) fail("node-block rotations of the wrong size");
  if (!(c.active_tension_pa.empty() || static_cast<int>(c.active_tension_pa.size()) == ne))
    fail("active tension of the wrong size");
  if (model_.contraction.enabled() && c.active_tension_pa.empty()) fail("no active tension for a contracting model");
  if (!(std::isfinite(c.time_s) && c.step_count >= 0)) fail("bad time or step count");
  if (c.cavity_response.size() != st_.cavity_response.size() || c.cavity_volume_m3.size() != st_.cavity_volume_m3.size())
    fail("circulation state of another number of coupled cavities");
  solver_->load_state(c.solver, sys_.matrix());  // throws before anything else changes
  st_ = c;  // the state part (SimulatorState), whole
  assembled_ahead_ = false;  // not in the checkpoint: the next step makes its element pass
}

}  // namespace fiberfem::core
