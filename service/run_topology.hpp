#pragma once
/// @file The topology record a run publishes once (docs/dds.md MeshTopology), made the
/// same way for a live run (the running model) and a replay (the archive's header).

#include "service/run_endpoints.hpp"

#include "core/mesh.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace fiberfem::service {

/// The rest mesh, its boundary triangles and their elements, regions and their names,
/// the fiber of each element (+x where `fibers` is empty), the nodes with a fixed degree
/// of freedom (`fixed_dofs`: 3 per node, 1 = fixed; may be empty) and the nodes the
/// states carry (`state_nodes`; empty: all). The scene's name and hash, and the replay
/// flag, are the caller's.
TopologyData topology_record(const core::TetMesh& mesh, const std::vector<core::Vec3>& fibers,
                             const std::vector<std::uint8_t>& fixed_dofs, const std::vector<std::string>& region_names,
                             const std::vector<int>& state_nodes);

}  // namespace fiberfem::service
