#pragma once
/// @file A small accurate-tier scene the service tests share: Land's beam problem (Guccione,
/// incompressible, Taylor-Hood P2/P1) on a coarse order-2 mesh, mass damping, its follower
/// pressure ramped in over 0.05 s, stepped in time; the probe on a corner node of the tip.

namespace fiberfem::testing {

inline constexpr const char* kAccurateBeamScene = R"(
name: accurate-beam
mesh: {generator: box, size: [0.010, 0.001, 0.001], cells: [4, 1, 1], order: 2}
regions:
  - name: myocardium
    select: all
    material: {law: guccione, C: 2000.0, b_f: 8.0, b_t: 2.0, b_fs: 4.0, incompressible: true, density: 1000.0}
    damping: {mass: 20.0}
fibers: {uniform: [1, 0, 0]}
fixed:
  - plane: {axis: x, value: 0.0}
loads:
  tractions:
    - on: {plane: {axis: z, value: 0.0}}
      pressure: 4.0
      follower: true
      ramp: 0.05
solver: {dt: 0.01}
probes:
  tip: [0.010, 0.001, 0.001]
)";

}  // namespace fiberfem::testing
