// contraction (docs/scenes.md): read onto a ContractionSpec, built into core::Contraction
// for the mesh (per-region tensions by name, pacing delays per element), and written back.

#include "io/scene_internal.hpp"

#include <algorithm>

namespace fiberfem::io {

namespace {

void read_twitch(const CheckedMap& c, ContractionSpec& s) {
  const CheckedMap t(c.checks(), c["twitch"], "contraction.twitch", {"shape", "tau1", "tau2", "systole"});
  if (t.has("shape"))
    s.twitch.shape = t.choice("shape", {"biexponential", "sine"}) == "sine" ? core::TwitchShape::sine
                                                                            : core::TwitchShape::biexponential;
  if (t.has("tau1")) s.twitch.tau1_s = t.number("tau1", 0, 10, true);
  if (t.has("tau2")) s.twitch.tau2_s = t.number("tau2", 0, 10, true);
  if (t.has("systole")) s.twitch.systole_s = t.number("systole", 0, 60, true);
}

void read_region_peaks(const CheckedMap& c, const std::vector<std::string>& region_names, ContractionSpec& s) {
  const Checks& checks = c.checks();
  const YAML::Node r = c["regions"];
  if (!r.IsMap() || r.size() == 0) checks.fail(r, "contraction.regions", "expected a non-empty mapping region name: peak tension (Pa)");
  s.region_peak_pa.clear();
  for (const auto& kv : r) {
    const std::string name = checks.text(kv.first, "contraction.regions");
    if (std::find(region_names.begin(), region_names.end(), name) == region_names.end())
      checks.fail(kv.first, "contraction.regions." + name, "no region of that name (regions: " + join(region_names) + ")");
    s.region_peak_pa.emplace_back(name, checks.number(kv.second, "contraction.regions." + name, 0, 1e9));
  }
}

core::Contraction build(const ContractionSpec& s, const core::TetMesh& mesh, const std::vector<std::string>& region_names) {
  core::Contraction con;
  con.mode = s.mode;
  if (s.heart_rate_bpm) con.period_s = 60.0 / *s.heart_rate_bpm;
  if (s.period_s) con.period_s = *s.period_s;
  con.twitch = s.twitch;
  con.region_peak_pa.assign(static_cast<size_t>(mesh.num_regions()), s.peak_tension_pa.value_or(0.0));
  for (const auto& [name, peak] : s.region_peak_pa)
    con.region_peak_pa[static_cast<size_t>(std::find(region_names.begin(), region_names.end(), name) - region_names.begin())] = peak;
  if (s.pacing) con.element_delay_s = core::pacing_delays(mesh.rest_positions(), mesh.tets(), s.pacing->at_m, s.pacing->speed_m_s);
  return con;
}

}  // namespace

core::Contraction read_contraction(const Checks& checks, const YAML::Node& node, const core::TetMesh& mesh,
                                   const std::vector<std::string>& region_names, ContractionSpec& spec) {
  const CheckedMap c(checks, node, "contraction", {"mode", "peak_tension", "heart_rate", "period", "twitch", "regions", "pacing"});
  ContractionSpec s = spec;
  if (c.has("mode"))
    s.mode = c.choice("mode", {"active_stress", "nodal_forces"}) == "nodal_forces" ? core::ContractionMode::nodal_forces
                                                                                   : core::ContractionMode::active_stress;
  if (c.has("heart_rate") && c.has("period")) c.fail("give heart_rate or period, not both");
  if (c.has("heart_rate")) s.heart_rate_bpm = c.number("heart_rate", 1, 600), s.period_s.reset();
  if (c.has("period")) s.period_s = c.number("period", 0.05, 60), s.heart_rate_bpm.reset();
  if (c.has("twitch")) read_twitch(c, s);
  if (c.has("peak_tension")) s.peak_tension_pa = c.number("peak_tension", 0, 1e9);
  if (c.has("peak_tension") && !c.has("regions")) s.region_peak_pa.clear();
  if (c.has("regions")) read_region_peaks(c, region_names, s);
  if (!s.peak_tension_pa && s.region_peak_pa.empty()) c.fail("needs peak_tension (Pa) or regions");
  if (c.has("pacing")) {
    const CheckedMap p(checks, c["pacing"], "contraction.pacing", {"at", "speed"});
    if (!p.has("at") || !p.has("speed")) p.fail("needs at: [x, y, z] and speed (m/s)");
    s.pacing = PacingSpec{p.vec3("at"), p.number("speed", 0, 1e3, true)};
  }
  const YAML::Node twitch_at = c.has("twitch") ? c["twitch"] : node;
  try {
    s.twitch.validate();
  } catch (const std::invalid_argument& e) {
    checks.fail(twitch_at, "contraction.twitch", e.what());
  }
  core::Contraction con = build(s, mesh, region_names);
  if (con.twitch.shape == core::TwitchShape::sine && con.twitch.systole_s > con.period_s)
    checks.fail(twitch_at, "contraction.twitch.systole", "is longer than the period");
  try {
    con.validate(mesh.num_regions(), mesh.num_elements());
  } catch (const std::invalid_argument& e) {
    c.fail(e.what());
  }
  spec = s;
  return con;
}

YAML::Node write_contraction(const ContractionSpec& s) {
  YAML::Node n(YAML::NodeType::Map);
  n["mode"] = core::to_string(s.mode);
  if (s.heart_rate_bpm) n["heart_rate"] = *s.heart_rate_bpm;
  if (s.period_s) n["period"] = *s.period_s;
  YAML::Node t(YAML::NodeType::Map);
  t["shape"] = core::to_string(s.twitch.shape);
  t["tau1"] = s.twitch.tau1_s;
  t["tau2"] = s.twitch.tau2_s;
  t["systole"] = s.twitch.systole_s;
  n["twitch"] = t;
  if (s.peak_tension_pa) n["peak_tension"] = *s.peak_tension_pa;
  if (!s.region_peak_pa.empty()) {
    YAML::Node r(YAML::NodeType::Map);
    for (const auto& [name, peak] : s.region_peak_pa) r[name] = peak;
    n["regions"] = r;
  }
  if (s.pacing) {
    YAML::Node p(YAML::NodeType::Map);
    p["at"] = detail::flow_vec3(s.pacing->at_m);
    p["speed"] = s.pacing->speed_m_s;
    n["pacing"] = p;
  }
  return n;
}

}  // namespace fiberfem::io
