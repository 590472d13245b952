#pragma once
/// @file `fiberfem render`'s frames (docs/rendering.md): every source of frames (a scene
/// run here, an archive, a live run on the bus) is a Feed, drawn by one loop into PNG
/// frames, an MP4 and a strip of one beat.

#include "core/circulation/snapshot.hpp"
#include "core/contraction.hpp"
#include "core/mesh.hpp"

#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace fiberfem::app {

/// The command line of `fiberfem render`.
struct RenderArgs {
  std::string scene_file, out_dir, field, camera = "iso", fit = "rest", mp4, strip;
  std::vector<double> eye, target, up, range, at;
  double fov = 30, until = 0, fps = 0, margin = 0.1;
  int width = 1280, height = 720, every = 1, steps = 0, png_level = 1, supersample = 1, strip_panels = 8, strip_width = 240;
  std::vector<std::string> overrides;
  std::string run_id;     // --live: the run (default the only one)
  long live_frames = 0;   // --live: stop after this many frames (0: at --until or Ctrl-C)
  bool live = false;
  bool no_pv_loop = false;  // no pressure-volume inset (a run with a circulation)
  bool fibers = false, no_png = false, time = false, no_overlay = false, force_static = false, last = false, flat = false, vertex_lighting = false;
};

/// A source of frames and what the renderer needs to know about it.
struct Feed {
  std::string name;    ///< The scene's name (captions).
  std::string origin;  ///< What is drawn, for messages ("archive RUN.h5", "run ID", "scene 'NAME'").
  /// The start line's description, up to the field (default: "ORIGIN (scene 'NAME'), N nodes").
  std::string title;
  std::string every_unit = "frames";  ///< The start line's "every K <unit>".
  std::optional<core::TetMesh> mesh;  ///< The rest mesh.
  std::vector<core::Vec3> fibers;     ///< Per element.
  core::Contraction contraction;      ///< For the beats (captions, strip); may be off.
  bool has_activation = false;        ///< Frames carry activation (0..1).
  std::string no_activation;          ///< Why --field activation is refused (default: "ORIGIN has no activation").
  double frame_dt_s = 0;              ///< Time between frames (the default video rate), s.
  long total = -1;                    ///< Frames the feed gives, when known (an archive, a scene).
  long to_draw = -1;                  ///< Frames that will be drawn, when known (progress "N/M").
  double strip_span_s = HUGE_VAL;     ///< Time the strip's panels spread over (default: a beat).
  const std::vector<core::Mat3>* dm_inv = nullptr;  ///< Rest-shape inverses (fiber strain), when known.
  /// The caption of a frame at time t (fps > 0: a sequence's rate); default: name, time, beat, rate.
  std::function<std::string(double t, double fps)> caption;
  /// The next frame: positions, activation (0..1, may be empty), time, step; false at the end.
  std::function<bool(core::Positions&, std::vector<double>&, double&, long&)> next;
  /// A run with a circulation: the circulation samples that came with the frame next() just
  /// gave (and any since the previous frame), oldest first; the renderer traces the
  /// pressure-volume loop through them. Unset: no circulation (no inset).
  std::function<std::vector<core::circulation::Snapshot>()> circulation;
  /// Engine time of each step, s, when the feed steps a simulation (--time).
  std::shared_ptr<std::vector<double>> step_s;
  /// Called after the last frame (a summary of the feed's own).
  std::function<void()> finish;
};

/// Refuses outputs that cannot be written as asked (before any feed starts).
/// @throws std::invalid_argument naming the option.
void check_outputs(const RenderArgs& a);
/// Draws a feed: every K-th frame (or the frames nearest --at, or the last), to PNG, MP4
/// and a strip. @return the exit code.
int render_feed(CLI::App& cmd, const RenderArgs& a, Feed& feed);

/// A scene (a.scene_file) simulated here: a RunDriver stepped frame by frame, or a static
/// scene's rest state and equilibrium.
Feed scene_feed(const RenderArgs& a);
/// An archive (a.scene_file, RUN.h5) read frame by frame (built with HDF5).
Feed archive_feed(const RenderArgs& a);
/// A running service (or replay) on the bus: its newest state each time (built with DDS).
Feed live_feed(const RenderArgs& a);

}  // namespace fiberfem::app
