#include "io/checked_yaml.hpp"

#include "io/input_file.hpp"

#include <algorithm>
#include <sstream>

namespace fiberfem::io {

namespace {

// The words of each dialect for the same problem.
struct Wording {
  const char* not_a_number;
  const char* not_an_integer;
  const char* not_whole;
  const char* not_finite;
  const char* not_a_string;
  const char* not_a_boolean;
  const char* not_three_numbers;
};
const Wording& wording(Dialect d) {
  static const Wording scene{"expected a number", "expected an integer", "expected an integer", "must be finite",
                             "expected a string", "", "expected a list of three numbers"};
  static const Wording arguments{"must be a number", "must be a number", "must be a whole number", "is not finite",
                                 "must be a string", "must be true or false", "must be a list of three numbers"};
  return d == Dialect::scene ? scene : arguments;
}

std::string number_text(double v, bool whole) {
  if (whole && std::abs(v) < 1e18 && v == std::floor(v)) return std::to_string(static_cast<long long>(v));
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

std::string join(const std::vector<std::string>& words) {
  std::string s;
  for (const auto& w : words) s += (s.empty() ? "" : ", ") + w;
  return s;
}

std::string emit(const YAML::Node& node) {
  YAML::Emitter e;
  e << node;
  return e.c_str();
}

void set_key_path(YAML::Node node, const std::string& path, double value) {
  // yaml-cpp's assignment copies content into a node; a chain of handles walks instead.
  std::vector<YAML::Node> chain{node};
  size_t start = 0;
  for (size_t dot = path.find('.'); dot != std::string::npos; start = dot + 1, dot = path.find('.', start))
    chain.push_back(chain.back()[path.substr(start, dot - start)]);
  chain.back()[path.substr(start)] = value;
}

void collect_numbers(const YAML::Node& node, const std::string& prefix, std::map<std::string, double>& out) {
  if (node.IsMap()) {
    for (const auto& kv : node) {
      const std::string key = kv.first.as<std::string>();
      collect_numbers(kv.second, prefix.empty() ? key : prefix + "." + key, out);
    }
    return;
  }
  double v = 0;
  if (!node.IsScalar() || !YAML::convert<double>::decode(node, v)) throw ArgumentError("'" + prefix + "' must be a number");
  out[prefix] = v;
}

Checks::Checks(std::string origin, Dialect dialect, std::vector<std::string> overridden)
    : origin_(std::move(origin)), dialect_(dialect), overridden_(std::move(overridden)) {}

void Checks::fail(const YAML::Node& at, const std::string& path, const std::string& what) const {
  if (dialect_ == Dialect::arguments) throw ArgumentError("'" + path + "' " + what);
  for (const std::string& o : overridden_)
    if (path.compare(0, o.size(), o) == 0 && (path.size() == o.size() || path[o.size()] == '.' || path[o.size()] == '['))
      throw SceneError(origin_ + ": --set " + printable(path, 200) + ": " + what);
  const int line = at.IsDefined() && at.Mark().line >= 0 ? at.Mark().line + 1 : 0;
  throw SceneError(origin_ + ":" + std::to_string(line) + ": " + (path.empty() ? "" : printable(path, 200) + ": ") + what);
}

void Checks::warn(const YAML::Node& at, const std::string& path, const std::string& what) const {
  const int line = at.IsDefined() && at.Mark().line >= 0 ? at.Mark().line + 1 : 0;
  warnings_.push_back(origin_ + ":" + std::to_string(line) + ": " + path + ": " + what);
}

void Checks::out_of_range(const YAML::Node& n, const std::string& path, double v, double lo, double hi, bool open_lo,
                          bool whole) const {
  std::ostringstream s;
  if (dialect_ == Dialect::scene)
    s << "must be in " << (open_lo ? "(" : "[") << number_text(lo, whole) << ", " << number_text(hi, whole) << "], got "
      << number_text(v, whole);
  else
    s << "= " << v << " is out of range " << (open_lo ? "(" : "[") << lo << ", " << hi << "]";
  fail(n, path, s.str());
}

double Checks::finite(const YAML::Node& n, const std::string& path, const char* not_a_number) const {
  double v = 0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "");
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    fail(n, path, not_a_number);
  }
  if (!std::isfinite(v)) fail(n, path, wording(dialect_).not_finite);
  return v;
}

double Checks::number(const YAML::Node& n, const std::string& path, double lo, double hi, bool open_lo) const {
  const double v = finite(n, path, wording(dialect_).not_a_number);
  if (v < lo || (open_lo && v == lo) || v > hi) out_of_range(n, path, v, lo, hi, open_lo, false);
  return v;
}

int Checks::integer(const YAML::Node& n, const std::string& path, long lo, long hi) const {
  const double v = finite(n, path, wording(dialect_).not_an_integer);
  const double l = static_cast<double>(lo), h = static_cast<double>(hi);
  if (v < l || v > h) out_of_range(n, path, v, l, h, false, true);
  if (v != std::floor(v)) fail(n, path, wording(dialect_).not_whole);
  return static_cast<int>(v);
}

std::string Checks::text(const YAML::Node& n, const std::string& path) const {
  if (!n.IsScalar()) fail(n, path, wording(dialect_).not_a_string);
  return n.as<std::string>();
}

std::string Checks::choice(const YAML::Node& n, const std::string& path, const std::vector<std::string>& options) const {
  const std::string v = text(n, path);
  if (std::find(options.begin(), options.end(), v) == options.end()) {
    if (dialect_ == Dialect::scene) fail(n, path, "'" + printable(v) + "' is not one of " + join(options));
    std::string alternatives;
    for (size_t i = 0; i < options.size(); ++i)
      alternatives += (i == 0 ? "" : i + 1 == options.size() ? " or " : ", ") + options[i];
    fail(n, path, "must be " + alternatives);
  }
  return v;
}

bool Checks::boolean(const YAML::Node& n, const std::string& path) const {
  // A scene says true or false; arguments take what YAML reads as a boolean (yes, on, ...).
  if (dialect_ == Dialect::scene) return choice(n, path, {"true", "false"}) == "true";
  try {
    if (n.IsScalar()) return n.as<bool>();
  } catch (const YAML::Exception&) {  // not a boolean: refused below
  }
  fail(n, path, wording(dialect_).not_a_boolean);
}

core::Vec3 Checks::vec3(const YAML::Node& n, const std::string& path, double bound) const {
  if (!n.IsSequence() || n.size() != 3) fail(n, path, wording(dialect_).not_three_numbers);
  return {number(n[0], path + "[0]", -bound, bound), number(n[1], path + "[1]", -bound, bound),
          number(n[2], path + "[2]", -bound, bound)};
}

CheckedMap::CheckedMap(const Checks& checks, const YAML::Node& node, std::string path, std::vector<std::string> allowed)
    : checks_(checks), node_(node), path_(std::move(path)) {
  const bool scene = checks_.dialect() == Dialect::scene;
  if (!node.IsMap()) {
    if (scene) checks_.fail(node, path_, "expected a mapping with keys " + join(allowed));
    throw ArgumentError("arguments must be a JSON object");
  }
  for (const auto& kv : node) {
    // A YAML complex key (`? ...`: a mapping or list as key) is no key name.
    if (!kv.first.IsScalar()) {
      if (scene) checks_.fail(kv.first, path_, "a key must be a plain name, not a mapping or a list");
      throw ArgumentError("argument names must be words, not lists or objects");
    }
    const std::string key = kv.first.as<std::string>();
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    if (scene) checks_.fail(kv.first, sub(key), "unknown key (allowed here: " + join(allowed) + ")");
    throw ArgumentError("unknown argument '" + key + "'" +
                        (allowed.empty() ? " (this command takes none)" : " (allowed: " + join(allowed) + ")"));
  }
}

}  // namespace fiberfem::io
