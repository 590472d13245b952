#include "service/batch_report.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <stdexcept>

namespace fiberfem::service::detail {

json vec_json(const core::Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

json energies_json(const core::Energies& e) {
  return {{"kinetic_j", e.kinetic_j}, {"elastic_j", e.elastic_j}, {"gravity_j", e.gravity_j}};
}

json report_head(const io::Scene& sc, const BatchOptions& o, const core::MeshQuality& quality, bool is_static) {
  const core::TetMesh& mesh = sc.model.mesh;
  json report;
  report["format"] = "fiberfem-run-report";
  report["version"] = 1;
  report["scene"] = {{"name", sc.name},
                     {"source", o.source},
                     {"sha256", sc.hash_sha256},
                     {"overrides", o.overrides},
                     {"mesh_file", sc.mesh_file},
                     {"nodes", mesh.num_nodes()},
                     {"elements", mesh.num_elements()},
                     {"regions", mesh.num_regions()},
                     {"min_dihedral_deg", quality.min_dihedral_deg},
                     {"max_dihedral_deg", quality.max_dihedral_deg},
                     {"min_radius_ratio", quality.min_radius_ratio}};
  report["mode"] = is_static ? "static" : "dynamic";
  return report;
}

json probes_json(const io::Scene& sc, const core::Positions& x) {
  json out = json::array();
  for (const io::Probe& p : sc.probes) {
    const core::Vec3 u = p.displacement(sc.model.mesh, x);
    out.push_back({{"name", p.name}, {"rest_m", vec_json(p.point_m)}, {"final_m", vec_json(p.point_m + u)},
                   {"displacement_m", vec_json(u)}, {"element", p.element}});
  }
  return out;
}

void print_probes(std::ostream& out, const io::Scene& sc, const core::Positions& x) {
  char line[256];
  for (const io::Probe& p : sc.probes) {
    const core::Vec3 u = p.displacement(sc.model.mesh, x);
    std::snprintf(line, sizeof line, "probe %s: displacement [%+.6e, %+.6e, %+.6e] m (|u| %.6e m)\n", p.name.c_str(), u.x(),
                  u.y(), u.z(), u.norm());
    out << line;
  }
}

core::Energies energies_at_rest(const io::Scene& sc, const core::Positions& x) {
  core::Simulator sim(sc.model, sc.settings);
  sim.set_state(x, core::Positions::Zero(3, x.cols()));
  return sim.energies();
}

void write_report(const std::string& path, const json& report) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error("--report " + path + ": cannot write " + tmp);
    f << report.dump(2) << "\n";
    if (!f) throw std::runtime_error("--report " + path + ": write failed");
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace fiberfem::service::detail
