#pragma once
/// @file The arguments of one command (a JSON or YAML object) with checked access, for the
/// command handlers of RunControl (service/run_control*.cpp). Internal to the run library.

#include "core/types.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::service::detail {

using core::Vec3;

inline std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

inline std::string emit(const YAML::Node& n) {
  YAML::Emitter e;
  e << n;
  return e.c_str();
}

// A rejected command: the message is the reason sent back in the ack.
struct Reject : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The arguments of one command: a mapping whose keys are checked.
class Args {
 public:
  Args(const std::string& text, std::vector<std::string> allowed) : allowed_(std::move(allowed)) {
    try {
      node_ = YAML::Load(text.empty() ? "{}" : text);
    } catch (const YAML::Exception& e) {
      throw Reject("arguments are not valid JSON: " + e.msg);
    }
    if (node_.IsNull()) node_ = YAML::Node(YAML::NodeType::Map);
    if (!node_.IsMap()) throw Reject("arguments must be a JSON object");
    for (const auto& kv : node_) {
      if (!kv.first.IsScalar()) throw Reject("argument names must be words, not lists or objects");
      const std::string key = kv.first.as<std::string>();
      if (std::find(allowed_.begin(), allowed_.end(), key) == allowed_.end())
        throw Reject("unknown argument '" + key + "'" +
                     (allowed_.empty() ? " (this command takes none)" : " (allowed: " + join(allowed_) + ")"));
    }
  }
  bool has(const std::string& k) const { return node_[k].IsDefined() && !node_[k].IsNull(); }
  YAML::Node operator[](const std::string& k) const { return node_[k]; }
  const YAML::Node& node() const { return node_; }

  double number(const std::string& k, double lo, double hi) const { return as_number(node_[k], k, lo, hi); }
  int integer(const std::string& k, long lo, long hi) const {
    const double v = number(k, static_cast<double>(lo), static_cast<double>(hi));
    if (v != std::floor(v)) throw Reject("'" + k + "' must be a whole number");
    return static_cast<int>(v);
  }
  std::string text(const std::string& k) const {
    if (!node_[k].IsScalar()) throw Reject("'" + k + "' must be a string");
    return node_[k].as<std::string>();
  }
  bool boolean(const std::string& k) const {
    try {
      return node_[k].as<bool>();
    } catch (const YAML::Exception&) {
      throw Reject("'" + k + "' must be true or false");
    }
  }
  Vec3 vec3(const std::string& k) const { return as_vec3(node_[k], k); }

  static double as_number(const YAML::Node& n, const std::string& k, double lo, double hi) {
    double v = 0;
    try {
      if (!n.IsScalar()) throw Reject("");
      v = n.as<double>();
    } catch (const std::exception&) {
      throw Reject("'" + k + "' must be a number");
    }
    if (!std::isfinite(v)) throw Reject("'" + k + "' is not finite");
    if (v < lo || v > hi) {
      std::ostringstream os;
      os << "'" << k << "' = " << v << " is out of range [" << lo << ", " << hi << "]";
      throw Reject(os.str());
    }
    return v;
  }
  /// A node index: a whole number in [0, num_nodes).
  static int as_node(const YAML::Node& n, const std::string& k, int num_nodes) {
    const double v = as_number(n, k, 0, num_nodes - 1);
    if (v != std::floor(v)) throw Reject("'" + k + "' must be a whole number (a node index)");
    return static_cast<int>(v);
  }
  static std::string as_text(const YAML::Node& n, const std::string& k) {
    if (!n.IsScalar()) throw Reject("'" + k + "' must be a string");
    return n.as<std::string>();
  }
  static Vec3 as_vec3(const YAML::Node& n, const std::string& k) {
    if (!n.IsSequence() || n.size() != 3) throw Reject("'" + k + "' must be a list of three numbers");
    return {as_number(n[0], k + "[0]", -1e12, 1e12), as_number(n[1], k + "[1]", -1e12, 1e12),
            as_number(n[2], k + "[2]", -1e12, 1e12)};
  }

 private:
  std::vector<std::string> allowed_;
  YAML::Node node_;
};

}  // namespace fiberfem::service::detail
