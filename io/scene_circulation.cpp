// circulation (docs/circulation.md): the lumped closed-loop circulation, its parameters in
// mmHg, mL and s (the units of the physiology literature), which measured cavity is which
// ventricle, read into core::Model::circulation in SI units.

#include "io/scene_internal.hpp"

#include <algorithm>
#include <cmath>

namespace fiberfem::io {
namespace detail {

namespace {

namespace cc = core::circulation;
constexpr double kMmHg = cc::kPaPerMmHg;
constexpr double kMl = cc::kM3PerMl;
constexpr double kR = kMmHg / kMl;  // mmHg s/mL (and mmHg/mL, mmHg s^2/mL) in SI

const char* const kChamberKeys[4] = {"left_atrium", "left_ventricle", "right_atrium", "right_ventricle"};
const char* const kValveKeys[4] = {"mitral", "aortic", "tricuspid", "pulmonary"};

void read_chamber(const CheckedMap& cm, const std::string& key, cc::Chamber& ch) {
  const CheckedMap c(cm.checks(), cm[key], cm.sub(key),
                     {"active_elastance", "passive_elastance", "rest_volume", "onset", "contraction", "relaxation", "pressure"});
  if (c.has("pressure")) {
    if (c.has("active_elastance") || c.has("passive_elastance")) c.fail("give pressure (a prescribed chamber) or elastances, not both");
    ch.kind = cc::ChamberKind::prescribed;
    ch.pressure_pa = c.number("pressure", -1e3, 1e3) * kMmHg;
    return;
  }
  cc::Elastance& e = ch.elastance;
  if (c.has("active_elastance")) e.active_pa_m3 = c.number("active_elastance", 0, 1e6) * kR;
  if (c.has("passive_elastance")) e.passive_pa_m3 = c.number("passive_elastance", 0, 1e6, true) * kR;
  if (c.has("rest_volume")) e.rest_volume_m3 = c.number("rest_volume", 0, 1e5) * kMl;
  if (c.has("onset")) e.onset_s = c.number("onset", -60, 60);
  if (c.has("contraction")) e.contraction_s = c.number("contraction", 0, 60, true);
  if (c.has("relaxation")) e.relaxation_s = c.number("relaxation", 0, 60, true);
}

void read_compartment(const CheckedMap& side, const std::string& key, cc::Compartment& k) {
  const CheckedMap c(side.checks(), side[key], side.sub(key), {"resistance", "compliance", "inertance"});
  if (c.has("resistance")) k.resistance_pa_s_m3 = c.number("resistance", 0, 1e6, true) * kR;
  if (c.has("compliance")) k.compliance_m3_pa = c.number("compliance", 0, 1e6, true) / kR;
  if (c.has("inertance")) k.inertance_pa_s2_m3 = c.number("inertance", 0, 1e6) * kR;
}

void read_loop(const CheckedMap& c, cc::Parameters& p) {
  if (c.has("chambers")) {
    const CheckedMap cm(c.checks(), c["chambers"], c.sub("chambers"),
                        {kChamberKeys[0], kChamberKeys[1], kChamberKeys[2], kChamberKeys[3]});
    for (int i = 0; i < 4; ++i)
      if (cm.has(kChamberKeys[i])) read_chamber(cm, kChamberKeys[i], p.chambers[static_cast<size_t>(i)]);
  }
  if (c.has("valves")) {
    const CheckedMap vm(c.checks(), c["valves"], c.sub("valves"), {kValveKeys[0], kValveKeys[1], kValveKeys[2], kValveKeys[3]});
    for (int i = 0; i < 4; ++i) {
      if (!vm.has(kValveKeys[i])) continue;
      const CheckedMap v(c.checks(), vm[kValveKeys[i]], vm.sub(kValveKeys[i]), {"R_min", "R_max"});
      cc::Valve& valve = p.valves[static_cast<size_t>(i)];
      if (v.has("R_min")) valve.r_min_pa_s_m3 = v.number("R_min", 0, 1e12, true) * kR;
      if (v.has("R_max")) valve.r_max_pa_s_m3 = v.number("R_max", 0, 1e12, true) * kR;
      if (!(valve.r_min_pa_s_m3 < valve.r_max_pa_s_m3))
        v.fail("R_min must be below R_max, or the valve never opens (R_min " + std::to_string(valve.r_min_pa_s_m3 / kR) +
               ", R_max " + std::to_string(valve.r_max_pa_s_m3 / kR) + " mmHg s/mL)");
    }
  }
  for (const char* side : {"systemic", "pulmonary"}) {
    if (!c.has(side)) continue;
    const CheckedMap s(c.checks(), c[side], c.sub(side), {"arteries", "veins"});
    const int base = std::string(side) == "systemic" ? cc::ar_sys : cc::ar_pul;
    if (s.has("arteries")) read_compartment(s, "arteries", p.compartments[static_cast<size_t>(base)]);
    if (s.has("veins")) read_compartment(s, "veins", p.compartments[static_cast<size_t>(base + 1)]);
  }
}

void read_initial(const CheckedMap& c, cc::State& s) {
  const CheckedMap in(c.checks(), c["initial"], "circulation.initial",
                      {"left_atrium", "left_ventricle", "right_atrium", "right_ventricle", "systemic_arteries",
                       "systemic_veins", "pulmonary_arteries", "pulmonary_veins"});
  for (int i = 0; i < 4; ++i)
    if (in.has(kChamberKeys[i])) s.volume_m3[static_cast<size_t>(i)] = in.number(kChamberKeys[i], 0, 1e5) * kMl;
  const char* const pressures[4] = {"systemic_arteries", "systemic_veins", "pulmonary_arteries", "pulmonary_veins"};
  for (int k = 0; k < 4; ++k)
    if (in.has(pressures[k])) s.pressure_pa[static_cast<size_t>(k)] = in.number(pressures[k], -1e3, 1e3) * kMmHg;
}

// A coupled cavity's rim must be fixed: otherwise the pressure does not work on the volume
// it measures (the lid across the rim would move).
void check_closed(const CheckedMap& v, const std::string& key, const CavityMeasure& cav, const core::Model& model) {
  const int open = core::open_rim_nodes(cav.surface, model.fixed_dofs);
  if (open > 0)
    v.checks().fail(v[key], v.sub(key),
                    "cavity '" + cav.name + "' is not closed: " + std::to_string(open) + " of the " +
                        std::to_string(cav.surface.rim_nodes.size()) +
                        " nodes of its rim are not fixed (fix its base, key fixed, so that the pressure works on its volume)");
}

void read_ventricles(const CheckedMap& c, const std::vector<CavityMeasure>& cavities, const core::Model& model,
                     cc::Coupling& coupling) {
  const CheckedMap v(c.checks(), c["ventricles"], "circulation.ventricles", {"left", "right"});
  std::vector<std::string> names;
  for (const CavityMeasure& m : cavities) names.push_back(m.name);
  for (const char* key : {"left", "right"}) {
    if (!v.has(key)) continue;
    const std::string name = v.text(key);
    const auto it = std::find_if(cavities.begin(), cavities.end(), [&](const CavityMeasure& m) { return m.name == name; });
    if (it == cavities.end())
      v.checks().fail(v[key], v.sub(key),
                      "'" + name + "' is not a measured cavity (measure.cavities: " + (names.empty() ? "none" : join(names)) + ")");
    check_closed(v, key, *it, model);
    coupling.cavities.push_back({std::string(key) == "left" ? cc::lv : cc::rv, name, it->surface});
  }
  if (coupling.cavities.empty()) v.fail("needs left and/or right: the measured cavities that are the ventricles");
  if (coupling.cavities.size() == 2 && coupling.cavities[0].name == coupling.cavities[1].name)
    v.fail("left and right name the same cavity");
}

}  // namespace

void read_circulation(const CheckedMap& top, const std::vector<CavityMeasure>& cavities, bool accurate, core::Model& model) {
  const Checks& checks = top.checks();
  const CheckedMap c(checks, top["circulation"], "circulation", circulation_keys());
  if (!c.has("ventricles")) c.fail("needs ventricles: {left: CAVITY, right: CAVITY} (names from measure.cavities)");
  cc::Coupling coupling;
  read_ventricles(c, cavities, model, coupling);
  model.circulation.cavities = coupling.cavities;  // the loop's reader makes their chambers external
  coupling.parameters = read_circulation_loop(c, model);
  if (c.has("initial")) read_initial(c, coupling.initial);
  if (c.has("scale")) {
    const CheckedMap s(checks, c["scale"], "circulation.scale", {"pressure", "volume"});
    const double ps = s.has("pressure") ? s.number("pressure", 0, 1e3, true) : 1.0;
    const double vs = s.has("volume") ? s.number("volume", 0, 1e3, true) : 1.0;
    for (double& v : coupling.initial.volume_m3) v *= vs;
    for (double& pr : coupling.initial.pressure_pa) pr *= ps;
    for (double& q : coupling.initial.flow_m3_s) q *= vs;
  }
  // The accurate tier's cavity volumes are as exact as its Newton solves (a relative
  // residual of 1e-9 leaves about 1e-8 of the volume): its default is looser.
  if (accurate) coupling.volume_tolerance = kAccurateVolumeTolerance;
  if (c.has("volume_tolerance")) coupling.volume_tolerance = c.number("volume_tolerance", 0, 1e-3, true);
  if (c.has("max_iterations")) coupling.max_iterations = c.integer("max_iterations", 1, 200);
  model.circulation = std::move(coupling);
}

}  // namespace detail

namespace cc = core::circulation;

const std::vector<std::string>& circulation_keys() {
  static const std::vector<std::string> keys = {"ventricles", "heart_rate", "scale",   "chambers",         "valves",
                                                "systemic",   "pulmonary",  "initial", "volume_tolerance", "max_iterations"};
  return keys;
}

core::circulation::Parameters read_circulation_loop(const CheckedMap& c, const core::Model& model) {
  cc::Parameters p;
  // The loop beats with the contraction unless told otherwise.
  if (c.has("heart_rate")) p.period_s = 60.0 / c.number("heart_rate", 1, 600);
  else if (model.contraction.enabled()) p.period_s = model.contraction.period_s;
  detail::read_loop(c, p);
  if (c.has("scale")) {
    const CheckedMap s(c.checks(), c["scale"], c.sub("scale"), {"pressure", "volume"});
    p.scale(s.has("pressure") ? s.number("pressure", 0, 1e3, true) : 1.0, s.has("volume") ? s.number("volume", 0, 1e3, true) : 1.0);
  }
  for (const cc::CoupledCavity& cav : model.circulation.cavities)
    p.chambers[static_cast<size_t>(cav.chamber)].kind = cc::ChamberKind::external;
  try {
    p.validate();
  } catch (const std::invalid_argument& e) {
    // "circulation: systemic.veins.compliance must be > 0" names the key already.
    const std::string what = std::string(e.what()).substr(std::string("circulation: ").size());
    if (c.checks().dialect() == Dialect::arguments) throw ArgumentError(what);
    c.fail(what);
  }
  return p;
}

}  // namespace fiberfem::io
