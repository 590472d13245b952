// mesh (docs/scenes.md): a mesh file, or a generator (box, lv_ellipsoid) with its
// resolution scaled by mesh.refine (or the fidelity preset's).

#include "core/box_generator.hpp"
#include "core/lv_ellipsoid.hpp"
#include "io/input_file.hpp"
#include "io/mesh_io.hpp"
#include "io/scene_internal.hpp"

#include <algorithm>
#include <sstream>

namespace fiberfem::io::detail {

namespace {

// The largest generated mesh, cells (6 tetrahedra each for the box): beyond any mesh the
// engine steps in real time, and a bound on the memory a scene file can ask for.
constexpr double kMaxGeneratedCells = 2e6;

// A generator's cell count times the refinement factor, at least `lo`.
int refined(int cells, double refine, int lo) { return std::max(lo, static_cast<int>(std::lround(cells * refine))); }

// A gmsh file may hold 10-node tetrahedra: its corner mesh, and its elements (with their
// curved edge nodes) for mesh.order 2, which such a file implies.
core::TetMesh mesh_file(const CheckedMap& m, SceneFiles& files, MeshExtras& extras) {
  if (m.has("refine")) m.checks().fail(m["refine"], "mesh.refine", "goes with a generator (a mesh file has one resolution)");
  const std::string path = resolve(m.text("file"), files.base_dir);
  files.mesh_file = path;
  const double scale = m.has("scale") ? m.number("scale", 0, HUGE_VAL, true) : 1.0;
  try {
    const bool embedded = files.embedded && files.embedded->count(path);  // a built-in scene's mesh (gmsh only)
    const bool gmsh = embedded || (path.size() >= 4 && path.compare(path.size() - 4, 4, ".msh") == 0);
    if (!gmsh) return io::read_mesh(path, scale);  // TetGen and VTK files hold linear tetrahedra only
    OrderedMesh read = [&] {
      if (embedded) {
        std::istringstream in(files.embedded->at(path));
        return read_gmsh_any_order(in, path, scale);
      }
      return io::read_mesh_any_order(path, scale);
    }();
    if (read.elements.order() == 2) {
      extras.order = 2;
      extras.file_elements = std::make_shared<const core::hyperelastic::ElementMesh>(std::move(read.elements));
    }
    return std::move(read.corners);
  } catch (const std::invalid_argument& e) {
    m.checks().fail(m["file"], "mesh.file", e.what());
  }
}

// Each generator's own keys: the other generator refuses them by name.
constexpr const char* kLvEllipsoidKeys[] = {"inner", "outer", "base_z", "resolution", "apex_grading"};
constexpr const char* kBoxKeys[] = {"size", "cells", "origin"};

core::TetMesh lv_ellipsoid(const CheckedMap& m, double refine, MeshExtras& extras) {
  for (const char* k : kBoxKeys)
    if (m.has(k)) m.checks().fail(m[k], m.sub(k), "is a box key (lv_ellipsoid takes inner, outer, base_z, resolution, apex_grading)");
  core::LvEllipsoidSpec lv;
  auto radii = [&](const char* key, double& rs, double& rl) {
    if (!m.has(key)) return;
    const CheckedMap r(m.checks(), m[key], m.sub(key), {"rs", "rl"});
    if (r.has("rs")) rs = r.number("rs", 0, HUGE_VAL, true);
    if (r.has("rl")) rl = r.number("rl", 0, HUGE_VAL, true);
  };
  radii("inner", lv.endo_rs_m, lv.endo_rl_m);
  radii("outer", lv.epi_rs_m, lv.epi_rl_m);
  if (m.has("base_z")) lv.base_z_m = m.number("base_z");
  if (m.has("apex_grading")) lv.apex_grading = m.number("apex_grading", 1.0, 3.0);
  if (m.has("resolution")) {
    const CheckedMap r(m.checks(), m["resolution"], "mesh.resolution", {"circumferential", "longitudinal", "transmural"});
    if (r.has("circumferential")) lv.circumferential = r.integer("circumferential", 6, 100000);
    if (r.has("longitudinal")) lv.longitudinal = r.integer("longitudinal", 2, 100000);
    if (r.has("transmural")) lv.transmural = r.integer("transmural", 1, 100000);
  }
  lv.circumferential = refined(lv.circumferential, refine, 6);
  lv.longitudinal = refined(lv.longitudinal, refine, 2);
  lv.transmural = refined(lv.transmural, refine, 1);
  const double cells = 1.0 * lv.circumferential * lv.longitudinal * lv.transmural;
  if (cells > kMaxGeneratedCells)
    m.checks().fail(m.has("resolution") ? m["resolution"] : m.node(), "mesh.resolution",
                    "asks for " + std::to_string(static_cast<long long>(cells)) + " cells" +
                        (refine != 1 ? " (after mesh.refine)" : "") +
                        "; at most 2000000 (circumferential x longitudinal x transmural)");
  extras.lv_ellipsoid = lv;
  try {
    return core::make_lv_ellipsoid(lv);
  } catch (const std::invalid_argument& e) {
    m.fail(e.what());
  }
}

core::TetMesh box(const CheckedMap& m, double refine) {
  const Checks& checks = m.checks();
  for (const char* k : kLvEllipsoidKeys)
    if (m.has(k)) checks.fail(m[k], m.sub(k), "is an lv_ellipsoid key (box takes size, cells, origin)");
  core::BoxSpec spec;
  if (m.has("size")) spec.size_m = m.vec3("size");
  if (m.has("cells")) {
    const YAML::Node c = m["cells"];
    if (!c.IsSequence() || c.size() != 3) checks.fail(c, "mesh.cells", "expected three integers");
    for (int i = 0; i < 3; ++i)
      spec.cells[static_cast<size_t>(i)] = checks.integer(c[i], "mesh.cells[" + std::to_string(i) + "]", 1, 100000);
  }
  for (int& c : spec.cells) c = refined(c, refine, 1);
  if (const double total = 1.0 * spec.cells[0] * spec.cells[1] * spec.cells[2]; total > kMaxGeneratedCells)
    checks.fail(m.has("cells") ? m["cells"] : m.node(), "mesh.cells",
                "asks for " + std::to_string(static_cast<long long>(total)) + " cells" +
                    (refine != 1 ? " (after mesh.refine)" : "") + "; at most 2000000 (12 million elements)");
  if (m.has("origin")) spec.origin_m = m.vec3("origin");
  if ((spec.size_m.array() <= 0).any()) checks.fail(m["size"], "mesh.size", "every edge length must be > 0 m");
  try {
    return core::make_box(spec);
  } catch (const std::invalid_argument& e) {  // e.g. cells so flat that an element is degenerate
    const std::string what = e.what();
    m.fail(what.rfind("mesh: ", 0) == 0 ? what.substr(6) : what);
  }
}

}  // namespace

std::string resolve(const std::string& path, const std::string& base_dir) {
  return !path.empty() && path[0] != '/' && !base_dir.empty() ? base_dir + "/" + path : path;
}

core::TetMesh read_scene_mesh(const CheckedMap& top, SceneFiles& files, double refine, MeshExtras& extras) {
  if (!top.has("mesh")) top.checks().fail(top.node(), "mesh", "missing (a generator or a file)");
  const CheckedMap m(top.checks(), top["mesh"], "mesh",
                     {"generator", "size", "cells", "origin", "file", "scale", "inner", "outer", "base_z", "resolution", "apex_grading", "refine", "order"});
  if (m.has("file") == m.has("generator")) m.fail("give exactly one of generator, file");
  if (m.has("file")) {
    core::TetMesh corners = mesh_file(m, files, extras);
    if (m.has("order")) extras.order = m.integer("order", 1, 2);
    return corners;
  }
  if (m.has("order")) extras.order = m.integer("order", 1, 2);
  if (m.has("refine")) refine = m.number("refine", 0.05, 20);
  if (m.has("scale")) m.checks().fail(m["scale"], "mesh.scale", "goes with mesh.file");
  const std::string gen = m.text("generator");
  if (gen == "lv_ellipsoid") return lv_ellipsoid(m, refine, extras);
  if (gen != "box")
    m.checks().fail(m["generator"], "mesh.generator", "'" + printable(gen) + "' is not available (available: box, lv_ellipsoid)");
  return box(m, refine);
}

}  // namespace fiberfem::io::detail
