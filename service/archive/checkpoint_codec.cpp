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
namespace {

// A sparse matrix from its three sections (add_sparse), its indices checked.
core::hyperelastic::SparseMatrix sparse_of(const json& h, const std::vector<double>& data, const std::string& name) {
  const Section outer = section(h, data, name + ".outer"), inner = section(h, data, name + ".inner"),
                values = section(h, data, name + ".values");
  core::hyperelastic::SparseMatrix m;
  if (outer.n == 0) return m;
  const auto bad = [&] { throw std::runtime_error("archive: checkpoint matrix '" + name + "' has bad indices"); };
  const Eigen::Index n = static_cast<Eigen::Index>(outer.n) - 1;
  if (inner.n != values.n || outer.p[0] != 0 || outer.p[outer.n - 1] != static_cast<double>(inner.n)) bad();
  std::vector<Eigen::Triplet<double, int>> t;
  t.reserve(values.n);
  for (Eigen::Index c = 0; c < n; ++c) {
    const double b = outer.p[c], e = outer.p[c + 1];
    if (!(b <= e) || e > static_cast<double>(inner.n)) bad();
    for (size_t k = static_cast<size_t>(b); k < static_cast<size_t>(e); ++k) {
      if (!(inner.p[k] >= 0 && inner.p[k] < static_cast<double>(n))) bad();
      t.emplace_back(static_cast<int>(inner.p[k]), static_cast<int>(c), values.p[k]);
    }
  }
  m.resize(n, n);
  m.setFromTriplets(t.begin(), t.end());
  m.makeCompressed();
  return m;
}

// A run with a circulation (either tier): the loop's state and the coupled cavities'
// volumes; returns how many cavities (0, nothing read, without a circulation).
size_t read_circulation(const json& h, const std::vector<double>& data, core::circulation::State& loop,
                        std::vector<double>& volumes) {
  const size_t cavities = h.value("circulation_cavities", size_t{0});
  if (cavities == 0) return 0;
  loop = circulation_state_of(section(h, data, "circulation.state"));
  const Section v = section(h, data, "circulation.cavity_volume_m3");
  if (v.n != cavities) throw std::runtime_error("archive: checkpoint section 'circulation.cavity_volume_m3' has the wrong size");
  volumes.assign(v.p, v.p + v.n);
  // Absent in checkpoints written before the heart rate was steerable (never changed then).
  loop.beat_origin_s = h.value("circulation_beat_origin_s", 0.0);
  loop.previous_period_s = h.value("circulation_previous_period_s", 0.0);
  return cavities;
}

core::hyperelastic::DynamicState accurate_checkpoint_of(const json& h, const std::vector<double>& data) {
  core::hyperelastic::DynamicState c;
  c.time_s = h.at("time_s");
  c.steps = h.at("step_count");
  const Eigen::Index nodes = h.at("num_nodes").get<Eigen::Index>();
  const Section x = section(h, data, "x"), v = section(h, data, "v");
  if (nodes < 0 || x.n != static_cast<size_t>(3 * nodes) || v.n != x.n)
    throw std::runtime_error("archive: checkpoint positions or velocities do not match its " + std::to_string(nodes) + " nodes");
  c.x = Eigen::Map<const core::Positions>(x.p, 3, nodes);
  c.v = Eigen::Map<const core::Positions>(v.p, 3, nodes);
  c.p = vector_of(section(h, data, "p"));
  c.linear.analysed = sparse_of(h, data, "linear.analysed");
  c.linear.factored = sparse_of(h, data, "linear.factored");
  read_circulation(h, data, c.circulation, c.cavity_volume_m3);
  c.contraction_origin_s = h.value("contraction_origin_s", 0.0);  // absent before a steered rate kept its phase here
  return c;
}

core::SimulatorCheckpoint real_time_checkpoint_of(const json& h, const std::vector<double>& data) {
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
  // A run with a circulation (absent in checkpoints without one, and in those written
  // before 2026-11-26).
  const size_t cavities = read_circulation(h, data, c.circulation, c.cavity_volume_m3);
  if (cavities > 0) {
    for (size_t k = 0; k < cavities; ++k)
      c.cavity_response.push_back(vector_of(section(h, data, "circulation.cavity_response" + std::to_string(k))));
    c.circulation_iterations = h.value("circulation_iterations", 0);
  }
  const json& s = h.at("solver");
  c.solver.solver_name = s.at("name");
  c.solver.history_rows = s.at("history_rows");
  c.solver.history_cols = s.at("history_cols");
  c.solver.history_count = s.at("history_count");
  c.solver.history_next = s.at("history_next");
  c.solver.key = s.at("key");
  c.solver.clock = s.at("clock");
  c.solver.jacobi_first = s.value("jacobi_first", false);  // absent in checkpoints written before 2026-11-28
  c.solver.jacobi_first_excess = s.value("jacobi_first_excess", 0.0);
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
  return c;
}

}  // namespace

service::EngineCheckpoint checkpoint_of(const json& h, const std::vector<double>& data, std::string* parameter_state) {
  service::EngineCheckpoint c;
  if (h.value("tier", std::string("real_time")) == "accurate") c = accurate_checkpoint_of(h, data);
  else c = real_time_checkpoint_of(h, data);
  if (parameter_state) *parameter_state = h.at("parameter_state");
  return c;
}
}  // namespace detail

}  // namespace fiberfem::archive
