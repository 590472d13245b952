// A checkpoint read back from its JSON header and doubles (docs/archive.md, "Checkpoints").

#include "service/archive/archive_internal.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace fiberfem::archive {

using namespace detail;

namespace detail {
core::SimulatorCheckpoint checkpoint_of(const json& h, const std::vector<double>& data, std::string* parameter_state) {
  core::SimulatorCheckpoint c;
  c.time_s = h.at("time_s");
  c.step_count = h.at("step_count");
  c.dt_s = h.at("dt_s");
  c.num_nodes = h.at("num_nodes");
  c.num_elements = h.at("num_elements");
  c.last_h_s = h.at("last_h_s");
  c.rotations_current = h.at("rotations_current");
  c.inverted_current = h.at("inverted_current");
  c.energy_floor_j = h.at("energy_floor_j");
  c.contraction_origin_s = h.value("contraction_origin_s", 0.0);
  c.x = vector_of(section(h, data, "x"));
  c.v = vector_of(section(h, data, "v"));
  c.vfree = vector_of(section(h, data, "vfree"));
  c.vfree_prev = vector_of(section(h, data, "vfree_prev"));
  c.q = quaternions_of(section(h, data, "q"));
  c.R = matrices_of(section(h, data, "R"));
  c.block_q = quaternions_of(section(h, data, "block_q"));
  c.block_R = matrices_of(section(h, data, "block_R"));
  const Section a = section(h, data, "active_tension_pa");
  c.active_tension_pa.assign(a.p, a.p + a.n);
  c.f_ext = vector_of(section(h, data, "f_ext"));
  const json& s = h.at("solver");
  c.solver.solver_name = s.at("name");
  c.solver.history_rows = s.at("history_rows");
  c.solver.history_cols = s.at("history_cols");
  c.solver.history_count = s.at("history_count");
  c.solver.history_next = s.at("history_next");
  c.solver.key = s.at("key");
  c.solver.clock = s.at("clock");
  c.solver.history = vector_of(section(h, data, "solver.history"));
  size_t i = 0;
  for (const json& f : s.at("factors")) {
    core::LinearSolverState::Factor F;
    F.factored = f.at("factored");
    F.rows = f.at("rows");
    F.stale = f.at("stale");
    F.baseline = f.value("baseline", -1);  // absent in checkpoints written before 2026-11-25
    F.excess = f.value("excess", 0.0);
    F.key = f.at("key");
    F.last_used = f.at("last_used");
    F.beside = f.value("beside", false);  // absent in checkpoints written before 2026-11-26
    F.beside_left = f.value("beside_left", 0.0);
    F.matrix_values = vector_of(section(h, data, "solver.factor" + std::to_string(i) + ".matrix_values"));
    F.at_factor = matrices_of(section(h, data, "solver.factor" + std::to_string(i) + ".at_factor"));
    const std::string positions = "solver.factor" + std::to_string(i) + ".setup_positions";
    for (const auto& sec : h.at("layout"))
      if (sec.at("name") == positions) F.setup_positions = vector_of(section(h, data, positions));
    c.solver.factors.push_back(std::move(F));
    ++i;
  }
  if (parameter_state) *parameter_state = h.at("parameter_state");
  return c;
}
}  // namespace detail

}  // namespace fiberfem::archive
