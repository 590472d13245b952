#pragma once
/// @file Checked reading of YAML (scene files and command arguments, JSON being YAML):
/// typed getters with range checks, mappings whose keys are checked against the allowed
/// ones, and errors that name the key path of the bad value. The one place where both the
/// scene parser (io/scene_*.cpp) and the run library's command arguments
/// (service/command_args.hpp) check what they read.

#include "core/types.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::io {

/// A bad scene: the message starts with "<origin>:<line>: <key path>: ".
class SceneError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A bad command argument: the message names it ("'dt' = 100 is out of range [1e-06, 10]").
class ArgumentError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// How a bad value is reported. The checks are the same; the wording is the one each
/// kind of input has always had (docs/bad-input.md).
enum class Dialect {
  scene,      ///< "<origin>:<line>: solver.dt: expected a number"; throws SceneError.
  arguments,  ///< "'dt' must be a number"; throws ArgumentError.
};

/// "a, b, c".
std::string join(const std::vector<std::string>& words);

/// Where checked values come from and how a bad one is reported; the typed getters.
/// Every getter takes the node and its key path (`regions[0].material.E_L`, `gravity[2]`).
class Checks {
 public:
  /// `origin` names the source in scene messages (a file name, "set_contraction");
  /// `overridden` are key paths set by --set (reported as "--set <path>", they have no line).
  explicit Checks(std::string origin, Dialect dialect = Dialect::scene, std::vector<std::string> overridden = {});

  Dialect dialect() const { return dialect_; }
  const std::string& origin() const { return origin_; }
  /// Throws the dialect's error for the value at `at` (its line) with key path `path`.
  [[noreturn]] void fail(const YAML::Node& at, const std::string& path, const std::string& what) const;
  /// Records "<origin>:<line>: <path>: what" (a setting that runs but outside measured limits).
  void warn(const YAML::Node& at, const std::string& path, const std::string& what) const;
  const std::vector<std::string>& warnings() const { return warnings_; }

  /// A finite number in [lo, hi] ((lo, hi] with `open_lo`).
  double number(const YAML::Node& n, const std::string& path, double lo = -HUGE_VAL, double hi = HUGE_VAL,
                bool open_lo = false) const;
  /// A whole number in [lo, hi].
  int integer(const YAML::Node& n, const std::string& path, long lo, long hi) const;
  /// A scalar, as written.
  std::string text(const YAML::Node& n, const std::string& path) const;
  /// A scalar that is one of `options`.
  std::string choice(const YAML::Node& n, const std::string& path, const std::vector<std::string>& options) const;
  /// true or false.
  bool boolean(const YAML::Node& n, const std::string& path) const;
  /// A list of three finite numbers, each in [-bound, bound].
  core::Vec3 vec3(const YAML::Node& n, const std::string& path, double bound = HUGE_VAL) const;

 private:
  // A finite number, or the failure `not_a_number` (the wording differs for integers).
  double finite(const YAML::Node& n, const std::string& path, const char* not_a_number) const;
  [[noreturn]] void out_of_range(const YAML::Node& n, const std::string& path, double v, double lo, double hi,
                                 bool open_lo, bool whole) const;
  std::string origin_;
  Dialect dialect_;
  std::vector<std::string> overridden_;
  mutable std::vector<std::string> warnings_;
};

/// A mapping whose keys are checked when it is made: a key not in `allowed` (or a key
/// that is a list or mapping) is refused, naming the allowed ones. The getters read a
/// key of it with the key path `<path>.<key>`.
class CheckedMap {
 public:
  CheckedMap(const Checks& checks, const YAML::Node& node, std::string path, std::vector<std::string> allowed);

  /// The key is there and not null.
  bool has(const std::string& key) const { return node_[key].IsDefined() && !node_[key].IsNull(); }
  YAML::Node operator[](const std::string& key) const { return node_[key]; }
  /// The key path of `key` in this mapping.
  std::string sub(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  const YAML::Node& node() const { return node_; }
  const std::string& path() const { return path_; }
  const Checks& checks() const { return checks_; }
  [[noreturn]] void fail(const std::string& what) const { checks_.fail(node_, path_, what); }

  double number(const std::string& key, double lo = -HUGE_VAL, double hi = HUGE_VAL, bool open_lo = false) const {
    return checks_.number(node_[key], sub(key), lo, hi, open_lo);
  }
  int integer(const std::string& key, long lo, long hi) const { return checks_.integer(node_[key], sub(key), lo, hi); }
  std::string text(const std::string& key) const { return checks_.text(node_[key], sub(key)); }
  std::string choice(const std::string& key, const std::vector<std::string>& options) const {
    return checks_.choice(node_[key], sub(key), options);
  }
  bool boolean(const std::string& key) const { return checks_.boolean(node_[key], sub(key)); }
  core::Vec3 vec3(const std::string& key, double bound = HUGE_VAL) const { return checks_.vec3(node_[key], sub(key), bound); }

 private:
  const Checks& checks_;
  YAML::Node node_;
  std::string path_;
};

/// `node` as YAML text (block style).
std::string emit(const YAML::Node& node);

/// Sets the number at a dotted key path below `node` ("systemic.arteries.resistance"),
/// making the mappings on the way.
void set_key_path(YAML::Node node, const std::string& path, double value);
/// Every scalar below `node` as a number by its dotted key path (prefixed by `prefix`).
/// @throws ArgumentError for a list or a scalar that is not a number, naming its path.
void collect_numbers(const YAML::Node& node, const std::string& prefix, std::map<std::string, double>& out);

}  // namespace fiberfem::io
