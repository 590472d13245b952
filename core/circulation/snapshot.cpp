#include "core/circulation/snapshot.hpp"

#include <functional>
#include <unordered_map>

namespace fiberfem::core::circulation {
namespace {

// One column: its name and how it is read from and written into a snapshot.
struct Column {
  std::string name;
  std::function<double(const Snapshot&)> get;
  std::function<void(Snapshot&, double)> set;
};

template <class T>
Column member(std::string name, T Snapshot::*m) {
  return {std::move(name), [m](const Snapshot& s) { return static_cast<double>(s.*m); },
          [m](Snapshot& s, double v) { s.*m = static_cast<T>(v); }};
}
Column element(std::string name, std::array<double, 4> Snapshot::*m, size_t i) {
  return {std::move(name), [m, i](const Snapshot& s) { return (s.*m)[i]; }, [m, i](Snapshot& s, double v) { (s.*m)[i] = v; }};
}
template <class T>
Column beat_field(std::string name, T Beat::*m) {
  return {std::move(name), [m](const Snapshot& s) { return static_cast<double>(s.last_beat.*m); },
          [m](Snapshot& s, double v) { s.last_beat.*m = static_cast<T>(v); }};
}
Column ventricle_field(std::string name, int k, double VentricleBeat::*m) {
  return {std::move(name), [k, m](const Snapshot& s) { return s.last_beat.ventricle[k].*m; },
          [k, m](Snapshot& s, double v) { s.last_beat.ventricle[k].*m = v; }};
}
Column arterial_field(std::string name, double (Beat::*m)[2], int k) {
  return {std::move(name), [m, k](const Snapshot& s) { return (s.last_beat.*m)[k]; },
          [m, k](Snapshot& s, double v) { (s.last_beat.*m)[k] = v; }};
}

// The report's names (docs/report-format.md), by ChamberId, CompartmentId and ValveId.
const char* const kChambers[4] = {"la", "lv", "ra", "rv"};
const char* const kCompartments[4] = {"systemic_arterial", "systemic_venous", "pulmonary_arterial", "pulmonary_venous"};
const char* const kValves[4] = {"mitral", "aortic", "tricuspid", "pulmonary_valve"};

std::vector<Column> make_columns() {
  std::vector<Column> c{member("time_s", &Snapshot::time_s)};
  for (size_t i = 0; i < 4; ++i) {  // per step, interleaved as the report's columns are
    const std::string ch = kChambers[i], co = kCompartments[i], va = kValves[i];
    c.push_back(element(ch + "_pressure_pa", &Snapshot::chamber_pressure_pa, i));
    c.push_back(element(ch + "_volume_m3", &Snapshot::chamber_volume_m3, i));
    c.push_back(element(co + "_pressure_pa", &Snapshot::compartment_pressure_pa, i));
    c.push_back(element(co + "_flow_m3_s", &Snapshot::compartment_flow_m3_s, i));
    c.push_back(element(va + "_flow_m3_s", &Snapshot::valve_flow_m3_s, i));
  }
  c.push_back(member("pressure_iterations", &Snapshot::pressure_iterations));
  c.push_back(member("blood_volume_m3", &Snapshot::blood_volume_m3));
  c.push_back(beat_field("beat", &Beat::index));
  c.push_back(beat_field("beat_start_s", &Beat::start_s));
  for (int k = 0; k < 2; ++k) {
    const std::string v = k == 0 ? "lv_" : "rv_";
    c.push_back(ventricle_field(v + "end_diastolic_volume_m3", k, &VentricleBeat::end_diastolic_m3));
    c.push_back(ventricle_field(v + "end_systolic_volume_m3", k, &VentricleBeat::end_systolic_m3));
    c.push_back(ventricle_field(v + "stroke_volume_m3", k, &VentricleBeat::stroke_m3));
    c.push_back(ventricle_field(v + "ejection_fraction", k, &VentricleBeat::ejection_fraction));
    c.push_back(ventricle_field(v + "peak_pressure_pa", k, &VentricleBeat::peak_pa));
    c.push_back(ventricle_field(v + "end_diastolic_pressure_pa", k, &VentricleBeat::end_diastolic_pa));
  }
  c.push_back(arterial_field("systemic_arterial_max_pa", &Beat::arterial_max_pa, 0));
  c.push_back(arterial_field("systemic_arterial_min_pa", &Beat::arterial_min_pa, 0));
  c.push_back(arterial_field("pulmonary_arterial_max_pa", &Beat::arterial_max_pa, 1));
  c.push_back(arterial_field("pulmonary_arterial_min_pa", &Beat::arterial_min_pa, 1));
  return c;
}

const std::vector<Column>& columns() {
  static const std::vector<Column> c = make_columns();
  return c;
}

}  // namespace

Snapshot observe_snapshot(const Coupling& coupling, const State& s, const std::vector<double>& cavity_volumes_m3, int iterations) {
  const Observables o = observe(coupling.parameters, s);
  Snapshot r;
  r.time_s = s.time_s;
  r.chamber_pressure_pa = o.chamber_pa;
  r.chamber_volume_m3 = s.volume_m3;
  for (size_t k = 0; k < coupling.cavities.size() && k < cavity_volumes_m3.size(); ++k)
    r.chamber_volume_m3[static_cast<size_t>(coupling.cavities[k].chamber)] = cavity_volumes_m3[k];
  r.compartment_pressure_pa = s.pressure_pa;
  r.compartment_flow_m3_s = s.flow_m3_s;
  r.valve_flow_m3_s = o.valve_m3_s;
  r.pressure_iterations = iterations;
  r.blood_volume_m3 = total_volume(coupling.parameters, s);
  return r;
}

Sample beat_sample(const Snapshot& s) {
  Sample sample;
  sample.time_s = s.time_s;
  for (int k = 0; k < 2; ++k) {
    const size_t chamber = k == 0 ? lv : rv;
    sample.volume_m3[k] = s.chamber_volume_m3[chamber];
    sample.pressure_pa[k] = s.chamber_pressure_pa[chamber];
    sample.arterial_pa[k] = s.compartment_pressure_pa[k == 0 ? ar_sys : ar_pul];
  }
  return sample;
}

const std::vector<std::string>& snapshot_columns() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const Column& c : columns()) n.push_back(c.name);
    return n;
  }();
  return names;
}

std::vector<double> to_columns(const Snapshot& s) {
  std::vector<double> v;
  v.reserve(columns().size());
  for (const Column& c : columns()) v.push_back(c.get(s));
  return v;
}

Snapshot from_columns(const std::vector<std::string>& names, const double* values) {
  static const std::unordered_map<std::string, const Column*> by_name = [] {
    std::unordered_map<std::string, const Column*> m;
    for (const Column& c : columns()) m[c.name] = &c;
    return m;
  }();
  Snapshot s;
  for (size_t i = 0; i < names.size(); ++i)
    if (const auto it = by_name.find(names[i]); it != by_name.end()) it->second->set(s, values[i]);
  return s;
}

const Snapshot& Monitor::update(const Coupling& coupling, const State& s, const std::vector<double>& cavity_volumes_m3,
                                int iterations, double dt_s, bool after_step) {
  const double period = coupling.parameters.period_s;
  const Beat last = current_.last_beat;
  current_ = observe_snapshot(coupling, s, cavity_volumes_m3, iterations);
  if (s.time_s <= last_time_s_ || period != period_s_) {  // a new run of beats: none complete yet
    // Counted from where the loop counts its beats (moved when the heart rate changed:
    // keep_beat_phase), so each window holds one beat of the loop's.
    beats_ = BeatRecorder(period, s.beat_origin_s);
    period_s_ = period;
    beats_seen_ = 0;
  } else {
    current_.last_beat = last;
  }
  last_time_s_ = s.time_s;
  if (!after_step) return current_;
  beats_.add(beat_sample(current_));
  // A beat closes when the next one's first sample arrives; it counts when its samples
  // span its period (to half a step), as the report's "complete" does.
  for (; beats_seen_ < beats_.beats().size(); ++beats_seen_) {
    const Beat& b = beats_.beats()[beats_seen_];
    if (b.samples * dt_s > period - 0.5 * dt_s) current_.last_beat = b;
  }
  return current_;
}

}  // namespace fiberfem::core::circulation
