// The replay loop: an archive clock advancing at `rate` while playing; each iteration
// handles commands, publishes the newest frame at or before the clock, and sleeps until
// the next frame is due (listening for commands meanwhile). The archive is the frame
// source; the topology and states reach the bus as a live run's do (run_topology,
// RunEndpoints).

#include "service/replay.hpp"

#include "service/archive/archive.hpp"
#include "service/command_args.hpp"
#include "service/run_endpoints.hpp"
#include "service/run_topology.hpp"
#include "service/stop_signals.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <sstream>
#include <stdexcept>

namespace fiberfem::service {
namespace {

using Clock = std::chrono::steady_clock;
using detail::Args;
using detail::Reject;

double seconds_between(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

// Region names and peak tensions from the archived scene text (the peak normalises the
// published activation as the live service does).
void scene_facts(const std::string& yaml, int num_regions, std::vector<std::string>& names, std::vector<double>& peaks) {
  names.assign(static_cast<size_t>(num_regions), "");
  peaks.assign(static_cast<size_t>(num_regions), 0.0);
  try {
    const YAML::Node root = YAML::Load(yaml);
    const YAML::Node regions = root["regions"];
    for (size_t r = 0; regions && r < regions.size() && r < names.size(); ++r)
      names[r] = regions[r]["name"] ? regions[r]["name"].as<std::string>() : "region" + std::to_string(r);
    const YAML::Node c = root["contraction"];
    if (c && c["peak_tension"]) std::fill(peaks.begin(), peaks.end(), c["peak_tension"].as<double>());
    if (c && c["regions"])
      for (const auto& kv : c["regions"]) {
        const auto it = std::find(names.begin(), names.end(), kv.first.as<std::string>());
        if (it != names.end()) peaks[static_cast<size_t>(it - names.begin())] = kv.second.as<double>();
      }
  } catch (const YAML::Exception&) {
    // An unreadable scene text leaves names empty and activation in Pa / 1 (documented).
  }
}

// The archive as a frame source: its frames' times and steps, the frame shown and the
// archive clock, and how a frame becomes a published state.
class Playback {
 public:
  explicit Playback(const ReplayOptions& o) : reader_(o.path, o.follow), times_(reader_.times()), steps_(reader_.steps()) {
    const archive::ArchiveHeader& h = reader_.header();
    if (reader_.frames() == 0 && !o.follow) throw std::runtime_error(o.path + ": the archive has no frames");
    index_ = std::lower_bound(times_.begin(), times_.end(), o.from_s - 1e-9) - times_.begin();
    if (index_ >= static_cast<long>(times_.size())) index_ = std::max<long>(0, static_cast<long>(times_.size()) - 1);
    clock_s_ = times_.empty() ? 0.0 : times_[static_cast<size_t>(index_)];
    const core::TetMesh mesh(h.rest_positions, h.tets, h.regions);  // the boundary, from the rest mesh
    std::vector<std::string> names;
    std::vector<double> peaks;
    scene_facts(h.scene_yaml, mesh.num_regions(), names, peaks);
    topology_ = topology_record(mesh, h.fibers, h.fixed_dofs, names, {});
    topology_.scene_name = h.scene_name;
    topology_.scene_hash = h.scene_sha256;
    topology_.replay = true;
    peak_table_.region_peak_pa = peaks;
    has_peaks_ = std::any_of(peaks.begin(), peaks.end(), [](double p) { return p > 0; });
  }

  const archive::ArchiveHeader& header() const { return reader_.header(); }
  const TopologyData& topology() const { return topology_; }
  long frames() const { return static_cast<long>(times_.size()); }
  long last() const { return frames() - 1; }
  long index() const { return index_; }
  double clock_s() const { return clock_s_; }
  double end_s() const { return times_.empty() ? 0.0 : times_.back(); }
  double time_s() const { return times_.empty() ? 0.0 : times_[static_cast<size_t>(index_)]; }
  long step() const { return times_.empty() ? 0 : steps_[static_cast<size_t>(index_)]; }
  bool at_end() const { return last() >= 0 && index_ == last() && clock_s_ >= times_.back(); }
  /// Wall time until the next frame is due at `rate`, s (infinite at the last).
  double until_next_s(double rate) const {
    return index_ < last() ? std::max(0.0, (times_[static_cast<size_t>(index_) + 1] - clock_s_) / rate) : HUGE_VAL;
  }

  // The clock runs `dt_s` of archive time on: to the newest due frame, or (every_frame)
  // at most one frame on, the clock waiting for it.
  void advance(double dt_s, bool every_frame) {
    if (last() < 0) return;
    clock_s_ += dt_s;
    if (every_frame) {
      if (index_ < last() && next_time() <= clock_s_ + 1e-12) ++index_;
      clock_s_ = std::min(clock_s_, index_ < last() ? next_time() : clock_s_);
    } else {
      while (index_ < last() && next_time() <= clock_s_ + 1e-12) ++index_;
    }
  }
  // One frame on (an ordered step). @return false at the last frame.
  bool step_on() {
    if (index_ >= last()) return false;
    ++index_;
    clock_s_ = times_[static_cast<size_t>(index_)];
    return true;
  }
  void seek(long i) {
    index_ = i;
    clock_s_ = times_[static_cast<size_t>(i)];
  }
  // The last frame at or before t.
  long frame_at_time(double t) const {
    return std::max<long>(0, std::upper_bound(times_.begin(), times_.end(), t + 1e-9) - times_.begin() - 1);
  }
  // The first frame of a step at or after `step`, or frames().
  long frame_of_step(long step) const { return std::lower_bound(steps_.begin(), steps_.end(), step) - steps_.begin(); }
  long last_step() const { return steps_.back(); }
  // Following a live file: the frames written since. @return whether there are new ones.
  bool refresh() {
    if (reader_.refresh() <= frames()) return false;
    times_ = reader_.times(), steps_ = reader_.steps();
    return true;
  }

  // The frame's state, and its circulation when the archive has one.
  void publish(RunEndpoints& bus, unsigned version) {
    const archive::Frame f = reader_.frame(index_);
    // Over the archived scene's peaks; in Pa when the scene text gave none.
    const std::vector<double> a = has_peaks_ ? peak_table_.activation(header().regions, f.activation_pa) : f.activation_pa;
    bus.publish_state(static_cast<unsigned long>(f.step), f.time_s, version, f.positions, {}, a);
    if (f.circulation) bus.publish_circulation(static_cast<unsigned long>(f.step), *f.circulation);
  }

 private:
  double next_time() const { return times_[static_cast<size_t>(index_) + 1]; }

  archive::ArchiveReader reader_;
  std::vector<double> times_;
  std::vector<long> steps_;
  long index_ = 0;
  double clock_s_ = 0;
  TopologyData topology_;
  core::Contraction peak_table_;  // the peaks only, for Contraction::activation
  bool has_peaks_ = false;
};

// What the replay's commands change (docs/replay.md).
struct Controls {
  bool paused = false, loop = false, shutdown = false;
  double rate = 1.0;
  long ordered_steps = 0;
  unsigned version = 0;  // bumped by every accepted command
};

std::string seek(Playback& p, const Args& a) {
  if (a.has("time") == a.has("frame")) throw Reject("give exactly one of 'time' (s) and 'frame'");
  if (p.frames() == 0) throw Reject("the archive has no frames yet");
  long i = 0;
  if (a.has("time")) {
    i = p.frame_at_time(a.number("time", 0, 1e12));
  } else {
    const long step = a.whole("frame", 0, 1e15);
    i = p.frame_of_step(step);
    if (i >= p.frames()) throw Reject("no frame " + std::to_string(step) + " (last is " + std::to_string(p.last_step()) + ")");
  }
  p.seek(i);
  return "at frame " + std::to_string(p.step()) + ", t = " + std::to_string(p.clock_s()) + " s";
}

// The service's run controls plus seek, rate and loop; `text` is the arguments (JSON),
// checked against what `kind` allows before anything changes.
std::string apply(Playback& p, Controls& c, const std::string& kind, const std::string& text) {
  if (kind == "pause" || kind == "resume") {
    Args a(text, {});
    c.paused = kind == "pause", c.ordered_steps = 0;
    return c.paused ? "paused" : "playing";
  }
  if (kind == "step") {
    Args a(text, {"count"});
    const long n = a.has("count") ? a.whole("count", 1, 1e6) : 1;
    c.paused = true, c.ordered_steps += n;
    return std::to_string(n) + " frames ordered, then paused";
  }
  if (kind == "seek") return seek(p, Args(text, {"time", "frame"}));
  if (kind == "set_rate") {
    Args a(text, {"rate"});
    if (!a.has("rate")) throw Reject("needs 'rate' (archive seconds per wall second)");
    c.rate = a.number("rate", 1e-3, 1000);
    return "rate set";
  }
  if (kind == "loop") {
    Args a(text, {"on"});
    c.loop = a.has("on") ? a.boolean("on") : true;
    return c.loop ? "looping" : "not looping";
  }
  if (kind == "shutdown") {
    Args a(text, {});
    c.shutdown = true;
    return "shutting down";
  }
  throw Reject("'" + kind + "' is not a replay command (replay takes pause, resume, step, seek, set_rate, loop, shutdown)");
}

CommandReply apply_command(Playback& p, Controls& c, const std::string& kind, const std::string& text) {
  try {
    CommandReply r{true, apply(p, c, kind, text)};
    ++c.version;
    return r;
  } catch (const std::exception& e) {
    return {false, e.what()};
  }
}

void publish_status(RunEndpoints& bus, const Playback& p, const Controls& c, const ReplayOptions& o, bool at_end,
                    long frames_in_period, double period_s) {
  StatusData st;
  st.scene_name = p.header().scene_name;
  st.replay = true;
  st.mode = "replay";
  st.state = c.paused ? "paused" : at_end ? "ended" : "replay";
  st.frame = static_cast<unsigned long>(p.step());
  st.time_s = p.time_s();
  st.frames_per_second = period_s < 1e6 ? static_cast<double>(frames_in_period) / period_s : 0.0;
  st.real_time_factor = c.paused || at_end ? 0.0 : c.rate;
  st.dt_s = p.header().dt_s;
  st.parameter_version = c.version;
  st.recording = o.path;
  st.recorded_frames = static_cast<unsigned long>(p.frames());
  bus.publish_status(st);
  if (o.status_line) {
    std::fprintf(stderr, "\rreplay %-7s t=%8.3f s  frame %7lu  of %ld  x%.2f   ", st.state.c_str(), st.time_s,
                 static_cast<unsigned long>(st.frame), p.frames(), c.rate);
    std::fflush(stderr);
  }
}

}  // namespace

void ReplayOptions::validate() const {
  if (path.empty()) throw std::invalid_argument("replay: no archive given");
  if (!(rate > 0 && rate <= 1000)) throw std::invalid_argument("replay: --rate " + std::to_string(rate) + " must be in (0, 1000]");
  if (!(from_s >= 0 && std::isfinite(from_s))) throw std::invalid_argument("replay: from must be >= 0");
  if (!(status_hz > 0 && status_hz <= 100)) throw std::invalid_argument("replay: status_hz must be in (0, 100]");
}

int replay(const ReplayOptions& options, std::ostream& out) {
  options.validate();
  Playback p(options);
  const std::string run_id = options.run_id.empty() ? default_run_id("replay-" + p.header().scene_name) : options.run_id;
  std::unique_ptr<RunEndpoints> bus;
  try {
    bus = std::make_unique<RunEndpoints>(run_id);
  } catch (const dds::DdsError& e) {
    out << "fiberfem replay: " << e.what() << "\n";
    return 1;
  }
  if (!p.header().circulation_columns.empty())
    if (const std::string refused = bus->enable_circulation(); !refused.empty()) out << "fiberfem replay: " << refused << "\n";
  bus->publish_topology(p.topology());
  Controls c;
  c.paused = options.paused, c.loop = options.loop, c.rate = options.rate;
  out << "fiberfem replay: run '" << run_id << "' from " << options.path << " (scene '" << p.header().scene_name << "', "
      << p.frames() << " frames, " << p.end_s() << " s) at x" << c.rate << (c.loop ? ", looping" : "") << "\n" << std::flush;

  const StopSignals stop_signals;
  const auto t_begin = Clock::now();
  auto t_last = t_begin, t_status = t_begin - std::chrono::hours(1), t_state = t_begin;
  long published = -1, published_count = 0, frames_in_period = 0;
  std::string stop = "shut down by command";
  for (;;) {
    bus->handle_commands(
        [&](const std::string& kind, const std::string& args, const std::string&) {
          const CommandReply r = apply_command(p, c, kind, args);
          if (kind == "seek" && r.accepted) published = -1;  // the frame sought is published even if shown
          return r;
        },
        [&] { return std::make_pair(static_cast<unsigned long>(p.step()), c.version); });
    if (c.shutdown) break;
    if (stop_signals.caught()) {
      stop = std::string("stopped by ") + stop_signals.name();
      break;
    }
    const auto now = Clock::now();
    const double dt_wall = seconds_between(t_last, now);
    t_last = now;
    if (!c.paused) p.advance(c.rate * dt_wall, options.every_frame);
    else if (c.ordered_steps > 0 && p.step_on()) --c.ordered_steps;
    bool at_end = p.at_end();
    if (at_end && !c.paused) {
      if (options.follow && p.refresh()) at_end = false;
      else if (c.loop && published == p.last()) p.seek(0), at_end = false;
    }
    const bool fresh = p.last() >= 0 && p.index() != published;
    if (fresh || (p.last() >= 0 && seconds_between(t_state, now) >= 1.0)) {  // and at least once a second (the deadline)
      p.publish(*bus, c.version);
      published = p.index(), ++published_count, t_state = now;
      frames_in_period += fresh;
    }
    if (at_end && published == p.last() && options.exit_at_end && !c.loop && !options.follow) {
      stop = "reached the end of the archive";
      break;
    }
    if (seconds_between(t_status, now) >= 1.0 / options.status_hz) {
      publish_status(*bus, p, c, options, at_end, frames_in_period, seconds_between(t_status, now));
      frames_in_period = 0, t_status = now;
    }
    // Sleep until the next frame is due (or 50 ms), listening for commands.
    double wait_s = 0.05;
    if (!c.paused) wait_s = std::min(wait_s, p.until_next_s(c.rate));
    if (c.paused && c.ordered_steps > 0) wait_s = 0;
    if (wait_s > 0) bus->wait_for_command(std::chrono::nanoseconds(static_cast<long long>(wait_s * 1e9)));
  }
  if (options.status_line) std::fprintf(stderr, "\n");
  const double wall_s = seconds_between(t_begin, Clock::now());
  out << "fiberfem replay: " << stop << "; " << published_count << " frames published in " << wall_s << " s ("
      << static_cast<double>(published_count) / std::max(wall_s, 1e-9) << " frames/s)\n";
  return 0;
}

}  // namespace fiberfem::service
