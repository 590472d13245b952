#pragma once
/// @file The arguments of one command (a JSON or YAML object) with checked access, for the
/// command handlers of RunControl (service/run_control*.cpp): io's checked-YAML toolkit
/// (io/checked_yaml.hpp) in its arguments dialect ("'dt' = 100 is out of range [1e-06, 10]").
/// Internal to the run library.

#include "io/checked_yaml.hpp"

#include <string>
#include <vector>

namespace fiberfem::service::detail {

using core::Vec3;
using io::join;

/// A rejected command: the message is the reason sent back in the ack.
using Reject = io::ArgumentError;

/// The arguments of one command: an object whose keys are checked against `allowed`.
class Args {
 public:
  /// @throws Reject when `text` is not JSON (or YAML), not an object, or has a key not allowed.
  Args(const std::string& text, std::vector<std::string> allowed)
      : checks_("arguments", io::Dialect::arguments), map_(checks_, load(text), "", std::move(allowed)) {}
  Args(const Args&) = delete;
  Args& operator=(const Args&) = delete;

  bool has(const std::string& k) const { return map_.has(k); }
  YAML::Node operator[](const std::string& k) const { return map_[k]; }
  const YAML::Node& node() const { return map_.node(); }
  /// The checks in the arguments dialect, for values nested in an argument.
  const io::Checks& checks() const { return checks_; }

  double number(const std::string& k, double lo, double hi) const { return map_.number(k, lo, hi); }
  int integer(const std::string& k, long lo, long hi) const { return map_.integer(k, lo, hi); }
  std::string text(const std::string& k) const { return map_.text(k); }
  bool boolean(const std::string& k) const { return map_.boolean(k); }
  /// Three numbers, each within +-1e12.
  Vec3 vec3(const std::string& k) const { return map_.vec3(k, 1e12); }
  /// A whole number in [lo, hi] at key `k`, wider than int (a step or frame number).
  long whole(const std::string& k, double lo, double hi) const { return whole_at(map_[k], k, lo, hi, ""); }
  /// A node index at key path `k`: a whole number in [0, num_nodes).
  int node_index(const YAML::Node& n, const std::string& k, int num_nodes) const {
    return static_cast<int>(whole_at(n, k, 0, num_nodes - 1, " (a node index)"));
  }

 private:
  long whole_at(const YAML::Node& n, const std::string& k, double lo, double hi, const char* what) const {
    const double v = checks_.number(n, k, lo, hi);
    if (v != static_cast<double>(static_cast<long>(v))) throw Reject("'" + k + "' must be a whole number" + what);
    return static_cast<long>(v);
  }
  static YAML::Node load(const std::string& text) {
    YAML::Node n;
    try {
      n = YAML::Load(text.empty() ? "{}" : text);
    } catch (const YAML::Exception& e) {
      throw Reject("arguments are not valid JSON: " + e.msg);
    }
    return n.IsNull() ? YAML::Node(YAML::NodeType::Map) : n;
  }
  io::Checks checks_;
  io::CheckedMap map_;
};

}  // namespace fiberfem::service::detail
