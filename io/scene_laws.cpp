// regions[i].material with a `law` (docs/scenes.md, the accurate tier): the law's
// constants, its volumetric part, and the linear material of its small-strain limit that
// the real-time tier would use for the same region.

#include "core/hyperelastic/law.hpp"
#include "io/scene_sections.hpp"

#include <algorithm>
#include <cmath>

namespace fiberfem::io {

namespace {

using core::hyperelastic::LawKind;
using core::hyperelastic::LawParameters;

const std::vector<std::string> kLawNames = {"neo_hookean", "guccione", "holzapfel_ogden"};

std::vector<std::string> law_keys(LawKind kind) {
  std::vector<std::string> k = {"law", "density", "incompressible", "bulk_modulus"};
  const std::vector<std::string> own = kind == LawKind::neo_hookean ? std::vector<std::string>{"mu", "E", "nu"}
                                       : kind == LawKind::guccione  ? std::vector<std::string>{"C", "b_f", "b_t", "b_fs"}
                                                                    : std::vector<std::string>{"a", "b", "a_f", "b_f", "a_s", "b_s", "a_fs", "b_fs"};
  k.insert(k.end(), own.begin(), own.end());
  return k;
}

// The small-strain shear modulus of the law, Pa: the scale of its default bulk modulus.
double shear_scale(const LawParameters& l) {
  switch (l.kind) {
    case LawKind::neo_hookean: return l.mu_pa;
    case LawKind::guccione: return 0.5 * l.guccione_c_pa * std::max(l.guccione_b_t, 1e-3);
    case LawKind::holzapfel_ogden: return l.ho_a_pa;
  }
  return 0;
}

void read_constants(const CheckedMap& m, LawParameters& l) {
  auto set = [&](const char* key, double& field) {
    if (m.has(key)) field = m.number(key);
  };
  switch (l.kind) {
    case LawKind::neo_hookean:
      if (m.has("mu") == (m.has("E") || m.has("nu"))) m.fail("neo_hookean needs mu (with bulk_modulus), or E and nu");
      set("mu", l.mu_pa);
      if (m.has("E") || m.has("nu")) {
        if (!m.has("E") || !m.has("nu")) m.fail("neo_hookean's E goes with nu");
        const double E = m.number("E", 0, HUGE_VAL, true), nu = m.number("nu", -1, 0.5, true);
        if (nu >= 0.5) m.fail("nu must be below 0.5 (use incompressible: true for 0.5)");
        l.mu_pa = E / (2 * (1 + nu));
        if (m.has("bulk_modulus")) m.fail("give bulk_modulus or E and nu, not both");
        l.bulk_modulus_pa = E / (3 * (1 - 2 * nu));
      }
      break;
    case LawKind::guccione:
      set("C", l.guccione_c_pa), set("b_f", l.guccione_b_f), set("b_t", l.guccione_b_t), set("b_fs", l.guccione_b_fs);
      break;
    case LawKind::holzapfel_ogden:
      set("a", l.ho_a_pa), set("b", l.ho_b), set("a_f", l.ho_a_f_pa), set("b_f", l.ho_b_f);
      set("a_s", l.ho_a_s_pa), set("b_s", l.ho_b_s), set("a_fs", l.ho_a_fs_pa), set("b_fs", l.ho_b_fs);
      break;
  }
}

}  // namespace

const std::vector<std::string>& law_material_keys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> all;
    for (LawKind kind : {LawKind::neo_hookean, LawKind::guccione, LawKind::holzapfel_ogden})
      for (const std::string& k : law_keys(kind))
        if (std::find(all.begin(), all.end(), k) == all.end()) all.push_back(k);
    return all;
  }();
  return keys;
}

double default_bulk_modulus(const LawParameters& law) { return kDefaultBulkFactor * shear_scale(law); }

core::Material read_law_material(const Checks& checks, const YAML::Node& node, const std::string& path, MaterialSpec& spec) {
  const YAML::Node law_node = node.IsMap() ? node["law"] : YAML::Node();
  if (!law_node || !law_node.IsScalar()) checks.fail(node, path + ".law", "expected one of neo_hookean, guccione, holzapfel_ogden");
  const std::string name = law_node.as<std::string>();
  const auto it = std::find(kLawNames.begin(), kLawNames.end(), name);
  if (it == kLawNames.end())
    checks.fail(law_node, path + ".law", "'" + name + "' is not a law (available: neo_hookean, guccione, holzapfel_ogden)");
  LawParameters l;
  l.kind = static_cast<LawKind>(it - kLawNames.begin());
  // The same law again keeps the constants a command does not name.
  if (spec.law && spec.law->kind == l.kind) l = *spec.law;
  const CheckedMap m(checks, node, path, law_keys(l.kind));
  MaterialSpec s = spec;
  if (m.has("density")) s.density_kg_m3 = m.number("density", 0, HUGE_VAL, true);
  if (!(s.density_kg_m3 > 0)) m.fail("needs density (kg/m^3)");
  read_constants(m, l);
  if (m.has("incompressible")) l.incompressible = m.boolean("incompressible");
  if (m.has("bulk_modulus")) l.bulk_modulus_pa = m.number("bulk_modulus", 0, HUGE_VAL, true);
  if (!l.incompressible && !(l.bulk_modulus_pa > 0)) l.bulk_modulus_pa = default_bulk_modulus(l);
  try {
    l.validate();
    const core::Material linear = linearised_material(l, s.density_kg_m3);
    s.law = l;
    s.form = std::monostate{};
    spec = s;
    return linear;
  } catch (const std::invalid_argument& e) {
    m.fail(e.what());
  }
}

void write_law(const LawParameters& l, YAML::Node& n) {
  n["law"] = kLawNames[static_cast<size_t>(l.kind)];
  switch (l.kind) {
    case LawKind::neo_hookean: n["mu"] = l.mu_pa; break;
    case LawKind::guccione:
      n["C"] = l.guccione_c_pa, n["b_f"] = l.guccione_b_f, n["b_t"] = l.guccione_b_t, n["b_fs"] = l.guccione_b_fs;
      break;
    case LawKind::holzapfel_ogden:
      n["a"] = l.ho_a_pa, n["b"] = l.ho_b, n["a_f"] = l.ho_a_f_pa, n["b_f"] = l.ho_b_f;
      n["a_s"] = l.ho_a_s_pa, n["b_s"] = l.ho_b_s, n["a_fs"] = l.ho_a_fs_pa, n["b_fs"] = l.ho_b_fs;
      break;
  }
  n["incompressible"] = l.incompressible;
  if (!l.incompressible) n["bulk_modulus"] = l.bulk_modulus_pa;
}

// The small-strain stiffness is the law's tangent dP/dF at F = I (where P = 0, so the
// geometric part vanishes), read in a frame with the fiber along z (core::Material's
// convention); an incompressible law takes kLinearisedBulkFactor times its shear modulus
// for its bulk part.
core::Material linearised_material(const LawParameters& law, double density_kg_m3) {
  using core::hyperelastic::Response;
  const core::hyperelastic::MaterialAxes axes{core::Vec3::UnitZ(), core::Vec3::UnitX(), core::Vec3::UnitY()};
  Response r = core::hyperelastic::isochoric_response(law, axes, core::Mat3::Identity(), true);
  const double kappa = law.incompressible ? kLinearisedBulkFactor * shear_scale(law) : law.bulk_modulus_pa;
  const core::hyperelastic::Volumetric v = core::hyperelastic::volumetric_penalty(kappa, 1.0);
  core::hyperelastic::add_volumetric_stress(v.dU, v.d2U, core::Mat3::Identity(), r, true);
  // A(i + 3 J, k + 3 L) = C_iJkL at F = I.
  auto c = [&](int i, int j, int k, int l) { return r.A(i + 3 * j, k + 3 * l); };
  const core::StiffnessConstants k{c(0, 0, 0, 0), c(0, 0, 1, 1), c(0, 0, 2, 2), c(2, 2, 2, 2), c(0, 2, 0, 2)};
  return core::Material::from_stiffness(k, density_kg_m3);
}

}  // namespace fiberfem::io
