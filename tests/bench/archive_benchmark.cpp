// bench_archive: what recording a run into the HDF5 archive costs per frame (time and
// bytes), for the default heart (frames of a real beating run) and for large box meshes
// (one deformed state recorded repeatedly: recording does not depend on the motion). A
// program, not a timed test (docs/archive.md quotes its output).
//
//   bench_archive --scene configs/scenes/heart.yaml --frames 120 [--compression 0 1]
//   bench_archive --scene configs/scenes/box-gravity.yaml --cells 45 45 48 --frames 40 --static-state

#include "core/cavity.hpp"
#include "io/scene.hpp"
#include "service/archive/archive.hpp"
#include "service/archive/hdf5.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <string>
#include <vector>

namespace core = fiberfem::core;
namespace archive = fiberfem::archive;
using Clock = std::chrono::steady_clock;

namespace {

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// Bytes stored by the per-frame datasets (not the header or the checkpoints).
double frame_bytes(const std::string& path) {
  archive::h5::File f = archive::h5::File::open(path, archive::h5::Mode::read);
  archive::h5::Handle g = archive::h5::open_group(f.id(), "frames");
  double total = 0;
  hsize_t n = 0;
  H5Gget_num_objs(g.id(), &n);
  for (hsize_t i = 0; i < n; ++i) {
    char name[256];
    H5Gget_objname_by_idx(g.id(), i, name, sizeof name);
    archive::h5::Dataset d = archive::h5::open_dataset(g.id(), name, path);
    total += static_cast<double>(H5Dget_storage_size(d.id()));
  }
  return total;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_archive: recording cost per frame"};
  std::string scene_path, dir = std::filesystem::temp_directory_path().string();
  std::vector<int> cells, levels{0, 1};
  int frames = 120;
  bool static_state = false;
  app.add_option("--scene", scene_path)->required();
  app.add_option("--cells", cells)->expected(3);
  app.add_option("--frames", frames);
  app.add_option("--compression", levels);
  app.add_option("--dir", dir, "Where the archives are written (removed afterwards)");
  app.add_flag("--static-state", static_state, "Record one deformed state repeatedly instead of stepping");
  CLI11_PARSE(app, argc, argv);

  std::vector<std::string> sets;
  if (!cells.empty())
    sets.push_back("mesh.cells=[" + std::to_string(cells[0]) + ", " + std::to_string(cells[1]) + ", " + std::to_string(cells[2]) + "]");
  if (static_state) sets.push_back("solver.preconditioner=block_jacobi");  // no factor in the first checkpoint
  const fiberfem::io::Scene sc = fiberfem::io::load_scene(scene_path, sets);
  std::printf("scene %s: %d nodes, %d tets, %d frames per level\n", sc.name.c_str(), sc.model.mesh.num_nodes(),
              sc.model.mesh.num_elements(), frames);
  for (int level : levels) {
    core::Simulator sim(sc.model, sc.settings);
    if (static_state) {  // a smooth deformation (not the rest grid, which compresses unrealistically well)
      core::Positions x = sc.model.mesh.rest_positions();
      for (Eigen::Index n = 0; n < x.cols(); ++n)
        x.col(n) += 1e-4 * core::Vec3(std::sin(400 * x(2, n)), std::cos(300 * x(0, n)), std::sin(500 * x(1, n) + x(2, n)));
      sim.set_state(x, core::Positions::Zero(3, x.cols()));
    }
    archive::ArchiveOptions o;
    o.path = dir + "/bench_archive_" + std::to_string(level) + ".h5";
    o.compression = level;
    o.checkpoint_every_s = 0;  // checkpoints timed apart
    const auto t0 = Clock::now();
    std::vector<double> record_s, step_s;
    double checkpoint_s = 0;
    {
      fiberfem::service::RealTimeEngine engine(sim);
      archive::ArchiveWriter w(o, sc, engine, "bench");
      const double open_s = std::chrono::duration<double>(Clock::now() - t0).count();
      for (int f = 0; f < frames; ++f) {
        core::StepReport r;
        if (!static_state) {
          const auto s0 = Clock::now();
          r = sim.step();
          step_s.push_back(std::chrono::duration<double>(Clock::now() - s0).count());
        }
        archive::FrameExtras x;
        for (const auto& c : sc.cavities) x.cavity_volumes_m3.emplace_back(c.name, core::cavity_volume(c.surface, sim.positions()));
        const auto r0 = Clock::now();
        w.record_frame(engine, r, x);
        record_s.push_back(std::chrono::duration<double>(Clock::now() - r0).count());
      }
      const auto c0 = Clock::now();
      w.checkpoint(engine, "{}");
      w.flush();
      checkpoint_s = std::chrono::duration<double>(Clock::now() - c0).count();
      std::printf("  level %d: open + header + first checkpoint %.1f ms\n", level, 1e3 * open_s);
    }
    const double mean = std::accumulate(record_s.begin(), record_s.end(), 0.0) / static_cast<double>(record_s.size());
    const double bytes = frame_bytes(o.path) / frames;
    std::printf("  level %d: record_frame median %.3f ms, mean %.3f ms (flush every 10 frames included); %.0f bytes/frame "
                "(%.1f bytes/node); checkpoint %.1f ms; file %.1f MB",
                level, 1e3 * median(record_s), 1e3 * mean, bytes, bytes / sc.model.mesh.num_nodes(), 1e3 * checkpoint_s,
                static_cast<double>(std::filesystem::file_size(o.path)) / 1e6);
    if (!step_s.empty()) std::printf("; step median %.2f ms", 1e3 * median(step_s));
    std::printf("\n");
    std::filesystem::remove(o.path);
    std::filesystem::remove(dir + "/bench_archive_" + std::to_string(level) + ".xdmf");
  }
  return 0;
}
