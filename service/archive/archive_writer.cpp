// The archive writer (docs/archive.md): the header, frames, commands and checkpoints of a
// run into one HDF5 file, SWMR, flushed on a schedule.

#include "service/archive/archive_internal.hpp"

#include "io/scene_accurate.hpp"
#include "service/engine_accurate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace fiberfem::archive {

using namespace detail;

std::string software_version() { return FIBERFEM_VERSION; }
std::string git_commit() { return FIBERFEM_GIT_COMMIT; }

void ArchiveOptions::validate() const {
  const auto bad = [](const std::string& m) { throw std::invalid_argument("archive: " + m); };
  if (path.empty()) bad("path must not be empty");
  if (flush_frames < 1 || flush_frames > 100000) bad("flush_frames must be in [1, 100000], got " + std::to_string(flush_frames));
  if (!(flush_seconds >= 0 && flush_seconds <= 3600)) bad("flush_seconds must be in [0, 3600] s, got " + std::to_string(flush_seconds));
  if (every_steps < 1 || every_steps > 1000000) bad("every must be in [1, 1000000] steps, got " + std::to_string(every_steps));
  if (!(checkpoint_every_s >= 0 && checkpoint_every_s <= 1e9))
    bad("checkpoint_every must be in [0, 1e9] s, got " + std::to_string(checkpoint_every_s));
  if (compression < 0 || compression > 9) bad("compression must be in [0, 9], got " + std::to_string(compression));
}

namespace detail {

struct WriterFile {
  ArchiveOptions o;
  h5::File file;
  h5::Dataset step, time, positions, velocities, displacement, activation, cavities, probes, energies, iterations, residual, status,
      substeps, inverted, circulation;
  h5::Dataset cmd_step, cmd_time, cmd_accepted, cmd_end, cmd_bytes;
  h5::Dataset cp_step, cp_time, cp_header_end, cp_header, cp_data_end, cp_data;
  int nn = 0, ne = 0;
  core::Positions frame_rest;          // rest positions of the nodes a frame holds (3 x M)
  std::vector<io::Probe> probe_list;
  long frames = 0, since_flush = 0;
  std::chrono::steady_clock::time_point last_flush = std::chrono::steady_clock::now();
  double next_checkpoint_s = 0;
  std::string parameter_state = "{}";  // for the periodic checkpoints (set_parameter_state)
  std::vector<double> times;           // of the recorded frames (the sidecar's)
  std::chrono::steady_clock::time_point last_sidecar{};  // when the sidecar was last rewritten
  double sidecar_cost_s = 0;           // how long that took
  long sidecar_frames = 0;             // frames it lists
  long last_checkpoint_step = -1;         // the last checkpoint's step, state and parameters
  Eigen::VectorXd last_checkpoint_x, last_checkpoint_v;  // of either tier
  std::string last_checkpoint_params;
  std::vector<float> fbuf;
  bool closed = false;
  std::string xdmf_path;
};

}  // namespace detail
namespace {

// The time stepper's settings as the header's scene/solver_settings attribute.
json solver_settings(const service::Engine& engine) {
  if (const service::AccurateEngine* a = engine.accurate()) {
    const core::hyperelastic::DynamicSettings& s = a->settings();
    return {{"tier", "accurate"},
            {"dt_s", s.dt_s},
            {"order", a->element_mesh().order()},
            {"mass_damping_1_s", s.mass_damping_1_s},
            {"newton_tolerance", s.newton.tolerance},
            {"newton_max_iterations", s.newton.max_iterations},
            {"newton_line_search", s.newton.line_search},
            {"threads", s.newton.threads}};
  }
  const core::SimulatorSettings& s = engine.real_time()->settings();
  return {{"dt_s", s.dt_s},
          {"method", core::to_string(s.solver.method)},
          {"preconditioner", core::to_string(s.solver.preconditioner)},
          {"tolerance", s.solver.tolerance},
          {"max_iterations", s.solver.max_iterations},
          {"refresh_iterations", s.solver.refresh_iterations},
          {"refresh_budget", s.solver.refresh_budget},
          {"recycled_solutions", s.solver.recycled_solutions},
          {"warm_start", s.solver.warm_start},
          {"rotation", s.rotation == core::RotationMethod::polar ? "polar" : "svd"},
          {"corotation", s.corotation},
          {"first_factorisation", core::to_string(s.solver.first_factorisation)},
          {"max_substep_halvings", s.max_substep_halvings},
          {"max_energy_gain", std::isfinite(s.max_energy_gain) ? json(s.max_energy_gain) : json("inf")},
          {"threads", s.threads}};
}

// The nodes a frame holds: the element mesh's (corners first) on the accurate tier, the
// mesh's on the real-time tier.
const double* frame_positions(const service::Engine& engine) {
  const service::AccurateEngine* a = engine.accurate();
  return a ? a->element_positions().data() : engine.positions().data();
}
const double* frame_velocities(const service::Engine& engine) {
  const service::AccurateEngine* a = engine.accurate();
  return a ? a->element_velocities().data() : engine.velocities().data();
}

// An order-2 archive's element mesh (docs/archive.md): every node, and the elements in
// XDMF's node order (gmsh's, with its last two edges swapped).
void write_element_mesh(hid_t mesh_group, const core::hyperelastic::ElementMesh& em) {
  h5::write_attribute<std::int64_t>(mesh_group, "order", em.order());
  if (em.order() != 2) return;
  const hsize_t M = static_cast<hsize_t>(em.num_nodes()), E = static_cast<hsize_t>(em.num_elements());
  h5::Dataset rest = h5::create_fixed<double>(mesh_group, "order2_rest_positions", {M, 3}, em.rest_positions().data());
  h5::write_attribute(rest.id(), "unit", std::string("m"));
  std::vector<std::int32_t> tets;
  for (std::array<int, 10> t : em.elements()) {
    std::swap(t[8], t[9]);
    tets.insert(tets.end(), t.begin(), t.end());
  }
  h5::Dataset t = h5::create_fixed<std::int32_t>(mesh_group, "order2_tets", {E, 10}, tets.data());
  h5::write_attribute(t.id(), "node_order", std::string("XDMF Tetrahedron_10 / VTK: corners 0 1 2 3, edges 01 12 02 03 13 23"));
}

}  // namespace

ArchiveWriter::ArchiveWriter(ArchiveOptions options, const io::Scene& scene, const service::Engine& engine, std::string source)
    : f_(std::make_unique<detail::WriterFile>()) {
  options.validate();
  detail::WriterFile& w = *f_;
  w.o = std::move(options);
  const core::Model& m = engine.model();
  const core::TetMesh& mesh = m.mesh;
  const service::AccurateEngine* accurate = engine.accurate();
  w.nn = mesh.num_nodes();
  w.ne = mesh.num_elements();
  w.frame_rest = accurate ? accurate->element_mesh().rest_positions() : mesh.rest_positions();
  w.probe_list = scene.probes;
  const hsize_t N = static_cast<hsize_t>(w.nn), E = static_cast<hsize_t>(w.ne);
  const hsize_t M = static_cast<hsize_t>(w.frame_rest.cols());  // nodes of a frame
  w.file = h5::File::create(w.o.path);
  const hid_t root = w.file.id();
  h5::write_attribute(root, "format", std::string(kFormatName));
  h5::write_attribute<std::int64_t>(root, "format_version", accurate ? kFormatVersionAccurate : kFormatVersion);
  h5::write_attribute(root, "software_version", software_version());
  h5::write_attribute(root, "git_commit", git_commit());
  h5::write_attribute(root, "created_utc", utc_now());
  h5::write_attribute(root, "source", source);
  h5::write_attribute(root, "length_unit", std::string("m"));
  h5::write_attribute(root, "time_unit", std::string("s"));
  h5::write_attribute(root, "stress_unit", std::string("Pa"));

  {  // the scene
    h5::Handle g = h5::create_group(root, "scene");
    h5::write_attribute(g.id(), "name", scene.name);
    h5::write_attribute(g.id(), "sha256", scene.hash_sha256);
    h5::write_attribute(g.id(), "dt_s", engine.dt_s());
    h5::write_attribute(g.id(), "tier", std::string(accurate ? "accurate" : "real_time"));
    h5::write_attribute(g.id(), "until_s", scene.until_s);
    h5::write_attribute(g.id(), "base_dir",
                        std::filesystem::absolute(scene.base_dir.empty() ? std::string(".") : scene.base_dir).lexically_normal().string());
    h5::write_attribute(g.id(), "solver_settings", solver_settings(engine).dump());
    h5::create_text(g.id(), "yaml", scene.yaml_text);
    std::vector<std::string> probe_names;
    std::vector<std::int32_t> probe_elements;
    std::vector<double> probe_weights, probe_points;
    for (const io::Probe& p : scene.probes) {
      probe_names.push_back(p.name);
      probe_elements.push_back(p.element);
      probe_weights.insert(probe_weights.end(), p.weights.data(), p.weights.data() + 4);
      probe_points.insert(probe_points.end(), p.point_m.data(), p.point_m.data() + 3);
    }
    h5::Handle pg = h5::create_group(g.id(), "probes");
    h5::write_attribute(pg.id(), "names", join_json(probe_names));
    h5::create_fixed<std::int32_t>(pg.id(), "element", {probe_elements.size()}, probe_elements.data());
    h5::create_fixed<double>(pg.id(), "weights", {probe_elements.size(), 4}, probe_weights.data());
    h5::Dataset pp = h5::create_fixed<double>(pg.id(), "point", {probe_elements.size(), 3}, probe_points.data());
    h5::write_attribute(pp.id(), "unit", std::string("m"));
  }
  {  // the mesh
    h5::Handle g = h5::create_group(root, "mesh");
    h5::Dataset rest = h5::create_fixed<double>(g.id(), "rest_positions", {N, 3}, mesh.rest_positions().data());
    h5::write_attribute(rest.id(), "unit", std::string("m"));
    std::vector<std::int32_t> tets;
    for (const core::Tet& t : mesh.tets()) tets.insert(tets.end(), t.begin(), t.end());
    h5::create_fixed<std::int32_t>(g.id(), "tets", {E, 4}, tets.data());
    std::vector<std::int32_t> regions(mesh.regions().begin(), mesh.regions().end());
    h5::create_fixed<std::int32_t>(g.id(), "regions", {E}, regions.data());
    std::vector<std::int32_t> tris;
    for (const core::Tri& t : mesh.boundary_triangles()) tris.insert(tris.end(), t.begin(), t.end());
    h5::create_fixed<std::int32_t>(g.id(), "boundary_triangles", {mesh.boundary_triangles().size(), 3}, tris.data());
    std::vector<std::uint8_t> fixed(m.fixed_dofs.begin(), m.fixed_dofs.end());
    if (fixed.empty()) fixed.assign(3 * N, 0);
    h5::create_fixed<std::uint8_t>(g.id(), "fixed_dofs", {N, 3}, fixed.data());
    std::vector<std::int32_t> fixed_nodes;
    for (hsize_t n = 0; n < N; ++n)
      if (fixed[3 * n] || fixed[3 * n + 1] || fixed[3 * n + 2]) fixed_nodes.push_back(static_cast<std::int32_t>(n));
    h5::create_fixed<std::int32_t>(g.id(), "fixed_nodes", {fixed_nodes.size()}, fixed_nodes.data());
    std::vector<double> fibers;
    for (int e = 0; e < w.ne; ++e) {
      const core::Vec3 f = m.fibers.empty() ? core::Vec3(1, 0, 0) : m.fibers[static_cast<size_t>(e)];
      fibers.insert(fibers.end(), f.data(), f.data() + 3);
    }
    h5::create_fixed<double>(g.id(), "fibers", {E, 3}, fibers.data());
    if (accurate) write_element_mesh(g.id(), accurate->element_mesh());
  }
  {  // the material table
    h5::Handle g = h5::create_group(root, "materials");
    std::vector<double> C, rho;
    for (const core::Material& mat : m.region_materials) {
      const core::Mat6& c = mat.stiffness();
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) C.push_back(c(i, j));  // row-major
      rho.push_back(mat.density_kg_m3());
    }
    const hsize_t R = m.region_materials.size();
    h5::Dataset c = h5::create_fixed<double>(g.id(), "stiffness", {R, 6, 6}, C.data());
    h5::write_attribute(c.id(), "unit", std::string("Pa"));
    h5::write_attribute(c.id(), "voigt_order", std::string("xx yy zz xy yz zx (fiber frame, fiber along z)"));
    h5::Dataset d = h5::create_fixed<double>(g.id(), "density", {R}, rho.data());
    h5::write_attribute(d.id(), "unit", std::string("kg/m^3"));
  }
  {  // per-frame datasets: everything created before SWMR starts
    h5::Handle g = h5::create_group(root, "frames");
    const hid_t gid = g.id();
    h5::write_attribute<std::int64_t>(gid, "every_steps", w.o.every_steps);
    w.time = h5::create_extendible<double>(gid, "time", {}, kScalarChunk, 0);
    h5::write_attribute(w.time.id(), "unit", std::string("s"));
    w.positions = h5::create_extendible<float>(gid, "positions", {M, 3}, 1, w.o.compression);
    h5::write_attribute(w.positions.id(), "unit", std::string("m"));
    if (w.o.displacement) {
      w.displacement = h5::create_extendible<float>(gid, "displacement", {M, 3}, 1, w.o.compression);
      h5::write_attribute(w.displacement.id(), "unit", std::string("m"));
    }
    if (w.o.velocities) {
      w.velocities = h5::create_extendible<float>(gid, "velocities", {M, 3}, 1, w.o.compression);
      h5::write_attribute(w.velocities.id(), "unit", std::string("m/s"));
    }
    // Without contraction the activation rows are left unwritten (fill value 0, no bytes).
    w.activation = h5::create_extendible<float>(gid, "activation", {E}, 1, w.o.compression);
    h5::write_attribute(w.activation.id(), "unit", std::string("Pa"));
    std::vector<std::string> cavity_names;
    for (const io::CavityMeasure& c : scene.cavities) cavity_names.push_back(c.name);
    w.cavities = h5::create_extendible<double>(gid, "cavity_volumes", {cavity_names.size()}, kScalarChunk, 0);
    h5::write_attribute(w.cavities.id(), "unit", std::string("m^3"));
    h5::write_attribute(w.cavities.id(), "names", join_json(cavity_names));
    std::vector<std::string> probe_names;
    for (const io::Probe& p : scene.probes) probe_names.push_back(p.name);
    w.probes = h5::create_extendible<double>(gid, "probe_displacements", {probe_names.size(), 3}, kScalarChunk, 0);
    h5::write_attribute(w.probes.id(), "unit", std::string("m"));
    h5::write_attribute(w.probes.id(), "names", join_json(probe_names));
    w.energies = h5::create_extendible<double>(gid, "energies", {2}, kScalarChunk, 0);
    h5::write_attribute(w.energies.id(), "unit", std::string("J"));
    h5::write_attribute(w.energies.id(), "columns", std::string(R"(["kinetic", "elastic"])"));
    if (engine.circulation_state()) {  // a run with a circulation only: other runs write as before
      const std::vector<std::string>& columns = core::circulation::snapshot_columns();
      w.circulation = h5::create_extendible<double>(gid, "circulation", {columns.size()}, kScalarChunk, 0);
      h5::write_attribute(w.circulation.id(), "columns", join_json(columns));
      h5::write_attribute(w.circulation.id(), "unit", std::string("SI, by the column name's suffix: _pa Pa, _m3 m^3, _m3_s m^3/s, _s s"));
    }
    w.iterations = h5::create_extendible<std::int32_t>(gid, "solver_iterations", {}, kScalarChunk, 0);
    w.residual = h5::create_extendible<double>(gid, "solver_residual", {}, kScalarChunk, 0);
    w.status = h5::create_extendible<std::int8_t>(gid, "status", {}, kScalarChunk, 0);
    h5::write_attribute(w.status.id(), "values", std::string(R"({"0": "ok", "1": "recovered", "2": "failed"})"));
    w.substeps = h5::create_extendible<std::int32_t>(gid, "substeps", {}, kScalarChunk, 0);
    w.inverted = h5::create_extendible<std::int32_t>(gid, "inverted_elements", {}, kScalarChunk, 0);
    w.step = h5::create_extendible<std::int64_t>(gid, "step", {}, kScalarChunk, 0);
  }
  {  // commands
    h5::Handle g = h5::create_group(root, "commands");
    w.cmd_step = h5::create_extendible<std::int64_t>(g.id(), "step", {}, 64, 0);
    w.cmd_time = h5::create_extendible<double>(g.id(), "time", {}, 64, 0);
    h5::write_attribute(w.cmd_time.id(), "unit", std::string("s"));
    w.cmd_accepted = h5::create_extendible<std::uint8_t>(g.id(), "accepted", {}, 64, 0);
    w.cmd_bytes = h5::create_extendible<std::uint8_t>(g.id(), "records", {}, 4096, 0);
    w.cmd_end = h5::create_extendible<std::int64_t>(g.id(), "record_end", {}, 64, 0);
  }
  {  // checkpoints
    h5::Handle g = h5::create_group(root, "checkpoints");
    w.cp_step = h5::create_extendible<std::int64_t>(g.id(), "step", {}, 16, 0);
    w.cp_time = h5::create_extendible<double>(g.id(), "time", {}, 16, 0);
    h5::write_attribute(w.cp_time.id(), "unit", std::string("s"));
    w.cp_header = h5::create_extendible<std::uint8_t>(g.id(), "headers", {}, 4096, 0);
    w.cp_header_end = h5::create_extendible<std::int64_t>(g.id(), "header_end", {}, 16, 0);
    w.cp_data = h5::create_extendible<double>(g.id(), "data", {}, 65536, 0);
    w.cp_data_end = h5::create_extendible<std::int64_t>(g.id(), "data_end", {}, 16, 0);
  }
  w.file.start_swmr_write();
  checkpoint(engine, "{}");
  w.next_checkpoint_s = engine.time_s() + w.o.checkpoint_every_s;
  flush();
  const std::filesystem::path p(w.o.path);
  w.xdmf_path = (p.parent_path() / p.stem()).string() + ".xdmf";
}

ArchiveWriter::~ArchiveWriter() {
  try {
    close();
  } catch (...) {
  }
}

long ArchiveWriter::frames() const { return f_->frames; }

void ArchiveWriter::record_frame(const service::Engine& sim, const core::StepReport& r, const FrameExtras& x) {
  detail::WriterFile& w = *f_;
  if (w.closed) throw std::logic_error("archive: record_frame after close");
  if (sim.step_count() % w.o.every_steps != 0) return;
  const auto as_float = [&](const double* p, size_t n) -> const float* {
    w.fbuf.resize(n);
    for (size_t i = 0; i < n; ++i) w.fbuf[i] = static_cast<float>(p[i]);
    return w.fbuf.data();
  };
  const size_t n3 = static_cast<size_t>(w.frame_rest.size());
  w.time.append(&r.time_s, 1);
  w.positions.append(as_float(frame_positions(sim), n3), 1);
  if (w.displacement) {
    const double* x = frame_positions(sim);
    const double* x0 = w.frame_rest.data();
    w.fbuf.resize(n3);
    for (size_t i = 0; i < n3; ++i) w.fbuf[i] = static_cast<float>(x[i] - x0[i]);
    w.displacement.append(w.fbuf.data(), 1);
  }
  if (w.velocities) w.velocities.append(as_float(frame_velocities(sim), n3), 1);
  const std::vector<double>& a = sim.active_tension();
  if (a.empty()) {
    w.activation.extend(1);  // reads as zeros, stores nothing
  } else {
    w.activation.append(as_float(a.data(), a.size()), 1);
  }
  std::vector<double> vols;
  for (const auto& [name, v] : x.cavity_volumes_m3) vols.push_back(v);
  if (vols.size() != w.cavities.dims()[1])
    throw std::invalid_argument("archive: " + std::to_string(vols.size()) + " cavity volumes for " +
                                std::to_string(w.cavities.dims()[1]) + " cavities");
  w.cavities.append(vols.data(), 1);
  std::vector<double> probe;
  const core::Positions x_now = sim.positions();
  const service::AccurateEngine* accurate = sim.accurate();
  for (const io::Probe& p : w.probe_list) {
    const core::Vec3 u = accurate ? io::accurate_probe_displacement(accurate->element_mesh(), p, accurate->element_positions())
                                  : p.displacement(sim.model().mesh, x_now);
    probe.insert(probe.end(), u.data(), u.data() + 3);
  }
  w.probes.append(probe.data(), 1);
  if (w.circulation) {
    if (!x.circulation) throw std::invalid_argument("archive: the run has a circulation, the frame carries none");
    const std::vector<double> numbers = core::circulation::to_columns(*x.circulation);
    w.circulation.append(numbers.data(), 1);
  }
  const double en[2] = {r.kinetic_energy_j, r.elastic_energy_j};
  w.energies.append(en, 1);
  const std::int32_t it = r.solver_iterations, sub = r.substeps, inv = r.inverted_elements;
  w.iterations.append(&it, 1);
  w.residual.append(&r.solver_residual, 1);
  const std::int8_t st = static_cast<std::int8_t>(r.status);
  w.status.append(&st, 1);
  w.substeps.append(&sub, 1);
  w.inverted.append(&inv, 1);
  const std::int64_t step = sim.step_count();
  w.step.append(&step, 1);  // last: the frame is complete
  ++w.frames;
  ++w.since_flush;
  w.times.push_back(r.time_s);
  if (w.o.checkpoint_every_s > 0 && sim.time_s() >= w.next_checkpoint_s - 1e-9) {
    checkpoint(sim, w.parameter_state);
    while (w.next_checkpoint_s <= sim.time_s() + 1e-9) w.next_checkpoint_s += w.o.checkpoint_every_s;
  }
  const double since_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - w.last_flush).count();
  // The first frame is flushed at once (a reader sees the run start); then by cadence.
  if (w.frames == 1 || w.since_flush >= w.o.flush_frames || (w.o.flush_seconds > 0 && since_s >= w.o.flush_seconds)) flush();
}

void ArchiveWriter::record_command(const CommandRecord& c) {
  detail::WriterFile& w = *f_;
  if (w.closed) throw std::logic_error("archive: record_command after close");
  json text;
  try {
    text = json::parse(c.text);
  } catch (const json::exception&) {
    text = c.text;  // kept verbatim when it is not JSON
  }
  const std::string rec =
      json{{"id", c.id}, {"kind", c.kind}, {"command", text}, {"accepted", c.accepted}, {"reason", c.reason}}.dump();
  const std::int64_t step = c.step;
  const std::uint8_t acc = c.accepted ? 1 : 0;
  const hsize_t end = w.cmd_bytes.append(reinterpret_cast<const std::uint8_t*>(rec.data()), rec.size());
  const std::int64_t end64 = static_cast<std::int64_t>(end);
  w.cmd_end.append(&end64, 1);
  w.cmd_time.append(&c.time_s, 1);
  w.cmd_accepted.append(&acc, 1);
  w.cmd_step.append(&step, 1);  // last: the record is complete
}

void ArchiveWriter::set_parameter_state(std::string parameter_state_json) { f_->parameter_state = std::move(parameter_state_json); }

namespace {

// The real-time tier's checkpoint: its header fields and the data sections into `b`.
json real_time_checkpoint(const core::SimulatorCheckpoint& c, Blob& b) {
  b.add("x", c.x.data(), static_cast<size_t>(c.x.size()));
  b.add("v", c.v.data(), static_cast<size_t>(c.v.size()));
  b.add("vfree", c.vfree.data(), static_cast<size_t>(c.vfree.size()));
  b.add("vfree_prev", c.vfree_prev.data(), static_cast<size_t>(c.vfree_prev.size()));
  add_quaternions(b, "q", c.q);
  add_matrices(b, "R", c.R);
  add_quaternions(b, "block_q", c.block_q);
  add_matrices(b, "block_R", c.block_R);
  b.add("active_tension_pa", c.active_tension_pa.data(), c.active_tension_pa.size());
  b.add("f_ext", c.f_ext.data(), static_cast<size_t>(c.f_ext.size()));
  // A run with a circulation: the loop's state, each coupled cavity's volume and the warm
  // starts of its unit-pressure response.
  if (!c.cavity_volume_m3.empty()) {
    const std::vector<double> loop = circulation_numbers(c.circulation);
    b.add("circulation.state", loop.data(), loop.size());
    b.add("circulation.cavity_volume_m3", c.cavity_volume_m3.data(), c.cavity_volume_m3.size());
    for (size_t k = 0; k < c.cavity_response.size(); ++k)
      b.add("circulation.cavity_response" + std::to_string(k), c.cavity_response[k].data(),
            static_cast<size_t>(c.cavity_response[k].size()));
  }
  b.add("solver.history", c.solver.history.data(), static_cast<size_t>(c.solver.history.size()));
  json factors = json::array();
  for (size_t k = 0; k < c.solver.factors.size(); ++k) {
    const auto& f = c.solver.factors[k];
    b.add("solver.factor" + std::to_string(k) + ".matrix_values", f.matrix_values.data(), static_cast<size_t>(f.matrix_values.size()));
    add_matrices(b, "solver.factor" + std::to_string(k) + ".at_factor", f.at_factor);
    if (f.setup_positions.size() > 0)  // an amg hierarchy's setup positions (absent for a Cholesky factor)
      b.add("solver.factor" + std::to_string(k) + ".setup_positions", f.setup_positions.data(),
            static_cast<size_t>(f.setup_positions.size()));
    factors.push_back({{"factored", f.factored}, {"rows", f.rows}, {"stale", f.stale}, {"baseline", f.baseline},
                       {"excess", f.excess}, {"key", f.key}, {"last_used", f.last_used},
                       {"beside", f.beside}, {"beside_left", f.beside_left}});
  }
  return {{"time_s", c.time_s},
          {"step_count", c.step_count},
          {"dt_s", c.dt_s},
          {"num_nodes", c.num_nodes},
          {"num_elements", c.num_elements},
          {"last_h_s", c.last_h_s},
          {"rotations_current", c.rotations_current},
          {"inverted_current", c.inverted_current},
          {"energy_floor_j", c.energy_floor_j},
          {"contraction_origin_s", c.contraction_origin_s},
          {"circulation_cavities", c.cavity_volume_m3.size()},
          {"circulation_iterations", c.circulation_iterations},
          {"circulation_beat_origin_s", c.circulation.beat_origin_s},
          {"circulation_previous_period_s", c.circulation.previous_period_s},
          {"solver",
           {{"name", c.solver.solver_name},
            {"history_rows", c.solver.history_rows},
            {"history_cols", c.solver.history_cols},
            {"history_count", c.solver.history_count},
            {"history_next", c.solver.history_next},
            {"key", c.solver.key},
            {"clock", c.solver.clock},
            {"jacobi_first", c.solver.jacobi_first},
            {"jacobi_first_excess", c.solver.jacobi_first_excess},
            {"factors", factors}}}};
}

// The accurate tier's checkpoint: positions, velocities and pressures on every node of the
// element mesh, and the matrices of the lagged factor (docs/archive.md).
json accurate_checkpoint(const core::hyperelastic::DynamicState& c, double dt_s, Blob& b) {
  b.add("x", c.x.data(), static_cast<size_t>(c.x.size()));
  b.add("v", c.v.data(), static_cast<size_t>(c.v.size()));
  b.add("p", c.p.data(), static_cast<size_t>(c.p.size()));
  add_sparse(b, "linear.analysed", c.linear.analysed);
  add_sparse(b, "linear.factored", c.linear.factored);
  // A run with a circulation: the loop's state and each coupled cavity's volume.
  if (!c.cavity_volume_m3.empty()) {
    const std::vector<double> loop = circulation_numbers(c.circulation);
    b.add("circulation.state", loop.data(), loop.size());
    b.add("circulation.cavity_volume_m3", c.cavity_volume_m3.data(), c.cavity_volume_m3.size());
  }
  return {{"tier", "accurate"},
          {"time_s", c.time_s},
          {"step_count", c.steps},
          {"dt_s", dt_s},
          {"num_nodes", c.x.cols()},
          {"num_pressures", c.p.size()},
          {"circulation_cavities", c.cavity_volume_m3.size()},
          {"circulation_beat_origin_s", c.circulation.beat_origin_s},
          {"circulation_previous_period_s", c.circulation.previous_period_s},
          {"contraction_origin_s", c.contraction_origin_s}};
}

}  // namespace

void ArchiveWriter::checkpoint(const service::Engine& engine, const std::string& parameter_state_json) {
  detail::WriterFile& w = *f_;
  if (w.closed) throw std::logic_error("archive: checkpoint after close");
  const service::EngineCheckpoint state = engine.checkpoint();
  const auto* rt = std::get_if<core::SimulatorCheckpoint>(&state);
  const auto* acc = std::get_if<core::hyperelastic::DynamicState>(&state);
  const long step_count = rt ? rt->step_count : acc->steps;
  const double time_s = rt ? rt->time_s : acc->time_s;
  const Eigen::Map<const Eigen::VectorXd> x = rt ? Eigen::Map<const Eigen::VectorXd>(rt->x.data(), rt->x.size())
                                                 : Eigen::Map<const Eigen::VectorXd>(acc->x.data(), acc->x.size());
  const Eigen::Map<const Eigen::VectorXd> v = rt ? Eigen::Map<const Eigen::VectorXd>(rt->v.data(), rt->v.size())
                                                 : Eigen::Map<const Eigen::VectorXd>(acc->v.data(), acc->v.size());
  // The same state again (a periodic checkpoint on the run's last step, then the final
  // one): keep one. A state revisited after a restore differs in x or v or parameters.
  if (step_count == w.last_checkpoint_step && x == w.last_checkpoint_x && v == w.last_checkpoint_v &&
      parameter_state_json == w.last_checkpoint_params)
    return;
  Blob b;
  json header = rt ? real_time_checkpoint(*rt, b) : accurate_checkpoint(*acc, engine.dt_s(), b);
  header["parameter_state"] = parameter_state_json;
  header["layout"] = b.layout;
  const std::string text = header.dump();
  const std::int64_t data_end = static_cast<std::int64_t>(w.cp_data.append(b.data.data(), b.data.size()));
  const std::int64_t header_end =
      static_cast<std::int64_t>(w.cp_header.append(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
  w.cp_data_end.append(&data_end, 1);
  w.cp_header_end.append(&header_end, 1);
  w.cp_time.append(&time_s, 1);
  const std::int64_t step = step_count;
  w.cp_step.append(&step, 1);  // last: the checkpoint is complete
  w.last_checkpoint_step = step_count;
  w.last_checkpoint_x = x;
  w.last_checkpoint_v = v;
  w.last_checkpoint_params = parameter_state_json;
}

void ArchiveWriter::flush() {
  detail::WriterFile& w = *f_;
  if (w.closed) return;
  w.file.flush();
  w.since_flush = 0;
  w.last_flush = std::chrono::steady_clock::now();
  // The sidecar follows the flushed frames, rewritten at most every 5 s and at most a
  // tenth of the time (it grows with the run): ParaView opens a live run's flushed part.
  const double since_sidecar = std::chrono::duration<double>(w.last_flush - w.last_sidecar).count();
  if (w.frames > w.sidecar_frames && (w.sidecar_frames == 0 || since_sidecar >= std::max(5.0, 10 * w.sidecar_cost_s))) {
    try {
      const auto t0 = std::chrono::steady_clock::now();
      write_atomically(sidecar_path(w.o.path), detail::xdmf_text(w.o.path, w.frames, w.times, static_cast<hsize_t>(w.frame_rest.cols()),
                                                                 static_cast<hsize_t>(w.ne), w.o.velocities, w.o.displacement,
                                                                 w.frame_rest.cols() != w.nn));
      w.last_sidecar = std::chrono::steady_clock::now();
      w.sidecar_cost_s = std::chrono::duration<double>(w.last_sidecar - t0).count();
      w.sidecar_frames = w.frames;
    } catch (const std::exception&) {
      // The sidecar is a convenience: close() and recover rewrite it; recording goes on.
    }
  }
}

void ArchiveWriter::close() {
  detail::WriterFile& w = *f_;
  if (w.closed) return;
  w.file.flush();
  const std::string path = w.o.path;
  const long frames = w.frames;
  f_ = std::make_unique<detail::WriterFile>();  // the old one closes every dataset, then the file
  f_->closed = true;
  f_->frames = frames;
  f_->o.path = path;
  write_xdmf(path);
}

}  // namespace fiberfem::archive
