#pragma once
/// @file Scenes embedded in the binary (copies of configs/scenes/*.yaml and the meshes
/// they read, made at build time).

#include "io/scene.hpp"

#include <map>
#include <string>
#include <vector>

namespace fiberfem::service {

/// Built-in scene name -> YAML text. "cantilever" is configs/scenes/demo-cantilever.yaml,
/// "heart" is configs/scenes/heart.yaml (the default heart, with meshes/biventricle.msh).
const std::map<std::string, std::string>& builtin_scenes();

/// Parses a built-in scene with its embedded files.
/// @throws io::SceneError for an unknown name or a bad override.
/// The files the built-in scenes read (their meshes), by the path the scenes resolve.
const io::EmbeddedFiles& embedded_files();

io::Scene load_builtin_scene(const std::string& name, const std::vector<std::string>& overrides = {});

}  // namespace fiberfem::service
