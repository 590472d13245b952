#pragma once
/// @file The circulation of a run after a step as every output shows it (the service's
/// circulation topic, the archive's frames, the report's per-step columns, the renderer's
/// pressure-volume inset): chamber pressures and volumes, compartment pressures and flows,
/// valve flows, the pressure iterations, the blood volume and the figures of the last
/// complete beat. SI units (Pa, m^3, s).

#include "core/circulation/beat_metrics.hpp"
#include "core/circulation/coupling.hpp"

#include <array>
#include <string>
#include <vector>

namespace fiberfem::core::circulation {

/// The last complete beat's figures before any beat is complete: index -1.
inline Beat no_beat() {
  Beat b;
  b.index = -1;
  return b;
}

struct Snapshot {
  double time_s = 0;                                 ///< Simulation time, s.
  std::array<double, 4> chamber_pressure_pa{};       ///< By ChamberId, Pa.
  std::array<double, 4> chamber_volume_m3{};         ///< By ChamberId (a coupled ventricle: its cavity's), m^3.
  std::array<double, 4> compartment_pressure_pa{};   ///< By CompartmentId, Pa.
  std::array<double, 4> compartment_flow_m3_s{};     ///< By CompartmentId (out of it, downstream), m^3/s.
  std::array<double, 4> valve_flow_m3_s{};           ///< By ValveId, m^3/s.
  int pressure_iterations = 0;                       ///< Newton iterations on the cavity pressures in the step.
  double blood_volume_m3 = 0;                        ///< total_volume() of the loop, m^3.
  /// The last complete beat (every step of its period seen); index -1 until one is.
  Beat last_beat = no_beat();
};

/// The loop's state `s` after a step as a snapshot: the chamber pressures and valve flows
/// it implies (observe()), the coupled ventricles' volumes replaced by the mesh's cavity
/// volumes (`cavity_volumes_m3`, in `coupling.cavities` order; they equal the loop's to
/// the coupling's tolerance). The last beat is left as none.
Snapshot observe_snapshot(const Coupling& coupling, const State& s, const std::vector<double>& cavity_volumes_m3, int iterations);

/// What the beat figures read of a snapshot (ventricle volumes and pressures, arterial
/// pressures).
Sample beat_sample(const Snapshot& s);

/// The snapshot's numbers by name, in one fixed order: the archive's columns
/// (`/frames/circulation`), the members of the wire type (idl/circulation.idl, after
/// run_id and frame) and, up to kStepColumns, the report's per-step columns.
const std::vector<std::string>& snapshot_columns();
/// The leading columns that are per-step values (time to pressure_iterations); the rest are
/// the blood volume and the last beat's figures.
inline constexpr size_t kStepColumns = 22;
/// The numbers of `s` in snapshot_columns() order.
std::vector<double> to_columns(const Snapshot& s);
/// A snapshot from numbers under `names` (as an archive stored them): names not known are
/// skipped, columns not given keep their defaults. Precondition: `values` has names.size().
Snapshot from_columns(const std::vector<std::string>& names, const double* values);

/// Follows a run step by step: the snapshot of its current state, with the figures of the
/// last complete beat (beats of the loop's period counted from the loop's beat origin:
/// time zero, or the start of the beat under way when the heart rate last changed).
class Monitor {
 public:
  /// Takes the state after a step (`after_step`; its sample counts for the beats) or the
  /// state a run starts from (not counted, as the report's beats do not) and returns its
  /// snapshot. A time not after the last one's (a reset, a restore) or a new period (a
  /// heart rate changed) starts the beats afresh; the beat under way then is partial.
  /// `dt_s`: the step, s (a beat is complete when its samples span its period).
  const Snapshot& update(const Coupling& coupling, const State& s, const std::vector<double>& cavity_volumes_m3, int iterations,
                         double dt_s, bool after_step);
  /// The last update's snapshot.
  const Snapshot& snapshot() const { return current_; }

 private:
  Snapshot current_;
  BeatRecorder beats_{1.0, 0.0};
  double period_s_ = 0, last_time_s_ = -1;
  size_t beats_seen_ = 0;
};

}  // namespace fiberfem::core::circulation
