// fibers (docs/scenes.md, docs/fiber-format.md): uniform, the helix rule, strokes drawn
// through the mesh, or a file; read into a FiberSpec and a fiber per element, and written
// back.

#include "io/fiber_file.hpp"
#include "io/input_file.hpp"
#include "io/scene_internal.hpp"

#include <algorithm>
#include <fstream>

namespace fiberfem::io {

namespace {

using core::Vec3;

// Nodes selected by `key` (a node selector) or the named node set `fallback`.
std::vector<int> nodes_or_set(const CheckedMap& m, const std::string& key, const std::string& fallback,
                              const core::TetMesh& mesh, std::optional<NodeSelector>& spec) {
  if (m.has(key)) {
    NodeSelector s;
    std::vector<int> nodes = read_node_selector(m.checks(), m[key], m.sub(key), mesh, &s);
    spec = s;
    return nodes;
  }
  const auto it = mesh.node_sets().find(fallback);
  if (it == mesh.node_sets().end()) m.checks().fail(m.node(), m.sub(key), "missing, and the mesh has no node set '" + fallback + "' to default to");
  return it->second;
}

std::vector<Vec3> rule_fibers(const CheckedMap& f, const core::TetMesh& mesh, FiberSpec& s, std::vector<Vec3>* sheets) {
  const CheckedMap r(f.checks(), f["rule"], "fibers.rule", {"endo_angle", "epi_angle", "inner", "outer", "apex_to_base"});
  if (r.has("endo_angle")) s.rule.endo_angle_deg = r.number("endo_angle", -180, 180);
  if (r.has("epi_angle")) s.rule.epi_angle_deg = r.number("epi_angle", -180, 180);
  if (r.has("apex_to_base")) {
    s.rule.apex_to_base = r.vec3("apex_to_base");
    if (s.rule.apex_to_base.norm() < 1e-12) r.checks().fail(r["apex_to_base"], r.sub("apex_to_base"), "must not be zero");
  }
  const std::vector<int> inner = nodes_or_set(r, "inner", "endo", mesh, s.inner);
  const std::vector<int> outer = nodes_or_set(r, "outer", "epi", mesh, s.outer);
  const Eigen::VectorXd t = core::laplace_coordinate(mesh, inner, outer);
  core::FiberField field = core::helix_rule_fibers(mesh, t, s.rule);
  if (sheets) *sheets = std::move(field.sheet);
  return std::move(field.fiber);
}

// Opens a fiber or stroke file named at key path `path`, or fails naming it.
std::ifstream open_input(const Checks& checks, const YAML::Node& at, const std::string& path, const std::string& file) {
  if (const std::string bad = input_file_problem(file); !bad.empty()) checks.fail(at, path, "cannot open " + file + ": " + bad);
  std::ifstream in(file);
  if (!in) checks.fail(at, path, "cannot open " + file);
  return in;
}

std::vector<std::vector<Vec3>> stroke_lines(const Checks& checks, const YAML::Node& l) {
  if (!l.IsSequence() || l.size() == 0) checks.fail(l, "fibers.strokes.lines", "expected a list of polylines [[x,y,z], ...]");
  std::vector<std::vector<Vec3>> lines;
  for (size_t k = 0; k < l.size(); ++k) {
    const std::string path = "fibers.strokes.lines[" + std::to_string(k) + "]";
    if (!l[k].IsSequence() || l[k].size() < 2) checks.fail(l[k], path, "a polyline needs two points at least");
    std::vector<Vec3> pts;
    for (size_t i = 0; i < l[k].size(); ++i) pts.push_back(checks.vec3(l[k][i], path + "[" + std::to_string(i) + "]"));
    bool moves = false;
    for (size_t i = 1; i < pts.size(); ++i) moves = moves || (pts[i] - pts[i - 1]).norm() > 0;
    if (!moves) checks.fail(l[k], path, "needs two distinct points");
    lines.push_back(std::move(pts));
  }
  return lines;
}

// Each node within `radius` of a stroke takes the tangent of the nearest segment; the
// field is interpolated from those nodes.
std::vector<Vec3> stroke_fibers(const CheckedMap& st, const core::TetMesh& mesh, const std::vector<std::vector<Vec3>>& lines,
                                double radius) {
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
  if (nodes.empty()) st.fail("no node lies within radius " + std::to_string(radius) + " m of a stroke");
  return core::interpolate_directions(mesh, nodes, dirs);
}

std::vector<Vec3> strokes(const CheckedMap& f, const core::TetMesh& mesh, const std::string& base_dir, FiberSpec& s,
                          std::vector<std::string>* files_read) {
  const Checks& checks = f.checks();
  const CheckedMap st(checks, f["strokes"], "fibers.strokes", {"lines", "file", "radius"});
  std::vector<std::vector<Vec3>> lines;
  if (st.has("lines")) lines = s.stroke_lines = stroke_lines(checks, st["lines"]);
  if (st.has("file")) {
    s.stroke_file = st.text("file");
    const std::string path = detail::resolve(s.stroke_file, base_dir);
    if (files_read) files_read->push_back(path);
    std::ifstream in = open_input(checks, st["file"], "fibers.strokes.file", path);
    auto more = read_polylines(in, path);
    lines.insert(lines.end(), more.begin(), more.end());
  }
  if (lines.empty()) st.fail("give lines or file");
  // Default radius: the mean edge length of the mesh.
  double radius = 0;
  if (st.has("radius")) {
    radius = *(s.stroke_radius_m = st.number("radius", 0, HUGE_VAL, true));
  } else {
    double sum = 0;
    for (const core::Tet& t : mesh.tets())
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) sum += (mesh.rest_positions().col(t[a]) - mesh.rest_positions().col(t[b])).norm();
    radius = sum / (6.0 * mesh.num_elements());
  }
  return stroke_fibers(st, mesh, lines, radius);
}

// Each element's sheet made orthogonal to its fiber (unit); an element where they are
// parallel fails at key `path`.
std::vector<Vec3> sheets_across(const Checks& checks, const YAML::Node& at, const std::string& path,
                                const std::vector<Vec3>& fibers, const std::vector<Vec3>& sheets) {
  std::vector<Vec3> out(fibers.size());
  for (size_t e = 0; e < fibers.size(); ++e) {
    const Vec3 f = fibers[e].normalized(), sh = sheets[e];
    const Vec3 across = sh - sh.dot(f) * f;
    if (across.norm() <= 1e-6 * sh.norm())
      checks.fail(at, path, "the sheet of element " + std::to_string(e) + " is zero or parallel to its fiber");
    out[e] = across.normalized();
  }
  return out;
}

// One vector per element, or per node (then interpolated sign-blind); each line may add a
// sheet, which becomes each element's sheet the same way.
std::vector<Vec3> file_fibers(const CheckedMap& f, const core::TetMesh& mesh, const std::string& base_dir, FiberSpec& s,
                              std::vector<std::string>* files_read, std::vector<Vec3>* sheets) {
  s.file = f.text("file");
  const std::string path = detail::resolve(s.file, base_dir);
  if (files_read) files_read->push_back(path);
  std::ifstream in = open_input(f.checks(), f["file"], "fibers.file", path);
  const FiberVectors v = read_fiber_file(in, path);
  const size_t ne = static_cast<size_t>(mesh.num_elements()), count = v.fibers.size();
  std::vector<Vec3> fibers, element_sheets;
  if (count == ne) {
    for (const Vec3& d : v.fibers) fibers.push_back(d.normalized());
    element_sheets = v.sheets;
  } else if (count == static_cast<size_t>(mesh.num_nodes())) {
    std::vector<int> all(count);
    for (size_t n = 0; n < all.size(); ++n) all[n] = static_cast<int>(n);
    fibers = core::interpolate_directions(mesh, all, v.fibers);
    if (!v.sheets.empty()) element_sheets = core::interpolate_directions(mesh, all, v.sheets);
  } else {
    f.checks().fail(f["file"], "fibers.file",
                    path + " has " + std::to_string(count) + " vectors; the mesh has " + std::to_string(ne) +
                        " elements and " + std::to_string(mesh.num_nodes()) + " nodes");
  }
  if (sheets && !element_sheets.empty()) *sheets = sheets_across(f.checks(), f["file"], "fibers.file", fibers, element_sheets);
  return fibers;
}

}  // namespace

std::vector<Vec3> read_fibers(const Checks& checks, const YAML::Node& node, const core::TetMesh& mesh,
                              const std::string& base_dir, FiberSpec& spec, std::vector<std::string>* files_read,
                              std::vector<Vec3>* sheets) {
  const CheckedMap f(checks, node, "fibers", {"uniform", "strokes", "rule", "file", "sheet"});
  if (sheets) sheets->clear();
  if (f.has("sheet") && f.has("rule")) f.checks().fail(f["sheet"], "fibers.sheet", "does not go with fibers.rule (the rule makes its own sheet)");
  int kinds = 0;
  for (const char* k : {"uniform", "strokes", "rule", "file"}) kinds += f.has(k) ? 1 : 0;
  if (kinds != 1) f.fail("give exactly one of uniform, rule, strokes, file");
  FiberSpec s;
  std::vector<Vec3> fibers;
  try {
    if (f.has("uniform")) {
      s.kind = FiberSpec::Kind::uniform;
      s.uniform = f.vec3("uniform");
      if (s.uniform.norm() < 1e-12) checks.fail(f["uniform"], "fibers.uniform", "must not be zero");
      fibers.assign(static_cast<size_t>(mesh.num_elements()), s.uniform.normalized());
    } else if (f.has("rule")) {
      s.kind = FiberSpec::Kind::rule;
      fibers = rule_fibers(f, mesh, s, sheets);
    } else if (f.has("strokes")) {
      s.kind = FiberSpec::Kind::strokes;
      fibers = strokes(f, mesh, base_dir, s, files_read);
    } else {
      s.kind = FiberSpec::Kind::file;
      fibers = file_fibers(f, mesh, base_dir, s, files_read, sheets);
    }
    if (f.has("sheet")) {
      // One sheet direction for the body, made orthogonal to each element's fiber.
      if (sheets && !sheets->empty()) checks.fail(f["sheet"], "fibers.sheet", "the fiber file gives its own sheets");
      const Vec3 sheet = f.vec3("sheet");
      if (sheet.norm() < 1e-12) checks.fail(f["sheet"], "fibers.sheet", "must not be zero");
      s.uniform_sheet = sheet;
      const std::vector<Vec3> across = sheets_across(checks, f["sheet"], "fibers.sheet", fibers, std::vector<Vec3>(fibers.size(), sheet));
      if (sheets) *sheets = across;
    }
  } catch (const FiberFileError& e) {
    f.fail(e.what());
  } catch (const SceneError&) {
    throw;
  } catch (const std::invalid_argument& e) {
    f.fail(e.what());
  }
  spec = s;
  return fibers;
}

YAML::Node write_fibers(const FiberSpec& s) {
  YAML::Node n(YAML::NodeType::Map);
  switch (s.kind) {
    case FiberSpec::Kind::uniform:
      n["uniform"] = detail::flow_vec3(s.uniform);
      break;
    case FiberSpec::Kind::rule: {
      YAML::Node r(YAML::NodeType::Map);
      r["endo_angle"] = s.rule.endo_angle_deg;
      r["epi_angle"] = s.rule.epi_angle_deg;
      r["apex_to_base"] = detail::flow_vec3(s.rule.apex_to_base);
      if (s.inner) r["inner"] = write_node_selector(*s.inner);
      if (s.outer) r["outer"] = write_node_selector(*s.outer);
      n["rule"] = r;
      break;
    }
    case FiberSpec::Kind::strokes: {
      YAML::Node st(YAML::NodeType::Map);
      if (!s.stroke_lines.empty()) {
        YAML::Node lines(YAML::NodeType::Sequence);
        for (const auto& line : s.stroke_lines) {
          YAML::Node l(YAML::NodeType::Sequence);
          for (const Vec3& p : line) l.push_back(detail::flow_vec3(p));
          lines.push_back(l);
        }
        st["lines"] = lines;
      }
      if (!s.stroke_file.empty()) st["file"] = s.stroke_file;
      if (s.stroke_radius_m) st["radius"] = *s.stroke_radius_m;
      n["strokes"] = st;
      break;
    }
    case FiberSpec::Kind::file: n["file"] = s.file; break;
  }
  if (s.uniform_sheet) n["sheet"] = detail::flow_vec3(*s.uniform_sheet);
  return n;
}

}  // namespace fiberfem::io
