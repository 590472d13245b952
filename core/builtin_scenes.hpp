#pragma once
/// @file Scenes built in code, so tests, benchmarks and the demo need no files.

#include "core/box_generator.hpp"
#include "core/model.hpp"

namespace fiberfem::core {

/// A cantilever: a box clamped at x = 0 (node set "xmin"), with uniform fibers and loads.
struct CantileverSpec {
  BoxSpec box{};                              ///< Geometry and resolution (default 10 x 1 x 1 cm, 20x2x2 cells).
  EngineeringConstants material{};            ///< Default E_L 60 kPa, E_T 20 kPa, nu_T 0.45, nu_LT 0.25, G_L 8 kPa.
  double density_kg_m3 = 1000.0;              ///< Default 1000.
  Vec3 fiber{1.0, 0.0, 0.0};                  ///< Fiber direction (uniform). Default along the beam.
  Vec3 gravity_m_s2{0.0, 0.0, -9.81};         ///< Default -9.81 z.
  Vec3 tip_force_n{0.0, 0.0, 0.0};            ///< Total force on the x = L face, spread as a uniform traction.
  RayleighDamping damping{};                  ///< Default none.
};

/// Builds the cantilever model (validated).
Model make_cantilever(const CantileverSpec& spec);

/// Linear Timoshenko beam-theory tip deflection of a rectangular cantilever, metres:
/// q L^4 / (8 E I) + q L^2 / (2 k G A) for a distributed load q (N/m) plus
/// P L^3 / (3 E I) + P L / (k G A) for a tip load P (N), bending about y (deflection along z),
/// with shear coefficient k = 5/6.
double cantilever_tip_deflection(double length_m, double width_m, double height_m, double youngs_pa,
                                 double shear_pa, double q_n_per_m, double tip_n);

}  // namespace fiberfem::core
