// `fiberfem render SCENE.yaml | RUN.h5 | --live --out DIR` (docs/rendering.md): picks the
// feed of frames (a scene simulated here, an archive, a live run) and draws it
// off-screen (render_feed): PNG frames, an MP4 through ffmpeg, a strip of one beat.

#include "service/app/commands.hpp"
#include "service/app/render_feed.hpp"

#include <CLI/CLI.hpp>

#include <iostream>
#include <memory>
#include <stdexcept>

namespace fiberfem::app {
namespace {

bool is_archive(const std::string& path) { return path.size() > 3 && path.substr(path.size() - 3) == ".h5"; }

// The feed the command line asks for.
Feed make_feed(const RenderArgs& a) {
  if (a.live) {
#ifdef FIBERFEM_WITH_DDS
    if (!a.scene_file.empty()) throw std::invalid_argument("--live renders a running service: give no scene or archive");
    check_outputs(a);
    return live_feed(a);
#else
    throw std::invalid_argument("--live: this fiberfem was built without DDS");
#endif
  }
  if (a.scene_file.empty()) throw std::invalid_argument("give a scene file, an archive (RUN.h5) or --live");
  check_outputs(a);
  if (is_archive(a.scene_file)) {
#ifdef FIBERFEM_HAVE_ARCHIVE
    return archive_feed(a);
#else
    throw std::invalid_argument(a.scene_file + ": this fiberfem was built without HDF5, it cannot read archives");
#endif
  }
  return scene_feed(a);
}

int render_command(CLI::App& cmd, const RenderArgs& a) {
  try {
    Feed feed = make_feed(a);
    return render_feed(cmd, a, feed);
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
  cmd->add_flag("--no-overlay", a->no_overlay, "No colour bar, no caption and no pressure-volume inset");
  cmd->add_flag("--no-pv-loop", a->no_pv_loop,
                "No pressure-volume inset (drawn at the bottom left for a run with a circulation)");
  cmd->add_flag("--time", a->time, "Print the median time per frame of each phase");
  cmd->callback([cmd, a, &exit_code] { exit_code = render_command(*cmd, *a); });
}

}  // namespace fiberfem::app
