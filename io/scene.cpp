#include "io/scene.hpp"


#include "core/box_generator.hpp"
#include "core/lv_ellipsoid.hpp"
#include "core/fiber_fields.hpp"
#include "io/fiber_file.hpp"
#include "io/input_file.hpp"
#include "io/mesh_io.hpp"
#include "io/sha256.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

namespace fiberfem::io {
namespace {

using core::Vec3;

// Error helpers: every message is "<origin>:<line>: <key path>: <what>".
struct Ctx {
  std::string origin;
  std::vector<std::string> overridden;  // key paths set by --set (they have no file line)
  const EmbeddedFiles* embedded = nullptr;  // files held in memory, by resolved path
  mutable std::vector<std::string> warnings;  // Scene::warnings
  void warn(const YAML::Node& at, const std::string& path, const std::string& what) const {
    const int line = at.IsDefined() && at.Mark().line >= 0 ? at.Mark().line + 1 : 0;
    warnings.push_back(origin + ":" + std::to_string(line) + ": " + path + ": " + what);
  }
  [[noreturn]] void fail(const YAML::Node& at, const std::string& path, const std::string& what) const {
    for (const std::string& o : overridden)
      if (path.compare(0, o.size(), o) == 0 && (path.size() == o.size() || path[o.size()] == '.' || path[o.size()] == '['))
        throw SceneError(origin + ": --set " + printable(path, 200) + ": " + what);
    const int line = at.IsDefined() && at.Mark().line >= 0 ? at.Mark().line + 1 : 0;
    throw SceneError(origin + ":" + std::to_string(line) + ": " + (path.empty() ? "" : printable(path, 200) + ": ") + what);
  }
};

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// A mapping whose keys are checked: reading marks a key used, finish() refuses the rest.
class Map {
 public:
  Map(const Ctx& ctx, const YAML::Node& node, std::string path, std::vector<std::string> allowed)
      : ctx_(ctx), node_(node), path_(std::move(path)), allowed_(std::move(allowed)) {
    if (!node.IsMap()) ctx_.fail(node, path_, "expected a mapping with keys " + join(allowed_));
    for (const auto& kv : node) {
      // A YAML complex key (`? ...`: a mapping or list as key) is no key name.
      if (!kv.first.IsScalar()) ctx_.fail(kv.first, path_, "a key must be a plain name, not a mapping or a list");
      const std::string key = kv.first.as<std::string>();
      if (std::find(allowed_.begin(), allowed_.end(), key) == allowed_.end())
        ctx_.fail(kv.first, sub(key), "unknown key (allowed here: " + join(allowed_) + ")");
    }
  }
  bool has(const std::string& key) const { return node_[key].IsDefined() && !node_[key].IsNull(); }
  YAML::Node operator[](const std::string& key) const { return node_[key]; }
  std::string sub(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  const YAML::Node& node() const { return node_; }

 private:
  const Ctx& ctx_;
  YAML::Node node_;
  std::string path_;
  std::vector<std::string> allowed_;
};

double number(const Ctx& ctx, const YAML::Node& n, const std::string& path, double lo = -HUGE_VAL,
              double hi = HUGE_VAL, bool open_lo = false) {
  double v = 0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "");
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    ctx.fail(n, path, "expected a number");
  }
  if (!std::isfinite(v)) ctx.fail(n, path, "must be finite");
  if (v < lo || (open_lo && v == lo) || v > hi) {
    std::ostringstream s;
    s << "must be in " << (open_lo ? "(" : "[") << lo << ", " << hi << "], got " << v;
    ctx.fail(n, path, s.str());
  }
  return v;
}

int integer(const Ctx& ctx, const YAML::Node& n, const std::string& path, int lo, int hi) {
  int v = 0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "");
    v = n.as<int>();
  } catch (const YAML::Exception&) {
    ctx.fail(n, path, "expected an integer");
  }
  if (v < lo || v > hi)
    ctx.fail(n, path, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + std::to_string(v));
  return v;
}

std::string text(const Ctx& ctx, const YAML::Node& n, const std::string& path) {
  if (!n.IsScalar()) ctx.fail(n, path, "expected a string");
  return n.as<std::string>();
}

std::string choice(const Ctx& ctx, const YAML::Node& n, const std::string& path, const std::vector<std::string>& options) {
  const std::string v = text(ctx, n, path);
  if (std::find(options.begin(), options.end(), v) == options.end())
    ctx.fail(n, path, "'" + printable(v) + "' is not one of " + join(options));
  return v;
}

Vec3 vec3(const Ctx& ctx, const YAML::Node& n, const std::string& path) {
  if (!n.IsSequence() || n.size() != 3) ctx.fail(n, path, "expected a list of three numbers");
  return {number(ctx, n[0], path + "[0]"), number(ctx, n[1], path + "[1]"), number(ctx, n[2], path + "[2]")};
}

std::pair<Vec3, Vec3> box(const Ctx& ctx, const YAML::Node& n, const std::string& path) {
  if (!n.IsSequence() || n.size() != 2) ctx.fail(n, path, "expected [[x0, y0, z0], [x1, y1, z1]]");
  const Vec3 a = vec3(ctx, n[0], path + "[0]"), b = vec3(ctx, n[1], path + "[1]");
  if ((b.array() < a.array()).any()) ctx.fail(n, path, "the second corner must not be below the first");
  return {a, b};
}

// A node selector: plane, box or a named node set. Returns the matching nodes (sorted).
std::vector<int> select_nodes(const Ctx& ctx, const YAML::Node& n, const std::string& path, const core::TetMesh& mesh,
                              const std::vector<std::string>& also_allowed = {}) {
  std::vector<std::string> allowed{"plane", "box", "node_set"};
  allowed.insert(allowed.end(), also_allowed.begin(), also_allowed.end());
  Map m(ctx, n, path, allowed);
  std::vector<int> nodes;
  const auto& X = mesh.rest_positions();
  int kinds = 0;
  if (m.has("plane")) {
    ++kinds;
    Map p(ctx, m["plane"], m.sub("plane"), {"axis", "value", "tol"});
    if (!p.has("axis") || !p.has("value")) ctx.fail(m["plane"], m.sub("plane"), "needs axis and value");
    const std::string axis = choice(ctx, p["axis"], p.sub("axis"), {"x", "y", "z"});
    const int a = axis[0] - 'x';
    const double value = number(ctx, p["value"], p.sub("value"));
    const double tol = p.has("tol") ? number(ctx, p["tol"], p.sub("tol"), 0, HUGE_VAL) : 1e-9;
    for (int i = 0; i < mesh.num_nodes(); ++i)
      if (std::abs(X(a, i) - value) <= tol) nodes.push_back(i);
  }
  if (m.has("box")) {
    ++kinds;
    const auto [lo, hi] = box(ctx, m["box"], m.sub("box"));
    for (int i = 0; i < mesh.num_nodes(); ++i)
      if ((X.col(i).array() >= lo.array()).all() && (X.col(i).array() <= hi.array()).all()) nodes.push_back(i);
  }
  if (m.has("node_set")) {
    ++kinds;
    const std::string name = text(ctx, m["node_set"], m.sub("node_set"));
    const auto& sets = mesh.node_sets();
    const auto it = sets.find(name);
    if (it == sets.end()) {
      std::vector<std::string> names;
      for (const auto& kv : sets) names.push_back(kv.first);
      ctx.fail(m["node_set"], m.sub("node_set"), "no node set '" + printable(name) + "' (the mesh has: " + join(names) + ")");
    }
    nodes = it->second;
  }
  if (kinds != 1) ctx.fail(n, path, "give exactly one of plane, box, node_set");
  if (nodes.empty()) ctx.fail(n, path, "matches no node");
  return nodes;
}

// Beyond this E_L / E_T the stability map (docs/speed-accuracy.md) found a loaded tissue
// beam that gained energy and did not return to rest (10,000); up to 1,000 it was stable.
constexpr double kMaxStableFiberRatio = 1000.0;

// The fidelity presets (scene key `fidelity`, docs/scenes.md), chosen from the measured
// Pareto fronts of docs/speed-accuracy.md. Explicit keys of the scene override them.
struct Fidelity {
  double dt_s;             // solver.dt
  double refine;           // mesh.refine: factor on a generator's resolution
  double tolerance;        // solver.tolerance
  bool cost_refresh;       // core::with_cost_refresh (no scene key)
};
const std::map<std::string, Fidelity>& fidelity_presets() {
  static const std::map<std::string, Fidelity> p{
      {"interactive", {1.0 / 30.0, 0.5, 1e-3, true}},
      {"balanced", {1.0 / 60.0, 1.0, 1e-6, false}},
      {"accurate", {1.0 / 120.0, 1.5, 1e-6, false}},
  };
  return p;
}

core::Material material(const Ctx& ctx, const YAML::Node& n, const std::string& path) {
  Map m(ctx, n, path,
        {"E_L", "E_T", "nu_LT", "nu_T", "G_L", "lame", "fiber_factor", "shear_factor", "C", "E", "nu", "density"});
  if (!m.has("density")) ctx.fail(n, path, "needs density (kg/m^3)");
  const double rho = number(ctx, m["density"], m.sub("density"), 0, HUGE_VAL, true);
  const bool eng = m.has("E_L") || m.has("E_T") || m.has("nu_LT") || m.has("nu_T") || m.has("G_L");
  const bool lame = m.has("lame") || m.has("fiber_factor") || m.has("shear_factor");
  const bool stiff = m.has("C");
  const bool iso = m.has("E") || m.has("nu");
  if (eng + lame + stiff + iso != 1)
    ctx.fail(n, path, "give exactly one form: E_L/E_T/nu_LT/nu_T/G_L, lame (+ fiber_factor, shear_factor), C, or E/nu");
  try {
    if (eng) {
      core::EngineeringConstants c;
      for (const char* k : {"E_L", "E_T", "nu_LT", "nu_T", "G_L"})
        if (!m.has(k)) ctx.fail(n, path, std::string("the engineering form needs ") + k);
      c.E_L = number(ctx, m["E_L"], m.sub("E_L"));
      c.E_T = number(ctx, m["E_T"], m.sub("E_T"));
      c.nu_LT = number(ctx, m["nu_LT"], m.sub("nu_LT"));
      c.nu_T = number(ctx, m["nu_T"], m.sub("nu_T"));
      c.G_L = number(ctx, m["G_L"], m.sub("G_L"));
      if (c.E_T > 0 && c.E_L / c.E_T > kMaxStableFiberRatio)
        ctx.warn(m["E_T"], m.sub("E_T"),
                 "fiber/cross-fiber ratio E_L/E_T = " + std::to_string(c.E_L / c.E_T) +
                     " is above 1000, beyond the measured stability map: a loaded soft body may gain energy "
                     "and not return to rest (docs/speed-accuracy.md)");
      return core::Material::from_engineering(c, rho);
    }
    if (lame) {
      if (!m.has("lame")) ctx.fail(n, path, "fiber_factor and shear_factor go with lame: [lambda, mu]");
      const YAML::Node l = m["lame"];
      if (!l.IsSequence() || l.size() != 2) ctx.fail(l, m.sub("lame"), "expected [lambda, mu] in Pa");
      core::LameFiberConstants c;
      c.lambda = number(ctx, l[0], m.sub("lame") + "[0]");
      c.mu = number(ctx, l[1], m.sub("lame") + "[1]");
      if (m.has("fiber_factor")) c.fiber_factor = number(ctx, m["fiber_factor"], m.sub("fiber_factor"));
      if (m.has("shear_factor")) c.shear_factor = number(ctx, m["shear_factor"], m.sub("shear_factor"));
      return core::Material::from_lame(c, rho);
    }
    if (stiff) {
      Map C(ctx, m["C"], m.sub("C"), {"C11", "C12", "C13", "C33", "C55"});
      core::StiffnessConstants c;
      for (const char* k : {"C11", "C12", "C13", "C33", "C55"})
        if (!C.has(k)) ctx.fail(m["C"], m.sub("C"), std::string("needs ") + k);
      c.C11 = number(ctx, C["C11"], C.sub("C11"));
      c.C12 = number(ctx, C["C12"], C.sub("C12"));
      c.C13 = number(ctx, C["C13"], C.sub("C13"));
      c.C33 = number(ctx, C["C33"], C.sub("C33"));
      c.C55 = number(ctx, C["C55"], C.sub("C55"));
      return core::Material::from_stiffness(c, rho);
    }
    if (!m.has("E") || !m.has("nu")) ctx.fail(n, path, "the isotropic form needs E and nu");
    return core::Material::isotropic(number(ctx, m["E"], m.sub("E")), number(ctx, m["nu"], m.sub("nu")), rho);
  } catch (const SceneError&) {
    throw;
  } catch (const std::invalid_argument& e) {
    ctx.fail(n, path, e.what());
  }
}

// Barycentric weights of p in element e (sum to one).
Eigen::Vector4d barycentric(const core::TetMesh& mesh, int e, const Vec3& p) {
  const core::Tet& t = mesh.tets()[static_cast<size_t>(e)];
  const auto& X = mesh.rest_positions();
  core::Mat3 D;
  for (int j = 0; j < 3; ++j) D.col(j) = X.col(t[static_cast<size_t>(j + 1)]) - X.col(t[0]);
  const Vec3 l = D.inverse() * (p - X.col(t[0]));
  return {1 - l.sum(), l.x(), l.y(), l.z()};
}

// The largest generated mesh, cells (6 tetrahedra each for the box): beyond any mesh the
// engine steps in real time, and a bound on the memory a scene file can ask for.
constexpr double kMaxGeneratedCells = 2e6;

// A generator's cell count times the refinement factor, at least `lo`.
int refined(int cells, double refine, int lo) { return std::max(lo, static_cast<int>(std::lround(cells * refine))); }

core::TetMesh build_mesh(const Ctx& ctx, const Map& top, const std::string& base_dir, std::string& mesh_file,
                         double preset_refine) {
  if (!top.has("mesh")) ctx.fail(top.node(), "mesh", "missing (a generator or a file)");
  Map m(ctx, top["mesh"], "mesh",
        {"generator", "size", "cells", "origin", "file", "scale", "inner", "outer", "base_z", "resolution", "refine"});
  if (m.has("file") == m.has("generator")) ctx.fail(top["mesh"], "mesh", "give exactly one of generator, file");
  if (m.has("refine") && m.has("file")) ctx.fail(m["refine"], "mesh.refine", "goes with a generator (a mesh file has one resolution)");
  const double refine = m.has("refine") ? number(ctx, m["refine"], "mesh.refine", 0.05, 20) : preset_refine;
  if (m.has("file")) {
    std::string path = text(ctx, m["file"], "mesh.file");
    if (!path.empty() && path[0] != '/' && !base_dir.empty()) path = base_dir + "/" + path;
    mesh_file = path;
    const double scale = m.has("scale") ? number(ctx, m["scale"], "mesh.scale", 0, HUGE_VAL, true) : 1.0;
    try {
      if (ctx.embedded && ctx.embedded->count(path)) {  // a built-in scene's mesh (gmsh only)
        std::istringstream in(ctx.embedded->at(path));
        return read_gmsh(in, path, scale);
      }
      return read_mesh(path, scale);
    } catch (const std::invalid_argument& e) {
      ctx.fail(m["file"], "mesh.file", e.what());
    }
  }
  if (m.has("scale")) ctx.fail(m["scale"], "mesh.scale", "goes with mesh.file");
  const std::string gen = text(ctx, m["generator"], "mesh.generator");
  if (gen == "lv_ellipsoid") {
    for (const char* k : {"size", "cells", "origin"})
      if (m.has(k)) ctx.fail(m[k], m.sub(k), "is a box key (lv_ellipsoid takes inner, outer, base_z, resolution)");
    core::LvEllipsoidSpec lv;
    auto radii = [&](const char* key, double& rs, double& rl) {
      if (!m.has(key)) return;
      Map r(ctx, m[key], m.sub(key), {"rs", "rl"});
      if (r.has("rs")) rs = number(ctx, r["rs"], r.sub("rs"), 0, HUGE_VAL, true);
      if (r.has("rl")) rl = number(ctx, r["rl"], r.sub("rl"), 0, HUGE_VAL, true);
    };
    radii("inner", lv.endo_rs_m, lv.endo_rl_m);
    radii("outer", lv.epi_rs_m, lv.epi_rl_m);
    if (m.has("base_z")) lv.base_z_m = number(ctx, m["base_z"], "mesh.base_z");
    if (m.has("resolution")) {
      Map r(ctx, m["resolution"], "mesh.resolution", {"circumferential", "longitudinal", "transmural"});
      if (r.has("circumferential")) lv.circumferential = integer(ctx, r["circumferential"], r.sub("circumferential"), 6, 100000);
      if (r.has("longitudinal")) lv.longitudinal = integer(ctx, r["longitudinal"], r.sub("longitudinal"), 2, 100000);
      if (r.has("transmural")) lv.transmural = integer(ctx, r["transmural"], r.sub("transmural"), 1, 100000);
    }
    lv.circumferential = refined(lv.circumferential, refine, 6);
    lv.longitudinal = refined(lv.longitudinal, refine, 2);
    lv.transmural = refined(lv.transmural, refine, 1);
    const double cells = 1.0 * lv.circumferential * lv.longitudinal * lv.transmural;
    if (cells > kMaxGeneratedCells)
      ctx.fail(m.has("resolution") ? m["resolution"] : m.node(), "mesh.resolution",
               "asks for " + std::to_string(static_cast<long long>(cells)) + " cells" +
                   (refine != 1 ? " (after mesh.refine)" : "") + "; at most 2000000 (circumferential x longitudinal x transmural)");
    try {
      return core::make_lv_ellipsoid(lv);
    } catch (const std::invalid_argument& e) {
      ctx.fail(top["mesh"], "mesh", e.what());
    }
  }
  if (gen != "box")
    ctx.fail(m["generator"], "mesh.generator", "'" + printable(gen) + "' is not available (available: box, lv_ellipsoid)");
  for (const char* k : {"inner", "outer", "base_z", "resolution"})
    if (m.has(k)) ctx.fail(m[k], m.sub(k), "is an lv_ellipsoid key (box takes size, cells, origin)");
  core::BoxSpec spec;
  if (m.has("size")) spec.size_m = vec3(ctx, m["size"], "mesh.size");
  if (m.has("cells")) {
    const YAML::Node c = m["cells"];
    if (!c.IsSequence() || c.size() != 3) ctx.fail(c, "mesh.cells", "expected three integers");
    for (int i = 0; i < 3; ++i) spec.cells[static_cast<size_t>(i)] = integer(ctx, c[i], "mesh.cells[" + std::to_string(i) + "]", 1, 100000);
  }
  for (int& c : spec.cells) c = refined(c, refine, 1);
  if (const double total = 1.0 * spec.cells[0] * spec.cells[1] * spec.cells[2]; total > kMaxGeneratedCells)
    ctx.fail(m.has("cells") ? m["cells"] : m.node(), "mesh.cells",
             "asks for " + std::to_string(static_cast<long long>(total)) + " cells" +
                 (refine != 1 ? " (after mesh.refine)" : "") + "; at most 2000000 (12 million elements)");
  if (m.has("origin")) spec.origin_m = vec3(ctx, m["origin"], "mesh.origin");
  if ((spec.size_m.array() <= 0).any()) ctx.fail(m["size"], "mesh.size", "every edge length must be > 0 m");
  try {
    return core::make_box(spec);
  } catch (const std::invalid_argument& e) {  // e.g. cells so flat that an element is degenerate
    const std::string what = e.what();
    ctx.fail(top["mesh"], "mesh", what.rfind("mesh: ", 0) == 0 ? what.substr(6) : what);
  }
}

// Applies "a.b[2].c=value" to the tree (YAML::Node handles are references into it).
void apply_override(YAML::Node root, const std::string& assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw SceneError("--set " + assignment + ": expected key.path=value");
  const std::string path = assignment.substr(0, eq);
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(eq + 1));
  } catch (const YAML::Exception& e) {
    throw SceneError("--set " + assignment + ": the value is not valid YAML: " + e.msg);
  }
  // Split into keys and [index] parts.
  std::vector<std::pair<std::string, long>> parts;  // key or (empty, index)
  size_t i = 0;
  while (i < path.size()) {
    if (path[i] == '.') {
      ++i;
      continue;
    }
    if (path[i] == '[') {
      const size_t close = path.find(']', i);
      if (close == std::string::npos) throw SceneError("--set " + assignment + ": unclosed [");
      try {
        parts.emplace_back("", std::stol(path.substr(i + 1, close - i - 1)));
      } catch (const std::exception&) {
        throw SceneError("--set " + assignment + ": bad list index");
      }
      i = close + 1;
      continue;
    }
    const size_t end = path.find_first_of(".[", i);
    parts.emplace_back(path.substr(i, end == std::string::npos ? std::string::npos : end - i), -1);
    i = end == std::string::npos ? path.size() : end;
  }
  if (parts.empty()) throw SceneError("--set " + assignment + ": empty key path");
  YAML::Node node = root;
  for (size_t k = 0; k < parts.size(); ++k) {
    const bool last = k + 1 == parts.size();
    if (parts[k].first.empty()) {
      const long idx = parts[k].second;
      if (!node.IsSequence() || idx < 0 || idx >= static_cast<long>(node.size()))
        throw SceneError("--set " + assignment + ": no list element [" + std::to_string(idx) + "] there");
      if (last) {
        node[static_cast<size_t>(idx)] = value;
        return;
      }
      node.reset(node[static_cast<size_t>(idx)]);
    } else {
      if (!node.IsMap() && !node.IsNull())
        throw SceneError("--set " + assignment + ": '" + parts[k].first + "' is not under a mapping");
      if (last) {
        node[parts[k].first] = value;
        return;
      }
      YAML::Node child = node[parts[k].first];
      if (!child.IsDefined() || child.IsNull()) {  // a missing mapping on the way is created
        node[parts[k].first] = YAML::Node(YAML::NodeType::Map);
        child = node[parts[k].first];
      }
      node.reset(child);
    }
  }
}

// Nodes selected by `key` (a node selector) or the named node set `fallback`.
std::vector<int> nodes_or_set(const Ctx& ctx, const Map& m, const std::string& key, const std::string& fallback,
                              const core::TetMesh& mesh) {
  if (m.has(key)) return select_nodes(ctx, m[key], m.sub(key), mesh);
  const auto it = mesh.node_sets().find(fallback);
  if (it == mesh.node_sets().end())
    ctx.fail(m.node(), m.sub(key), "missing, and the mesh has no node set '" + fallback + "' to default to");
  return it->second;
}

std::string resolve(const std::string& path, const std::string& base_dir) {
  return !path.empty() && path[0] != '/' && !base_dir.empty() ? base_dir + "/" + path : path;
}

// fibers: uniform | rule | strokes | file (docs/scenes.md, docs/fiber-format.md).
std::vector<Vec3> fibers(const Ctx& ctx, const YAML::Node& node, const core::TetMesh& mesh, const std::string& base_dir,
                         std::vector<std::string>& files_read) {
  Map f(ctx, node, "fibers", {"uniform", "strokes", "rule", "file"});
  int kinds = 0;
  for (const char* k : {"uniform", "strokes", "rule", "file"}) kinds += f.has(k) ? 1 : 0;
  if (kinds != 1) ctx.fail(node, "fibers", "give exactly one of uniform, rule, strokes, file");
  const size_t ne = static_cast<size_t>(mesh.num_elements());
  if (f.has("uniform")) {
    const Vec3 u = vec3(ctx, f["uniform"], "fibers.uniform");
    if (u.norm() < 1e-12) ctx.fail(f["uniform"], "fibers.uniform", "must not be zero");
    return std::vector<Vec3>(ne, u.normalized());
  }
  try {
    if (f.has("rule")) {
      Map r(ctx, f["rule"], "fibers.rule", {"endo_angle", "epi_angle", "inner", "outer", "apex_to_base"});
      core::HelixRule rule;
      if (r.has("endo_angle")) rule.endo_angle_deg = number(ctx, r["endo_angle"], r.sub("endo_angle"), -180, 180);
      if (r.has("epi_angle")) rule.epi_angle_deg = number(ctx, r["epi_angle"], r.sub("epi_angle"), -180, 180);
      if (r.has("apex_to_base")) {
        rule.apex_to_base = vec3(ctx, r["apex_to_base"], r.sub("apex_to_base"));
        if (rule.apex_to_base.norm() < 1e-12) ctx.fail(r["apex_to_base"], r.sub("apex_to_base"), "must not be zero");
      }
      const std::vector<int> inner = nodes_or_set(ctx, r, "inner", "endo", mesh);
      const std::vector<int> outer = nodes_or_set(ctx, r, "outer", "epi", mesh);
      const Eigen::VectorXd t = core::laplace_coordinate(mesh, inner, outer);
      return core::helix_rule_fibers(mesh, t, rule).fiber;
    }
    if (f.has("strokes")) {
      Map st(ctx, f["strokes"], "fibers.strokes", {"lines", "file", "radius"});
      std::vector<std::vector<Vec3>> lines;
      if (st.has("lines")) {
        const YAML::Node l = st["lines"];
        if (!l.IsSequence() || l.size() == 0) ctx.fail(l, "fibers.strokes.lines", "expected a list of polylines [[x,y,z], ...]");
        for (size_t k = 0; k < l.size(); ++k) {
          const std::string path = "fibers.strokes.lines[" + std::to_string(k) + "]";
          if (!l[k].IsSequence() || l[k].size() < 2) ctx.fail(l[k], path, "a polyline needs two points at least");
          std::vector<Vec3> pts;
          for (size_t i = 0; i < l[k].size(); ++i) pts.push_back(vec3(ctx, l[k][i], path + "[" + std::to_string(i) + "]"));
          bool moves = false;
          for (size_t i = 1; i < pts.size(); ++i) moves = moves || (pts[i] - pts[i - 1]).norm() > 0;
          if (!moves) ctx.fail(l[k], path, "needs two distinct points");
          lines.push_back(std::move(pts));
        }
      }
      if (st.has("file")) {
        const std::string path = resolve(text(ctx, st["file"], "fibers.strokes.file"), base_dir);
        files_read.push_back(path);
        if (const std::string bad = input_file_problem(path); !bad.empty())
          ctx.fail(st["file"], "fibers.strokes.file", "cannot open " + path + ": " + bad);
        std::ifstream in(path);
        if (!in) ctx.fail(st["file"], "fibers.strokes.file", "cannot open " + path);
        auto more = read_polylines(in, path);
        lines.insert(lines.end(), more.begin(), more.end());
      }
      if (lines.empty()) ctx.fail(f["strokes"], "fibers.strokes", "give lines or file");
      // Default radius: the mean edge length of the mesh.
      double radius = 0;
      if (st.has("radius")) {
        radius = number(ctx, st["radius"], "fibers.strokes.radius", 0, HUGE_VAL, true);
      } else {
        double sum = 0;
        for (const core::Tet& t : mesh.tets())
          for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b) sum += (mesh.rest_positions().col(t[a]) - mesh.rest_positions().col(t[b])).norm();
        radius = sum / (6.0 * mesh.num_elements());
      }
      std::vector<int> nodes;
      std::vector<Vec3> dirs;
      for (int n = 0; n < mesh.num_nodes(); ++n) {
        const Vec3 p = mesh.rest_positions().col(n);
        double best = HUGE_VAL;
        Vec3 tangent = Vec3::Zero();
        for (const auto& line : lines)
          for (size_t i = 1; i < line.size(); ++i) {
            const Vec3 a = line[i - 1], d = line[i] - line[i - 1];
            if (d.norm() == 0) continue;
            const double s = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
            const double dist = (a + s * d - p).norm();
            if (dist < best) best = dist, tangent = d;
          }
        if (best <= radius) {
          nodes.push_back(n);
          dirs.push_back(tangent.normalized());
        }
      }
      if (nodes.empty())
        ctx.fail(f["strokes"], "fibers.strokes", "no node lies within radius " + std::to_string(radius) + " m of a stroke");
      return core::interpolate_directions(mesh, nodes, dirs);
    }
    // file: one vector per element, or per node (then interpolated sign-blind).
    const std::string path = resolve(text(ctx, f["file"], "fibers.file"), base_dir);
    files_read.push_back(path);
    if (const std::string bad = input_file_problem(path); !bad.empty()) ctx.fail(f["file"], "fibers.file", "cannot open " + path + ": " + bad);
    std::ifstream in(path);
    if (!in) ctx.fail(f["file"], "fibers.file", "cannot open " + path);
    const std::vector<Vec3> v = read_fiber_vectors(in, path);
    if (v.size() == ne) {
      std::vector<Vec3> out(ne);
      for (size_t e = 0; e < ne; ++e) out[e] = v[e].normalized();
      return out;
    }
    if (v.size() == static_cast<size_t>(mesh.num_nodes())) {
      std::vector<int> all(v.size());
      for (size_t n = 0; n < all.size(); ++n) all[n] = static_cast<int>(n);
      return core::interpolate_directions(mesh, all, v);
    }
    ctx.fail(f["file"], "fibers.file",
             path + " has " + std::to_string(v.size()) + " vectors; the mesh has " + std::to_string(ne) + " elements and " +
                 std::to_string(mesh.num_nodes()) + " nodes");
  } catch (const FiberFileError& e) {
    ctx.fail(node, "fibers", e.what());
  } catch (const SceneError&) {
    throw;
  } catch (const std::invalid_argument& e) {
    ctx.fail(node, "fibers", e.what());
  }
}

// contraction (docs/scenes.md).
core::Contraction contraction(const Ctx& ctx, const YAML::Node& node, const core::TetMesh& mesh,
                              const std::vector<std::string>& region_names) {
  Map c(ctx, node, "contraction", {"mode", "peak_tension", "heart_rate", "period", "twitch", "regions", "pacing"});
  core::Contraction con;
  if (c.has("mode"))
    con.mode = choice(ctx, c["mode"], "contraction.mode", {"active_stress", "nodal_forces"}) == "nodal_forces"
                   ? core::ContractionMode::nodal_forces
                   : core::ContractionMode::active_stress;
  if (c.has("heart_rate") && c.has("period")) ctx.fail(node, "contraction", "give heart_rate or period, not both");
  if (c.has("heart_rate")) con.period_s = 60.0 / number(ctx, c["heart_rate"], "contraction.heart_rate", 1, 600);
  if (c.has("period")) con.period_s = number(ctx, c["period"], "contraction.period", 0.05, 60);
  if (c.has("twitch")) {
    Map t(ctx, c["twitch"], "contraction.twitch", {"shape", "tau1", "tau2", "systole"});
    if (t.has("shape"))
      con.twitch.shape = choice(ctx, t["shape"], t.sub("shape"), {"biexponential", "sine"}) == "sine" ? core::TwitchShape::sine
                                                                                                   : core::TwitchShape::biexponential;
    if (t.has("tau1")) con.twitch.tau1_s = number(ctx, t["tau1"], t.sub("tau1"), 0, 10, true);
    if (t.has("tau2")) con.twitch.tau2_s = number(ctx, t["tau2"], t.sub("tau2"), 0, 10, true);
    if (t.has("systole")) con.twitch.systole_s = number(ctx, t["systole"], t.sub("systole"), 0, 60, true);
    try {
      con.twitch.validate();
    } catch (const std::invalid_argument& e) {
      ctx.fail(c["twitch"], "contraction.twitch", e.what());
    }
    if (con.twitch.shape == core::TwitchShape::sine && con.twitch.systole_s > con.period_s)
      ctx.fail(c["twitch"], "contraction.twitch.systole", "is longer than the period");
  }
  const double peak = c.has("peak_tension") ? number(ctx, c["peak_tension"], "contraction.peak_tension", 0, 1e9) : 0.0;
  con.region_peak_pa.assign(static_cast<size_t>(mesh.num_regions()), peak);
  if (c.has("regions")) {
    const YAML::Node r = c["regions"];
    if (!r.IsMap() || r.size() == 0) ctx.fail(r, "contraction.regions", "expected a non-empty mapping region name: peak tension (Pa)");
    for (const auto& kv : r) {
      const std::string name = text(ctx, kv.first, "contraction.regions");
      const auto it = std::find(region_names.begin(), region_names.end(), name);
      if (it == region_names.end())
        ctx.fail(kv.first, "contraction.regions." + name, "no region of that name (regions: " + join(region_names) + ")");
      con.region_peak_pa[static_cast<size_t>(it - region_names.begin())] =
          number(ctx, kv.second, "contraction.regions." + name, 0, 1e9);
    }
  }
  if (!c.has("peak_tension") && !c.has("regions")) ctx.fail(node, "contraction", "needs peak_tension (Pa) or regions");
  if (c.has("pacing")) {
    Map p(ctx, c["pacing"], "contraction.pacing", {"at", "speed"});
    if (!p.has("at") || !p.has("speed")) ctx.fail(c["pacing"], "contraction.pacing", "needs at: [x, y, z] and speed (m/s)");
    con.element_delay_s = core::pacing_delays(mesh.rest_positions(), mesh.tets(), vec3(ctx, p["at"], p.sub("at")),
                                              number(ctx, p["speed"], p.sub("speed"), 0, 1e3, true));
  }
  return con;
}

// archive (docs/archive.md): where and how a run is recorded.
ArchiveSettings archive_settings(const Ctx& ctx, const YAML::Node& node) {
  ArchiveSettings archive;
  Map a(ctx, node, "archive",
        {"path", "flush_frames", "flush_seconds", "every", "velocities", "displacement", "checkpoint_every", "compression"});
  archive.enabled = true;
  if (!a.has("path")) ctx.fail(node, "archive.path", "required: the .h5 file to record into");
  archive.path = text(ctx, a["path"], "archive.path");
  if (archive.path.empty()) ctx.fail(a["path"], "archive.path", "must not be empty");
  if (a.has("flush_frames")) archive.flush_frames = integer(ctx, a["flush_frames"], "archive.flush_frames", 1, 100000);
  if (a.has("flush_seconds")) archive.flush_seconds = number(ctx, a["flush_seconds"], "archive.flush_seconds", 0, 3600);
  if (a.has("every")) archive.every_steps = integer(ctx, a["every"], "archive.every", 1, 1000000);
  if (a.has("velocities")) archive.velocities = choice(ctx, a["velocities"], "archive.velocities", {"true", "false"}) == "true";
  if (a.has("displacement"))
    archive.displacement = choice(ctx, a["displacement"], "archive.displacement", {"true", "false"}) == "true";
  if (a.has("checkpoint_every")) archive.checkpoint_every_s = number(ctx, a["checkpoint_every"], "archive.checkpoint_every", 0, 1e9);
  if (a.has("compression")) archive.compression = integer(ctx, a["compression"], "archive.compression", 0, 9);
  return archive;
}

}  // namespace

Scene parse_scene(const std::string& yaml_text, const std::string& origin, const std::string& base_dir,
                  const std::vector<std::string>& overrides, const EmbeddedFiles* embedded) {
  Ctx ctx{origin, {}, embedded, {}};
  for (const std::string& o : overrides) ctx.overridden.push_back(o.substr(0, o.find('=')));
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw SceneError(origin + ":" + std::to_string(e.mark.line + 1) + ": not valid YAML: " + e.msg);
  }
  for (const std::string& o : overrides) apply_override(root, o);
  const Map top(ctx, root, "", {"name", "mesh", "regions", "fibers", "fixed", "loads", "solver", "probes", "contraction", "measure", "archive",
                        "fidelity"});
  // Fidelity preset (docs/scenes.md): step, mesh refinement and PCG tolerance, under the
  // scene's explicit keys.
  std::optional<Fidelity> fidelity;
  std::string fidelity_name;
  if (top.has("fidelity")) {
    std::vector<std::string> names;
    for (const auto& [k, v] : fidelity_presets()) names.push_back(k);
    fidelity_name = choice(ctx, top["fidelity"], "fidelity", names);
    fidelity = fidelity_presets().at(fidelity_name);
  }

  // Mesh, then the region of every element (first match wins).
  std::string mesh_file;
  core::TetMesh box_mesh = build_mesh(ctx, top, base_dir, mesh_file, fidelity ? fidelity->refine : 1.0);
  if (!top.has("regions")) ctx.fail(root, "regions", "missing (at least one region with a material)");
  const YAML::Node regions = top["regions"];
  if (!regions.IsSequence() || regions.size() == 0) ctx.fail(regions, "regions", "expected a non-empty list");
  const int ne = box_mesh.num_elements();
  std::vector<int> region_of(static_cast<size_t>(ne), -1);
  std::vector<core::Material> materials;
  std::vector<core::RayleighDamping> dampings;
  std::vector<std::string> region_names;
  bool any_damping = false;
  for (size_t r = 0; r < regions.size(); ++r) {
    const std::string path = "regions[" + std::to_string(r) + "]";
    Map reg(ctx, regions[r], path, {"name", "select", "material", "damping"});
    if (!reg.has("material")) ctx.fail(regions[r], path, "needs a material");
    region_names.push_back(reg.has("name") ? text(ctx, reg["name"], reg.sub("name")) : "regions[" + std::to_string(r) + "]");
    if (std::count(region_names.begin(), region_names.end(), region_names.back()) > 1)
      ctx.fail(reg["name"], reg.sub("name"), "'" + printable(region_names.back()) + "' names an earlier region too");
    materials.push_back(material(ctx, reg["material"], reg.sub("material")));
    core::RayleighDamping d;
    if (reg.has("damping")) {
      Map dm(ctx, reg["damping"], reg.sub("damping"), {"mass", "stiffness"});
      if (dm.has("mass")) d.mass_1_s = number(ctx, dm["mass"], dm.sub("mass"), 0, HUGE_VAL);
      if (dm.has("stiffness")) d.stiffness_s = number(ctx, dm["stiffness"], dm.sub("stiffness"), 0, HUGE_VAL);
      any_damping = any_damping || !d.is_zero();
    }
    dampings.push_back(d);
    const YAML::Node sel = reg.has("select") ? reg["select"] : YAML::Node("all");
    int matched = 0;
    for (int e = 0; e < ne; ++e) {
      if (region_of[static_cast<size_t>(e)] >= 0) continue;
      bool hit = false;
      if (sel.IsScalar()) {
        if (sel.as<std::string>() != "all") ctx.fail(sel, reg.sub("select"), "expected all, {tag: N} or {box: [[..], [..]]}");
        hit = true;
      } else {
        Map s(ctx, sel, reg.sub("select"), {"tag", "box"});
        if (s.has("tag")) {
          hit = box_mesh.regions()[static_cast<size_t>(e)] == integer(ctx, s["tag"], s.sub("tag"), 0, 1 << 30);
        } else if (s.has("box")) {
          const auto [lo, hi] = box(ctx, s["box"], s.sub("box"));
          Vec3 c = Vec3::Zero();
          for (int n : box_mesh.tets()[static_cast<size_t>(e)]) c += 0.25 * box_mesh.rest_positions().col(n);
          hit = (c.array() >= lo.array()).all() && (c.array() <= hi.array()).all();
        } else {
          ctx.fail(sel, reg.sub("select"), "give tag or box");
        }
      }
      if (hit) {
        region_of[static_cast<size_t>(e)] = static_cast<int>(r);
        ++matched;
      }
    }
    if (matched == 0) ctx.fail(regions[r], path, "matches no element (earlier regions took them, or the selector is empty)");
  }
  for (int e = 0; e < ne; ++e)
    if (region_of[static_cast<size_t>(e)] < 0)
      ctx.fail(regions, "regions", "element " + std::to_string(e) + " is matched by no region");

  core::TetMesh mesh(box_mesh.rest_positions(), box_mesh.tets(), region_of);
  for (const auto& [name, nodes] : box_mesh.node_sets()) mesh.set_node_set(name, nodes);
  core::Model model(std::move(mesh));
  model.region_materials = std::move(materials);
  if (any_damping) model.region_damping = std::move(dampings);

  // Fibers.
  model.set_uniform_fiber(Vec3::UnitX());
  std::vector<std::string> files_read;  // besides the mesh: fiber and stroke files (hashed)
  if (top.has("fibers")) model.fibers = fibers(ctx, top["fibers"], model.mesh, base_dir, files_read);

  if (top.has("contraction")) model.contraction = contraction(ctx, top["contraction"], model.mesh, region_names);

  // Fixed nodes.
  if (top.has("fixed")) {
    const YAML::Node fx = top["fixed"];
    if (!fx.IsSequence()) ctx.fail(fx, "fixed", "expected a list of node selectors");
    for (size_t i = 0; i < fx.size(); ++i) {
      const std::string path = "fixed[" + std::to_string(i) + "]";
      const std::vector<int> nodes = select_nodes(ctx, fx[i], path, model.mesh, {"components"});
      unsigned mask = 0b111;
      if (fx[i]["components"].IsDefined()) {
        const YAML::Node c = fx[i]["components"];
        if (!c.IsSequence() || c.size() == 0 || c.size() > 3)
          ctx.fail(c, path + ".components", "expected a list of x, y, z (the fixed displacement components)");
        mask = 0;
        for (size_t k = 0; k < c.size(); ++k) {
          const unsigned bit = 1u << (choice(ctx, c[k], path + ".components[" + std::to_string(k) + "]", {"x", "y", "z"})[0] - 'x');
          if (mask & bit) ctx.fail(c[k], path + ".components[" + std::to_string(k) + "]", "repeated");
          mask |= bit;
        }
      }
      model.fix_nodes(nodes, mask);
    }
  }

  // Loads.
  if (top.has("loads")) {
    Map l(ctx, top["loads"], "loads", {"gravity", "tractions", "point_forces"});
    if (l.has("gravity")) model.loads.gravity_m_s2 = vec3(ctx, l["gravity"], "loads.gravity");
    if (l.has("tractions")) {
      const YAML::Node tr = l["tractions"];
      if (!tr.IsSequence()) ctx.fail(tr, "loads.tractions", "expected a list");
      for (size_t i = 0; i < tr.size(); ++i) {
        const std::string path = "loads.tractions[" + std::to_string(i) + "]";
        Map t(ctx, tr[i], path, {"on", "pressure", "force_per_area", "follower", "ramp"});
        if (!t.has("on")) ctx.fail(tr[i], path, "needs on: <node selector>");
        std::vector<int> nodes = select_nodes(ctx, t["on"], t.sub("on"), model.mesh);
        core::SurfaceLoad load;
        for (const core::Tri& tri : model.mesh.boundary_triangles())
          if (std::all_of(tri.begin(), tri.end(), [&](int n) { return std::binary_search(nodes.begin(), nodes.end(), n); }))
            load.faces.push_back(tri);
        if (load.faces.empty()) ctx.fail(t["on"], t.sub("on"), "selects no boundary face (all three nodes must match)");
        if (t.has("pressure") == t.has("force_per_area")) ctx.fail(tr[i], path, "give exactly one of pressure, force_per_area");
        if (t.has("pressure")) load.pressure_pa = number(ctx, t["pressure"], t.sub("pressure"));
        if (t.has("force_per_area")) load.force_per_area_pa = vec3(ctx, t["force_per_area"], t.sub("force_per_area"));
        if (t.has("follower")) {
          load.follower = choice(ctx, t["follower"], t.sub("follower"), {"true", "false"}) == "true";
          if (load.follower && !t.has("pressure")) ctx.fail(t["follower"], t.sub("follower"), "goes with pressure");
        }
        if (t.has("ramp")) load.ramp_s = number(ctx, t["ramp"], t.sub("ramp"), 0, 1e6);
        model.loads.surface_loads.push_back(std::move(load));
      }
    }
    if (l.has("point_forces")) {
      const YAML::Node pf = l["point_forces"];
      if (!pf.IsSequence()) ctx.fail(pf, "loads.point_forces", "expected a list");
      for (size_t i = 0; i < pf.size(); ++i) {
        const std::string path = "loads.point_forces[" + std::to_string(i) + "]";
        Map p(ctx, pf[i], path, {"at", "force"});
        if (!p.has("at") || !p.has("force")) ctx.fail(pf[i], path, "needs at and force");
        const Vec3 at = vec3(ctx, p["at"], p.sub("at"));
        int best = 0;
        double bd = HUGE_VAL;
        for (int n = 0; n < model.mesh.num_nodes(); ++n) {
          const double d = (model.mesh.rest_positions().col(n) - at).squaredNorm();
          if (d < bd) bd = d, best = n;
        }
        model.loads.point_forces.push_back({best, vec3(ctx, p["force"], p.sub("force"))});
      }
    }
  }

  // Solver.
  core::SimulatorSettings st;
  if (fidelity) {
    st.dt_s = fidelity->dt_s;
    st.solver.tolerance = fidelity->tolerance;
    if (fidelity->cost_refresh) st.solver = core::with_cost_refresh(st.solver);
  }
  Mode mode = Mode::dynamic;
  double until_s = 2.0;
  if (top.has("solver")) {
    Map s(ctx, top["solver"], "solver",
          {"mode", "dt", "method", "tolerance", "max_iterations", "rotation", "preconditioner", "warm_start",
           "max_energy_gain", "until", "recycled_solutions", "threads", "corotation"});
    if (s.has("threads")) st.threads = integer(ctx, s["threads"], "solver.threads", 0, 1024);
    if (s.has("recycled_solutions"))
      st.solver.recycled_solutions = integer(ctx, s["recycled_solutions"], "solver.recycled_solutions", 0, 64);
    if (s.has("until")) until_s = number(ctx, s["until"], "solver.until", 0, 1e9, true);
    if (s.has("mode")) mode = choice(ctx, s["mode"], "solver.mode", {"dynamic", "static"}) == "static" ? Mode::static_ : Mode::dynamic;
    if (s.has("dt")) st.dt_s = number(ctx, s["dt"], "solver.dt", 0, 10, true);
    if (s.has("method"))
      st.solver.method = choice(ctx, s["method"], "solver.method", {"pcg", "direct"}) == "direct"
                             ? core::LinearSolverKind::direct
                             : core::LinearSolverKind::pcg;
    if (s.has("tolerance")) st.solver.tolerance = number(ctx, s["tolerance"], "solver.tolerance", 0, 1, true);
    if (s.has("max_iterations")) st.solver.max_iterations = integer(ctx, s["max_iterations"], "solver.max_iterations", 1, 1 << 30);
    if (s.has("rotation"))
      st.rotation = choice(ctx, s["rotation"], "solver.rotation", {"svd", "polar"}) == "svd" ? core::RotationMethod::svd
                                                                                            : core::RotationMethod::polar;
    if (s.has("preconditioner")) {
      const std::string p = choice(ctx, s["preconditioner"], "solver.preconditioner", {"cholesky", "block_jacobi", "amg"});
      st.solver.preconditioner = p == "cholesky" ? core::PreconditionerKind::cholesky
                                 : p == "amg"    ? core::PreconditionerKind::amg
                                                 : core::PreconditionerKind::block_jacobi;
    }
    if (s.has("corotation"))
      st.corotation = choice(ctx, s["corotation"], "solver.corotation", {"true", "false"}) == "true";
    if (s.has("warm_start")) {
      const std::string w = choice(ctx, s["warm_start"], "solver.warm_start", {"true", "false"});
      st.solver.warm_start = w == "true";
    }
    if (s.has("max_energy_gain")) {
      const YAML::Node g = s["max_energy_gain"];
      st.max_energy_gain = g.IsScalar() && (g.as<std::string>() == "inf" || g.as<std::string>() == ".inf")
                               ? std::numeric_limits<double>::infinity()
                               : number(ctx, g, "solver.max_energy_gain", 0, HUGE_VAL);
    }
  }

  // A step larger than the requested fidelity's: the accuracy asked for is not what runs.
  if (fidelity && mode == Mode::dynamic && st.dt_s > fidelity->dt_s * (1 + 1e-9)) {
    const YAML::Node solver = top.has("solver") ? top["solver"] : YAML::Node();
    const YAML::Node at = solver.IsMap() && solver["dt"] ? solver["dt"] : top["fidelity"];
    std::ostringstream w;
    w << "step " << st.dt_s << " s is larger than the '" << fidelity_name << "' preset's " << fidelity->dt_s
      << " s: the run will be less accurate than that preset (measured error against the step: docs/speed-accuracy.md)";
    ctx.warn(at, "solver.dt", w.str());
  }

  // Probes.
  std::vector<Probe> probes;
  if (top.has("probes")) {
    const YAML::Node pr = top["probes"];
    if (!pr.IsMap()) ctx.fail(pr, "probes", "expected a mapping name: [x, y, z]");
    for (const auto& kv : pr) {
      if (!kv.first.IsScalar()) ctx.fail(kv.first, "probes", "a probe's name must be a plain name, not a mapping or a list");
      const std::string name = kv.first.as<std::string>();
      Probe p{name, vec3(ctx, kv.second, "probes." + name)};
      // The containing element (the least negative weight, within round-off of the hull).
      double best = -HUGE_VAL;
      for (int e = 0; e < model.mesh.num_elements(); ++e) {
        const Eigen::Vector4d w = barycentric(model.mesh, e, p.point_m);
        if (w.minCoeff() > best) best = w.minCoeff(), p.element = e, p.weights = w;
      }
      if (best < -1e-9) ctx.fail(kv.second, "probes." + name, "the point is outside the mesh");
      probes.push_back(p);
    }
  }

  try {
    model.validate();
    st.validate();
  } catch (const std::invalid_argument& e) {
    throw SceneError(origin + ": " + e.what());
  }
  std::string name = top.has("name") ? text(ctx, top["name"], "name") : origin;
  // Cavities: boundary parts (node selectors) whose enclosed volume is measured.
  std::vector<CavityMeasure> cavities;
  if (top.has("measure")) {
    Map me(ctx, top["measure"], "measure", {"cavities"});
    if (me.has("cavities")) {
      const YAML::Node cv = me["cavities"];
      if (!cv.IsMap()) ctx.fail(cv, "measure.cavities", "expected a mapping name: node selector");
      for (const auto& kv : cv) {
        const std::string cname = text(ctx, kv.first, "measure.cavities");
        const std::string path = "measure.cavities." + cname;
        const std::vector<int> nodes = select_nodes(ctx, kv.second, path, model.mesh);
        try {
          cavities.push_back({cname, core::cavity_surface(model.mesh, nodes)});
        } catch (const std::invalid_argument& e) {
          ctx.fail(kv.second, path, e.what());
        }
        const double v = core::cavity_volume(cavities.back().surface, model.mesh.rest_positions());
        if (!(v > 0))
          ctx.fail(kv.second, path,
                   "encloses a volume of " + std::to_string(v) + " m^3 at rest: select the cavity's own wall (an endocardium)");
      }
    }
  }
  ArchiveSettings archive;
  if (top.has("archive")) archive = archive_settings(ctx, top["archive"]);
  Scene scene{std::move(name), std::move(model), st, mode, until_s, std::move(probes), std::move(cavities), {}, {}, {}, {}, {}, {}, {}};
  // The hash covers what determines the run: the scene as parsed (after overrides; comments
  // and layout do not count) and the bytes of the files it reads (mesh, fibers, strokes).
  // Recording (the archive key) does not change the run.
  YAML::Node run_root = YAML::Clone(root);
  run_root.remove("archive");
  YAML::Emitter canonical;
  canonical << run_root;
  std::string hashed = canonical.c_str();
  scene.yaml_text = hashed;
  scene.base_dir = base_dir;
  scene.archive = archive;
  std::vector<std::string> hashed_files = files_read;
  if (!mesh_file.empty()) hashed_files.insert(hashed_files.begin(), mesh_file);
  for (const std::string& file : hashed_files) {
    std::string bytes;
    if (embedded && embedded->count(file)) {
      bytes = embedded->at(file);
    } else {
      std::ifstream mf(file, std::ios::binary);
      std::stringstream ss;
      ss << mf.rdbuf();
      bytes = ss.str();
    }
    hashed += "\n--- " + file.substr(file.rfind('/') + 1) + " ---\n" + bytes;
  }
  scene.hash_sha256 = sha256_hex(hashed);
  scene.region_names = region_names;
  scene.mesh_file = mesh_file;
  scene.warnings = ctx.warnings;
  return scene;
}

core::Vec3 Probe::displacement(const core::TetMesh& mesh, const core::Positions& x) const {
  Vec3 u = Vec3::Zero();
  const core::Tet& t = mesh.tets()[static_cast<size_t>(element)];
  for (int a = 0; a < 4; ++a) {
    const int n = t[static_cast<size_t>(a)];
    u += weights(a) * (x.col(n) - mesh.rest_positions().col(n));
  }
  return u;
}

namespace {
YAML::Node load_section(const std::string& yaml_text, const std::string& origin) {
  try {
    return YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw SceneError(origin + ":" + std::to_string(e.mark.line + 1) + ": not valid YAML or JSON: " + e.msg);
  }
}
}  // namespace

core::Material parse_material(const std::string& yaml_text, const std::string& origin) {
  const Ctx ctx{origin, {}, nullptr, {}};
  return material(ctx, load_section(yaml_text, origin), "material");
}

core::Contraction parse_contraction(const std::string& yaml_text, const core::TetMesh& mesh,
                                    const std::vector<std::string>& region_names, const std::string& origin) {
  const Ctx ctx{origin, {}, nullptr, {}};
  core::Contraction c = contraction(ctx, load_section(yaml_text, origin), mesh, region_names);
  try {
    c.validate(mesh.num_regions(), mesh.num_elements());
  } catch (const std::invalid_argument& e) {
    throw SceneError(origin + ": contraction: " + e.what());
  }
  return c;
}

ArchiveSettings parse_archive_settings(const std::string& yaml_text, const std::string& origin) {
  const Ctx ctx{origin, {}, nullptr, {}};
  return archive_settings(ctx, load_section(yaml_text, origin));
}

std::vector<core::Vec3> parse_fibers(const std::string& yaml_text, const core::TetMesh& mesh, const std::string& base_dir,
                                     const std::string& origin) {
  const Ctx ctx{origin, {}, nullptr, {}};
  std::vector<std::string> files_read;
  return fibers(ctx, load_section(yaml_text, origin), mesh, base_dir, files_read);
}

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides) {
  if (const std::string bad = input_file_problem(path); !bad.empty()) throw SceneError(path + ": cannot open the scene file: " + bad);
  std::ifstream f(path);
  if (!f) throw SceneError(path + ": cannot open the scene file");
  std::stringstream ss;
  ss << f.rdbuf();
  const size_t slash = path.rfind('/');
  return parse_scene(ss.str(), path, slash == std::string::npos ? "." : path.substr(0, slash), overrides);
}

}  // namespace fiberfem::io
