// regions (docs/scenes.md): which elements each region takes, and its material and
// damping; the material and damping readers and writers.

#include "io/input_file.hpp"
#include "io/scene_internal.hpp"

#include <algorithm>

namespace fiberfem::io {

namespace {

using core::Vec3;

// Beyond this E_L / E_T the stability map (docs/speed-accuracy.md) found a loaded tissue
// beam that gained energy and did not return to rest (10,000); up to 1,000 it was stable.
constexpr double kMaxStableFiberRatio = 1000.0;

// The four forms, by the index of their alternative in MaterialSpec::form.
const std::vector<std::vector<std::string>>& form_keys() {
  static const std::vector<std::vector<std::string>> k = {
      {}, {"E_L", "E_T", "nu_LT", "nu_T", "G_L"}, {"lame", "fiber_factor", "shear_factor"}, {"C"}, {"E", "nu"}};
  return k;
}

void read_engineering(const CheckedMap& m, core::EngineeringConstants& c, bool fresh) {
  if (fresh)
    for (const char* k : {"E_L", "E_T", "nu_LT", "nu_T", "G_L"})
      if (!m.has(k)) m.fail(std::string("the engineering form needs ") + k);
  if (m.has("E_L")) c.E_L = m.number("E_L");
  if (m.has("E_T")) c.E_T = m.number("E_T");
  if (m.has("nu_LT")) c.nu_LT = m.number("nu_LT");
  if (m.has("nu_T")) c.nu_T = m.number("nu_T");
  if (m.has("G_L")) c.G_L = m.number("G_L");
  if (c.E_T > 0 && c.E_L / c.E_T > kMaxStableFiberRatio)
    m.checks().warn(m.has("E_T") ? m["E_T"] : m.node(), m.sub("E_T"),
                    "fiber/cross-fiber ratio E_L/E_T = " + std::to_string(c.E_L / c.E_T) +
                        " is above 1000, beyond the measured stability map: a loaded soft body may gain energy "
                        "and not return to rest (docs/speed-accuracy.md)");
}

void read_lame(const CheckedMap& m, core::LameFiberConstants& c, bool fresh) {
  if (fresh && !m.has("lame")) m.fail("fiber_factor and shear_factor go with lame: [lambda, mu]");
  if (m.has("lame")) {
    const YAML::Node l = m["lame"];
    if (!l.IsSequence() || l.size() != 2) m.checks().fail(l, m.sub("lame"), "expected [lambda, mu] in Pa");
    c.lambda = m.checks().number(l[0], m.sub("lame") + "[0]");
    c.mu = m.checks().number(l[1], m.sub("lame") + "[1]");
  }
  if (m.has("fiber_factor")) c.fiber_factor = m.number("fiber_factor");
  if (m.has("shear_factor")) c.shear_factor = m.number("shear_factor");
}

// C replaces the whole stiffness: all five constants.
void read_stiffness(const CheckedMap& m, core::StiffnessConstants& c) {
  const CheckedMap s(m.checks(), m["C"], m.sub("C"), {"C11", "C12", "C13", "C33", "C55"});
  for (const char* k : {"C11", "C12", "C13", "C33", "C55"})
    if (!s.has(k)) s.fail(std::string("needs ") + k);
  c = {s.number("C11"), s.number("C12"), s.number("C13"), s.number("C33"), s.number("C55")};
}

void read_isotropic(const CheckedMap& m, IsotropicConstants& c, bool fresh) {
  if (fresh && (!m.has("E") || !m.has("nu"))) m.fail("the isotropic form needs E and nu");
  if (m.has("E")) c.E = m.number("E");
  if (m.has("nu")) c.nu = m.number("nu");
}

core::Material build_material(const MaterialSpec& s) {
  const double rho = s.density_kg_m3;
  switch (s.form.index()) {
    case 1: return core::Material::from_engineering(std::get<1>(s.form), rho);
    case 2: return core::Material::from_lame(std::get<2>(s.form), rho);
    case 3: return core::Material::from_stiffness(std::get<3>(s.form), rho);
    default: return core::Material::isotropic(std::get<4>(s.form).E, std::get<4>(s.form).nu, rho);
  }
}

}  // namespace

const std::vector<std::string>& material_keys() {
  static const std::vector<std::string> k = {"E_L", "E_T", "nu_LT", "nu_T", "G_L", "lame", "fiber_factor", "shear_factor",
                                             "C", "E", "nu", "density"};
  return k;
}

core::Material read_material(const Checks& checks, const YAML::Node& node, const std::string& path, MaterialSpec& spec,
                             const std::vector<std::string>& also_allowed) {
  if (node.IsMap() && node["law"]) return read_law_material(checks, node, path, spec);
  std::vector<std::string> allowed = material_keys();
  allowed.insert(allowed.end(), also_allowed.begin(), also_allowed.end());
  const CheckedMap m(checks, node, path, allowed);
  MaterialSpec s = spec;
  s.law.reset();
  if (m.has("density")) s.density_kg_m3 = m.number("density", 0, HUGE_VAL, true);
  if (!(s.density_kg_m3 > 0)) m.fail("needs density (kg/m^3)");
  size_t given = 0, forms = 0;
  for (size_t f = 1; f < form_keys().size(); ++f)
    if (std::any_of(form_keys()[f].begin(), form_keys()[f].end(), [&](const std::string& k) { return m.has(k); }))
      given = f, ++forms;
  if (forms > 1 || (forms == 0 && s.form.index() == 0))
    m.fail("give exactly one form: E_L/E_T/nu_LT/nu_T/G_L, lame (+ fiber_factor, shear_factor), C, or E/nu");
  // A form other than the one held starts afresh (its keys are then all needed).
  const bool fresh = given != 0 && given != s.form.index();
  if (fresh) {
    if (given == 1) s.form = core::EngineeringConstants{};
    if (given == 2) s.form = core::LameFiberConstants{};
    if (given == 3) s.form = core::StiffnessConstants{};
    if (given == 4) s.form = IsotropicConstants{};
  }
  if (given == 1) read_engineering(m, std::get<1>(s.form), fresh);
  if (given == 2) read_lame(m, std::get<2>(s.form), fresh);
  if (given == 3) read_stiffness(m, std::get<3>(s.form));
  if (given == 4) read_isotropic(m, std::get<4>(s.form), fresh);
  try {
    core::Material built = build_material(s);
    spec = s;
    return built;
  } catch (const std::invalid_argument& e) {
    m.fail(e.what());
  }
}

YAML::Node write_material(const MaterialSpec& spec) {
  YAML::Node n(YAML::NodeType::Map);
  if (spec.law) {
    write_law(*spec.law, n);
  } else if (const auto* c = std::get_if<core::EngineeringConstants>(&spec.form)) {
    n["E_L"] = c->E_L, n["E_T"] = c->E_T, n["nu_LT"] = c->nu_LT, n["nu_T"] = c->nu_T, n["G_L"] = c->G_L;
  } else if (const auto* l = std::get_if<core::LameFiberConstants>(&spec.form)) {
    n["lame"] = std::vector<double>{l->lambda, l->mu};
    n["lame"].SetStyle(YAML::EmitterStyle::Flow);
    n["fiber_factor"] = l->fiber_factor, n["shear_factor"] = l->shear_factor;
  } else if (const auto* s = std::get_if<core::StiffnessConstants>(&spec.form)) {
    YAML::Node C(YAML::NodeType::Map);
    C["C11"] = s->C11, C["C12"] = s->C12, C["C13"] = s->C13, C["C33"] = s->C33, C["C55"] = s->C55;
    n["C"] = C;
  } else if (const auto* i = std::get_if<IsotropicConstants>(&spec.form)) {
    n["E"] = i->E, n["nu"] = i->nu;
  }
  n["density"] = spec.density_kg_m3;
  return n;
}

core::RayleighDamping read_damping(const Checks& checks, const YAML::Node& node, const std::string& path) {
  const CheckedMap m(checks, node, path, {"mass", "stiffness"});
  core::RayleighDamping d;
  if (m.has("mass")) d.mass_1_s = m.number("mass", 0, HUGE_VAL);
  if (m.has("stiffness")) d.stiffness_s = m.number("stiffness", 0, HUGE_VAL);
  return d;
}

YAML::Node write_damping(const core::RayleighDamping& damping) {
  YAML::Node n(YAML::NodeType::Map);
  n["mass"] = damping.mass_1_s;
  n["stiffness"] = damping.stiffness_s;
  return n;
}

namespace detail {
namespace {

// Whether element `e` is in region selector `sel` (all, {tag: N} or {box: [[..], [..]]}).
bool selects(const Checks& checks, const YAML::Node& sel, const std::string& path, const core::TetMesh& mesh, int e) {
  if (sel.IsScalar()) {
    if (sel.as<std::string>() != "all") checks.fail(sel, path, "expected all, {tag: N} or {box: [[..], [..]]}");
    return true;
  }
  const CheckedMap s(checks, sel, path, {"tag", "box"});
  if (s.has("tag")) return mesh.regions()[static_cast<size_t>(e)] == s.integer("tag", 0, 1 << 30);
  if (!s.has("box")) s.fail("give tag or box");
  const auto [lo, hi] = read_box(checks, s["box"], s.sub("box"));
  Vec3 c = Vec3::Zero();
  for (int n : mesh.tets()[static_cast<size_t>(e)]) c += 0.25 * mesh.rest_positions().col(n);
  return (c.array() >= lo.array()).all() && (c.array() <= hi.array()).all();
}

}  // namespace

Regions read_regions(const CheckedMap& top, const core::TetMesh& mesh) {
  const Checks& checks = top.checks();
  if (!top.has("regions")) top.checks().fail(top.node(), "regions", "missing (at least one region with a material)");
  const YAML::Node list = top["regions"];
  if (!list.IsSequence() || list.size() == 0) checks.fail(list, "regions", "expected a non-empty list");
  const int ne = mesh.num_elements();
  Regions out;
  out.region_of.assign(static_cast<size_t>(ne), -1);
  for (size_t r = 0; r < list.size(); ++r) {
    const std::string path = "regions[" + std::to_string(r) + "]";
    const CheckedMap reg(checks, list[r], path, {"name", "select", "material", "damping"});
    if (!reg.has("material")) reg.fail("needs a material");
    out.names.push_back(reg.has("name") ? reg.text("name") : path);
    if (std::count(out.names.begin(), out.names.end(), out.names.back()) > 1)
      checks.fail(reg["name"], reg.sub("name"), "'" + printable(out.names.back()) + "' names an earlier region too");
    RegionParameters p;
    out.materials.push_back(read_material(checks, reg["material"], reg.sub("material"), p.material));
    if (reg.has("damping")) p.damping = read_damping(checks, reg["damping"], reg.sub("damping"));
    out.parameters.push_back(p);
    const YAML::Node sel = reg.has("select") ? reg["select"] : YAML::Node("all");
    int matched = 0;
    for (int e = 0; e < ne; ++e) {
      if (out.region_of[static_cast<size_t>(e)] >= 0 || !selects(checks, sel, reg.sub("select"), mesh, e)) continue;
      out.region_of[static_cast<size_t>(e)] = static_cast<int>(r);
      ++matched;
    }
    if (matched == 0) reg.fail("matches no element (earlier regions took them, or the selector is empty)");
  }
  for (int e = 0; e < ne; ++e)
    if (out.region_of[static_cast<size_t>(e)] < 0)
      checks.fail(list, "regions", "element " + std::to_string(e) + " is matched by no region");
  return out;
}

}  // namespace detail
}  // namespace fiberfem::io
