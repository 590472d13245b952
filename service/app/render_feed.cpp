// The render loop shared by every feed: the camera framing the rest surface (or each
// frame's), the frames picked by --every, --at or --last, written as PNG frames and
// through ffmpeg to an MP4, and a strip of the first beat drawn at the end.

#include "service/app/render_feed.hpp"

#include "clients/render/png_io.hpp"
#include "clients/render/renderer.hpp"
#include "clients/render/surface.hpp"
#include "clients/render/video_writer.hpp"
#include "service/stop_signals.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <unistd.h>

namespace fiberfem::app {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

core::Vec3 vec3(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

// Shares of the image's width kept free beside the object: for a colour bar (or legend)
// at the right edge, for the pressure-volume inset at the left.
struct Reserve {
  double left = 0, right = 0;
};

// The camera: a preset framing `points`, then any explicit key on top. With parts of the
// width reserved, the object is framed in the rest and the camera moved so that it is
// centred there.
render::Camera make_camera(const RenderArgs& a, const core::Positions& points, CLI::App& cmd, Reserve reserve) {
  const double aspect = static_cast<double>(a.width) / a.height;
  render::Camera cam = render::frame_points(render::parse_camera_preset(a.camera), points,
                                            aspect * (1 - reserve.left - reserve.right), a.fov, a.margin);
  if (reserve.left + reserve.right > 0) {
    const core::Vec3 view = cam.target - cam.eye;
    const double half_width = view.norm() * std::tan(0.5 * cam.fov_deg * M_PI / 180) * aspect;  // at the target, m
    const core::Vec3 shift = view.cross(cam.up).normalized() * (reserve.right - reserve.left) * half_width;
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
// K-th frame; the MP4's rate), not for single frames picked with --at or --last.
std::string default_caption(const Feed& f, double t, double fps) {
  char buf[256];
  int n = std::snprintf(buf, sizeof buf, "%s    t = %.3f s", f.name.c_str(), t);
  if (f.contraction.enabled())
    n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "    beat %ld",
                       static_cast<long>(std::floor(t / f.contraction.period_s + 1e-9)) + 1);
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

render::RenderSettings render_settings(const RenderArgs& a, const Feed& feed) {
  render::RenderSettings rs;
  rs.width = a.width, rs.height = a.height, rs.supersample = a.supersample, rs.fibers = a.fibers;
  rs.field = a.field.empty() ? (feed.has_activation ? render::Field::activation : render::Field::displacement) : render::parse_field(a.field);
  if (!a.range.empty()) rs.range = std::make_pair(a.range[0], a.range[1]);
  rs.colour_bar = rs.caption = !a.no_overlay;
  rs.pv_inset = !a.no_overlay && !a.no_pv_loop && static_cast<bool>(feed.circulation);
  rs.smooth = !a.flat;
  rs.per_pixel_lighting = !a.vertex_lighting;
  rs.validate();
  if (rs.field == render::Field::activation && !feed.has_activation)
    throw std::invalid_argument("--field activation: " + (feed.no_activation.empty() ? feed.origin + " has no activation" : feed.no_activation) +
                                " (try --field displacement)");
  if (a.fit != "rest" && a.fit != "frame") throw std::invalid_argument("--fit '" + a.fit + "': use rest or frame");
  return rs;
}

// One panel of a strip: an owned copy of a state.
struct Panel {
  core::Positions x;
  std::vector<double> activation;
  double t;
};

// The strip: panels drawn at twice the panel size and averaged down; two passes so that an
// automatic colour range covers every panel before any is drawn.
void write_strip(const RenderArgs& a, const render::RenderSettings& rs, const Feed& feed, const render::Camera& camera,
                 const std::vector<Panel>& panels) {
  render::RenderSettings ps = rs;
  ps.width = 2 * a.strip_width;
  ps.height = std::max(16, static_cast<int>(std::lround(ps.width * static_cast<double>(a.height) / a.width)));
  ps.colour_bar = false;
  ps.pv_inset = false;  // too small a panel for a plot
  ps.supersample = 1;
  ps.font_px = std::max(9, ps.height / 9);
  render::Renderer strip_renderer(*feed.mesh, ps);
  strip_renderer.set_camera(camera);
  std::vector<render::Image> images;
  for (int pass = 0; pass < 2; ++pass)
    for (const Panel& p : panels) {
      render::FrameView frame(*feed.mesh, p.x);
      frame.activation = feed.has_activation ? &p.activation : nullptr;
      frame.fibers = &feed.fibers;
      frame.time_s = p.t;
      char cap[64];
      std::snprintf(cap, sizeof cap, "t = %.2f s", p.t);
      frame.caption = cap;
      const render::Image& im = strip_renderer.render(frame);
      if (pass == 1) images.push_back(render::downscale(im, a.strip_width, ps.height / 2));
    }
  render::write_png(a.strip, render::hstack(images, 4), 9);
}

// Which frames are drawn: every K-th, those nearest the --at times (a time asked for twice
// gets one frame), or the last.
class FrameSelection {
 public:
  FrameSelection(const RenderArgs& a, const Feed& feed) : a_(a), feed_(feed), at_(a.at) { std::sort(at_.begin(), at_.end()); }
  bool sequence() const { return at_.empty() && !a_.last; }
  bool wanted(long index, double t) {
    if (!at_.empty()) {
      bool wanted = false;
      while (next_at_ < at_.size() && t + 0.5 * feed_.frame_dt_s >= at_[next_at_]) ++next_at_, wanted = true;
      return wanted;
    }
    return a_.last ? index == feed_.total - 1 : index % a_.every == 0;
  }

 private:
  const RenderArgs& a_;
  const Feed& feed_;
  std::vector<double> at_;
  size_t next_at_ = 0;
};

// The outputs of one render: the renderer, PNG frames and the video, with the time each
// phase took per frame.
class Drawing {
 public:
  Drawing(CLI::App& cmd, const RenderArgs& a, const Feed& feed, const render::RenderSettings& rs, double fps)
      : cmd_(cmd), a_(a), feed_(feed), fps_(fps), renderer_(*feed.mesh, rs) {
    if (!a.no_overlay && rs.field != render::Field::none) reserve_.right = 0.12;
    if (rs.pv_inset) {
      const render::PvInsetBox box = render::PvInsetBox::in(a.width, a.height);
      reserve_.left = static_cast<double>(box.x0 + box.size) / a.width;
    }
    renderer_.set_camera(make_camera(a, render::surface_points(*feed.mesh), cmd, reserve_));
    prepare_out_dir(a);
    if (!a.mp4.empty()) {
      render::VideoSettings vs;
      vs.path = a.mp4, vs.width = a.width, vs.height = a.height, vs.fps = fps;
      video_ = std::make_unique<render::VideoWriter>(vs);
    }
    if (a.fit == "frame") surface_nodes_ = feed.mesh->boundary_nodes();
  }
  render::Renderer& renderer() { return renderer_; }
  render::VideoWriter* video() { return video_.get(); }
  /// The pressure-volume loops traced so far (drawn with every frame from now on).
  render::PvLoop& pv_loop() { return pv_loop_; }
  long frames() const { return frames_; }

  void draw(const core::Positions& x, const std::vector<double>& act, double t, bool sequence) {
    render::FrameView frame(*feed_.mesh, x);
    frame.activation = act.empty() ? nullptr : &act;
    frame.fibers = &feed_.fibers;
    frame.dm_inv = feed_.dm_inv;
    frame.pv_loop = &pv_loop_;
    frame.time_s = t;
    const double fps = sequence ? fps_ : 0.0;
    frame.caption = feed_.caption ? feed_.caption(t, fps) : default_caption(feed_, t, fps);
    if (!surface_nodes_.empty()) {  // --fit frame: re-frame on the deformed surface
      core::Positions current(3, static_cast<Eigen::Index>(surface_nodes_.size()));
      for (size_t i = 0; i < surface_nodes_.size(); ++i) current.col(static_cast<Eigen::Index>(i)) = x.col(surface_nodes_[i]);
      renderer_.set_camera(make_camera(a_, current, cmd_, reserve_));
    }
    const auto t0 = Clock::now();
    const render::Image& image = renderer_.render(frame);
    const render::RenderTimes& rt = renderer_.last_times();
    prepare_.push_back(rt.prepare_s), draw_.push_back(rt.draw_s), read_.push_back(rt.readback_s), overlay_.push_back(rt.overlay_s);
    if (!a_.no_png) {
      char name[64];
      std::snprintf(name, sizeof name, "/frame-%05ld.png", frames_);
      const auto tp = Clock::now();
      render::write_png(a_.out_dir + name, image, a_.png_level);
      png_.push_back(since(tp));
    }
    if (video_) {
      const auto tv = Clock::now();
      video_->write(image);
      pipe_.push_back(since(tv));
    }
    total_.push_back(since(t0));
    ++frames_;
  }

  // --time: the median time per frame of each phase.
  void print_times(const std::vector<double>& step_s) const {
    std::printf("render: median per frame over %zu frames, ms: step %.2f, prepare %.2f, draw %.2f, readback %.2f, overlay %.2f, "
                "png %.2f, ffmpeg pipe %.2f, render total %.2f\n",
                total_.size(), 1e3 * median(step_s), 1e3 * median(prepare_), 1e3 * median(draw_), 1e3 * median(read_),
                1e3 * median(overlay_), 1e3 * median(png_), 1e3 * median(pipe_), 1e3 * median(total_));
  }

 private:
  CLI::App& cmd_;
  const RenderArgs& a_;
  const Feed& feed_;
  double fps_;
  Reserve reserve_;
  render::Renderer renderer_;
  render::PvLoop pv_loop_;
  std::unique_ptr<render::VideoWriter> video_;
  std::vector<int> surface_nodes_;  // --fit frame
  std::vector<double> prepare_, draw_, read_, overlay_, png_, pipe_, total_;
  long frames_ = 0;
};

// A line per drawn frame: redrawn on a terminal; else, when the count is known, the
// first, every quarter and the last.
void show_progress(const Feed& feed, long frames, double t, Clock::time_point t_run, bool tty) {
  if (tty) {
    if (feed.to_draw >= 0)
      std::fprintf(stderr, "\rrender: frame %ld/%ld  t = %.3f s  %.1f frames/s\033[K", frames, feed.to_draw, t, frames / std::max(1e-9, since(t_run)));
    else
      std::fprintf(stderr, "\rrender: frame %ld  t = %.3f s  %.1f frames/s\033[K", frames, t, frames / std::max(1e-9, since(t_run)));
    std::fflush(stderr);
  } else if (feed.to_draw >= 0 && (frames == 1 || frames == feed.to_draw || frames % std::max(1L, feed.to_draw / 4) == 0)) {
    std::printf("render: frame %ld/%ld  t = %.3f s\n", frames, feed.to_draw, t);
    std::fflush(stdout);
  }
}

void print_start(const RenderArgs& a, const Feed& feed, const render::RenderSettings& rs, render::Renderer& renderer) {
  const std::string title = feed.title.empty() ? feed.origin + " (scene '" + feed.name + "'), " + std::to_string(feed.mesh->num_nodes()) + " nodes"
                                               : feed.title;
  std::cout << "fiberfem render: " << title << ", field " << render::to_string(rs.field) << ", " << a.width << "x" << a.height
            << ", every " << a.every << " " << feed.every_unit << ", " << renderer.describe() << "\n" << std::flush;
}

}  // namespace

void check_outputs(const RenderArgs& a) {
  if (a.out_dir.empty() && !a.no_png) throw std::invalid_argument("--out DIR is required (or --no-png with --mp4 / --strip)");
  if (a.no_png && a.mp4.empty() && a.strip.empty()) throw std::invalid_argument("--no-png leaves nothing to write: add --mp4 or --strip");
  if (a.png_level < 0 || a.png_level > 9) throw std::invalid_argument("--png-level " + std::to_string(a.png_level) + " is outside [0, 9]");
  if (a.last && !a.at.empty()) throw std::invalid_argument("--last and --at exclude each other");
}

int render_feed(CLI::App& cmd, const RenderArgs& a, Feed& feed) {
  check_outputs(a);
  if (a.last && feed.total < 0) throw std::invalid_argument("--last needs an archive (a live run has no last frame)");
  const render::RenderSettings rs = render_settings(a, feed);
  const double fps = a.fps > 0 ? a.fps : std::clamp(1.0 / (a.every * std::max(feed.frame_dt_s, 1e-6)), 1.0, 240.0);
  Drawing drawing(cmd, a, feed, rs, fps);
  print_start(a, feed, rs, drawing.renderer());
  const double strip_span = feed.strip_span_s < HUGE_VAL ? feed.strip_span_s
                            : feed.contraction.enabled() ? feed.contraction.period_s : HUGE_VAL;
  std::vector<Panel> panels;
  FrameSelection selection(a, feed);
  const bool tty = isatty(fileno(stderr)) != 0;
  const service::StopSignals stop_signals(/*term_too=*/false);
  core::Positions x;
  std::vector<double> act;
  double t = 0, t_first = -1;
  long step = 0, index = -1;
  const auto t_run = Clock::now();
  while (!stop_signals.caught() && feed.next(x, act, t, step)) {
    ++index;
    if (t_first < 0) t_first = t;
    if (feed.circulation)  // every frame's circulation, drawn or not: the loop is traced whole
      for (const core::circulation::Snapshot& c : feed.circulation()) {
        namespace cc = core::circulation;
        drawing.pv_loop().add(c.chamber_volume_m3[cc::lv], c.chamber_pressure_pa[cc::lv], c.chamber_volume_m3[cc::rv],
                              c.chamber_pressure_pa[cc::rv]);
      }
    const int next_panel = static_cast<int>(panels.size());
    if (!a.strip.empty() && next_panel < a.strip_panels && strip_span < HUGE_VAL &&
        t - t_first + 0.5 * feed.frame_dt_s >= next_panel * strip_span / a.strip_panels)
      panels.push_back({x, act, t});
    if (a.no_png && !drawing.video()) continue;
    if (!selection.wanted(index, t)) continue;
    drawing.draw(x, act, t, selection.sequence());
    show_progress(feed, drawing.frames(), t, t_run, tty);
  }
  if (tty) std::fprintf(stderr, "\n");
  if (drawing.video()) drawing.video()->close();
  if (!a.strip.empty()) {
    if (panels.size() < static_cast<size_t>(a.strip_panels))
      throw std::runtime_error("--strip: " + feed.origin + " holds " + std::to_string(panels.size()) + " of " +
                               std::to_string(a.strip_panels) + " panels of a beat (a beat is longer than the frames, or no contraction)");
    write_strip(a, rs, feed, drawing.renderer().camera(), panels);
  }
  std::printf("render: %ld frames in %.1f s", drawing.frames(), since(t_run));
  if (!a.no_png) std::printf(", PNG frames in %s/frame-NNNNN.png", a.out_dir.c_str());
  if (drawing.video()) std::printf(", video %s (%ld frames at %.3g fps)", a.mp4.c_str(), drawing.video()->frames(), fps);
  if (!a.strip.empty()) std::printf(", strip %s (%zu panels)", a.strip.c_str(), panels.size());
  std::printf("\n");
  const auto [lo, hi] = drawing.renderer().range();
  if (render::is_scalar(rs.field)) std::printf("render: colour range [%g, %g] (%s, SI units)\n", lo, hi, render::to_string(rs.field));
  if (a.time) drawing.print_times(feed.step_s ? *feed.step_s : std::vector<double>{});
  if (feed.finish) feed.finish();
  return drawing.frames() > 0 || (a.no_png && !drawing.video()) ? 0 : 1;
}

}  // namespace fiberfem::app
