// `fiberfem render SCENE.yaml --out DIR` simulates a scene as `fiberfem run` does and
// draws every K-th step off-screen (clients/render, docs/rendering.md): PNG frames, an
// MP4 through ffmpeg, and a strip of one beat for documentation.

#include "clients/render/png_io.hpp"
#include "clients/render/renderer.hpp"
#include "clients/render/surface.hpp"
#include "clients/render/video_writer.hpp"
#include "core/static_solver.hpp"
#include "io/scene.hpp"
#include "service/app/commands.hpp"
#include "service/stop_signals.hpp"
#ifdef FIBERFEM_HAVE_ARCHIVE
#include "service/archive/archive.hpp"
#endif
#ifdef FIBERFEM_WITH_DDS
#include "clients/ctl/client.hpp"
#endif

#include <CLI/CLI.hpp>

#include <algorithm>
#include <csignal>
#include <functional>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <unistd.h>

namespace fiberfem::service {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct RenderArgs {
  std::string scene_file, out_dir, field, camera = "iso", fit = "rest", mp4, strip;
  std::vector<double> eye, target, up, range, at;
  double fov = 30, until = 0, fps = 0, margin = 0.1;
  int width = 1280, height = 720, every = 1, steps = 0, png_level = 1, supersample = 1, strip_panels = 8, strip_width = 240;
  std::vector<std::string> overrides;
  std::string run_id;     // --live: the run (default the only one)
  long live_frames = 0;   // --live: stop after this many frames (0: at --until or Ctrl-C)
  bool live = false;
  bool fibers = false, no_png = false, time = false, no_overlay = false, force_static = false, last = false, flat = false, vertex_lighting = false;
};

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

core::Vec3 vec3(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

// The camera: a preset framing the rest shape, then any explicit key on top.
// With a colour bar (or legend) at the right edge, the object is framed in the image's
// left part and the camera moved so that it is centred there.
render::Camera make_camera(const RenderArgs& a, const core::Positions& points, CLI::App& cmd, bool side_bar) {
  const double aspect = static_cast<double>(a.width) / a.height;
  const double reserve = side_bar ? 0.12 : 0.0;  // share of the width kept for the bar
  render::Camera cam = render::frame_points(render::parse_camera_preset(a.camera), points, aspect * (1 - reserve), a.fov, a.margin);
  if (reserve > 0) {
    const core::Vec3 view = cam.target - cam.eye;
    const double half_width = view.norm() * std::tan(0.5 * cam.fov_deg * M_PI / 180) * aspect;  // at the target, m
    const core::Vec3 shift = view.cross(cam.up).normalized() * reserve * half_width;
    cam.target += shift, cam.eye += shift;
  }
  if (!a.target.empty()) {
    const core::Vec3 shift = vec3(a.target) - cam.target;
    cam.target += shift, cam.eye += shift;
  }
  if (!a.eye.empty()) cam.eye = vec3(a.eye);
  if (!a.up.empty()) cam.up = vec3(a.up);
  if (cmd.count("--fov")) cam.fov_deg = a.fov;
  cam.validate();
  return cam;
}

// "heart    t = 0.100 s    beat 1    60 fps": the frame rate only for a sequence (every
// K-th step; the MP4's rate), not for single frames picked with --at or --last.
std::string caption_of(const io::Scene& sc, double t, double fps) {
  char buf[256];
  const core::Contraction& c = sc.model.contraction;
  int n = std::snprintf(buf, sizeof buf, "%s    t = %.3f s", sc.name.c_str(), t);
  if (c.enabled())
    n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "    beat %ld", static_cast<long>(std::floor(t / c.period_s + 1e-9)) + 1);
  if (fps > 0) std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "    %.3g fps", fps);
  return buf;
}

// Creates --out (when PNG frames are written) or says why it cannot.
void prepare_out_dir(const RenderArgs& a) {
  if (a.out_dir.empty() || a.no_png) return;
  std::error_code ec;
  std::filesystem::create_directories(a.out_dir, ec);
  if (ec || access(a.out_dir.c_str(), W_OK) != 0)
    throw std::runtime_error("--out " + a.out_dir + ": cannot create or write the directory" + (ec ? ": " + ec.message() : ""));
}

// The MP4 writer when --mp4 is given.
std::unique_ptr<render::VideoWriter> make_video(const RenderArgs& a, double fps) {
  if (a.mp4.empty()) return nullptr;
  render::VideoSettings vs;
  vs.path = a.mp4, vs.width = a.width, vs.height = a.height, vs.fps = fps;
  return std::make_unique<render::VideoWriter>(vs);
}

// One panel of a strip: an owned copy of a state.
struct Panel {
  core::Positions x;
  std::vector<double> activation;
  double t;
};

// The strip: panels drawn at twice the panel size and averaged down; two passes so that an
// automatic colour range covers every panel before any is drawn.
void write_strip(const RenderArgs& a, const render::RenderSettings& rs, const core::TetMesh& mesh, const std::vector<core::Vec3>& fibers,
                 bool contracting, const render::Camera& camera, const std::vector<Panel>& panels) {
  render::RenderSettings ps = rs;
  ps.width = 2 * a.strip_width;
  ps.height = std::max(16, static_cast<int>(std::lround(ps.width * static_cast<double>(a.height) / a.width)));
  ps.colour_bar = false;
  ps.supersample = 1;
  ps.font_px = std::max(9, ps.height / 9);
  render::Renderer strip_renderer(mesh, ps);
  strip_renderer.set_camera(camera);
  std::vector<render::Image> images;
  for (int pass = 0; pass < 2; ++pass)
    for (const Panel& p : panels) {
      render::FrameView frame(mesh, p.x);
      frame.activation = contracting ? &p.activation : nullptr;
      frame.fibers = &fibers;
      frame.time_s = p.t;
      char cap[64];
      std::snprintf(cap, sizeof cap, "t = %.2f s", p.t);
      frame.caption = cap;
      const render::Image& im = strip_renderer.render(frame);
      if (pass == 1) images.push_back(render::downscale(im, a.strip_width, ps.height / 2));
    }
  render::write_png(a.strip, render::hstack(images, 4), 9);
}

// A source of frames other than a simulation run here: an archive or the live bus.
struct Feed {
  std::string name, origin;
  std::optional<core::TetMesh> mesh;  // the rest mesh (set by the feed's maker)
  std::vector<core::Vec3> fibers;
  core::Contraction contraction;  // for activation (normalised by the peaks) and beats
  bool has_activation = false;
  double frame_dt_s = 0;          // time between frames (the default video rate), s
  long total = -1;                // frames, when known (an archive)
  // The next frame: positions, activation (normalised, may be empty), time, step;
  // false at the end.
  std::function<bool(core::Positions&, std::vector<double>&, double&, long&)> next;
};


std::string feed_caption(const Feed& f, double t, double fps) {
  char buf[256];
  int n = std::snprintf(buf, sizeof buf, "%s    t = %.3f s", f.name.c_str(), t);
  if (f.contraction.enabled())
    n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "    beat %ld",
                       static_cast<long>(std::floor(t / f.contraction.period_s + 1e-9)) + 1);
  if (fps > 0) std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "    %.3g fps", fps);
  return buf;
}

// Renders a feed: every K-th frame (or the frames nearest --at, or the last), PNG, MP4
// and a strip of the first beat, as for a scene.
int render_feed(CLI::App& cmd, RenderArgs& a, Feed& feed) {
  if (a.out_dir.empty() && !a.no_png) throw std::invalid_argument("--out DIR is required (or --no-png with --mp4 / --strip)");
  if (a.no_png && a.mp4.empty() && a.strip.empty()) throw std::invalid_argument("--no-png leaves nothing to write: add --mp4 or --strip");
  if (a.png_level < 0 || a.png_level > 9) throw std::invalid_argument("--png-level " + std::to_string(a.png_level) + " is outside [0, 9]");
  if (a.last && !a.at.empty()) throw std::invalid_argument("--last and --at exclude each other");
  if (a.last && feed.total < 0) throw std::invalid_argument("--last needs an archive (a live run has no last frame)");
  render::RenderSettings rs;
  rs.width = a.width, rs.height = a.height, rs.supersample = a.supersample, rs.fibers = a.fibers;
  rs.field = a.field.empty() ? (feed.has_activation ? render::Field::activation : render::Field::displacement) : render::parse_field(a.field);
  if (!a.range.empty()) rs.range = std::make_pair(a.range[0], a.range[1]);
  rs.colour_bar = rs.caption = !a.no_overlay;
  rs.smooth = !a.flat;
  rs.per_pixel_lighting = !a.vertex_lighting;
  rs.validate();
  if (rs.field == render::Field::activation && !feed.has_activation)
    throw std::invalid_argument("--field activation: " + feed.origin + " has no activation (try --field displacement)");
  const render::Camera camera = make_camera(a, render::surface_points(*feed.mesh), cmd, !a.no_overlay && rs.field != render::Field::none);
  prepare_out_dir(a);
  const double fps = a.fps > 0 ? a.fps : std::clamp(1.0 / (a.every * std::max(feed.frame_dt_s, 1e-6)), 1.0, 240.0);
  render::Renderer renderer((*feed.mesh), rs);
  renderer.set_camera(camera);
  std::unique_ptr<render::VideoWriter> video = make_video(a, fps);
  const double strip_span = feed.contraction.enabled() ? feed.contraction.period_s : HUGE_VAL;
  std::vector<Panel> panels;
  int next_panel = 0;
  std::vector<double> at = a.at;
  std::sort(at.begin(), at.end());
  size_t next_at = 0;
  std::cout << "fiberfem render: " << feed.origin << " (scene '" << feed.name << "'), " << (*feed.mesh).num_nodes() << " nodes, field "
            << render::to_string(rs.field) << ", " << a.width << "x" << a.height << ", every " << a.every << " frames, "
            << renderer.describe() << "\n" << std::flush;
  const bool tty = isatty(fileno(stderr)) != 0;
  const StopSignals stop_signals(/*term_too=*/false);
  core::Positions x;
  std::vector<double> act;
  double t = 0, t_first = -1;
  long step = 0, index = -1, frames = 0;
  const auto t_run = Clock::now();
  while (!stop_signals.caught() && feed.next(x, act, t, step)) {
    ++index;
    if (t_first < 0) t_first = t;
    if (!a.strip.empty() && next_panel < a.strip_panels && strip_span < HUGE_VAL &&
        t - t_first + 0.5 * feed.frame_dt_s >= next_panel * strip_span / a.strip_panels) {
      panels.push_back({x, act, t});
      ++next_panel;
    }
    if (a.no_png && !video) continue;
    if (!at.empty()) {
      bool wanted = false;
      while (next_at < at.size() && t + 0.5 * feed.frame_dt_s >= at[next_at]) ++next_at, wanted = true;
      if (!wanted) continue;
    } else if (a.last ? index != feed.total - 1 : index % a.every != 0) {
      continue;
    }
    render::FrameView frame((*feed.mesh), x);
    frame.activation = act.empty() ? nullptr : &act;
    frame.fibers = &feed.fibers;
    frame.time_s = t;
    frame.caption = feed_caption(feed, t, at.empty() && !a.last ? fps : 0.0);
    const render::Image& image = renderer.render(frame);
    if (!a.no_png) {
      char name[64];
      std::snprintf(name, sizeof name, "/frame-%05ld.png", frames);
      render::write_png(a.out_dir + name, image, a.png_level);
    }
    if (video) video->write(image);
    ++frames;
    if (tty) {
      std::fprintf(stderr, "\rrender: frame %ld  t = %.3f s  %.1f frames/s\033[K", frames, t, frames / std::max(1e-9, since(t_run)));
      std::fflush(stderr);
    }
  }
  if (tty) std::fprintf(stderr, "\n");
  if (video) video->close();
  if (!a.strip.empty()) {
    if (panels.size() < static_cast<size_t>(a.strip_panels))
      throw std::runtime_error("--strip: " + feed.origin + " holds " + std::to_string(panels.size()) + " of " +
                               std::to_string(a.strip_panels) + " panels of a beat (a beat is longer than the frames, or no contraction)");
    write_strip(a, rs, (*feed.mesh), feed.fibers, feed.has_activation, renderer.camera(), panels);
  }
  std::printf("render: %ld frames in %.1f s", frames, since(t_run));
  if (!a.no_png) std::printf(", PNG frames in %s/frame-NNNNN.png", a.out_dir.c_str());
  if (video) std::printf(", video %s (%ld frames at %.3g fps)", a.mp4.c_str(), video->frames(), fps);
  if (!a.strip.empty()) std::printf(", strip %s (%zu panels)", a.strip.c_str(), panels.size());
  std::printf("\n");
  return frames > 0 ? 0 : 1;
}

#ifdef FIBERFEM_HAVE_ARCHIVE
// An archive: the mesh, fibers and regions from its header; the contraction (for the
// activation's normalisation and the beat count) from its scene text when that parses.
int render_archive(CLI::App& cmd, RenderArgs& a) {
  auto reader = std::make_shared<archive::ArchiveReader>(a.scene_file);
  const archive::ArchiveHeader& h = reader->header();
  Feed f;
  f.name = h.scene_name;
  f.origin = "archive " + a.scene_file;
  f.mesh.emplace(h.rest_positions, h.tets, h.regions);
  f.fibers = h.fibers;
  try {
    f.contraction = io::parse_scene(h.scene_yaml, "archive:" + a.scene_file, h.scene_base_dir).model.contraction;
  } catch (const std::exception& e) {
    std::cerr << "fiberfem render: the archived scene does not parse here (" << e.what()
              << "); activation is shown relative to each frame's largest\n";
  }
  f.total = reader->frames();
  if (f.total == 0) throw std::runtime_error(a.scene_file + ": the archive has no frames");
  const std::vector<double> times = reader->times();
  f.frame_dt_s = f.total > 1 ? (times.back() - times.front()) / static_cast<double>(f.total - 1) : h.dt_s;
  // Activation when the scene contracts, or (its text not parsing here) when the last frame
  // has any (an archive stores zeros without a contraction).
  const std::vector<double> last_act = reader->frame(f.total - 1).activation_pa;
  f.has_activation = f.contraction.enabled() || std::any_of(last_act.begin(), last_act.end(), [](double v) { return v > 0; });
  long i = 0;
  const long stop = a.until > 0 ? static_cast<long>(std::upper_bound(times.begin(), times.end(), a.until + 1e-9) - times.begin()) : f.total;
  f.next = [reader, &f, i, stop](core::Positions& x, std::vector<double>& act, double& t, long& step) mutable {
    if (i >= stop) return false;
    const archive::Frame fr = reader->frame(i++);
    x = fr.positions;
    t = fr.time_s, step = fr.step;
    if (f.contraction.enabled()) {
      act = render::activation_from_tension(f.contraction, f.mesh->regions(), fr.activation_pa);
    } else {
      act = fr.activation_pa;
      const double peak = act.empty() ? 0.0 : *std::max_element(act.begin(), act.end());
      for (double& v : act) v = peak > 0 ? v / peak : 0.0;
    }
    return true;
  };
  return render_feed(cmd, a, f);
}
#endif

#ifdef FIBERFEM_WITH_DDS
// The live bus: the run's topology, then the newest state each time (the service never
// waits for the renderer: states it publishes while a frame is drawn are skipped).
int render_live(CLI::App& cmd, RenderArgs& a) {
  using namespace std::chrono_literals;
  auto client = std::make_shared<clients::Client>();
  const std::string run = client->resolve_run(a.run_id, 20s);
  const auto topo = client->topology(run, 20s);
  if (!topo) throw std::runtime_error("no topology from run '" + run + "'");
  Feed f;
  f.name = topo->scene_name;
  f.origin = "run " + run + (topo->replay ? " (replay)" : "");
  core::Positions rest(3, topo->num_nodes);
  for (unsigned n = 0; n < topo->num_nodes; ++n)
    for (int d = 0; d < 3; ++d) rest(d, n) = topo->rest_positions[3 * n + d];
  std::vector<core::Tet> tets(topo->num_elements);
  for (unsigned e = 0; e < topo->num_elements; ++e)
    for (int k = 0; k < 4; ++k) tets[e][static_cast<size_t>(k)] = topo->tets[4 * e + k];
  f.mesh.emplace(rest, tets, std::vector<int>(topo->element_regions.begin(), topo->element_regions.end()));
  for (unsigned e = 0; e < topo->num_elements; ++e) f.fibers.emplace_back(topo->fibers[3 * e], topo->fibers[3 * e + 1], topo->fibers[3 * e + 2]);
  const auto st = client->status(run, 10s);
  if (st && st->heart_rate_bpm > 0) {  // beats in the caption and the strip
    f.contraction.period_s = 60.0 / st->heart_rate_bpm;
    f.contraction.region_peak_pa.assign(static_cast<size_t>(f.mesh->num_regions()), 1.0);
  }
  f.has_activation = st && st->heart_rate_bpm > 0;
  f.frame_dt_s = st && st->dt_s > 0 ? st->dt_s : 1.0 / 30;
  auto skipped = std::make_shared<long>(0);
  long last = -1, shown = 0;
  const auto state_nodes = topo->state_nodes;
  const double until = a.until;
  const long max_frames = a.live_frames;
  // Follows the run across restarts of its service (the rule of clients::RunFollower,
  // docs/ctl.md: the run id given, else the only live run and then the only one of the
  // same scene): a run that comes back with the same mesh is drawn on; one with another
  // mesh, or none within kComeBack, ends the render.
  static constexpr auto kComeBack = std::chrono::seconds(60);
  auto follower = std::make_shared<clients::RunFollower>(*client, a.run_id.empty() ? run : a.run_id);
  const unsigned num_nodes = topo->num_nodes, num_elements = topo->num_elements;
  int founds = 0;
  f.next = [client, follower, rest, state_nodes, last, shown, until, max_frames, skipped, num_nodes, num_elements, founds](
               core::Positions& x, std::vector<double>& act, double& t, long& step) mutable {
    if (max_frames > 0 && shown >= max_frames) return false;
    auto give_up = std::chrono::steady_clock::now() + kComeBack;
    std::optional<clients::State> s;
    while (!s) {
      const auto ev = follower->next(500ms);
      if (!ev) {
        if (std::chrono::steady_clock::now() > give_up) {
          std::printf("render: no run to follow for %lld s\n", static_cast<long long>(kComeBack.count()));
          return false;
        }
        continue;
      }
      switch (ev->kind) {
        case clients::RunFollower::Event::Kind::found: {
          // The first is the run whose topology is drawn; a later one is a restart, with
          // a topology of its own.
          const auto t2 = founds++ == 0 ? std::optional<clients::Topology>() : client->topology(ev->run_id, 10s);
          if (founds > 1 && (!t2 || t2->num_nodes != num_nodes || t2->num_elements != num_elements)) {
            std::printf("render: run %s has another mesh: stopping (start the render anew)\n", ev->run_id.c_str());
            return false;
          }
          std::printf("following run %s: %s\n", ev->run_id.c_str(), ev->message.c_str());
          last = -1;
          break;
        }
        case clients::RunFollower::Event::Kind::lost:
          std::printf("lost run %s: %s\n", ev->run_id.c_str(), ev->message.c_str());
          give_up = std::chrono::steady_clock::now() + kComeBack;
          break;
        case clients::RunFollower::Event::Kind::state:
          s = ev->state;
          break;
      }
      std::fflush(stdout);
    }
    if (last >= 0 && static_cast<long>(s->frame) > last + 1) *skipped += static_cast<long>(s->frame) - last - 1;
    last = static_cast<long>(s->frame);
    x = rest;
    if (state_nodes.empty()) {
      for (Eigen::Index i = 0; i < x.size() && static_cast<size_t>(i) < s->positions.size(); ++i) x.data()[i] = s->positions[static_cast<size_t>(i)];
    } else {
      for (size_t k = 0; k < state_nodes.size(); ++k)
        for (int d = 0; d < 3; ++d) x(d, state_nodes[k]) = s->positions[3 * k + d];
    }
    act.assign(s->activation.begin(), s->activation.end());
    t = s->time_s, step = static_cast<long>(s->frame);
    ++shown;
    std::printf("frame %ld t=%.4f s\n", step, t);
    std::fflush(stdout);
    return until <= 0 || t <= until + 1e-9;
  };
  const int rc = render_feed(cmd, a, f);
  std::printf("render: %ld published frames skipped while drawing (the service never waits for the renderer)\n", *skipped);
  return rc;
}
#endif

int render_command(CLI::App& cmd, RenderArgs& a) {
  try {
    if (a.live) {
#ifdef FIBERFEM_WITH_DDS
      if (!a.scene_file.empty()) throw std::invalid_argument("--live renders a running service: give no scene or archive");
      return render_live(cmd, a);
#else
      throw std::invalid_argument("--live: this fiberfem was built without DDS");
#endif
    }
    if (a.scene_file.empty()) throw std::invalid_argument("give a scene file, an archive (RUN.h5) or --live");
    if (a.scene_file.size() > 3 && a.scene_file.substr(a.scene_file.size() - 3) == ".h5") {
#ifdef FIBERFEM_HAVE_ARCHIVE
      return render_archive(cmd, a);
#else
      throw std::invalid_argument(a.scene_file + ": this fiberfem was built without HDF5, it cannot read archives");
#endif
    }
    if (a.out_dir.empty() && !a.no_png) throw std::invalid_argument("--out DIR is required (or --no-png with --mp4 / --strip)");
    if (a.no_png && a.mp4.empty() && a.strip.empty()) throw std::invalid_argument("--no-png leaves nothing to write: add --mp4 or --strip");
    if (a.png_level < 0 || a.png_level > 9) throw std::invalid_argument("--png-level " + std::to_string(a.png_level) + " is outside [0, 9]");
    io::Scene sc = io::load_scene(a.scene_file, a.overrides);
    const core::Model& model = sc.model;
    const bool contracting = model.contraction.enabled();
    const bool is_static = a.force_static || sc.mode == io::Mode::static_;
    if (is_static && !a.strip.empty()) throw std::invalid_argument("--strip: a static scene has no beat to show");

    render::RenderSettings rs;
    rs.width = a.width, rs.height = a.height, rs.supersample = a.supersample, rs.fibers = a.fibers;
    rs.field = a.field.empty() ? (contracting ? render::Field::activation : render::Field::displacement) : render::parse_field(a.field);
    if (!a.range.empty()) rs.range = std::make_pair(a.range[0], a.range[1]);
    rs.colour_bar = rs.caption = !a.no_overlay;
    rs.smooth = !a.flat;
    rs.per_pixel_lighting = !a.vertex_lighting;
    rs.validate();
    if (rs.field == render::Field::activation && !contracting)
      throw std::invalid_argument("--field activation: scene '" + sc.name + "' has no contraction (try --field displacement)");
    if (a.fit != "rest" && a.fit != "frame") throw std::invalid_argument("--fit '" + a.fit + "': use rest or frame");
    const core::Positions rest_surface = render::surface_points(model.mesh);
    const bool side_bar = !a.no_overlay && rs.field != render::Field::none;
    const render::Camera camera = make_camera(a, rest_surface, cmd, side_bar);
    const std::vector<int> surface_nodes = model.mesh.boundary_nodes();

    prepare_out_dir(a);

    const double dt = sc.settings.dt_s;
    std::vector<double> at = a.at;  // --at: render only the steps nearest these times
    std::sort(at.begin(), at.end());
    const double until = a.until > 0 ? a.until : !at.empty() ? std::max(at.back(), dt) : sc.until_s;
    const long steps = a.steps > 0 ? a.steps : std::max(1L, std::lround(until / dt));
    if (!at.empty() && at.back() > (steps + 0.5) * dt)
      throw std::invalid_argument("--at " + std::to_string(at.back()) + " s is after the end of the run (" + std::to_string(steps * dt) + " s)");
    if (steps > 100000000L) throw std::invalid_argument("render: over 1e8 steps");
    const double fps = a.fps > 0 ? a.fps : std::clamp(1.0 / (a.every * dt), 1.0, 240.0);

    core::Simulator sim(model, sc.settings);
    render::Renderer renderer(model.mesh, rs);
    renderer.set_camera(camera);
    std::unique_ptr<render::VideoWriter> video = make_video(a, fps);
    // The strip: N panels evenly over one beat (the first; the whole run without a
    // contraction), captured as owned copies and drawn at the end with one colour range.
    const double strip_span = contracting ? model.contraction.period_s : steps * dt;
    if (!a.strip.empty() && steps * dt < strip_span * (1 - 1.0 / a.strip_panels) - 0.5 * dt)
      throw std::invalid_argument("--strip: the run (" + std::to_string(steps * dt) + " s) is shorter than one beat (" +
                                  std::to_string(strip_span) + " s); raise --until");
    std::vector<Panel> panels;
    int next_panel = 0;

    std::cout << "fiberfem render: scene '" << sc.name << "', " << model.mesh.num_nodes() << " nodes, "
              << model.mesh.boundary_triangles().size() << " surface triangles, field " << render::to_string(rs.field) << ", "
              << a.width << "x" << a.height << ", every " << a.every << " steps (" << steps << " steps), " << renderer.describe()
              << "\n" << std::flush;
    const bool tty = isatty(fileno(stderr)) != 0;
    std::vector<double> t_step, t_prepare, t_draw, t_read, t_overlay, t_png, t_pipe, t_total;
    long frames = 0;
    if (a.last && !at.empty()) throw std::invalid_argument("--last and --at exclude each other");
    const long total_frames = a.last ? 1 : is_static ? 2 : !at.empty() ? static_cast<long>(at.size()) : steps / a.every + 1;
    size_t next_at = 0;
    std::vector<double> activation;
    const auto t_run = Clock::now();
    // Draws one state into the outputs.
    auto emit = [&](const Eigen::Ref<const core::Positions>& x, double t) {
      render::FrameView frame(model.mesh, x);
      frame.activation = contracting ? &activation : nullptr;
      frame.fibers = &model.fibers;
      frame.dm_inv = &sim.caches().Dm_inv;
      frame.time_s = t;
      frame.caption = is_static ? sc.name + (t > 0 ? "    static equilibrium" : "    rest") : caption_of(sc, t, at.empty() && !a.last ? fps : 0.0);
      if (a.fit == "frame") {  // re-frame on the deformed surface
        core::Positions current(3, static_cast<Eigen::Index>(surface_nodes.size()));
        for (size_t i = 0; i < surface_nodes.size(); ++i) current.col(static_cast<Eigen::Index>(i)) = x.col(surface_nodes[i]);
        renderer.set_camera(make_camera(a, current, cmd, side_bar));
      }
      const auto t0 = Clock::now();
      const render::Image& image = renderer.render(frame);
      const render::RenderTimes& rt = renderer.last_times();
      t_prepare.push_back(rt.prepare_s), t_draw.push_back(rt.draw_s), t_read.push_back(rt.readback_s), t_overlay.push_back(rt.overlay_s);
      if (!a.no_png) {
        char name[64];
        std::snprintf(name, sizeof name, "/frame-%05ld.png", frames);
        const auto tp = Clock::now();
        render::write_png(a.out_dir + name, image, a.png_level);
        t_png.push_back(since(tp));
      }
      if (video) {
        const auto tv = Clock::now();
        video->write(image);
        t_pipe.push_back(since(tv));
      }
      t_total.push_back(since(t0));
      ++frames;
      if (tty) {
        std::fprintf(stderr, "\rrender: frame %ld/%ld  t = %.3f s  %.1f frames/s\033[K", frames, total_frames, t,
                     frames / std::max(1e-9, since(t_run)));
        std::fflush(stderr);
      } else if (frames == 1 || frames == total_frames || frames % std::max(1L, total_frames / 4) == 0) {
        std::printf("render: frame %ld/%ld  t = %.3f s\n", frames, total_frames, t);
        std::fflush(stdout);
      }
    };
    if (is_static) {
      // A static scene: the rest state, then the equilibrium (Newton, as fiberfem run --static,
      // which has no active stress: activation zero).
      if (contracting) activation.assign(static_cast<size_t>(model.mesh.num_elements()), 0.0);
      if (!a.last) emit(sim.positions(), 0.0);
      core::StaticSettings ss;
      ss.rotation = sc.settings.rotation;
      ss.corotation = sc.settings.corotation;
      core::Positions x;
      const core::StaticReport r = core::solve_static(model, x, ss);
      if (!r.converged) throw std::runtime_error("static solve did not converge: " + r.message);
      emit(x, 1.0);
    }
    for (long s = 0; !is_static && s <= steps; ++s) {
      if (s > 0) {
        const auto t0 = Clock::now();
        const core::StepReport r = sim.step();
        t_step.push_back(since(t0));
        if (r.status == core::StepStatus::failed)
          throw std::runtime_error("step " + std::to_string(s) + " failed at t = " + std::to_string(sim.time_s()) + " s: " + r.message);
      }
      if (contracting) activation = render::activation_from_tension(model.contraction, model.mesh.regions(), sim.active_tension());
      const double t = sim.time_s();
      if (!a.strip.empty() && next_panel < a.strip_panels && t + 0.5 * dt >= next_panel * strip_span / a.strip_panels) {
        panels.push_back({sim.positions(), activation, t});
        ++next_panel;
      }
      if (a.no_png && !video) continue;
      if (!at.empty()) {
        bool wanted = false;  // a time may be asked for twice; one frame serves both
        while (next_at < at.size() && t + 0.5 * dt >= at[next_at]) ++next_at, wanted = true;
        if (!wanted) continue;
      } else if (a.last ? s != steps : s % a.every != 0) {
        continue;
      }
      emit(sim.positions(), t);
    }
    if (tty) std::fprintf(stderr, "\n");
    if (video) video->close();

    if (!a.strip.empty()) write_strip(a, rs, model.mesh, model.fibers, contracting, renderer.camera(), panels);

    std::printf("render: %ld frames in %.1f s", frames, since(t_run));
    if (!a.no_png) std::printf(", PNG frames in %s/frame-NNNNN.png", a.out_dir.c_str());
    if (video) std::printf(", video %s (%ld frames at %.3g fps)", a.mp4.c_str(), video->frames(), fps);
    if (!a.strip.empty()) std::printf(", strip %s (%zu panels)", a.strip.c_str(), panels.size());
    std::printf("\n");
    const auto [lo, hi] = renderer.range();
    if (render::is_scalar(rs.field)) std::printf("render: colour range [%g, %g] (%s, SI units)\n", lo, hi, render::to_string(rs.field));
    if (a.time) {
      std::printf("render: median per frame over %zu frames, ms: step %.2f, prepare %.2f, draw %.2f, readback %.2f, overlay %.2f, "
                  "png %.2f, ffmpeg pipe %.2f, render total %.2f\n",
                  t_total.size(), 1e3 * median(t_step), 1e3 * median(t_prepare), 1e3 * median(t_draw), 1e3 * median(t_read),
                  1e3 * median(t_overlay), 1e3 * median(t_png), 1e3 * median(t_pipe), 1e3 * median(t_total));
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "fiberfem render: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

void add_render_command(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("render", "Simulate a scene and render it off-screen to PNG frames and MP4 (docs/rendering.md)");
  auto a = std::make_shared<RenderArgs>();
  cmd->add_option("scene", a->scene_file, "Scene file (YAML, docs/scenes.md) to simulate, or a run archive RUN.h5 to draw");
  cmd->add_flag("--live", a->live, "Render a running service from the bus (the newest state each time; see --run, --frames)");
  cmd->add_option("--run", a->run_id, "With --live: the run id (default: the only run on the domain)");
  cmd->add_option("--frames", a->live_frames, "With --live: stop after this many frames (default: at --until or Ctrl-C)")->check(CLI::PositiveNumber);
  cmd->add_option("--out", a->out_dir, "Directory for the PNG frames (created)");
  cmd->add_option("--field", a->field, "activation | fiber_strain | displacement | region | none (default: activation if the scene contracts, else displacement)");
  cmd->add_option("--camera", a->camera, "Preset: front | back | left | right | top | iso, framing the rest surface")->capture_default_str();
  cmd->add_option("--eye", a->eye, "Eye position x y z, m (overrides the preset's)")->expected(3);
  cmd->add_option("--target", a->target, "Point looked at x y z, m; the preset eye moves with it (default: the preset framing's, near the box centre)")->expected(3);
  cmd->add_option("--up", a->up, "Up direction x y z (default: +z; +y for top)")->expected(3);
  cmd->add_option("--fit", a->fit, "What the preset frames: rest (the rest surface, fixed camera) or frame (each frame's deformed surface)")
      ->capture_default_str();
  cmd->add_option("--margin", a->margin, "Framing margin of the presets, relative to the extent, in [0, 2]")
      ->check(CLI::Range(0.0, 2.0))->capture_default_str();
  cmd->add_option("--fov", a->fov, "Vertical field of view, degrees, in (0, 170)")->capture_default_str();
  cmd->add_option("--width", a->width, "Image width, pixels, in [16, 8192]")->capture_default_str();
  cmd->add_option("--height", a->height, "Image height, pixels, in [16, 8192]")->capture_default_str();
  cmd->add_option("--every", a->every, "Render every K-th step (and the initial state)")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--at", a->at, "Render only the steps nearest these times, s (instead of --every; the run lasts to the last)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--last", a->last, "Render only the final state (the end of the run, or the static equilibrium)");
  cmd->add_option("--until", a->until, "Simulated time, s (default: the scene's solver.until)")->check(CLI::PositiveNumber);
  cmd->add_option("--steps", a->steps, "Number of steps (instead of --until)")->check(CLI::PositiveNumber);
  cmd->add_option("--set", a->overrides, "Override a scene key: key.path=value (repeatable, as fiberfem run)");
  cmd->add_flag("--static", a->force_static, "Solve for static equilibrium and render the rest state and the solution (static scenes do this anyway)");
  cmd->add_flag("--flat", a->flat, "Colour each triangle by its element's value (activation, fiber_strain) instead of smoothing to the nodes");
  cmd->add_flag("--vertex-lighting", a->vertex_lighting, "Light per vertex (fixed-function Gouraud) instead of per pixel");
  cmd->add_flag("--fibers", a->fibers, "Draw fiber glyphs (F f) on the surface");
  cmd->add_option("--range", a->range, "Fixed colour range MIN MAX in the field's SI unit (displacement in m)")->expected(2);
  cmd->add_option("--mp4", a->mp4, "Also encode the frames into this MP4 (ffmpeg)");
  cmd->add_option("--fps", a->fps, "MP4 frame rate, 1/s (default: real time, 1 / (every * dt), within [1, 240])")->check(CLI::Range(0.1, 240.0));
  cmd->add_option("--strip", a->strip, "Write a PNG strip of one beat (the first) here");
  cmd->add_option("--strip-panels", a->strip_panels, "Panels in the strip")->check(CLI::Range(1, 64))->capture_default_str();
  cmd->add_option("--strip-width", a->strip_width, "Width of one strip panel, pixels")->check(CLI::Range(16, 2048))->capture_default_str();
  cmd->add_option("--png-level", a->png_level, "PNG compression level, 0 (fastest) to 9 (smallest)")->capture_default_str();
  cmd->add_flag("--no-png", a->no_png, "Write no PNG frames (only --mp4 / --strip)");
  cmd->add_option("--supersample", a->supersample, "Anti-aliasing: draw at K times the size and average down, K in [1, 4]")->capture_default_str();
  cmd->add_flag("--no-overlay", a->no_overlay, "No colour bar and no caption");
  cmd->add_flag("--time", a->time, "Print the median time per frame of each phase");
  cmd->callback([cmd, a, &exit_code] { exit_code = render_command(*cmd, *a); });
}

}  // namespace fiberfem::service
