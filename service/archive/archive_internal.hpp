#pragma once
/// @file What the archive's parts share (writer, reader, checkpoint codec, sidecars):
/// checkpoint blobs and sections, small HDF5 helpers, and the sidecar and codec entry
/// points. Internal to fiberfem::archive.

#include "core/circulation/circulation.hpp"
#include "service/archive/archive.hpp"
#include "service/archive/hdf5.hpp"

#include <Eigen/SparseCore>
#include <nlohmann/json.hpp>

#include <ctime>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::archive::detail {

using nlohmann::json;


inline std::string utc_now() {
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

inline void add_quaternions(Blob& b, const std::string& name, const std::vector<Eigen::Quaterniond>& q) {
  std::vector<double> v;
  v.reserve(4 * q.size());
  for (const auto& x : q) v.insert(v.end(), x.coeffs().data(), x.coeffs().data() + 4);  // x y z w
  b.add(name, v.data(), v.size());
}
inline void add_matrices(Blob& b, const std::string& name, const std::vector<core::Mat3>& m) {
  std::vector<double> v;
  v.reserve(9 * m.size());
  for (const auto& x : m) v.insert(v.end(), x.data(), x.data() + 9);  // column-major
  b.add(name, v.data(), v.size());
}

// A sparse matrix (compressed columns) as three sections: NAME.outer (cols + 1),
// NAME.inner (nonzeros) and NAME.values; the indices are whole numbers held exactly in
// doubles. A 0 x 0 matrix (none) has an empty outer.
inline void add_sparse(Blob& b, const std::string& name, Eigen::SparseMatrix<double, Eigen::ColMajor, int> m) {
  m.makeCompressed();
  std::vector<double> outer, inner;
  if (m.rows() > 0) {
    outer.assign(m.outerIndexPtr(), m.outerIndexPtr() + m.cols() + 1);
    inner.assign(m.innerIndexPtr(), m.innerIndexPtr() + m.nonZeros());
  }
  b.add(name + ".outer", outer.data(), outer.size());
  b.add(name + ".inner", inner.data(), inner.size());
  b.add(name + ".values", m.valuePtr(), m.rows() > 0 ? static_cast<size_t>(m.nonZeros()) : 0);
}

struct Section {
  const double* p = nullptr;
  size_t n = 0;
};
inline Section section(const json& header, const std::vector<double>& data, const std::string& name) {
  for (const auto& s : header.at("layout"))
    if (s.at("name") == name) {
      const std::int64_t off = s.at("offset"), n = s.at("count");
      if (off < 0 || n < 0 || static_cast<size_t>(off) > data.size() || static_cast<size_t>(n) > data.size() - static_cast<size_t>(off)) throw std::runtime_error("archive: checkpoint section '" + name + "' runs past its data");
      return {data.data() + off, static_cast<size_t>(n)};
    }
  throw std::runtime_error("archive: checkpoint has no section '" + name + "'");
}
inline Eigen::VectorXd vector_of(const Section& s) { return Eigen::Map<const Eigen::VectorXd>(s.p, static_cast<Eigen::Index>(s.n)); }
inline std::vector<Eigen::Quaterniond> quaternions_of(const Section& s) {
  std::vector<Eigen::Quaterniond> q(s.n / 4);
  for (size_t i = 0; i < q.size(); ++i) q[i].coeffs() = Eigen::Map<const Eigen::Vector4d>(s.p + 4 * i);
  return q;
}
inline std::vector<core::Mat3> matrices_of(const Section& s) {
  std::vector<core::Mat3> m(s.n / 9);
  for (size_t i = 0; i < m.size(); ++i) m[i] = Eigen::Map<const core::Mat3>(s.p + 9 * i);
  return m;
}

// The lumped circulation's state as one section of 15 numbers: time, the 4 chamber
// volumes, the 4 compartment pressures, the 4 flows, the 2 external (ventricle) pressures.
inline constexpr size_t kCirculationStateNumbers = 15;
inline std::vector<double> circulation_numbers(const core::circulation::State& s) {
  std::vector<double> v{s.time_s};
  v.insert(v.end(), s.volume_m3.begin(), s.volume_m3.end());
  v.insert(v.end(), s.pressure_pa.begin(), s.pressure_pa.end());
  v.insert(v.end(), s.flow_m3_s.begin(), s.flow_m3_s.end());
  v.insert(v.end(), s.external_pa.begin(), s.external_pa.end());
  return v;
}
inline core::circulation::State circulation_state_of(const Section& sec) {
  if (sec.n != kCirculationStateNumbers) throw std::runtime_error("archive: checkpoint section 'circulation.state' has the wrong size");
  core::circulation::State s;
  const double* p = sec.p;
  s.time_s = *p++;
  for (double& x : s.volume_m3) x = *p++;
  for (double& x : s.pressure_pa) x = *p++;
  for (double& x : s.flow_m3_s) x = *p++;
  for (double& x : s.external_pa) x = *p++;
  return s;
}

inline std::string join_json(const std::vector<std::string>& names) { return json(names).dump(); }

inline std::vector<std::string> names_attribute(hid_t obj, const std::string& name) {
  if (!h5::has_attribute(obj, name)) return {};
  return json::parse(h5::read_string_attribute(obj, name)).get<std::vector<std::string>>();
}


/// Writes `text` to `path` through a temporary file and a rename (readers never see half).
void write_atomically(const std::string& path, const std::string& text);
/// The XDMF sidecar's path for an archive (RUN.h5 -> RUN.xdmf).
std::string sidecar_path(const std::string& h5_path);
/// The XDMF sidecar's text for F frames of N nodes and E elements (of 10 nodes when order2).
std::string xdmf_text(const std::string& h5_path, long F, const std::vector<double>& times, hsize_t N, hsize_t E, bool velocities,
                      bool displacement, bool order2);
/// The checkpoint in a header (JSON) and its data, of either tier. @throws json::exception
/// or std::runtime_error when malformed.
service::EngineCheckpoint checkpoint_of(const json& h, const std::vector<double>& data, std::string* parameter_state);

}  // namespace fiberfem::archive::detail
