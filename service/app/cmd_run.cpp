// `fiberfem run SCENE.yaml` (or `--builtin cantilever`, an embedded copy of
// configs/scenes/demo-cantilever.yaml) runs a scene in batch: a progress bar on a
// terminal, a summary, and an optional JSON report (docs/options.md, docs/report-format.md).

#include "io/scene.hpp"
#include "service/batch_run.hpp"
#include "service/run_driver.hpp"
#include "service/builtin_scenes.hpp"
#include "service/app/commands.hpp"

#include <CLI/CLI.hpp>

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <cstdio>
#include <iostream>
#include <memory>
#include <unistd.h>

namespace fiberfem::app {
namespace {

// Shortest text that reads back as `v` (so `--dt 0.005` is `solver.dt=0.005`).
std::string format_number(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

struct RunArgs {
  std::string scene_file, builtin = "cantilever", solver, preconditioner, rotation, max_energy_gain;
  std::string archive, resume;
  int flush_frames = 0, record_every = 0, compression = -1;
  double flush_seconds = -1, checkpoint_every = -1;
  bool velocities = false;
  bool scene_hash_only = false;
  double dt = 0, tolerance = 0;
  int threads = 0;
  std::vector<int> cells;
  service::BatchOptions o;
};

int run_command(CLI::App& run, RunArgs& a) {
  service::BatchOptions& o = a.o;
  std::vector<std::string> sets;
  if (run.count("--dt")) sets.push_back("solver.dt=" + format_number(a.dt));
  if (!a.solver.empty()) sets.push_back("solver.method=" + a.solver);
  if (!a.preconditioner.empty()) sets.push_back("solver.preconditioner=" + a.preconditioner);
  if (run.count("--tolerance")) sets.push_back("solver.tolerance=" + format_number(a.tolerance));
  if (!a.rotation.empty()) sets.push_back("solver.rotation=" + a.rotation);
  if (run.count("--threads")) sets.push_back("solver.threads=" + std::to_string(a.threads));
  if (!a.max_energy_gain.empty()) sets.push_back("solver.max_energy_gain=" + a.max_energy_gain);
  if (!a.cells.empty())
    sets.push_back("mesh.cells=[" + std::to_string(a.cells[0]) + ", " + std::to_string(a.cells[1]) + ", " +
                   std::to_string(a.cells[2]) + "]");
  sets.insert(sets.end(), o.overrides.begin(), o.overrides.end());
  o.overrides = sets;
  o.progress_bar = isatty(fileno(stderr)) != 0;

  // The archive: the scene's `archive` key, then the command line over it.
  const auto with_archive = [&](io::Scene sc) {
    io::ArchiveSettings& ar = sc.archive;
    if (!a.archive.empty()) {
      ar.enabled = true;
      ar.path = a.archive;
    }
    const bool tuned = run.count("--flush-frames") || run.count("--flush-seconds") || run.count("--record-every") ||
                       run.count("--velocities") || run.count("--checkpoint-every") || run.count("--compression");
    if (tuned && !ar.enabled) throw std::invalid_argument("archive options need --archive RUN.h5 (or the scene's archive key)");
    if (run.count("--flush-frames")) ar.flush_frames = a.flush_frames;
    if (run.count("--flush-seconds")) ar.flush_seconds = a.flush_seconds;
    if (run.count("--record-every")) ar.every_steps = a.record_every;
    if (run.count("--velocities")) ar.velocities = a.velocities;
    if (run.count("--checkpoint-every")) ar.checkpoint_every_s = a.checkpoint_every;
    if (run.count("--compression")) ar.compression = a.compression;
    o.archive = ar;
    return sc;
  };
  // `--scene-hash` parses the scene as a run would and prints its hash instead of running:
  // `fiberfem sweep` keys finished configurations by it without running them again.
  const auto run_or_hash = [&](io::Scene sc) {
    if (!a.scene_hash_only) return service::run_batch(with_archive(std::move(sc)), o, std::cout);
    std::cout << sc.hash_sha256 << "\n";
    return 0;
  };

  try {
    if (!a.resume.empty()) {
      o.resume = service::parse_resume(a.resume);
      if (!a.archive.empty() && std::filesystem::exists(a.archive) && std::filesystem::exists(o.resume.path) &&
          std::filesystem::equivalent(a.archive, o.resume.path))
        throw std::invalid_argument("--archive must not be the archive being resumed from (" + a.archive + ")");
      if (a.scene_file.empty()) {
        o.source = "archive:" + o.resume.path;
        return run_or_hash(service::scene_from_archive(o.resume.path, o.overrides, o.resume.time_s));
      }
    }
    if (!a.scene_file.empty()) {
      o.source = a.scene_file;
      return run_or_hash(io::load_scene(a.scene_file, o.overrides));
    }
    if (!service::builtin_scenes().count(a.builtin)) {
      std::cerr << "fiberfem: unknown built-in scene '" << a.builtin << "' (available: cantilever, heart)\n";
      return 2;
    }
    o.source = "builtin:" + a.builtin;
    return run_or_hash(service::load_builtin_scene(a.builtin, o.overrides));
  } catch (const std::exception& e) {
    std::cerr << "fiberfem: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

void add_run_command(CLI::App& app, int& exit_code) {
  auto* run = app.add_subcommand("run", "Run a scene in batch (no bus)");
  auto a = std::make_shared<RunArgs>();
  service::BatchOptions& o = a->o;
  run->add_option("scene", a->scene_file, "Scene file (YAML, docs/scenes.md); without one, --builtin runs");
  run->add_option("--scene", a->scene_file, "Same as the positional scene file");
  run->add_option("--builtin", a->builtin, "Built-in scene when no file is given: cantilever | heart")->capture_default_str();
  run->add_option("--set", o.overrides, "Override a scene key: key.path=value (repeatable)");
  run->add_flag("--static", o.force_static, "Solve for static equilibrium instead of time stepping");
  run->add_option("--steps", o.steps, "Number of steps (instead of --until)")->check(CLI::Range(1, 1000000000));
  run->add_option("--until", o.until_s, "Simulated time, s (default: the scene's solver.until)")->check(CLI::Range(1e-9, 1e9));
  run->add_option("--report", o.report_path, "Write a JSON report here (docs/report-format.md)");
  run->add_flag("--scene-hash", a->scene_hash_only, "Print the scene's SHA-256 (after every --set) and exit without running");
  run->add_flag("--compare-static", o.compare_static, "After a dynamic run, solve statically and compare the probes");
  // Shorthands for scene keys (each becomes a --set before the explicit ones).
  run->add_option("--dt", a->dt, "Time step, s (solver.dt)")->check(CLI::Range(1e-6, 10.0));
  run->add_option("--solver", a->solver, "pcg | direct (solver.method)")->check(CLI::IsMember({"pcg", "direct"}));
  run->add_option("--preconditioner", a->preconditioner, "cholesky | block_jacobi | amg (solver.preconditioner)")
      ->check(CLI::IsMember({"cholesky", "block_jacobi", "amg"}));
  run->add_option("--tolerance", a->tolerance, "PCG relative tolerance (solver.tolerance)")->check(CLI::Range(1e-14, 0.5));
  run->add_option("--rotation", a->rotation, "polar | svd (solver.rotation)")->check(CLI::IsMember({"svd", "polar"}));
  run->add_option("--max-energy-gain", a->max_energy_gain, "Energy check per step, relative; inf: off (solver.max_energy_gain)");
  run->add_option("--threads", a->threads, "OpenMP threads, 0: chosen step by step from measured step times, up to all cores (solver.threads)")->check(CLI::Range(0, 1024));
  run->add_option("--cells", a->cells, "Box cells along x y z (mesh.cells)")->expected(3)->check(CLI::Range(1, 2000));
  // Recording (docs/archive.md); each also a key of the scene's `archive` mapping.
  run->add_option("--archive", a->archive, "Record the run into this HDF5 archive (archive.path)");
  run->add_option("--flush-frames", a->flush_frames, "Flush the archive every N frames (archive.flush_frames, default 10)")
      ->check(CLI::Range(1, 100000));
  run->add_option("--flush-seconds", a->flush_seconds, "... or every S s of wall time, 0: off (archive.flush_seconds, default 1)")
      ->check(CLI::Range(0.0, 3600.0));
  run->add_option("--record-every", a->record_every, "Record every K-th step (archive.every, default 1)")->check(CLI::Range(1, 1000000));
  run->add_flag("--velocities", a->velocities, "Also record velocities (archive.velocities)");
  run->add_option("--checkpoint-every", a->checkpoint_every, "Checkpoint every S simulated s, 0: first and last only (archive.checkpoint_every, default 1)")
      ->check(CLI::Range(0.0, 1e9));
  run->add_option("--compression", a->compression, "Deflate level 0-9 of the per-frame arrays (archive.compression, default 0)")
      ->check(CLI::Range(0, 9));
  run->add_flag("--log-frames", o.log_frames, "With --archive: print 'frame F step S' after each recorded frame");
  run->add_option("--resume", a->resume,
                  "Continue a recorded run from its checkpoint at or before a time: RUN.h5[@t] (the scene from the archive unless one is given)");
  run->callback([run, a, &exit_code] { exit_code = run_command(*run, *a); });
}

}  // namespace fiberfem::app
