#pragma once
/// @file Scenes embedded in the binary (copies of configs/scenes/*.yaml made at build time).

#include <map>
#include <string>

namespace fiberfem::service {

/// Built-in scene name -> YAML text. "cantilever" is configs/scenes/demo-cantilever.yaml.
const std::map<std::string, std::string>& builtin_scenes();

}  // namespace fiberfem::service
