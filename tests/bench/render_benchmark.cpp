// bench_render: time per frame of the off-screen renderer (docs/rendering.md, "Figures").
// A program, not a timed test.
//
// Two meshes: the default heart (configs/scenes/heart.yaml, meshes/biventricle.msh) and a
// box with --cells (default 46 x 46 x 46: 103,823 nodes). Each frame moves the nodes (a
// travelling sine wobble of 2 % of the size, so every frame differs) and colours by
// activation (a travelling wave). Per frame it times the renderer's phases (prepare:
// field values, normals, vertex arrays; draw: GL calls and glFinish, where llvmpipe
// rasterises; readback: copying the colour buffer out; overlay: colour bar and caption),
// then a PNG encode (libpng, --png-level) into a temporary file and the write of the raw
// frame into an ffmpeg pipe (libx264 into a temporary MP4; the write blocks while ffmpeg
// is behind, so it is the encoder's cost as seen by the producer). Medians of --frames.
//
//   bench_render                                   # 1280x720, 40 frames per mesh
//   bench_render --quick                           # 160x90, 3 frames, small box (ctest)

#include "clients/render/png_io.hpp"
#include "clients/render/renderer.hpp"
#include "clients/render/video_writer.hpp"
#include "core/box_generator.hpp"
#include "io/scene.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <vector>

namespace core = fiberfem::core;
namespace render = fiberfem::render;

namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n == 0 ? 0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void bench(const std::string& label, const core::TetMesh& mesh, int width, int height, int frames, int png_level, bool per_pixel) {
  render::RenderSettings s;
  s.width = width, s.height = height, s.field = render::Field::activation, s.per_pixel_lighting = per_pixel;
  render::Renderer r(mesh, s);
  const auto [lo, hi] = mesh.bounding_box();
  const double size = (hi - lo).norm();
  const std::string dir = std::filesystem::temp_directory_path() / ("bench_render_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  render::VideoSettings vs;
  vs.path = dir + "/bench.mp4", vs.width = width, vs.height = height;
  render::VideoWriter video(vs);
  std::vector<double> prepare, draw, readback, overlay, png, pipe, total;
  core::Positions x = mesh.rest_positions();
  std::vector<double> activation(static_cast<size_t>(mesh.num_elements()));
  for (int f = 0; f < frames + 2; ++f) {  // two warm-up frames
    const double phase = 0.3 * f;
    for (int v = 0; v < mesh.num_nodes(); ++v) {
      const core::Vec3 X = mesh.rest_positions().col(v);
      x.col(v) = X + 0.02 * size * std::sin(12 * (X - lo).norm() / size + phase) * core::Vec3(0.3, 0.2, 1.0).normalized();
    }
    for (size_t e = 0; e < activation.size(); ++e) {
      const double z = mesh.rest_positions().col(mesh.tets()[e][0]).z();
      activation[e] = 0.5 + 0.5 * std::sin(20 * (z - lo.z()) / size - phase);
    }
    render::FrameView frame(mesh, x);
    frame.activation = &activation;
    frame.caption = label + "    frame " + std::to_string(f);
    const auto t0 = Clock::now();
    const render::Image& im = r.render(frame);
    const auto t1 = Clock::now();
    render::write_png(dir + "/frame.png", im, png_level);
    const auto t2 = Clock::now();
    video.write(im);
    const auto t3 = Clock::now();
    if (f < 2) continue;
    const render::RenderTimes& t = r.last_times();
    prepare.push_back(t.prepare_s), draw.push_back(t.draw_s), readback.push_back(t.readback_s), overlay.push_back(t.overlay_s);
    png.push_back(std::chrono::duration<double>(t2 - t1).count());
    pipe.push_back(std::chrono::duration<double>(t3 - t2).count());
    total.push_back(std::chrono::duration<double>(t3 - t0).count());
  }
  video.close();
  std::filesystem::remove_all(dir);
  std::printf("| %s | %s | %d | %zu | %dx%d | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f |\n", label.c_str(),
              per_pixel ? "pixel" : "vertex", mesh.num_nodes(),
              mesh.boundary_triangles().size(), width, height, 1e3 * median(prepare), 1e3 * median(draw), 1e3 * median(readback),
              1e3 * median(overlay), 1e3 * median(png), 1e3 * median(pipe), 1e3 * median(total));
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_render: time per frame of the off-screen renderer"};
  int width = 1280, height = 720, frames = 40, png_level = 1;
  std::vector<int> cells = {46, 46, 46};
  bool quick = false;
  std::string heart = std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart.yaml";
  app.add_option("--width", width, "Image width, px")->capture_default_str();
  app.add_option("--height", height, "Image height, px")->capture_default_str();
  app.add_option("--frames", frames, "Frames timed per mesh (after two warm-up frames)")->capture_default_str();
  app.add_option("--png-level", png_level, "PNG compression level")->capture_default_str();
  app.add_option("--cells", cells, "Cells of the box mesh")->expected(3);
  app.add_option("--heart", heart, "The heart scene")->capture_default_str();
  app.add_flag("--quick", quick, "Tiny run (ctest)");
  CLI11_PARSE(app, argc, argv);
  if (quick) width = 160, height = 90, frames = 3, cells = {4, 4, 4};
  try {
    std::printf("| mesh | lighting | nodes | surface triangles | image | prepare ms | draw ms | readback ms | overlay ms | PNG level %d ms | ffmpeg pipe ms | total ms |\n",
                png_level);
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    const fiberfem::io::Scene sc = fiberfem::io::load_scene(heart);
    core::BoxSpec spec;
    spec.size_m = {0.1, 0.1, 0.1};
    spec.cells = {cells[0], cells[1], cells[2]};
    const core::TetMesh box = core::make_box(spec);
    const std::string box_label = "box " + std::to_string(cells[0]) + "x" + std::to_string(cells[1]) + "x" + std::to_string(cells[2]);
    for (bool per_pixel : {true, false}) {
      bench("heart", sc.model.mesh, width, height, frames, png_level, per_pixel);
      bench(box_label, box, width, height, frames, png_level, per_pixel);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_render: %s\n", e.what());
    return 1;
  }
  return 0;
}
