#pragma once
/// @file Scene files (YAML, docs/scenes.md) parsed into the engine's model and settings.
/// Outside core/ (STYLE.md habit 1): core never sees a file.

#include "core/cavity.hpp"
#include "core/model.hpp"
#include "core/simulator.hpp"
#include "io/checked_yaml.hpp"
#include "io/scene_parameters.hpp"

#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::io {

/// A point whose displacement is reported, interpolated linearly in the element that
/// contains it (located when the scene is parsed; a point outside the mesh is an error).
struct Probe {
  std::string name;
  core::Vec3 point_m = core::Vec3::Zero();
  int element = -1;                                        ///< Containing element.
  Eigen::Vector4d weights = Eigen::Vector4d::Zero();       ///< Barycentric weights of its nodes.
  /// Displacement of the probe for positions `x` (3 x N), metres.
  core::Vec3 displacement(const core::TetMesh& mesh, const core::Positions& x) const;
};

/// A cavity whose volume is measured (scene key measure.cavities).
struct CavityMeasure {
  std::string name;
  core::CavitySurface surface;
};

/// Recording of the run into an HDF5 archive (scene key `archive`, docs/scenes.md and
/// docs/archive.md). Ranges are checked when the scene is parsed.
struct ArchiveSettings {
  bool enabled = false;            ///< The scene has an `archive` key.
  std::string path;                ///< archive.path: the .h5 file (relative to the working dir).
  int flush_frames = 10;           ///< archive.flush_frames, frames, in [1, 100000]. Default 10.
  double flush_seconds = 1.0;      ///< archive.flush_seconds, wall s, in [0, 3600]; 0 = by frames only. Default 1.
  int every_steps = 1;             ///< archive.every: record every K-th step, in [1, 1000000]. Default 1.
  bool velocities = false;         ///< archive.velocities. Default false.
  bool displacement = true;        ///< archive.displacement (the sidecar's point data). Default true.
  double checkpoint_every_s = 1.0; ///< archive.checkpoint_every, simulated s, in [0, 1e9]. Default 1.
  int compression = 0;             ///< archive.compression: deflate level, in [0, 9]. Default 0.
};

/// Everything a scene file describes.
struct Scene {
  /// A scene of `m` with every other field at its default (parse_scene fills them).
  explicit Scene(core::Model m) : model(std::move(m)) {}
  std::string name;
  core::Model model;
  core::SimulatorSettings settings;
  Mode mode = Mode::dynamic;
  /// How long a dynamic run lasts (solver.until), s. Default 2.
  double until_s = 2.0;
  std::vector<Probe> probes;
  std::vector<CavityMeasure> cavities;
  /// SHA-256 (hex) of the scene as parsed, after overrides (comments and layout do not
  /// count), followed by the bytes of the files it reads (mesh, fiber, stroke files).
  std::string hash_sha256;
  /// The mesh file read (path as opened), or empty for a generator.
  std::string mesh_file;
  /// The scene as parsed (after overrides), emitted as YAML without the `archive` key:
  /// parse_scene(yaml_text, ..., base_dir) gives the same scene (the run archive keeps it).
  std::string yaml_text;
  /// Where relative file paths of the scene are looked up (empty: the working dir).
  std::string base_dir;
  /// The `archive` key (recording does not change the run, so it is left out of the hash).
  ArchiveSettings archive;
  /// Region names, by region id.
  std::vector<std::string> region_names;
  /// What the scene says about the sections a parameter command changes (the model and
  /// settings above are built from these).
  SceneParameters parameters;
  /// Settings the scene may run with but outside the measured limits (docs/speed-accuracy.md),
  /// each "<origin>:<line>: <key path>: why"; `fiberfem run` and `serve` print them.
  std::vector<std::string> warnings;
};

/// Files held in memory (built-in scenes' meshes), by path as the scene resolves it
/// (base_dir + "/" + the scene's path). Such a file is read from here instead of disk.
using EmbeddedFiles = std::map<std::string, std::string>;

/// Parses YAML text. `origin` names the source in error messages (a file name);
/// `base_dir` is where relative mesh file paths are looked up (empty: the working dir).
/// @throws SceneError naming the line and key path of the first problem, or what the
/// engine's validation refused.
/// `overrides` are "key.path=value" assignments applied to the YAML before parsing (for
/// sweeps): a path names mapping keys and list indices (`regions[0].material.E_L=7e4`,
/// `solver.dt=0.01`); the value is parsed as YAML (`loads.gravity=[0, 0, -1]`). Missing
/// mapping keys are created; a bad path is a SceneError naming the override.
Scene parse_scene(const std::string& yaml_text, const std::string& origin = "<scene>",
                  const std::string& base_dir = "", const std::vector<std::string>& overrides = {},
                  const EmbeddedFiles* embedded = nullptr);

/// The `archive` mapping (path, flush_frames, ...) alone, YAML or JSON text, for
/// start_recording. @throws SceneError naming the key.
ArchiveSettings parse_archive_settings(const std::string& yaml_text, const std::string& origin);

/// Reads and parses a scene file (with optional overrides, as parse_scene).
/// @throws SceneError (also for an unreadable file).
Scene load_scene(const std::string& path, const std::vector<std::string>& overrides = {});

}  // namespace fiberfem::io
