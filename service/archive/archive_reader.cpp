// The archive reader (docs/archive.md): header, frames, commands and checkpoints of a run,
// following a file still being written (SWMR) when asked.

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

// ---------------------------------------------------------------------------- reader

namespace {

// An accurate-tier archive's element order and, at order 2, its 10-node mesh (absent in
// version 1 archives: order 1), checked against the corner mesh of N nodes.
void read_element_mesh(hid_t root, ArchiveHeader& h, hsize_t N, const std::string& where) {
  h5::Handle g = h5::open_group(root, "mesh");
  if (!h5::has_attribute(g.id(), "order")) return;
  h.order = static_cast<int>(h5::read_attribute<std::int64_t>(g.id(), "order"));
  const auto bad = [&](const std::string& what) { throw std::runtime_error(where + ": " + what); };
  if (h.order != 1 && h.order != 2) bad("mesh order " + std::to_string(h.order) + " is not 1 or 2");
  if (h.order != 2) return;
  const std::vector<double> rest = h5::open_dataset(root, "mesh/order2_rest_positions", where).read_all<double>();
  const std::vector<std::int32_t> tets = h5::open_dataset(root, "mesh/order2_tets", where).read_all<std::int32_t>();
  const hsize_t M = rest.size() / 3;
  if (rest.size() % 3 != 0 || M < N) bad("mesh/order2_rest_positions does not hold 3 numbers for each of at least " + std::to_string(N) + " nodes");
  if (tets.size() != 10 * h.tets.size()) bad("mesh/order2_tets does not hold 10 nodes for each of the " + std::to_string(h.tets.size()) + " elements");
  h.element_rest_positions = Eigen::Map<const core::Positions>(rest.data(), 3, static_cast<Eigen::Index>(M));
  if (!h.element_rest_positions.allFinite() || h.element_rest_positions.leftCols(static_cast<Eigen::Index>(N)) != h.rest_positions)
    bad("mesh/order2_rest_positions does not start with the mesh's rest positions");
  for (size_t i = 0; i < tets.size(); i += 10) {
    std::array<int, 10> t;
    for (size_t a = 0; a < 10; ++a) {
      if (tets[i + a] < 0 || static_cast<hsize_t>(tets[i + a]) >= M) bad("mesh/order2_tets[" + std::to_string(i + a) + "] is not a node index");
      t[a] = tets[i + a];
    }
    h.element_tets.push_back(t);
  }
}

}  // namespace

struct ArchiveReader::Impl {
  h5::File file;
  bool follow = false;
  std::vector<h5::Dataset> per_frame;  // every per-frame dataset (frames = min of rows)
  h5::Dataset step, time, positions, velocities, displacement, activation, cavities, probes, energies, iterations, residual, status,
      substeps, inverted, circulation;
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
  if (h.format_version != kFormatVersion && h.format_version != kFormatVersionAccurate)
    throw std::runtime_error(where + " has archive format version " + std::to_string(h.format_version) + "; this fiberfem reads version " +
                             std::to_string(kFormatVersion) + " and " + std::to_string(kFormatVersionAccurate));
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
    if (h5::has_attribute(g.id(), "tier")) h.tier = h5::read_string_attribute(g.id(), "tier");
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
  if (h5::exists(h5::open_group(root, "frames").id(), "circulation")) {  // a run with a circulation
    d.circulation = open("frames/circulation");
    h.circulation_columns = names_attribute(d.circulation.id(), "columns");
  }
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
  read_element_mesh(root, h, N, where);
  const hsize_t M = h.order == 2 ? static_cast<hsize_t>(h.element_rest_positions.cols()) : N;  // nodes of a frame
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
  if (d.positions.dims().size() != 3 || d.positions.dims()[1] != M || d.positions.dims()[2] != 3)
    throw std::runtime_error(where + ": frames/positions does not match the mesh's " + std::to_string(M) + " nodes");
  for (const auto* ds : {&d.velocities, &d.displacement})
    if (*ds && (ds->dims().size() != 3 || ds->dims()[1] != M || ds->dims()[2] != 3))
      bad("frames/velocities or frames/displacement does not match the mesh's " + std::to_string(M) + " nodes");
  if (d.energies.dims().size() != 2 || d.energies.dims()[1] != 2) bad("frames/energies is not 2 numbers per frame");
  if (d.circulation && (d.circulation.dims().size() != 2 || d.circulation.dims()[1] != h.circulation_columns.size()))
    bad("frames/circulation does not have one number per name of its attribute columns");
  refresh();
}

long ArchiveReader::refresh() {
  Impl& d = *impl_;
  std::vector<h5::Dataset*> ds = {&d.time, &d.positions, &d.activation, &d.cavities, &d.probes, &d.energies, &d.iterations,
                                  &d.residual, &d.status, &d.substeps, &d.inverted, &d.step};
  if (d.velocities) ds.push_back(&d.velocities);
  if (d.displacement) ds.push_back(&d.displacement);
  if (d.circulation) ds.push_back(&d.circulation);
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
  const Eigen::Index N = header_.rest_positions.cols();  // the corner mesh: the first N of a frame's nodes
  Frame f;
  f.step = d.step.read_rows<std::int64_t>(k, 1)[0];
  f.time_s = d.time.read_rows<double>(k, 1)[0];
  const std::vector<float> x = d.positions.read_rows<float>(k, 1);
  f.positions = Eigen::Map<const Eigen::Matrix<float, 3, Eigen::Dynamic>>(x.data(), 3, N).cast<double>();
  if (header_.order == 2)
    f.element_positions = Eigen::Map<const Eigen::Matrix<float, 3, Eigen::Dynamic>>(x.data(), 3, static_cast<Eigen::Index>(x.size() / 3))
                              .cast<double>();
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
  if (d.circulation) f.circulation = core::circulation::from_columns(header_.circulation_columns, d.circulation.read_rows<double>(k, 1).data());
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

core::SimulatorCheckpoint ArchiveReader::read_checkpoint(size_t k, std::string* parameter_state) const {
  service::EngineCheckpoint c = read_engine_checkpoint(k, parameter_state);
  auto* rt = std::get_if<core::SimulatorCheckpoint>(&c);
  if (rt == nullptr)
    throw std::runtime_error("archive: checkpoint " + std::to_string(k) + " in '" + path_ + "' is of an accurate-tier run");
  return std::move(*rt);
}

service::EngineCheckpoint ArchiveReader::read_engine_checkpoint(size_t k, std::string* parameter_state) const {
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


}  // namespace fiberfem::archive
