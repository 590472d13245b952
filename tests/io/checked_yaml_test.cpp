// The checked-YAML toolkit (io/checked_yaml.hpp): one set of checks, each bad value
// refused with its key path in the wording of its dialect (scene files: "<origin>:<line>:
// <path>: ..."; command arguments: "'<path>' ...").

#include "io/checked_yaml.hpp"

#include <gtest/gtest.h>

#include <functional>

namespace fiberfem::io {
namespace {

// The message of the error `f` throws (of type E), or "" when it throws none.
template <class E>
std::string message(const std::function<void()>& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

TEST(CheckedYaml, SceneDialectNamesOriginLineAndPath) {
  const Checks c("s.yaml");
  const YAML::Node doc = YAML::Load("a: 1\nb: fast\nc: -1\nd: 1.5\ne: [1, 2]\nf: maybe\ng: .nan\n");
  EXPECT_EQ(c.number(doc["a"], "a"), 1.0);
  EXPECT_EQ(message<SceneError>([&] { c.number(doc["b"], "x.b"); }), "s.yaml:2: x.b: expected a number");
  EXPECT_EQ(message<SceneError>([&] { c.number(doc["c"], "c", 0, 10, true); }), "s.yaml:3: c: must be in (0, 10], got -1");
  EXPECT_EQ(message<SceneError>([&] { c.integer(doc["c"], "c", 1, 100000); }), "s.yaml:3: c: must be in [1, 100000], got -1");
  EXPECT_EQ(message<SceneError>([&] { c.integer(doc["d"], "d", 0, 10); }), "s.yaml:4: d: expected an integer");
  EXPECT_EQ(message<SceneError>([&] { c.vec3(doc["e"], "e"); }), "s.yaml:5: e: expected a list of three numbers");
  EXPECT_EQ(message<SceneError>([&] { c.boolean(doc["f"], "f"); }), "s.yaml:6: f: 'maybe' is not one of true, false");
  EXPECT_EQ(message<SceneError>([&] { c.number(doc["g"], "g"); }), "s.yaml:7: g: must be finite");
  EXPECT_EQ(message<SceneError>([&] { c.text(doc["e"], "e"); }), "s.yaml:5: e: expected a string");
  EXPECT_EQ(message<SceneError>([&] { CheckedMap(c, doc, "top", {"a"}); }), "s.yaml:2: top.b: unknown key (allowed here: a)");
  EXPECT_EQ(message<SceneError>([&] { CheckedMap(c, doc["a"], "top", {"a", "b"}); }),
            "s.yaml:1: top: expected a mapping with keys a, b");
  // A key path set by --set is reported as the override (it has no line of its own).
  const Checks o("s.yaml", Dialect::scene, {"x"});
  EXPECT_EQ(message<SceneError>([&] { o.number(doc["b"], "x.b"); }), "s.yaml: --set x.b: expected a number");
}

TEST(CheckedYaml, ArgumentsDialectNamesTheArgument) {
  const Checks c("arguments", Dialect::arguments);
  const YAML::Node args = YAML::Load(R"({"dt": 100, "n": 1.5, "s": [1], "g": [0, 0], "on": "maybe", "m": "magic", "x": .inf})");
  EXPECT_EQ(message<ArgumentError>([&] { c.number(args["dt"], "dt", 1e-6, 10); }), "'dt' = 100 is out of range [1e-06, 10]");
  EXPECT_EQ(message<ArgumentError>([&] { c.number(args["s"], "s"); }), "'s' must be a number");
  EXPECT_EQ(message<ArgumentError>([&] { c.integer(args["n"], "n", 1, 1000000); }), "'n' must be a whole number");
  EXPECT_EQ(message<ArgumentError>([&] { c.integer(args["dt"], "dt", 1, 10); }), "'dt' = 100 is out of range [1, 10]");
  EXPECT_EQ(message<ArgumentError>([&] { c.vec3(args["g"], "g"); }), "'g' must be a list of three numbers");
  EXPECT_EQ(message<ArgumentError>([&] { c.boolean(args["on"], "on"); }), "'on' must be true or false");
  EXPECT_EQ(message<ArgumentError>([&] { c.choice(args["m"], "m", {"pcg", "direct"}); }), "'m' must be pcg or direct");
  EXPECT_EQ(message<ArgumentError>([&] { c.number(args["x"], "x"); }), "'x' is not finite");
  EXPECT_EQ(message<ArgumentError>([&] { CheckedMap(c, args, "", {"dt"}); }).rfind("unknown argument 'n' (allowed: dt)", 0), 0u);
  EXPECT_EQ(message<ArgumentError>([&] { CheckedMap(c, YAML::Load("{a: 1}"), "", {}); }),
            "unknown argument 'a' (this command takes none)");
  EXPECT_EQ(message<ArgumentError>([&] { CheckedMap(c, YAML::Load("[1]"), "", {}); }), "arguments must be a JSON object");
  EXPECT_EQ(message<ArgumentError>([&] { CheckedMap(c, YAML::Load("{[1]: 2}"), "", {}); }),
            "argument names must be words, not lists or objects");
}

}  // namespace
}  // namespace fiberfem::io
