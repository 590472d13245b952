// The replay loop: an archive clock advancing at `rate` while playing; each iteration
// handles commands, publishes the newest frame at or before the clock, and sleeps until
// the next frame is due (listening for commands meanwhile).

#include "service/replay.hpp"

#include "service/archive/archive.hpp"
#include "service/run_endpoints.hpp"
#include "service/stop_signals.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <csignal>
#include <cstdio>
#include <ostream>
#include <stdexcept>

namespace fiberfem::service {
namespace {

using Clock = std::chrono::steady_clock;


struct Reject : std::runtime_error {
  using std::runtime_error::runtime_error;
};

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

double number_arg(const YAML::Node& args, const char* key, double lo, double hi) {
  double v = 0;
  try {
    v = args[key].as<double>();
  } catch (const YAML::Exception&) {
    throw Reject(std::string("'") + key + "' must be a number");
  }
  if (!std::isfinite(v)) throw Reject(std::string("'") + key + "' is not finite");
  if (v < lo || v > hi) {
    std::ostringstream m;
    m << "'" << key << "' = " << v << " is out of range [" << lo << ", " << hi << "]";
    throw Reject(m.str());
  }
  return v;
}

// A whole number in [lo, hi] (a count or a frame).
long whole_arg(const YAML::Node& args, const char* key, double lo, double hi) {
  const double v = number_arg(args, key, lo, hi);
  if (v != std::floor(v)) throw Reject(std::string("'") + key + "' must be a whole number");
  return static_cast<long>(v);
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
  archive::ArchiveReader reader(options.path, options.follow);
  const archive::ArchiveHeader& h = reader.header();
  if (reader.frames() == 0 && !options.follow) throw std::runtime_error(options.path + ": the archive has no frames");

  // The topology, as the live service published it (boundary from the rest mesh).
  const core::TetMesh mesh(h.rest_positions, h.tets, h.regions);
  TopologyData topo;
  topo.scene_name = h.scene_name;
  topo.scene_hash = h.scene_sha256;
  topo.replay = true;
  topo.num_nodes = mesh.num_nodes();
  topo.num_elements = mesh.num_elements();
  for (int n = 0; n < mesh.num_nodes(); ++n)
    for (int d = 0; d < 3; ++d) topo.rest_positions.push_back(static_cast<float>(h.rest_positions(d, n)));
  for (const auto& t : h.tets) topo.tets.insert(topo.tets.end(), t.begin(), t.end());
  for (const auto& t : mesh.boundary_triangles()) topo.triangles.insert(topo.triangles.end(), t.begin(), t.end());
  topo.triangle_elements.assign(mesh.boundary_triangle_elements().begin(), mesh.boundary_triangle_elements().end());
  topo.element_regions.assign(h.regions.begin(), h.regions.end());
  std::vector<double> peaks;
  scene_facts(h.scene_yaml, mesh.num_regions(), topo.region_names, peaks);
  core::Contraction peak_table;  // the peaks only, for Contraction::activation
  peak_table.region_peak_pa = peaks;
  const bool has_peaks = std::any_of(peaks.begin(), peaks.end(), [](double p) { return p > 0; });
  for (const auto& f : h.fibers)
    for (int d = 0; d < 3; ++d) topo.fibers.push_back(static_cast<float>(f(d)));
  for (int n = 0; n < mesh.num_nodes(); ++n)
    if (!h.fixed_dofs.empty() && (h.fixed_dofs[3 * static_cast<size_t>(n)] || h.fixed_dofs[3 * static_cast<size_t>(n) + 1] ||
                                  h.fixed_dofs[3 * static_cast<size_t>(n) + 2]))
      topo.fixed_nodes.push_back(n);

  const std::string run_id = options.run_id.empty() ? default_run_id("replay-" + h.scene_name) : options.run_id;
  std::unique_ptr<RunEndpoints> bus;
  try {
    bus = std::make_unique<RunEndpoints>(run_id);
  } catch (const dds::DdsError& e) {
    out << "fiberfem replay: " << e.what() << "\n";
    return 1;
  }
  bus->publish_topology(topo);

  std::vector<double> times = reader.times();
  std::vector<long> steps = reader.steps();
  long index = std::lower_bound(times.begin(), times.end(), options.from_s - 1e-9) - times.begin();
  if (index >= static_cast<long>(times.size())) index = std::max<long>(0, static_cast<long>(times.size()) - 1);
  double clock_s = times.empty() ? 0.0 : times[static_cast<size_t>(index)];
  bool paused = options.paused, loop = options.loop, shutdown = false;
  double rate = options.rate;
  long ordered_steps = 0;
  unsigned version = 0;
  long published = -1, published_count = 0;
  std::vector<float> pos, act;

  out << "fiberfem replay: run '" << run_id << "' from " << options.path << " (scene '" << h.scene_name << "', " << times.size()
      << " frames, " << (times.empty() ? 0.0 : times.back()) << " s) at x" << rate << (loop ? ", looping" : "") << "\n"
      << std::flush;

  auto publish = [&](long i) {
    const archive::Frame f = reader.frame(i);
    pos.resize(static_cast<size_t>(f.positions.size()));
    for (Eigen::Index k = 0; k < f.positions.size(); ++k) pos[static_cast<size_t>(k)] = static_cast<float>(f.positions.data()[k]);
    // Over the archived scene's peaks; in Pa when the scene text gave none.
    const std::vector<double> a = has_peaks ? peak_table.activation(h.regions, f.activation_pa) : f.activation_pa;
    act.assign(a.begin(), a.end());
    bus->publish_state(static_cast<unsigned long>(f.step), f.time_s, version, pos, act);
    published = i;
    ++published_count;
  };

  // Commands: the service's run controls plus seek, rate and loop (docs/replay.md).
  auto apply = [&](const std::string& kind, const std::string& text, const std::string&) -> CommandReply {
    try {
      YAML::Node args = YAML::Load(text.empty() ? "{}" : text);
      if (args.IsNull()) args = YAML::Node(YAML::NodeType::Map);
      if (!args.IsMap()) throw Reject("arguments must be a JSON object");
      auto allow = [&](std::initializer_list<const char*> keys) {
        for (const auto& kv : args) {
          if (!kv.first.IsScalar()) throw Reject("argument names must be words, not lists or objects");
          const std::string k = kv.first.as<std::string>();
          if (std::none_of(keys.begin(), keys.end(), [&](const char* a) { return k == a; }))
            throw Reject("unknown argument '" + k + "' for " + kind);
        }
      };
      CommandReply r{true, ""};
      if (kind == "pause") {
        allow({});
        paused = true, ordered_steps = 0, r.reason = "paused";
      } else if (kind == "resume") {
        allow({});
        paused = false, ordered_steps = 0, r.reason = "playing";
      } else if (kind == "step") {
        allow({"count"});
        const long n = args["count"] ? whole_arg(args, "count", 1, 1e6) : 1;
        paused = true, ordered_steps += n, r.reason = std::to_string(n) + " frames ordered, then paused";
      } else if (kind == "seek") {
        allow({"time", "frame"});
        if (static_cast<bool>(args["time"]) == static_cast<bool>(args["frame"])) throw Reject("give exactly one of 'time' (s) and 'frame'");
        if (times.empty()) throw Reject("the archive has no frames yet");
        long i = 0;
        if (args["time"]) {
          const double t = number_arg(args, "time", 0, 1e12);
          i = std::upper_bound(times.begin(), times.end(), t + 1e-9) - times.begin() - 1;  // last frame at or before t
          i = std::max<long>(0, i);
        } else {
          const double fr = static_cast<double>(whole_arg(args, "frame", 0, 1e15));
          i = std::lower_bound(steps.begin(), steps.end(), static_cast<long>(fr)) - steps.begin();
          if (i >= static_cast<long>(steps.size())) throw Reject("no frame " + std::to_string(static_cast<long>(fr)) + " (last is " + std::to_string(steps.back()) + ")");
        }
        index = i, clock_s = times[static_cast<size_t>(i)], published = -1;
        r.reason = "at frame " + std::to_string(steps[static_cast<size_t>(i)]) + ", t = " + std::to_string(clock_s) + " s";
      } else if (kind == "set_rate") {
        allow({"rate"});
        if (!args["rate"]) throw Reject("needs 'rate' (archive seconds per wall second)");
        rate = number_arg(args, "rate", 1e-3, 1000), r.reason = "rate set";
      } else if (kind == "loop") {
        allow({"on"});
        try {
          loop = args["on"] ? args["on"].as<bool>() : true;
        } catch (const YAML::Exception&) {
          throw Reject("'on' must be true or false");
        }
        r.reason = loop ? "looping" : "not looping";
      } else if (kind == "shutdown") {
        allow({});
        shutdown = true, r.reason = "shutting down";
      } else {
        throw Reject("'" + kind + "' is not a replay command (replay takes pause, resume, step, seek, set_rate, loop, shutdown)");
      }
      ++version;
      return r;
    } catch (const YAML::Exception& e) {
      return {false, "arguments are not valid JSON: " + e.msg};
    } catch (const std::exception& e) {
      return {false, e.what()};
    }
  };

  const StopSignals stop_signals;
  const auto t_begin = Clock::now();
  auto t_last = Clock::now(), t_status = Clock::now() - std::chrono::hours(1), t_state = Clock::now();
  long frames_in_period = 0;
  std::string stop = "shut down by command";
  for (;;) {
    bus->handle_commands(apply, [&] {
      return std::make_pair(static_cast<unsigned long>(times.empty() ? 0 : steps[static_cast<size_t>(index)]), version);
    });
    if (shutdown) break;
    if (stop_signals.caught()) {
      stop = std::string("stopped by ") + stop_signals.name();
      break;
    }
    const auto now = Clock::now();
    const double dt_wall = std::chrono::duration<double>(now - t_last).count();
    t_last = now;
    const long last = static_cast<long>(times.size()) - 1;
    if (!paused && last >= 0) {
      clock_s += rate * dt_wall;
      if (options.every_frame) {  // at most one frame on per iteration; the clock waits for it
        if (index < last && times[static_cast<size_t>(index) + 1] <= clock_s + 1e-12) ++index;
        clock_s = std::min(clock_s, index < last ? times[static_cast<size_t>(index) + 1] : clock_s);
      } else {
        while (index < last && times[static_cast<size_t>(index) + 1] <= clock_s + 1e-12) ++index;
      }
    } else if (paused && ordered_steps > 0 && index < last) {
      ++index, --ordered_steps;
      clock_s = times[static_cast<size_t>(index)];
    }
    bool at_end = last >= 0 && index == last && clock_s >= times.back();
    if (at_end && !paused) {
      if (options.follow && reader.refresh() > static_cast<long>(times.size())) {
        times = reader.times(), steps = reader.steps();
        at_end = false;
      } else if (loop) {
        if (published == last) index = 0, clock_s = times.front(), at_end = false;
      }
    }
    if (last >= 0 && index != published) {
      publish(index);
      ++frames_in_period;
      t_state = now;
    } else if (last >= 0 && std::chrono::duration<double>(now - t_state).count() >= 1.0) {
      publish(index);  // at least once a second (the state deadline)
      t_state = now;
    }
    if (at_end && published == last && options.exit_at_end && !loop && !options.follow) {
      stop = "reached the end of the archive";
      break;
    }
    const double since_status = std::chrono::duration<double>(now - t_status).count();
    if (since_status >= 1.0 / options.status_hz) {
      StatusData st;
      st.scene_name = h.scene_name;
      st.replay = true;
      st.mode = "replay";
      st.state = paused ? "paused" : at_end ? "ended" : "replay";
      st.frame = static_cast<unsigned long>(last >= 0 ? steps[static_cast<size_t>(index)] : 0);
      st.time_s = last >= 0 ? times[static_cast<size_t>(index)] : 0.0;
      st.frames_per_second = since_status < 1e6 ? static_cast<double>(frames_in_period) / since_status : 0.0;
      st.real_time_factor = paused || at_end ? 0.0 : rate;
      st.dt_s = h.dt_s;
      st.parameter_version = version;
      st.recording = options.path;
      st.recorded_frames = static_cast<unsigned long>(times.size());
      bus->publish_status(st);
      if (options.status_line) {
        std::fprintf(stderr, "\rreplay %-7s t=%8.3f s  frame %7lu  of %zu  x%.2f   ", st.state.c_str(), st.time_s, st.frame, times.size(), rate);
        std::fflush(stderr);
      }
      frames_in_period = 0;
      t_status = now;
    }
    // Sleep until the next frame is due (or 50 ms), listening for commands.
    double wait_s = 0.05;
    if (!paused && index < last) wait_s = std::min(wait_s, std::max(0.0, (times[static_cast<size_t>(index) + 1] - clock_s) / rate));
    if (paused && ordered_steps > 0) wait_s = 0;
    if (wait_s > 0) bus->wait_for_command(std::chrono::nanoseconds(static_cast<long long>(wait_s * 1e9)));
  }
  if (options.status_line) std::fprintf(stderr, "\n");
  const double wall_s = std::chrono::duration<double>(Clock::now() - t_begin).count();
  out << "fiberfem replay: " << stop << "; " << published_count << " frames published in " << wall_s << " s ("
      << static_cast<double>(published_count) / std::max(wall_s, 1e-9) << " frames/s)\n";
  return 0;
}

}  // namespace fiberfem::service
