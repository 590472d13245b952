#include "idl/records.hpp"

#include "idl/bus.hpp"

#include <stdexcept>

namespace fiberfem::dds {
namespace {

template <class V, class Seq>
std::vector<V> copy(const Seq& s) {
  return std::vector<V>(s._buffer, s._buffer + s._length);
}

}  // namespace

// The topology's sequences (region_names apart), in IDL order: field, element type, and
// the C sequence type, for both directions.
#define FIBERFEM_TOPOLOGY_SEQUENCES(X)                                                            \
  X(rest_positions, float, dds_sequence_float) X(tets, int32_t, dds_sequence_int32)               \
  X(triangles, int32_t, dds_sequence_int32) X(triangle_elements, int32_t, dds_sequence_int32)     \
  X(element_regions, int16_t, dds_sequence_int16) X(fibers, float, dds_sequence_float)            \
  X(state_nodes, int32_t, dds_sequence_int32) X(fixed_nodes, int32_t, dds_sequence_int32)
#define FIBERFEM_TOPOLOGY_SCALARS(X) X(replay) X(num_nodes) X(num_elements)
#define FIBERFEM_TOPOLOGY_STRINGS(X) X(run_id) X(scene_name) X(scene_hash)
#define FIBERFEM_COPY(f) r.f = s.f;
#define FIBERFEM_COPY_STR(f) r.f = str(s.f);
#define FIBERFEM_SET(f) s.f = b.f;
#define FIBERFEM_BORROW_STR(f) s.f = b.f.data();
#define FIBERFEM_COPY_SEQ(f, V, Seq) r.f = copy<V>(s.f);
#define FIBERFEM_BORROW_SEQ(f, V, Seq) s.f = borrow<Seq>(b.f);

Topology to_record(const fiberfem_MeshTopology& s) {
  Topology r;
  FIBERFEM_TOPOLOGY_STRINGS(FIBERFEM_COPY_STR)
  FIBERFEM_TOPOLOGY_SCALARS(FIBERFEM_COPY)
  FIBERFEM_TOPOLOGY_SEQUENCES(FIBERFEM_COPY_SEQ)
  for (uint32_t i = 0; i < s.region_names._length; ++i) r.region_names.push_back(str(s.region_names._buffer[i]));
  return r;
}

void with_sample(const Topology& record, const std::function<void(const fiberfem_MeshTopology&)>& write) {
  Topology b = record;  // the sample borrows these buffers (DDS takes non-const pointers)
  std::vector<char*> names;
  for (auto& n : b.region_names) names.push_back(n.data());
  fiberfem_MeshTopology s{};
  FIBERFEM_TOPOLOGY_STRINGS(FIBERFEM_BORROW_STR)
  FIBERFEM_TOPOLOGY_SCALARS(FIBERFEM_SET)
  FIBERFEM_TOPOLOGY_SEQUENCES(FIBERFEM_BORROW_SEQ)
  s.region_names = borrow<dds_sequence_string>(names);
  write(s);
}

// The status's scalar fields, in IDL order, for both directions (strings apart).
#define FIBERFEM_STATUS_SCALARS(X)                                                                  \
  X(pid) X(replay) X(frame) X(time_s) X(frames_per_second) X(real_time_factor) X(step_ms)           \
  X(rotations_ms) X(assembly_ms) X(solve_ms) X(publish_ms) X(record_ms) X(solver_iterations)        \
  X(solver_residual) X(inverted_elements) X(kinetic_energy_j) X(elastic_energy_j) X(recovered_steps) \
  X(failed_steps) X(parameter_version) X(heart_rate_bpm) X(peak_tension_pa) X(dt_s) X(recorded_frames)
#define FIBERFEM_STATUS_STRINGS(X) X(run_id) X(scene_name) X(host) X(state) X(mode) X(last_message) X(recording)

Status to_record(const fiberfem_ServiceStatus& s) {
  Status r;
  FIBERFEM_STATUS_SCALARS(FIBERFEM_COPY)
  FIBERFEM_STATUS_STRINGS(FIBERFEM_COPY_STR)
  return r;
}

void with_sample(const Status& record, const std::function<void(const fiberfem_ServiceStatus&)>& write) {
  Status b = record;
  fiberfem_ServiceStatus s{};
  FIBERFEM_STATUS_SCALARS(FIBERFEM_SET)
  FIBERFEM_STATUS_STRINGS(FIBERFEM_BORROW_STR)
  write(s);
}

// The circulation's members after run_id and frame, in IDL order (the snapshot's columns).
#define FIBERFEM_CIRCULATION_MEMBERS(X) \
  X(time_s) X(la_pressure_pa) X(la_volume_m3) X(systemic_arterial_pressure_pa) \
  X(systemic_arterial_flow_m3_s) X(mitral_flow_m3_s) X(lv_pressure_pa) X(lv_volume_m3) \
  X(systemic_venous_pressure_pa) X(systemic_venous_flow_m3_s) X(aortic_flow_m3_s) X(ra_pressure_pa) \
  X(ra_volume_m3) X(pulmonary_arterial_pressure_pa) X(pulmonary_arterial_flow_m3_s) \
  X(tricuspid_flow_m3_s) X(rv_pressure_pa) X(rv_volume_m3) X(pulmonary_venous_pressure_pa) \
  X(pulmonary_venous_flow_m3_s) X(pulmonary_valve_flow_m3_s) X(pressure_iterations) \
  X(blood_volume_m3) X(beat) X(beat_start_s) X(lv_end_diastolic_volume_m3) \
  X(lv_end_systolic_volume_m3) X(lv_stroke_volume_m3) X(lv_ejection_fraction) \
  X(lv_peak_pressure_pa) X(lv_end_diastolic_pressure_pa) X(rv_end_diastolic_volume_m3) \
  X(rv_end_systolic_volume_m3) X(rv_stroke_volume_m3) X(rv_ejection_fraction) \
  X(rv_peak_pressure_pa) X(rv_end_diastolic_pressure_pa) X(systemic_arterial_max_pa) \
  X(systemic_arterial_min_pa) X(pulmonary_arterial_max_pa) X(pulmonary_arterial_min_pa)

const std::vector<std::string>& circulation_members() {
#define FIBERFEM_NAME(f) #f,
  static const std::vector<std::string> names{FIBERFEM_CIRCULATION_MEMBERS(FIBERFEM_NAME)};
#undef FIBERFEM_NAME
  return names;
}

Circulation to_record(const fiberfem_CirculationState& s) {
  const std::vector<double> numbers{
#define FIBERFEM_NUMBER(f) static_cast<double>(s.f),
      FIBERFEM_CIRCULATION_MEMBERS(FIBERFEM_NUMBER)
#undef FIBERFEM_NUMBER
  };
  return {str(s.run_id), s.frame, core::circulation::from_columns(circulation_members(), numbers.data())};
}

void with_sample(const Circulation& record, const std::function<void(const fiberfem_CirculationState&)>& write) {
  static const bool same_order = circulation_members() == core::circulation::snapshot_columns();
  if (!same_order) throw std::logic_error("idl/circulation.idl's members differ from core::circulation::snapshot_columns()");
  const std::vector<double> numbers = core::circulation::to_columns(record.snapshot);
  std::string run_id = record.run_id;
  fiberfem_CirculationState s{};
  s.run_id = run_id.data();
  s.frame = record.frame;
  size_t i = 0;
#define FIBERFEM_SET_NUMBER(f) s.f = static_cast<decltype(s.f)>(numbers[i++]);
  FIBERFEM_CIRCULATION_MEMBERS(FIBERFEM_SET_NUMBER)
#undef FIBERFEM_SET_NUMBER
  write(s);
}

#undef FIBERFEM_CIRCULATION_MEMBERS

#undef FIBERFEM_COPY
#undef FIBERFEM_COPY_STR
#undef FIBERFEM_BORROW_STR
#undef FIBERFEM_SET
#undef FIBERFEM_STATUS_SCALARS
#undef FIBERFEM_STATUS_STRINGS
#undef FIBERFEM_COPY_SEQ
#undef FIBERFEM_BORROW_SEQ
#undef FIBERFEM_TOPOLOGY_SEQUENCES
#undef FIBERFEM_TOPOLOGY_SCALARS
#undef FIBERFEM_TOPOLOGY_STRINGS

}  // namespace fiberfem::dds
