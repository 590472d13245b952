#pragma once
/// @file The sections of a scene file (docs/scenes.md), each read from a checked YAML node
/// and, for the sections a parameter command changes, written back from its typed value.
///
/// A reader reads `node` onto the typed value it is given: keys present replace, keys left
/// out keep what the value had (the scene parser starts from an empty value, a command from
/// the running one), so a command's arguments take the same keys, units and checks as the
/// scene file. A reader returns the engine object it builds and changes the typed value
/// only when the whole section is good. A writer is its reader's inverse:
/// read(write(x)) gives x (tests/io/scene_sections_test.cpp).

#include "core/mesh.hpp"
#include "core/simulator.hpp"
#include "io/checked_yaml.hpp"
#include "io/scene_parameters.hpp"

#include <string>
#include <vector>

namespace fiberfem::io {

/// The keys of a material mapping: every form's and density.
const std::vector<std::string>& material_keys();
/// regions[i].material onto `spec`. A key of another form than spec's replaces the form
/// (its missing keys are then errors); keys of the same form merge. `also_allowed` keys
/// are accepted and left to the caller (a command's `region`).
core::Material read_material(const Checks& checks, const YAML::Node& node, const std::string& path, MaterialSpec& spec,
                             const std::vector<std::string>& also_allowed = {});
/// The material mapping that its reader reads back to the same value.
YAML::Node write_material(const MaterialSpec& spec);
/// A material with a `law` key (read_material hands it over): the law's constants into
/// spec.law; returns the linear material of its small-strain limit.
core::Material read_law_material(const Checks& checks, const YAML::Node& node, const std::string& path, MaterialSpec& spec);
/// Every key a material with a law may have (of any law).
const std::vector<std::string>& law_material_keys();
/// The law's keys into a material mapping.
void write_law(const core::hyperelastic::LawParameters& law, YAML::Node& node);
/// The small-strain limit of a law (its tangent at rest), as the real-time tier's material.
core::Material linearised_material(const core::hyperelastic::LawParameters& law, double density_kg_m3);
/// The bulk modulus a compressible law gets when the scene gives none:
/// kDefaultBulkFactor times its small-strain shear modulus (Poisson's ratio about 0.499), Pa.
/// From the study across tiers (docs/speed-accuracy-tiers.md): of 10 to 500 times, 400
/// keeps the Land problems' error lowest in the worse of the two (3-4%; 100 times left
/// 11% on problem 2), at 1.5 to 2 times the Newton cost of 100 times.
inline constexpr double kDefaultBulkFactor = 400.0;
double default_bulk_modulus(const core::hyperelastic::LawParameters& law);
/// The bulk modulus of an incompressible law's small-strain limit on the real-time tier:
/// kLinearisedBulkFactor times its shear modulus (Poisson's ratio about 0.495), which the
/// linear tetrahedra and their solver carry without the worse locking and conditioning of
/// a stiffer limit.
inline constexpr double kLinearisedBulkFactor = 100.0;

/// regions[i].damping.
core::RayleighDamping read_damping(const Checks& checks, const YAML::Node& node, const std::string& path);
/// The damping mapping that its reader reads back to the same value.
YAML::Node write_damping(const core::RayleighDamping& damping);

/// A node selector (plane, box or node_set); returns the nodes it matches (sorted), at
/// least one. `spec` (optional) receives the selector.
std::vector<int> read_node_selector(const Checks& checks, const YAML::Node& node, const std::string& path,
                                    const core::TetMesh& mesh, NodeSelector* spec = nullptr,
                                    const std::vector<std::string>& also_allowed = {});
/// The selector mapping that its reader reads back to the same value.
YAML::Node write_node_selector(const NodeSelector& selector);

/// fibers: one whole field (it replaces `spec`), per element for `mesh`. Relative file
/// paths are looked up in `base_dir`; the files read are appended to `files_read`.
std::vector<core::Vec3> read_fibers(const Checks& checks, const YAML::Node& node, const core::TetMesh& mesh,
                                    const std::string& base_dir, FiberSpec& spec,
                                    std::vector<std::string>* files_read = nullptr,
                                    std::vector<core::Vec3>* sheets = nullptr);
/// The fibers mapping that its reader reads back to the same value.
YAML::Node write_fibers(const FiberSpec& spec);

/// contraction onto `spec`, built and validated for `mesh` (regions by name). A
/// heart_rate replaces a period and the other way round; a peak_tension without regions
/// drops the per-region tensions; twitch keys merge.
core::Contraction read_contraction(const Checks& checks, const YAML::Node& node, const core::TetMesh& mesh,
                                   const std::vector<std::string>& region_names, ContractionSpec& spec);
/// The contraction mapping (every twitch key written) that its reader reads back to the same value.
YAML::Node write_contraction(const ContractionSpec& spec);

/// solver.method, solver.preconditioner, solver.rotation by their scene names.
core::LinearSolverKind read_solver_method(const Checks& checks, const YAML::Node& node, const std::string& path);
core::PreconditionerKind read_preconditioner(const Checks& checks, const YAML::Node& node, const std::string& path);
core::RotationMethod read_rotation(const Checks& checks, const YAML::Node& node, const std::string& path);
/// solver onto `spec` (checked keys; settings are built with solver_settings).
void read_solver(const Checks& checks, const YAML::Node& node, SolverSpec& spec);
/// The solver mapping (the keys given; empty for none) that its reader reads back to the same value.
YAML::Node write_solver(const SolverSpec& spec);
/// The engine settings for `spec` over `base` (defaults, or a fidelity preset's).
core::SimulatorSettings solver_settings(const SolverSpec& spec, core::SimulatorSettings base);

/// The keys of the `circulation` section (docs/circulation.md).
const std::vector<std::string>& circulation_keys();
/// The lumped loop's parameters from a `circulation` mapping `c` (the scene's section, or a
/// set_circulation command's keys merged into it), in SI units: heart_rate (default: the
/// contraction's, 75 beats/min without one), chambers, valves, systemic, pulmonary, all
/// multiplied by scale; the chambers of model.circulation.cavities are the mesh's
/// (ChamberKind::external). The other keys are the caller's.
/// @throws the dialect's error naming the key (validated whole).
core::circulation::Parameters read_circulation_loop(const CheckedMap& c, const core::Model& model);

/// The scene text `scene_yaml` with its parameter sections written from `parameters`
/// (regions[i].material and .damping, fibers, contraction, loads.gravity, solver, the
/// circulation keys set by commands); the other keys as they are.
std::string write_scene_parameters(const std::string& scene_yaml, const SceneParameters& parameters);

}  // namespace fiberfem::io
