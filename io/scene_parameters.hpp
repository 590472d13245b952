#pragma once
/// @file What a scene says about the sections a command may change (material, damping,
/// fibers, contraction, gravity, solver), as typed values: the forms and keys the scene
/// gives, beside the engine objects built from them (core::Material, core::Contraction,
/// the fiber per element). The run library keeps these as its parameter state; the scene
/// text it records is written back from them (io/scene_sections.hpp).

#include "core/contraction.hpp"
#include "core/fiber_fields.hpp"
#include "core/hyperelastic/law.hpp"
#include "core/linear_solver.hpp"
#include "core/material.hpp"
#include "core/model.hpp"
#include "core/rotation.hpp"

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace fiberfem::io {

enum class Mode { dynamic, static_ };

/// Which engine runs the scene (solver.tier): automatic picks the accurate tier when a region
/// names a material.law or the mesh is of order 2.
enum class Tier { automatic, real_time, accurate };

/// The isotropic form of a material (scene keys E, nu), Pa and 1.
struct IsotropicConstants {
  double E = 0;
  double nu = 0;
};

/// A region's material as the scene gives it (regions[i].material): one of the four forms
/// (none before one is read) and the density.
struct MaterialSpec {
  /// material.law and its constants (the accurate tier); absent: the linear forms below.
  std::optional<core::hyperelastic::LawParameters> law;
  std::variant<std::monostate, core::EngineeringConstants, core::LameFiberConstants, core::StiffnessConstants,
               IsotropicConstants>
      form;
  double density_kg_m3 = 0;  ///< > 0 once read.
};

/// What a scene says about one region's parameters.
struct RegionParameters {
  MaterialSpec material;
  std::optional<core::RayleighDamping> damping;  ///< regions[i].damping, when given.
};

/// A set of mesh nodes (a node selector, docs/scenes.md): a plane, a box or a named set.
struct NodeSelector {
  enum class Kind { plane, box, node_set };
  Kind kind = Kind::node_set;
  int axis = 0;                            ///< plane: 0, 1, 2 for x, y, z.
  double value_m = 0;                      ///< plane: the coordinate, m.
  double tol_m = 1e-9;                     ///< plane: tolerance, m. Default 1e-9.
  core::Vec3 lo_m = core::Vec3::Zero();    ///< box: lower corner, m.
  core::Vec3 hi_m = core::Vec3::Zero();    ///< box: upper corner, m.
  std::string node_set;                    ///< node_set: the name.
};

/// The fiber field as the scene gives it (fibers): one of four kinds.
struct FiberSpec {
  enum class Kind { uniform, rule, strokes, file };
  Kind kind = Kind::uniform;
  core::Vec3 uniform = core::Vec3::UnitX();             ///< uniform: the direction as given.
  std::optional<core::Vec3> uniform_sheet;              ///< fibers.sheet, when given (not with rule).
  core::HelixRule rule;                                 ///< rule: angles and long axis.
  std::optional<NodeSelector> inner, outer;             ///< rule: default the node sets endo, epi.
  std::vector<std::vector<core::Vec3>> stroke_lines;    ///< strokes.lines, m.
  std::string stroke_file;                              ///< strokes.file as given ("" none).
  std::optional<double> stroke_radius_m;                ///< strokes.radius (default: mean edge).
  std::string file;                                     ///< file: the path as given.
};

/// A pacing site: activation delayed by distance over conduction speed.
struct PacingSpec {
  core::Vec3 at_m = core::Vec3::Zero();
  double speed_m_s = 0;
};

/// The contraction as the scene gives it (contraction); core::Contraction is built from
/// it for a mesh (per-region tensions by name, pacing delays per element).
struct ContractionSpec {
  core::ContractionMode mode = core::ContractionMode::active_stress;
  std::optional<double> heart_rate_bpm;  ///< contraction.heart_rate (at most one of this and period_s).
  std::optional<double> period_s;        ///< contraction.period.
  core::Twitch twitch;
  std::optional<double> peak_tension_pa;                        ///< contraction.peak_tension.
  std::vector<std::pair<std::string, double>> region_peak_pa;   ///< contraction.regions, in order.
  std::optional<PacingSpec> pacing;
};

/// The solver section as the scene gives it: each key that is given.
struct SolverSpec {
  std::optional<Mode> mode;
  std::optional<double> dt_s;
  std::optional<core::LinearSolverKind> method;
  std::optional<double> tolerance;
  std::optional<int> max_iterations;
  std::optional<core::RotationMethod> rotation;
  std::optional<core::PreconditionerKind> preconditioner;
  std::optional<bool> warm_start;
  std::optional<double> max_energy_gain;  ///< infinity: the check off.
  std::optional<double> until_s;
  std::optional<int> recycled_solutions;
  std::optional<int> threads;
  std::optional<bool> corotation;
  std::optional<core::FirstFactorisation> first_factorisation;
  std::optional<int> jacobi_first;  ///< solver.jacobi_first: core::kJacobiFirstAuto, 0 (off) or a count.
  // The accurate tier's Newton solver (docs/scenes.md, solver.newton and friends).
  std::optional<int> load_steps;              ///< solver.load_steps.
  std::optional<double> newton_tolerance;     ///< solver.newton.tolerance.
  std::optional<double> newton_increment_tolerance;  ///< solver.newton.increment_tolerance.
  std::optional<int> newton_max_iterations;   ///< solver.newton.max_iterations.
  std::optional<bool> newton_line_search;     ///< solver.newton.line_search.
  std::optional<int> quadrature;              ///< solver.quadrature: points per element.
  std::optional<Tier> tier;                   ///< solver.tier.
};

/// Every section of a scene that a parameter command can change.
struct SceneParameters {
  std::vector<RegionParameters> regions;       ///< By region id.
  std::optional<FiberSpec> fibers;             ///< Absent: (1, 0, 0) everywhere.
  std::optional<ContractionSpec> contraction;  ///< Absent: no contraction.
  std::optional<core::Vec3> gravity_m_s2;      ///< loads.gravity, when given.
  SolverSpec solver;
  /// Keys of the `circulation` section set by set_circulation commands, by their path
  /// below it ("heart_rate", "systemic.arteries.resistance", ...) in the scene's units
  /// (docs/circulation.md); written over the scene's section. Empty for a scene as loaded.
  std::map<std::string, double> circulation;
};

}  // namespace fiberfem::io
