// Cycle scripts (clients/ctl/cycle.hpp) parsed into timed commands, and bad scripts
// refused with the action and key named.

#include "clients/ctl/cycle.hpp"

#include <gtest/gtest.h>

namespace fiberfem::clients {
namespace {

TEST(CycleScript, ActionsRampsAndRepeatsBecomeTimedCommands) {
  const CycleScript s = parse_cycle(R"(
name: demo
actions:
  - at: 2.0
    set_contraction: {heart_rate: 90}
  - from: 4.0
    to: 8.0
    ramp: {key: peak_tension, from: 60.0e3, to: 120.0e3}
    steps: 4
    command: set_contraction
  - at: 5.0
    apply_force: {target: {node_set: apex}, force: [0, 0, 0.5], duration: 0.2}
  - at: 1.0
    every: 0.5
    until: 2.0
    command: pause
)", "demo.yaml");
  EXPECT_EQ(s.name, "demo");
  ASSERT_EQ(s.events.size(), 1u + 5u + 1u + 3u);
  for (size_t i = 1; i < s.events.size(); ++i) EXPECT_LE(s.events[i - 1].time_s, s.events[i].time_s);
  EXPECT_EQ(s.events[0].kind, "pause");
  EXPECT_DOUBLE_EQ(s.events[0].time_s, 1.0);
  std::vector<double> ramp_t;
  for (const auto& e : s.events)
    if (e.kind == "set_contraction" && e.args.find("peak_tension") != std::string::npos) ramp_t.push_back(e.time_s);
  EXPECT_EQ(ramp_t, (std::vector<double>{4, 5, 6, 7, 8}));
  const auto mid = std::find_if(s.events.begin(), s.events.end(), [](const CycleEvent& e) { return e.time_s == 6.0; });
  ASSERT_NE(mid, s.events.end());
  EXPECT_NE(mid->args.find("peak_tension: 90000"), std::string::npos) << mid->args;
}

TEST(CycleScript, BadScriptsNameTheActionAndKey) {
  const std::pair<const char*, const char*> bad[] = {
      {"actions: []", "non-empty list 'actions'"},
      {"actions: [{set_gravity: {gravity: [0, 0, 0]}}]", "action 1"},
      {"actions: [{at: -1, pause: {}}]", "'at'"},
      {"actions: [{at: 1, pause: {}, resume: {}}]", "two commands"},
      {"actions: [{at: 1, every: 0.5, pause: {}}]", "'until'"},
      {"actions: [{from: 1, to: 2, command: set_contraction}]", "ramp"},
      {"actions: [{at: 1, set_contraction: 5}]", "must be a mapping"},
      {"speed: 3\nactions: [{at: 1, pause: {}}]", "unknown key 'speed'"},
      {"time: wall\nactions: [{at: 1, pause: {}}]", "time must be"},
  };
  for (const auto& [text, expect] : bad) {
    try {
      parse_cycle(text, "bad.yaml");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const CycleError& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).rfind("bad.yaml", 0), 0u) << e.what();
    }
  }
}

TEST(CycleScript, ShippedScriptsParse) {
  for (const char* f : {"exercise.yaml", "beat-taps.yaml"})
    EXPECT_NO_THROW(load_cycle(std::string(FIBERFEM_SOURCE_DIR) + "/configs/cycles/" + f)) << f;
}

}  // namespace
}  // namespace fiberfem::clients
