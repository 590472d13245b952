#pragma once
/// @file The run's topology, status and circulation as C++ values, one record each for the
/// services that publish them and the clients that read them, and their conversions to and
/// from the wire types of idl/mesh.idl, idl/status.idl and idl/circulation.idl (field for
/// field, same names).

#include "core/circulation/snapshot.hpp"

#include "circulation.h"
#include "mesh.h"
#include "status.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace fiberfem::dds {

/// fiberfem::MeshTopology (idl/mesh.idl): the rest mesh, regions and fibers of a run.
struct Topology {
  std::string run_id, scene_name, scene_hash;  ///< scene_hash: SHA-256 of the scene, hex.
  bool replay = false;                         ///< Republished from an archive.
  uint32_t num_nodes = 0, num_elements = 0;
  std::vector<float> rest_positions;  ///< 3 per node, m, node-major.
  std::vector<int32_t> tets;          ///< 4 per element.
  std::vector<int32_t> triangles;     ///< 3 per boundary triangle, outward counter-clockwise.
  std::vector<int32_t> triangle_elements;  ///< The element of each boundary triangle.
  std::vector<int16_t> element_regions;    ///< Per element, into region_names.
  std::vector<std::string> region_names;
  std::vector<float> fibers;           ///< 3 per element, unit.
  std::vector<int32_t> state_nodes;    ///< Nodes a state carries; empty: all.
  std::vector<int32_t> fixed_nodes;    ///< Nodes with a fixed component.
};

/// fiberfem::ServiceStatus (idl/status.idl): the health of a run; units in the IDL.
struct Status {
  std::string run_id, scene_name, host;
  int32_t pid = 0;
  std::string state, mode;  ///< state: starting | running | paused | ...; mode: realtime | fast | replay.
  bool replay = false;
  uint64_t frame = 0;
  double time_s = 0, frames_per_second = 0, real_time_factor = 0;
  double step_ms = 0, rotations_ms = 0, assembly_ms = 0, solve_ms = 0, publish_ms = 0, record_ms = 0;
  int32_t solver_iterations = 0;
  double solver_residual = 0;
  int32_t inverted_elements = 0;
  double kinetic_energy_j = 0, elastic_energy_j = 0;
  uint32_t recovered_steps = 0, failed_steps = 0;
  std::string last_message;
  uint32_t parameter_version = 0;
  double heart_rate_bpm = 0, peak_tension_pa = 0, dt_s = 0;
  std::string recording;  ///< Archive path, "" when not recording.
  uint64_t recorded_frames = 0;
};

/// fiberfem::CirculationState (idl/circulation.idl): a run's circulation at one frame.
struct Circulation {
  std::string run_id;
  uint64_t frame = 0;  ///< The state's frame it goes with.
  core::circulation::Snapshot snapshot;
};

/// The wire type's members after run_id and frame, in IDL order: equal to
/// core::circulation::snapshot_columns() (tests/idl/circulation_record_test.cpp).
const std::vector<std::string>& circulation_members();

/// Copies a received sample out of DDS.
Topology to_record(const fiberfem_MeshTopology& sample);
Status to_record(const fiberfem_ServiceStatus& sample);
Circulation to_record(const fiberfem_CirculationState& sample);

/// Calls `write` with a sample whose strings and sequences borrow `record`'s buffers (valid
/// during the call only).
void with_sample(const Topology& record, const std::function<void(const fiberfem_MeshTopology&)>& write);
void with_sample(const Status& record, const std::function<void(const fiberfem_ServiceStatus&)>& write);
void with_sample(const Circulation& record, const std::function<void(const fiberfem_CirculationState&)>& write);

}  // namespace fiberfem::dds
