#include "service/archive/archive.hpp"

#include "service/archive/hdf5.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace fiberfem::archive {

using nlohmann::json;

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

namespace {

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

// Per-frame datasets under /frames (name, row shape); `step` is extended last, so a frame
// is complete when `step` has it.
constexpr hsize_t kScalarChunk = 256;

// A checkpoint is a JSON header (scalars and the layout of the doubles) and one run of
// doubles in /checkpoints/data; see docs/archive.md.
struct Blob {
  json layout = json::array();
  std::vector<double> data;
  void add(const std::string& name, const double* p, size_t n) {
    layout.push_back({{"name", name}, {"offset", data.size()}, {"count", n}});
    data.insert(data.end(), p, p + n);
  }
};

void add_quaternions(Blob& b, const std::string& name, const std::vector<Eigen::Quaterniond>& q) {
  std::vector<double> v;
  v.reserve(4 * q.size());
  for (const auto& x : q) v.insert(v.end(), x.coeffs().data(), x.coeffs().data() + 4);  // x y z w
  b.add(name, v.data(), v.size());
}
void add_matrices(Blob& b, const std::string& name, const std::vector<core::Mat3>& m) {
  std::vector<double> v;
  v.reserve(9 * m.size());
  for (const auto& x : m) v.insert(v.end(), x.data(), x.data() + 9);  // column-major
  b.add(name, v.data(), v.size());
}

struct Section {
  const double* p = nullptr;
  size_t n = 0;
};
Section section(const json& header, const std::vector<double>& data, const std::string& name) {
  for (const auto& s : header.at("layout"))
    if (s.at("name") == name) {
      const std::int64_t off = s.at("offset"), n = s.at("count");
      if (off < 0 || n < 0 || static_cast<size_t>(off) > data.size() || static_cast<size_t>(n) > data.size() - static_cast<size_t>(off)) throw std::runtime_error("archive: checkpoint section '" + name + "' runs past its data");
      return {data.data() + off, static_cast<size_t>(n)};
    }
  throw std::runtime_error("archive: checkpoint has no section '" + name + "'");
}
Eigen::VectorXd vector_of(const Section& s) { return Eigen::Map<const Eigen::VectorXd>(s.p, static_cast<Eigen::Index>(s.n)); }
std::vector<Eigen::Quaterniond> quaternions_of(const Section& s) {
  std::vector<Eigen::Quaterniond> q(s.n / 4);
  for (size_t i = 0; i < q.size(); ++i) q[i].coeffs() = Eigen::Map<const Eigen::Vector4d>(s.p + 4 * i);
  return q;
}
std::vector<core::Mat3> matrices_of(const Section& s) {
  std::vector<core::Mat3> m(s.n / 9);
  for (size_t i = 0; i < m.size(); ++i) m[i] = Eigen::Map<const core::Mat3>(s.p + 9 * i);
  return m;
}

std::string join_json(const std::vector<std::string>& names) { return json(names).dump(); }

std::vector<std::string> names_attribute(hid_t obj, const std::string& name) {
  if (!h5::has_attribute(obj, name)) return {};
  return json::parse(h5::read_string_attribute(obj, name)).get<std::vector<std::string>>();
}

}  // namespace

namespace {
void write_atomically(const std::string& path, const std::string& text);
std::string sidecar_path(const std::string& h5_path);
}  // namespace

namespace detail {
std::string xdmf_text(const std::string& h5_path, long F, const std::vector<double>& times, hsize_t N, hsize_t E, bool velocities,
                      bool displacement);
}  // namespace detail

namespace detail {

struct WriterFile {
  ArchiveOptions o;
  h5::File file;
  h5::Dataset step, time, positions, velocities, displacement, activation, cavities, probes, energies, iterations, residual, status,
      substeps, inverted;
  h5::Dataset cmd_step, cmd_time, cmd_accepted, cmd_end, cmd_bytes;
  h5::Dataset cp_step, cp_time, cp_header_end, cp_header, cp_data_end, cp_data;
  int nn = 0, ne = 0;
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
  Eigen::VectorXd last_checkpoint_x, last_checkpoint_v;
  std::string last_checkpoint_params;
  std::vector<float> fbuf;
  bool closed = false;
  std::string xdmf_path;
};

}  // namespace detail

ArchiveWriter::ArchiveWriter(ArchiveOptions options, const io::Scene& scene, const core::Simulator& sim, std::string source)
    : f_(std::make_unique<detail::WriterFile>()) {
  options.validate();
  detail::WriterFile& w = *f_;
  w.o = std::move(options);
  const core::Model& m = sim.model();
  const core::TetMesh& mesh = m.mesh;
  w.nn = mesh.num_nodes();
  w.ne = mesh.num_elements();
  w.probe_list = scene.probes;
  const hsize_t N = static_cast<hsize_t>(w.nn), E = static_cast<hsize_t>(w.ne);
  w.file = h5::File::create(w.o.path);
  const hid_t root = w.file.id();
  h5::write_attribute(root, "format", std::string(kFormatName));
  h5::write_attribute<std::int64_t>(root, "format_version", kFormatVersion);
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
    h5::write_attribute(g.id(), "dt_s", sim.settings().dt_s);
    h5::write_attribute(g.id(), "until_s", scene.until_s);
    h5::write_attribute(g.id(), "base_dir",
                        std::filesystem::absolute(scene.base_dir.empty() ? std::string(".") : scene.base_dir).lexically_normal().string());
    const core::SimulatorSettings& s = sim.settings();
    const json settings = {{"dt_s", s.dt_s},
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
                           {"max_substep_halvings", s.max_substep_halvings},
                           {"max_energy_gain", std::isfinite(s.max_energy_gain) ? json(s.max_energy_gain) : json("inf")},
                           {"threads", s.threads}};
    h5::write_attribute(g.id(), "solver_settings", settings.dump());
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
    w.positions = h5::create_extendible<float>(gid, "positions", {N, 3}, 1, w.o.compression);
    h5::write_attribute(w.positions.id(), "unit", std::string("m"));
    if (w.o.displacement) {
      w.displacement = h5::create_extendible<float>(gid, "displacement", {N, 3}, 1, w.o.compression);
      h5::write_attribute(w.displacement.id(), "unit", std::string("m"));
    }
    if (w.o.velocities) {
      w.velocities = h5::create_extendible<float>(gid, "velocities", {N, 3}, 1, w.o.compression);
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
  checkpoint(sim, "{}");
  w.next_checkpoint_s = sim.time_s() + w.o.checkpoint_every_s;
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

void ArchiveWriter::record_frame(const core::Simulator& sim, const core::StepReport& r, const FrameExtras& x) {
  detail::WriterFile& w = *f_;
  if (w.closed) throw std::logic_error("archive: record_frame after close");
  if (sim.step_count() % w.o.every_steps != 0) return;
  const auto as_float = [&](const double* p, size_t n) -> const float* {
    w.fbuf.resize(n);
    for (size_t i = 0; i < n; ++i) w.fbuf[i] = static_cast<float>(p[i]);
    return w.fbuf.data();
  };
  const size_t n3 = 3 * static_cast<size_t>(w.nn);
  w.time.append(&r.time_s, 1);
  w.positions.append(as_float(sim.positions().data(), n3), 1);
  if (w.displacement) {
    const double* x = sim.positions().data();
    const double* x0 = sim.model().mesh.rest_positions().data();
    w.fbuf.resize(n3);
    for (size_t i = 0; i < n3; ++i) w.fbuf[i] = static_cast<float>(x[i] - x0[i]);
    w.displacement.append(w.fbuf.data(), 1);
  }
  if (w.velocities) w.velocities.append(as_float(sim.velocities().data(), n3), 1);
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
  for (const io::Probe& p : w.probe_list) {
    const core::Vec3 u = p.displacement(sim.model().mesh, x_now);
    probe.insert(probe.end(), u.data(), u.data() + 3);
  }
  w.probes.append(probe.data(), 1);
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

void ArchiveWriter::checkpoint(const core::Simulator& sim, const std::string& parameter_state_json) {
  detail::WriterFile& w = *f_;
  if (w.closed) throw std::logic_error("archive: checkpoint after close");
  const core::SimulatorCheckpoint c = sim.checkpoint();
  // The same state again (a periodic checkpoint on the run's last step, then the final
  // one): keep one. A state revisited after a restore differs in x or v or parameters.
  if (c.step_count == w.last_checkpoint_step && c.x == w.last_checkpoint_x && c.v == w.last_checkpoint_v &&
      parameter_state_json == w.last_checkpoint_params)
    return;
  Blob b;
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
                       {"excess", f.excess}, {"key", f.key}, {"last_used", f.last_used}});
  }
  const json header = {
      {"time_s", c.time_s},
      {"step_count", c.step_count},
      {"dt_s", c.dt_s},
      {"num_nodes", c.num_nodes},
      {"num_elements", c.num_elements},
      {"last_h_s", c.last_h_s},
      {"rotations_current", c.rotations_current},
      {"inverted_current", c.inverted_current},
      {"energy_floor_j", c.energy_floor_j},
      {"contraction_origin_s", c.contraction_origin_s},
      {"solver",
       {{"name", c.solver.solver_name},
        {"history_rows", c.solver.history_rows},
        {"history_cols", c.solver.history_cols},
        {"history_count", c.solver.history_count},
        {"history_next", c.solver.history_next},
        {"key", c.solver.key},
        {"clock", c.solver.clock},
        {"factors", factors}}},
      {"parameter_state", parameter_state_json},
      {"layout", b.layout}};
  const std::string text = header.dump();
  const std::int64_t data_end = static_cast<std::int64_t>(w.cp_data.append(b.data.data(), b.data.size()));
  const std::int64_t header_end =
      static_cast<std::int64_t>(w.cp_header.append(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
  w.cp_data_end.append(&data_end, 1);
  w.cp_header_end.append(&header_end, 1);
  w.cp_time.append(&c.time_s, 1);
  const std::int64_t step = c.step_count;
  w.cp_step.append(&step, 1);  // last: the checkpoint is complete
  w.last_checkpoint_step = c.step_count;
  w.last_checkpoint_x = c.x;
  w.last_checkpoint_v = c.v;
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
      write_atomically(sidecar_path(w.o.path), detail::xdmf_text(w.o.path, w.frames, w.times, static_cast<hsize_t>(w.nn),
                                                                 static_cast<hsize_t>(w.ne), w.o.velocities, w.o.displacement));
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

// ---------------------------------------------------------------------------- reader

struct ArchiveReader::Impl {
  h5::File file;
  bool follow = false;
  std::vector<h5::Dataset> per_frame;  // every per-frame dataset (frames = min of rows)
  h5::Dataset step, time, positions, velocities, displacement, activation, cavities, probes, energies, iterations, residual, status,
      substeps, inverted;
  h5::Dataset cmd_step, cmd_time, cmd_accepted, cmd_end, cmd_bytes;
  h5::Dataset cp_step, cp_time, cp_header_end, cp_header, cp_data_end, cp_data;
  long min_rows(std::vector<h5::Dataset*> ds) {
    hsize_t n = std::numeric_limits<hsize_t>::max();
    for (h5::Dataset* d : ds) {
      if (follow) d->refresh();
      n = std::min(n, d->dims()[0]);
    }
    return static_cast<long>(n);
  }
};

ArchiveReader::ArchiveReader(ArchiveReader&&) noexcept = default;
ArchiveReader& ArchiveReader::operator=(ArchiveReader&&) noexcept = default;
ArchiveReader::~ArchiveReader() = default;

ArchiveReader::ArchiveReader(const std::string& path, bool follow) : impl_(std::make_unique<Impl>()), path_(path) {
  Impl& d = *impl_;
  d.follow = follow;
  d.file = h5::File::open(path, follow ? h5::Mode::read_swmr : h5::Mode::read);
  const hid_t root = d.file.id();
  const std::string where = "'" + path + "'";
  if (!h5::has_attribute(root, "format") || h5::read_string_attribute(root, "format") != kFormatName)
    throw std::runtime_error(where + " is not a fiberfem archive (no root attribute format = \"" + std::string(kFormatName) + "\")");
  ArchiveHeader& h = header_;
  h.format_version = static_cast<int>(h5::read_attribute<std::int64_t>(root, "format_version"));
  if (h.format_version != kFormatVersion)
    throw std::runtime_error(where + " has archive format version " + std::to_string(h.format_version) + "; this fiberfem reads version " +
                             std::to_string(kFormatVersion));
  h.software_version = h5::read_string_attribute(root, "software_version");
  h.git_commit = h5::read_string_attribute(root, "git_commit");
  h.created_utc = h5::read_string_attribute(root, "created_utc");
  h.source = h5::read_string_attribute(root, "source");
  const auto open = [&](const std::string& name) { return h5::open_dataset(root, name, where); };
  {
    h5::Handle g = h5::open_group(root, "scene");
    h.scene_name = h5::read_string_attribute(g.id(), "name");
    h.scene_sha256 = h5::read_string_attribute(g.id(), "sha256");
    h.dt_s = h5::read_attribute<double>(g.id(), "dt_s");
    h.scene_base_dir = h5::read_string_attribute(g.id(), "base_dir");
    h.scene_yaml = h5::read_text(open("scene/yaml"));
  }
  const std::vector<double> rest = open("mesh/rest_positions").read_all<double>();
  h.rest_positions = Eigen::Map<const core::Positions>(rest.data(), 3, static_cast<Eigen::Index>(rest.size() / 3));
  const std::vector<std::int32_t> tets = open("mesh/tets").read_all<std::int32_t>();
  for (size_t i = 0; i + 3 < tets.size(); i += 4) h.tets.push_back({tets[i], tets[i + 1], tets[i + 2], tets[i + 3]});
  const std::vector<std::int32_t> regions = open("mesh/regions").read_all<std::int32_t>();
  h.regions.assign(regions.begin(), regions.end());
  const std::vector<std::int32_t> tris = open("mesh/boundary_triangles").read_all<std::int32_t>();
  for (size_t i = 0; i + 2 < tris.size(); i += 3) h.boundary_triangles.push_back({tris[i], tris[i + 1], tris[i + 2]});
  h.fixed_dofs = open("mesh/fixed_dofs").read_all<std::uint8_t>();
  const std::vector<double> fib = open("mesh/fibers").read_all<double>();
  for (size_t i = 0; i + 2 < fib.size(); i += 3) h.fibers.emplace_back(fib[i], fib[i + 1], fib[i + 2]);
  const std::vector<double> C = open("materials/stiffness").read_all<double>();
  for (size_t r = 0; r + 35 < C.size(); r += 36) h.stiffness_pa.push_back(Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(C.data() + r));
  h.density_kg_m3 = open("materials/density").read_all<double>();

  d.step = open("frames/step");
  d.time = open("frames/time");
  d.positions = open("frames/positions");
  h.has_velocities = h5::exists(h5::open_group(root, "frames").id(), "velocities");
  if (h.has_velocities) d.velocities = open("frames/velocities");
  h.has_displacement = h5::exists(h5::open_group(root, "frames").id(), "displacement");
  if (h.has_displacement) d.displacement = open("frames/displacement");
  d.activation = open("frames/activation");
  d.cavities = open("frames/cavity_volumes");
  h.cavity_names = names_attribute(d.cavities.id(), "names");
  d.probes = open("frames/probe_displacements");
  h.probe_names = names_attribute(d.probes.id(), "names");
  d.energies = open("frames/energies");
  d.iterations = open("frames/solver_iterations");
  d.residual = open("frames/solver_residual");
  d.status = open("frames/status");
  d.substeps = open("frames/substeps");
  d.inverted = open("frames/inverted_elements");
  h.every_steps = static_cast<int>(h5::read_attribute<std::int64_t>(h5::open_group(root, "frames").id(), "every_steps"));
  d.cmd_step = open("commands/step");
  d.cmd_time = open("commands/time");
  d.cmd_accepted = open("commands/accepted");
  d.cmd_end = open("commands/record_end");
  d.cmd_bytes = open("commands/records");
  d.cp_step = open("checkpoints/step");
  d.cp_time = open("checkpoints/time");
  d.cp_header_end = open("checkpoints/header_end");
  d.cp_header = open("checkpoints/headers");
  d.cp_data_end = open("checkpoints/data_end");
  d.cp_data = open("checkpoints/data");
  const hsize_t N = static_cast<hsize_t>(h.rest_positions.cols());
  const auto bad = [&](const std::string& what) { throw std::runtime_error(where + ": " + what); };
  if (rest.size() % 3 != 0 || N == 0) bad("mesh/rest_positions holds " + std::to_string(rest.size()) + " numbers, not 3 per node");
  if (!h.rest_positions.allFinite()) bad("mesh/rest_positions has a non-finite coordinate");
  if (tets.empty() || tets.size() % 4 != 0) bad("mesh/tets holds " + std::to_string(tets.size()) + " indices, not 4 per element");
  for (size_t i = 0; i < tets.size(); ++i)
    if (tets[i] < 0 || static_cast<hsize_t>(tets[i]) >= N)
      bad("mesh/tets[" + std::to_string(i) + "] = " + std::to_string(tets[i]) + " is not a node index (the mesh has " + std::to_string(N) + ")");
  for (size_t i = 0; i < tris.size(); ++i)
    if (tris[i] < 0 || static_cast<hsize_t>(tris[i]) >= N)
      bad("mesh/boundary_triangles[" + std::to_string(i) + "] = " + std::to_string(tris[i]) + " is not a node index");
  const size_t E = h.tets.size();
  if (h.regions.size() != E) bad("mesh/regions has " + std::to_string(h.regions.size()) + " entries for " + std::to_string(E) + " elements");
  if (h.fibers.size() != E || fib.size() != 3 * E) bad("mesh/fibers holds " + std::to_string(fib.size()) + " numbers for " + std::to_string(E) + " elements");
  if (h.fixed_dofs.size() != 3 * N) bad("mesh/fixed_dofs has " + std::to_string(h.fixed_dofs.size()) + " entries for " + std::to_string(N) + " nodes");
  if (C.size() % 36 != 0 || h.stiffness_pa.size() != h.density_kg_m3.size())
    bad("materials/stiffness and materials/density disagree on the number of regions");
  for (int r : h.regions)
    if (r < 0 || static_cast<size_t>(r) >= h.density_kg_m3.size()) bad("mesh/regions names region " + std::to_string(r) + ", which has no material");
  if (d.positions.dims().size() != 3 || d.positions.dims()[1] != N || d.positions.dims()[2] != 3)
    throw std::runtime_error(where + ": frames/positions does not match the mesh's " + std::to_string(N) + " nodes");
  for (const auto* ds : {&d.velocities, &d.displacement})
    if (*ds && (ds->dims().size() != 3 || ds->dims()[1] != N || ds->dims()[2] != 3))
      bad("frames/velocities or frames/displacement does not match the mesh's " + std::to_string(N) + " nodes");
  if (d.energies.dims().size() != 2 || d.energies.dims()[1] != 2) bad("frames/energies is not 2 numbers per frame");
  refresh();
}

long ArchiveReader::refresh() {
  Impl& d = *impl_;
  std::vector<h5::Dataset*> ds = {&d.time, &d.positions, &d.activation, &d.cavities, &d.probes, &d.energies, &d.iterations,
                                  &d.residual, &d.status, &d.substeps, &d.inverted, &d.step};
  if (d.velocities) ds.push_back(&d.velocities);
  if (d.displacement) ds.push_back(&d.displacement);
  frames_ = d.min_rows(ds);
  return frames_;
}

std::vector<double> ArchiveReader::times() const { return impl_->time.read_rows<double>(0, static_cast<hsize_t>(frames_)); }

std::vector<long> ArchiveReader::steps() const {
  const auto s = impl_->step.read_rows<std::int64_t>(0, static_cast<hsize_t>(frames_));
  return {s.begin(), s.end()};
}

Frame ArchiveReader::frame(long i) const {
  if (i < 0 || i >= frames_)
    throw std::out_of_range("archive: frame " + std::to_string(i) + " of " + std::to_string(frames_) + " in '" + path_ + "'");
  const Impl& d = *impl_;
  const hsize_t k = static_cast<hsize_t>(i);
  const Eigen::Index N = header_.rest_positions.cols();
  Frame f;
  f.step = d.step.read_rows<std::int64_t>(k, 1)[0];
  f.time_s = d.time.read_rows<double>(k, 1)[0];
  const std::vector<float> x = d.positions.read_rows<float>(k, 1);
  f.positions = Eigen::Map<const Eigen::Matrix<float, 3, Eigen::Dynamic>>(x.data(), 3, N).cast<double>();
  if (d.displacement) {
    const std::vector<float> u = d.displacement.read_rows<float>(k, 1);
    f.displacement = Eigen::Map<const Eigen::Matrix<float, 3, Eigen::Dynamic>>(u.data(), 3, N).cast<double>();
  }
  if (d.velocities) {
    const std::vector<float> v = d.velocities.read_rows<float>(k, 1);
    f.velocities = Eigen::Map<const Eigen::Matrix<float, 3, Eigen::Dynamic>>(v.data(), 3, N).cast<double>();
  }
  const std::vector<float> a = d.activation.read_rows<float>(k, 1);
  f.activation_pa.assign(a.begin(), a.end());
  f.cavity_volumes_m3 = d.cavities.read_rows<double>(k, 1);
  const std::vector<double> p = d.probes.read_rows<double>(k, 1);
  for (size_t j = 0; j + 2 < p.size(); j += 3) f.probe_displacements_m.emplace_back(p[j], p[j + 1], p[j + 2]);
  const std::vector<double> en = d.energies.read_rows<double>(k, 1);
  f.kinetic_energy_j = en[0];
  f.elastic_energy_j = en[1];
  f.solver_iterations = d.iterations.read_rows<std::int32_t>(k, 1)[0];
  f.solver_residual = d.residual.read_rows<double>(k, 1)[0];
  f.substeps = d.substeps.read_rows<std::int32_t>(k, 1)[0];
  f.inverted_elements = d.inverted.read_rows<std::int32_t>(k, 1)[0];
  f.status = core::to_string(static_cast<core::StepStatus>(d.status.read_rows<std::int8_t>(k, 1)[0]));
  return f;
}

std::vector<CommandRecord> ArchiveReader::commands() const {
  Impl& d = *impl_;
  std::vector<h5::Dataset*> ds = {&d.cmd_step, &d.cmd_time, &d.cmd_accepted, &d.cmd_end};
  const long n = d.min_rows(ds);
  const auto step = d.cmd_step.read_rows<std::int64_t>(0, static_cast<hsize_t>(n));
  const auto time = d.cmd_time.read_rows<double>(0, static_cast<hsize_t>(n));
  const auto end = d.cmd_end.read_rows<std::int64_t>(0, static_cast<hsize_t>(n));
  if (d.follow) d.cmd_bytes.refresh();
  for (long i = 0; i < n; ++i)
    if (end[static_cast<size_t>(i)] < (i ? end[static_cast<size_t>(i - 1)] : 0))
      throw std::runtime_error("archive: commands/record_end is not ascending at record " + std::to_string(i) + " in '" + path_ + "'");
  const auto bytes = n > 0 ? d.cmd_bytes.read_rows<std::uint8_t>(0, static_cast<hsize_t>(end.back())) : std::vector<std::uint8_t>{};
  std::vector<CommandRecord> out;
  std::int64_t begin = 0;
  for (long i = 0; i < n; ++i) try {
    const json r = json::parse(bytes.begin() + begin, bytes.begin() + end[static_cast<size_t>(i)]);
    begin = end[static_cast<size_t>(i)];
    CommandRecord c;
    c.step = step[static_cast<size_t>(i)];
    c.time_s = time[static_cast<size_t>(i)];
    c.id = r.at("id");
    c.kind = r.at("kind");
    c.text = r.at("command").is_string() ? r.at("command").get<std::string>() : r.at("command").dump();
    c.accepted = r.at("accepted");
    c.reason = r.at("reason");
    out.push_back(std::move(c));
  } catch (const json::exception& e) {
    throw std::runtime_error("archive: command record " + std::to_string(i) + " in '" + path_ + "' is malformed: " + e.what());
  }
  return out;
}

std::vector<CheckpointInfo> ArchiveReader::checkpoints() const {
  Impl& d = *impl_;
  std::vector<h5::Dataset*> ds = {&d.cp_step, &d.cp_time, &d.cp_header_end, &d.cp_data_end};
  const long n = d.min_rows(ds);
  const auto step = d.cp_step.read_rows<std::int64_t>(0, static_cast<hsize_t>(n));
  const auto time = d.cp_time.read_rows<double>(0, static_cast<hsize_t>(n));
  std::vector<CheckpointInfo> out;
  for (long i = 0; i < n; ++i) out.push_back({step[static_cast<size_t>(i)], time[static_cast<size_t>(i)]});
  return out;
}

size_t ArchiveReader::checkpoint_at_or_before(double time_s) const {
  const std::vector<CheckpointInfo> cps = checkpoints();
  size_t best = cps.size();
  for (size_t k = 0; k < cps.size(); ++k)
    if (cps[k].time_s <= time_s + 1e-9) best = k;
  if (best == cps.size()) {
    std::ostringstream m;
    m << "archive: no checkpoint at or before t = " << time_s << " s in '" << path_ << "' (checkpoints at:";
    for (const auto& c : cps) m << " " << c.time_s;
    m << (cps.empty() ? " none)" : " s)");
    throw std::invalid_argument(m.str());
  }
  return best;
}

namespace {
// The checkpoint in a header (JSON) and its data. @throws json::exception when malformed.
core::SimulatorCheckpoint checkpoint_of(const json& h, const std::vector<double>& data, std::string* parameter_state);
}  // namespace

core::SimulatorCheckpoint ArchiveReader::read_checkpoint(size_t k, std::string* parameter_state) const {
  Impl& d = *impl_;
  const std::vector<CheckpointInfo> cps = checkpoints();
  if (k >= cps.size())
    throw std::out_of_range("archive: checkpoint " + std::to_string(k) + " of " + std::to_string(cps.size()) + " in '" + path_ + "'");
  const hsize_t n = static_cast<hsize_t>(cps.size());
  const auto hend = d.cp_header_end.read_rows<std::int64_t>(0, n);
  const auto dend = d.cp_data_end.read_rows<std::int64_t>(0, n);
  const std::int64_t hb0 = k == 0 ? 0 : hend[k - 1], db0 = k == 0 ? 0 : dend[k - 1];
  if (hb0 < 0 || hend[k] < hb0 || db0 < 0 || dend[k] < db0)
    throw std::runtime_error("archive: checkpoint " + std::to_string(k) + " in '" + path_ + "' has bad extents (header_end, data_end)");
  const hsize_t h0 = static_cast<hsize_t>(hb0), h1 = static_cast<hsize_t>(hend[k]);
  const hsize_t d0 = static_cast<hsize_t>(db0), d1 = static_cast<hsize_t>(dend[k]);
  if (d.follow) {
    d.cp_header.refresh();
    d.cp_data.refresh();
  }
  const auto hb = d.cp_header.read_rows<std::uint8_t>(h0, h1 - h0);
  const std::vector<double> data = d.cp_data.read_rows<double>(d0, d1 - d0);
  try {
    return checkpoint_of(json::parse(hb.begin(), hb.end()), data, parameter_state);
  } catch (const json::exception& e) {
    throw std::runtime_error("archive: checkpoint " + std::to_string(k) + " in '" + path_ + "' is malformed: " + e.what());
  }
}

namespace {
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
}  // namespace

// ---------------------------------------------------------------------------- sidecars

namespace {

void write_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw std::runtime_error("archive: cannot write '" + tmp + "'");
    f << text;
    if (!f) throw std::runtime_error("archive: cannot write '" + tmp + "'");
  }
  std::filesystem::rename(tmp, path);
}

std::string sidecar_path(const std::string& h5_path) {
  const std::filesystem::path p(h5_path);
  return (p.parent_path() / p.stem()).string() + ".xdmf";
}

}  // namespace

namespace detail {
// The sidecar's text for F frames (their times) of an archive of N nodes and E elements.
std::string xdmf_text(const std::string& h5_path, long F, const std::vector<double>& times, hsize_t N, hsize_t E, bool velocities,
                      bool displacement) {
  const std::string file = std::filesystem::path(h5_path).filename().string();
  const std::string n = std::to_string(N), e = std::to_string(E), f = std::to_string(F);
  std::ostringstream x;
  x.precision(17);
  x << "<?xml version=\"1.0\" ?>\n<!-- fiberfem run archive sidecar (docs/archive.md); data stay in " << file
    << " -->\n<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n<Domain>\n"
    << "<Grid Name=\"run\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const auto slab = [&](const std::string& ds, long i, bool vec) {
    // file.h5:/path|start:stride:count:dims (ParaView's Xdmf3 hyperslab syntax)
    const std::string s = std::to_string(i);
    return vec ? file + ":/frames/" + ds + "|" + s + " 0 0:1 1 1:1 " + n + " 3:" + f + " " + n + " 3"
               : file + ":/frames/" + ds + "|" + s + " 0:1 1:1 " + e + ":" + f + " " + e;
  };
  for (long i = 0; i < F; ++i) {
    x << "<Grid Name=\"frame " << i << "\" GridType=\"Uniform\">\n<Time Value=\"" << times[static_cast<size_t>(i)] << "\"/>\n"
      << "<Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" << e << "\">\n"
      << " <DataItem Dimensions=\"" << e << " 4\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">" << file
      << ":/mesh/tets</DataItem>\n</Topology>\n"
      << "<Geometry GeometryType=\"XYZ\">\n <DataItem Dimensions=\"" << n
      << " 3\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << slab("positions", i, true)
      << "</DataItem>\n</Geometry>\n";
    if (displacement)
      x << "<Attribute Name=\"displacement\" AttributeType=\"Vector\" Center=\"Node\">\n <DataItem Dimensions=\"" << n
        << " 3\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << slab("displacement", i, true)
        << "</DataItem>\n</Attribute>\n";
    if (velocities)
      x << "<Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n <DataItem Dimensions=\"" << n
        << " 3\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << slab("velocities", i, true)
        << "</DataItem>\n</Attribute>\n";
    x << "<Attribute Name=\"activation\" AttributeType=\"Scalar\" Center=\"Cell\">\n <DataItem Dimensions=\"" << e
      << "\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << slab("activation", i, false)
      << "</DataItem>\n</Attribute>\n"
      << "<Attribute Name=\"region\" AttributeType=\"Scalar\" Center=\"Cell\">\n <DataItem Dimensions=\"" << e
      << "\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">" << file << ":/mesh/regions</DataItem>\n</Attribute>\n"
      << "</Grid>\n";
  }
  x << "</Grid>\n</Domain>\n</Xdmf>\n";
  return x.str();
}

}  // namespace detail

void write_xdmf(const std::string& h5_path) {
  long F = 0;
  std::vector<double> times;
  bool velocities = false, displacement = false;
  hsize_t N = 0, E = 0;
  {
    ArchiveReader r(h5_path, /*follow=*/true);
    F = r.frames();
    times = r.times();
    velocities = r.header().has_velocities;
    displacement = r.header().has_displacement;
    N = static_cast<hsize_t>(r.header().rest_positions.cols());
    E = r.header().tets.size();
  }
  write_atomically(sidecar_path(h5_path), detail::xdmf_text(h5_path, F, times, N, E, velocities, displacement));
}

long recover(const std::string& h5_path) {
  h5::silence_errors();
  if (H5Fis_hdf5(h5_path.c_str()) <= 0) throw std::runtime_error("'" + h5_path + "' is not an HDF5 file (or cannot be read)");
  {
    // What h5clear --status does: open read-write with the file access property that
    // clears the consistency flags a SWMR writer leaves set when it dies.
    h5::Handle fapl = h5::latest_format_access();
    hbool_t clear = 1;
    h5::check(H5Pset(fapl.id(), "clear_status_flags", &clear), "cannot ask to clear the status flags of '" + h5_path + "'");
    h5::Handle f(H5Fopen(h5_path.c_str(), H5F_ACC_RDWR, fapl.id()), H5Fclose,
                 "cannot open '" + h5_path + "' to clear its status flags");
    h5::write_attribute(f.id(), "recovered_utc", utc_now());
  }
  long frames = 0;
  {
    ArchiveReader r(h5_path, /*follow=*/false);  // an ordinary open must work now
    frames = r.frames();
    if (frames > 0) (void)r.frame(frames - 1);
  }
  write_xdmf(h5_path);
  return frames;
}

void export_meshio(const std::string& h5_path, const std::string& out_xdmf) {
  ArchiveReader r(h5_path, /*follow=*/true);
  const ArchiveHeader& h = r.header();
  const std::filesystem::path xp(out_xdmf);
  const std::string data_path = (xp.parent_path() / xp.stem()).string() + ".h5";
  if (std::filesystem::exists(data_path) && std::filesystem::equivalent(data_path, h5_path))
    throw std::invalid_argument("archive: export-meshio would overwrite the archive '" + h5_path + "'");
  const std::string file = std::filesystem::path(data_path).filename().string();
  const hsize_t N = static_cast<hsize_t>(h.rest_positions.cols()), E = h.tets.size();
  h5::File out = h5::File::create(data_path);
  h5::create_fixed<double>(out.id(), "points", {N, 3}, h.rest_positions.data());
  std::vector<std::int64_t> cells;
  for (const core::Tet& t : h.tets) cells.insert(cells.end(), t.begin(), t.end());
  h5::create_fixed<std::int64_t>(out.id(), "cells", {E, 4}, cells.data());
  std::ostringstream x;
  x.precision(17);
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n<Domain>\n"
    << "<Grid Name=\"mesh\" GridType=\"Uniform\">\n<Geometry GeometryType=\"XYZ\">\n <DataItem DataType=\"Float\" Dimensions=\"" << N
    << " 3\" Format=\"HDF\" Precision=\"8\">" << file << ":/points</DataItem>\n</Geometry>\n"
    << "<Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" << E << "\">\n <DataItem DataType=\"Int\" Dimensions=\"" << E
    << " 4\" Format=\"HDF\" Precision=\"8\">" << file << ":/cells</DataItem>\n</Topology>\n</Grid>\n"
    << "<Grid Name=\"TimeSeries\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const long F = r.frames();
  for (long i = 0; i < F; ++i) {
    const Frame fr = r.frame(i);
    const core::Positions u = fr.positions - h.rest_positions;
    const std::string s = std::to_string(i);
    h5::create_fixed<double>(out.id(), "positions_" + s, {N, 3}, fr.positions.data());
    h5::create_fixed<double>(out.id(), "displacement_" + s, {N, 3}, u.data());
    h5::create_fixed<double>(out.id(), "activation_" + s, {E}, fr.activation_pa.data());
    x << "<Grid Name=\"frame " << s << "\">\n<xi:include xpointer=\"xpointer(//Grid[@Name=&quot;mesh&quot;]/*[self::Topology or "
         "self::Geometry])\"/>\n<Time Value=\""
      << fr.time_s << "\"/>\n";
    for (const char* name : {"positions", "displacement"})
      x << "<Attribute Name=\"" << name << "\" AttributeType=\"Vector\" Center=\"Node\">\n <DataItem DataType=\"Float\" Dimensions=\""
        << N << " 3\" Format=\"HDF\" Precision=\"8\">" << file << ":/" << name << "_" << s << "</DataItem>\n</Attribute>\n";
    x << "<Attribute Name=\"activation\" AttributeType=\"Scalar\" Center=\"Cell\">\n <DataItem DataType=\"Float\" Dimensions=\"" << E
      << "\" Format=\"HDF\" Precision=\"8\">" << file << ":/activation_" << s << "</DataItem>\n</Attribute>\n</Grid>\n";
  }
  x << "</Grid>\n</Domain>\n</Xdmf>\n";
  out.close();
  write_atomically(out_xdmf, x.str());
}

}  // namespace fiberfem::archive
