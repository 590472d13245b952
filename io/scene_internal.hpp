#pragma once
/// @file The scene parser's sections that no command changes (mesh, regions, boundary
/// conditions and loads, probes, cavities, archive, --set overrides), one file each
/// (io/scene_*.cpp), as io/scene.cpp's parse_scene calls them. Internal to io.

#include "core/hyperelastic/element_mesh.hpp"
#include "core/lv_ellipsoid.hpp"

#include <memory>
#include "io/scene.hpp"
#include "io/scene_sections.hpp"

#include <optional>
#include <string>
#include <vector>

namespace fiberfem::io::detail {

/// The scene text as a YAML tree. @throws SceneError "<origin>:<line>: not valid <kind>: ...".
YAML::Node load_document(const std::string& yaml_text, const std::string& origin, const std::string& kind = "YAML");

/// Applies "a.b[2].c=value" to the tree. @throws SceneError naming the override.
void apply_override(YAML::Node root, const std::string& assignment);

/// A fidelity preset (scene key `fidelity`): step, mesh refinement and PCG tolerance,
/// under the scene's explicit keys.
struct Fidelity {
  std::string name;
  double dt_s;          // solver.dt
  double refine;        // mesh.refine: factor on a generator's resolution
  double tolerance;     // solver.tolerance
  bool cost_refresh;    // core::with_cost_refresh (no scene key)
};
std::optional<Fidelity> read_fidelity(const CheckedMap& top);

/// Where the scene's files are read from, and which were read (for the hash).
struct SceneFiles {
  std::string base_dir;                 // relative paths are looked up here
  const EmbeddedFiles* embedded;        // files held in memory, by resolved path
  std::string mesh_file;                // the mesh file read, or ""
  std::vector<std::string> others;      // fiber and stroke files read
};
/// `path` relative to `base_dir` (absolute paths and an empty base_dir: as given).
std::string resolve(const std::string& path, const std::string& base_dir);

/// [[x0, y0, z0], [x1, y1, z1]]: a box's corners, the second not below the first.
std::pair<core::Vec3, core::Vec3> read_box(const Checks& checks, const YAML::Node& node, const std::string& path);

/// [x, y, z] in flow style (how a writer puts a vector).
YAML::Node flow_vec3(const core::Vec3& v);

/// What the mesh section says beyond the corner mesh: the element order (mesh.order) and,
/// for the lv_ellipsoid generator, its surfaces (where quadratic edge nodes are placed).
struct MeshExtras {
  int order = 1;
  std::optional<core::LvEllipsoidSpec> lv_ellipsoid;
  /// A mesh file's 10-node elements (a gmsh file of order 2), with its curved edge nodes.
  std::shared_ptr<const core::hyperelastic::ElementMesh> file_elements;
};
/// mesh: a generator (refined by `refine`) or a file.
core::TetMesh read_scene_mesh(const CheckedMap& top, SceneFiles& files, double refine, MeshExtras& extras);

/// regions: the region of every element (first match wins), the names and parameters.
struct Regions {
  std::vector<int> region_of;                 // by element
  std::vector<std::string> names;             // by region id
  std::vector<core::Material> materials;      // by region id
  std::vector<RegionParameters> parameters;   // by region id
};
Regions read_regions(const CheckedMap& top, const core::TetMesh& mesh);

/// fixed: node selectors with optional components, into the model's fixed dofs.
void read_fixed(const CheckedMap& top, core::Model& model);
/// loads: gravity (also into `gravity`), tractions and point forces.
void read_loads(const CheckedMap& top, core::Model& model, std::optional<core::Vec3>& gravity);
/// probes: named points located in their elements.
std::vector<Probe> read_probes(const CheckedMap& top, const core::TetMesh& mesh);
/// measure.cavities.
std::vector<CavityMeasure> read_cavities(const CheckedMap& top, const core::TetMesh& mesh);
/// circulation: the lumped loop coupled to the measured `cavities` it names (into
/// model.circulation; needs model.fixed_dofs and model.contraction read). `accurate`: the
/// scene runs on the accurate tier (its default volume tolerance).
void read_circulation(const CheckedMap& top, const std::vector<CavityMeasure>& cavities, bool accurate, core::Model& model);
/// circulation.volume_tolerance's default on the accurate tier.
inline constexpr double kAccurateVolumeTolerance = 1e-6;
/// archive.
ArchiveSettings read_archive(const Checks& checks, const YAML::Node& node);

}  // namespace fiberfem::io::detail
