#include "clients/ctl/cycle.hpp"

#include "io/input_file.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <ostream>
#include <sstream>

namespace fiberfem::clients {
namespace {

using namespace std::chrono_literals;

[[noreturn]] void fail(const std::string& where, const YAML::Node& at, const std::string& what) {
  // `where` is "FILE" or "FILE: action N": the line goes after the file name.
  const int line = at.IsDefined() && at.Mark().line >= 0 ? at.Mark().line + 1 : 0;
  const size_t action = where.rfind(": action ");
  if (action == std::string::npos) throw CycleError(where + ":" + std::to_string(line) + ": " + what);
  throw CycleError(where.substr(0, action) + ":" + std::to_string(line) + where.substr(action) + ": " + what);
}

std::string flow(const YAML::Node& n) {
  YAML::Emitter e;
  e.SetMapFormat(YAML::Flow);
  e.SetSeqFormat(YAML::Flow);
  e << n;
  return e.c_str();
}

double number(const std::string& where, const YAML::Node& n, const std::string& key, double lo, double hi) {
  double v = 0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "");
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    fail(where, n, "'" + key + "' must be a number");
  }
  if (!std::isfinite(v)) fail(where, n, "'" + key + "' must be finite");
  if (v < lo || v > hi) {
    std::ostringstream m;
    m << "'" << key << "' = " << v << " must be in [" << lo << ", " << hi << "]";
    fail(where, n, m.str());
  }
  return v;
}

// A scalar as text (a list or mapping where a word belongs is an error naming the key).
std::string word(const std::string& where, const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) fail(where, n, "'" + key + "' must be a word or number, not a list or mapping");
  return n.as<std::string>();
}

// A whole number in [lo, hi].
int whole(const std::string& where, const YAML::Node& n, const std::string& key, int lo, int hi) {
  const double v = number(where, n, key, lo, hi);
  if (v != std::floor(v)) fail(where, n, "'" + key + "' must be a whole number");
  return static_cast<int>(v);
}

// Every action's events together (repeats and ramp steps expanded): a script is played
// against a live run, one acknowledged command at a time.
constexpr size_t kMaxEvents = 100000;

// The command of an action: `command: KIND` + `args: {...}`, or one key that is the kind.
void command_of(const std::string& where, const YAML::Node& a, const std::vector<std::string>& timing, std::string& kind,
                YAML::Node& args) {
  if (a["command"]) {
    kind = word(where, a["command"], "command");
    args = a["args"] ? a["args"] : YAML::Node(YAML::NodeType::Map);
    for (const auto& kv : a) {
      const std::string k = word(where, kv.first, "a key");
      if (k != "command" && k != "args" && std::find(timing.begin(), timing.end(), k) == timing.end())
        fail(where, kv.first, "unknown key '" + k + "' beside command");
    }
    return;
  }
  for (const auto& kv : a) {
    const std::string k = word(where, kv.first, "a key");
    if (std::find(timing.begin(), timing.end(), k) != timing.end()) continue;
    if (!kind.empty()) fail(where, kv.first, "two commands in one action ('" + kind + "' and '" + k + "')");
    kind = k;
    args = kv.second.IsNull() ? YAML::Node(YAML::NodeType::Map) : kv.second;
  }
  if (kind.empty()) fail(where, a, "no command (give `command: KIND` or a key that is a command kind)");
  if (!args.IsMap()) fail(where, args, "the arguments of '" + kind + "' must be a mapping");
}

}  // namespace

namespace {
CycleScript parse_cycle_tree(const YAML::Node& root, const std::string& origin);
}  // namespace

CycleScript parse_cycle(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw CycleError(origin + ":" + std::to_string(e.mark.line + 1) + ": not valid YAML: " + e.msg);
  }
  try {
    return parse_cycle_tree(root, origin);
  } catch (const YAML::Exception& e) {  // a conversion the checks above did not foresee
    throw CycleError(origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
}

namespace {
CycleScript parse_cycle_tree(const YAML::Node& root, const std::string& origin) {
  if (!root.IsMap()) throw CycleError(origin + ": expected a mapping with name, actions");
  CycleScript s;
  for (const auto& kv : root) {
    const std::string k = word(origin, kv.first, "a key");
    if (k != "name" && k != "time" && k != "on_reject" && k != "actions")
      fail(origin, kv.first, "unknown key '" + k + "' (allowed: name, time, on_reject, actions)");
  }
  s.name = root["name"] ? word(origin, root["name"], "name") : origin;
  if (root["time"]) {
    const std::string t = word(origin, root["time"], "time");
    if (t != "script" && t != "run") fail(origin, root["time"], "time must be script (from the start of playing) or run");
    s.absolute_time = t == "run";
  }
  if (root["on_reject"]) {
    const std::string r = word(origin, root["on_reject"], "on_reject");
    if (r != "stop" && r != "continue") fail(origin, root["on_reject"], "on_reject must be stop or continue");
    s.stop_on_reject = r == "stop";
  }
  const YAML::Node actions = root["actions"];
  if (!actions || !actions.IsSequence() || actions.size() == 0) fail(origin, root, "needs a non-empty list 'actions'");
  for (size_t i = 0; i < actions.size(); ++i) {
    const YAML::Node a = actions[i];
    const std::string where = origin + ": action " + std::to_string(i + 1);
    if (!a.IsMap()) fail(where, a, "expected a mapping");
    std::string kind;
    YAML::Node args;
    if (a["at"]) {  // at T [for D] | at T every S|beat [until T | times N]
      command_of(where, a, {"at", "every", "until", "times"}, kind, args);
      const double t = number(where, a["at"], "at", 0, 1e9);
      if (!a["every"]) {
        if (a["until"] || a["times"]) fail(where, a, "'until' and 'times' go with 'every'");
        s.events.push_back({t, kind, flow(args), "action " + std::to_string(i + 1)});
        continue;
      }
      if (!a["until"] && !a["times"]) fail(where, a, "'every' needs 'until' (s) or 'times'");
      const double until = a["until"] ? number(where, a["until"], "until", t, 1e9) : 1e18;
      const int times = a["times"] ? whole(where, a["times"], "times", 1, 100000) : 1000000;
      if (a["every"].IsScalar() && a["every"].as<std::string>() == "beat") {
        CycleEvent e{t, kind, flow(args), "action " + std::to_string(i + 1) + " (every beat)"};
        e.every_beat = true;
        e.repeat_until_s = until;
        e.repeat_left = times - 1;
        s.events.push_back(e);
        continue;
      }
      const double every = number(where, a["every"], "every", 1e-3, 1e9);
      int n = 0;
      for (double tk = t; tk <= until + 1e-9 && n < times; tk = t + every * ++n) {
        if (n >= 100000) fail(where, a, "repeats more than 100000 times");
        if (s.events.size() >= kMaxEvents) fail(where, a, "the script has more than 100000 events in all");
        s.events.push_back({tk, kind, flow(args), "action " + std::to_string(i + 1) + " (" + std::to_string(n + 1) + ")"});
      }
      continue;
    }
    if (a["from"] || a["to"]) {  // from T0 to T1 ramp KEY from A to B in N steps
      command_of(where, a, {"from", "to", "ramp", "steps"}, kind, args);
      if (!a["from"] || !a["to"] || !a["ramp"]) fail(where, a, "a ramp needs from, to (s) and ramp: {key, from, to}");
      const double t0 = number(where, a["from"], "from", 0, 1e9), t1 = number(where, a["to"], "to", t0, 1e9);
      const YAML::Node r = a["ramp"];
      if (!r.IsMap() || !r["key"] || !r["from"] || !r["to"]) fail(where, r, "ramp needs key, from, to");
      const std::string key = word(where, r["key"], "ramp.key");
      const double v0 = number(where, r["from"], "ramp.from", -1e12, 1e12), v1 = number(where, r["to"], "ramp.to", -1e12, 1e12);
      const int steps = a["steps"] ? whole(where, a["steps"], "steps", 1, 10000) : 10;
      for (int k = 0; k <= steps; ++k) {
        if (s.events.size() >= kMaxEvents) fail(where, a, "the script has more than 100000 events in all");
        const double w = static_cast<double>(k) / steps;
        YAML::Node ak = YAML::Clone(args);
        ak[key] = v0 + w * (v1 - v0);
        s.events.push_back({t0 + w * (t1 - t0), kind, flow(ak),
                            "action " + std::to_string(i + 1) + " (ramp " + std::to_string(k) + "/" + std::to_string(steps) + ")"});
      }
      continue;
    }
    fail(where, a, "needs 'at' (s) or a ramp 'from'/'to'");
  }
  std::stable_sort(s.events.begin(), s.events.end(), [](const CycleEvent& a, const CycleEvent& b) { return a.time_s < b.time_s; });
  return s;
}
}  // namespace

CycleScript load_cycle(const std::string& path) {
  if (const std::string bad = io::input_file_problem(path); !bad.empty()) throw CycleError(path + ": cannot open the cycle script: " + bad);
  std::ifstream f(path);
  if (!f) throw CycleError(path + ": cannot open the cycle script");
  std::stringstream ss;
  ss << f.rdbuf();
  return parse_cycle(ss.str(), path);
}

int play_cycle(Client& client, const std::string& run_id, CycleScript script, std::ostream& log) {
  auto first = client.next_state(run_id, 10s);
  if (!first) {
    log << "cycle: no state from '" << run_id << "'\n";
    return 4;
  }
  const double t0 = script.absolute_time ? 0.0 : first->time_s;
  log << "cycle '" << script.name << "': " << script.events.size() << " actions on run '" << run_id << "', script time 0 = run time "
      << t0 << " s\n";
  long frame = static_cast<long>(first->frame);
  double now = first->time_s;
  int rejected = 0;
  auto& ev = script.events;
  while (!ev.empty()) {
    std::stable_sort(ev.begin(), ev.end(), [](const CycleEvent& a, const CycleEvent& b) { return a.time_s < b.time_s; });
    CycleEvent e = ev.front();
    ev.erase(ev.begin());
    while (now < t0 + e.time_s - 1e-9) {  // wait for the run to reach the action's time
      const auto st = client.next_state(run_id, 10s, frame);
      if (!st) {
        log << "cycle: run '" << run_id << "' stopped publishing at t = " << now << " s\n";
        return 4;
      }
      frame = static_cast<long>(st->frame), now = st->time_s;
    }
    const Ack ack = client.send(run_id, e.kind, e.args);
    char line[512];
    std::snprintf(line, sizeof line, "t=%9.4f s (script %8.4f s)  %-16s %-48s %s at frame %lu%s%s\n", now, e.time_s, e.kind.c_str(),
                  e.args.c_str(), ack.accepted ? "accepted" : "REJECTED", ack.frame, ack.accepted ? "" : ": ",
                  ack.accepted ? "" : ack.reason.c_str());
    log << line << std::flush;
    if (!ack.accepted) {
      ++rejected;
      if (script.stop_on_reject) return 3;
    }
    if (e.every_beat && e.repeat_left > 0) {  // next one a heart period on, at the service's rate
      const auto st = client.status(run_id, 5s);
      const double bpm = st ? st->heart_rate_bpm : 0.0;
      if (bpm <= 0) {
        log << "cycle: " << e.label << " repeats every beat but the run has no contraction\n";
        return 3;
      }
      CycleEvent next = e;
      next.time_s = e.time_s + 60.0 / bpm;
      --next.repeat_left;
      if (next.time_s <= e.repeat_until_s + 1e-9) ev.push_back(next);
    }
  }
  log << "cycle '" << script.name << "': done, " << rejected << " rejected\n";
  return rejected ? 3 : 0;
}

}  // namespace fiberfem::clients
