#include "core/simulator.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>
#include <string>

namespace fiberfem::core {

namespace {

// Checkpoints keep the free-DOF data in the mesh's node order (DofOrder::nodes) and the
// per-element data by element, whatever numbering and loop order the engine uses, so that a
// checkpoint does not depend on them: `to_natural` renumbers this system's items (free DOFs,
// node blocks, matrix non-zeros, loop positions) to those orders, and back when it is false.
// Arrays of another size are left as they are (restore's checks name them).
template <class V>
void renumber(V& a, const std::vector<int>& map, int per_item, bool to_natural) {
  if (static_cast<size_t>(a.size()) != map.size() * static_cast<size_t>(per_item) || map.empty()) return;
  V out = a;
  for (size_t k = 0; k < map.size(); ++k)
    for (int j = 0; j < per_item; ++j) {
      const size_t here = k * static_cast<size_t>(per_item) + static_cast<size_t>(j);
      const size_t there = static_cast<size_t>(map[k]) * static_cast<size_t>(per_item) + static_cast<size_t>(j);
      if (to_natural) {
        out[static_cast<Eigen::Index>(there)] = a[static_cast<Eigen::Index>(here)];
      } else {
        out[static_cast<Eigen::Index>(here)] = a[static_cast<Eigen::Index>(there)];
      }
    }
  a = std::move(out);
}

// Per-element rotations: the engine keeps them by the element loop's position
// (`element_order`: the element at each position), checkpoints by element.
void renumber_checkpoint(SimulatorCheckpoint& c, const NaturalOrder& o, const std::vector<int>& element_order,
                         bool to_natural) {
  renumber(c.q, element_order, 1, to_natural);
  renumber(c.R, element_order, 1, to_natural);
  if (o.identity) return;
  renumber(c.vfree, o.free, 1, to_natural);
  renumber(c.vfree_prev, o.free, 1, to_natural);
  renumber(c.block_q, o.block, 1, to_natural);
  renumber(c.block_R, o.block, 1, to_natural);
  for (Eigen::VectorXd& r : c.cavity_response) renumber(r, o.free, 1, to_natural);
  if (c.solver.history_rows == static_cast<Eigen::Index>(o.free.size()))
    renumber(c.solver.history, o.free, c.solver.history_cols, to_natural);
  for (LinearSolverState::Factor& f : c.solver.factors) {
    renumber(f.matrix_values, o.value, 1, to_natural);
    renumber(f.at_factor, o.block, 1, to_natural);
    renumber(f.setup_positions, o.block, 3, to_natural);
  }
}

}  // namespace

SimulatorCheckpoint Simulator::checkpoint() const {
  SimulatorCheckpoint c;
  static_cast<SimulatorState&>(c) = st_;
  c.dt_s = settings_.dt_s;
  c.num_nodes = model_.mesh.num_nodes();
  c.num_elements = model_.mesh.num_elements();
  c.solver = solver_->save_state();
  renumber_checkpoint(c, sys_.natural_order(), sys_.element_order(), /*to_natural=*/true);
  return c;
}

void Simulator::restore(const SimulatorCheckpoint& saved) {
  SimulatorCheckpoint c = saved;
  renumber_checkpoint(c, sys_.natural_order(), sys_.element_order(), /*to_natural=*/false);
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
