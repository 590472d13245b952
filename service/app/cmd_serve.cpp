// `fiberfem serve [SCENE.yaml]`: the service on DDS (docs/dds.md, docs/options.md). Without
// a scene file it serves the embedded default heart (configs/scenes/heart.yaml).

#include "service/builtin_scenes.hpp"
#include "service/app/commands.hpp"
#include "service/serve.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <unistd.h>

namespace fiberfem::app {
namespace {

struct ServeArgs {
  std::string scene_file, builtin = "heart", archive, resume;
  int flush_frames = 0, threads = 0;
  double flush_seconds = -1;
  std::vector<std::string> overrides;
  bool fast = false;
  service::ServeOptions o;
};

int serve_command(CLI::App& cmd, ServeArgs& a) {
  a.o.realtime = !a.fast;
  a.o.status_line = isatty(fileno(stderr)) != 0;
  try {
    if (!a.resume.empty()) a.o.resume = service::parse_resume(a.resume);
    if (cmd.count("--threads")) a.overrides.insert(a.overrides.begin(), "solver.threads=" + std::to_string(a.threads));
    io::Scene scene = [&] {
      if (!a.scene_file.empty()) {
        a.o.source = a.scene_file;
        return io::load_scene(a.scene_file, a.overrides);
      }
      a.o.source = "builtin:" + a.builtin;
      a.o.files = &service::embedded_files();
      return service::load_builtin_scene(a.builtin, a.overrides);
    }();
    for (const std::string& w : scene.warnings) std::cerr << "fiberfem: warning: " << w << "\n";
    // Recording: the scene's archive key, then the command line over it.
    a.o.archive = scene.archive;
    if (!a.archive.empty()) a.o.archive.enabled = true, a.o.archive.path = a.archive;
    if ((cmd.count("--flush-frames") || cmd.count("--flush-seconds")) && !a.o.archive.enabled)
      throw std::invalid_argument("--flush-frames and --flush-seconds need --archive RUN.h5 (or the scene's archive key)");
    if (cmd.count("--flush-frames")) a.o.archive.flush_frames = a.flush_frames;
    if (cmd.count("--flush-seconds")) a.o.archive.flush_seconds = a.flush_seconds;
    return service::serve(scene, a.o, std::cout);
  } catch (const std::exception& e) {
    std::cerr << "fiberfem serve: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

void add_serve_command(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("serve", "Run a scene as a DDS service (publish states, accept commands)");
  auto a = std::make_shared<ServeArgs>();
  cmd->add_option("scene", a->scene_file, "Scene file (YAML); without one the built-in scene runs");
  cmd->add_option("--scene", a->scene_file, "Same as the positional scene file");
  cmd->add_option("--builtin", a->builtin, "Built-in scene when no file is given: heart | cantilever")->capture_default_str();
  cmd->add_option("--set", a->overrides, "Override a scene key: key.path=value (repeatable)");
  cmd->add_option("--run-id", a->o.run_id, "Run id (the key of every sample); default <scene>-<host>-<pid>");
  cmd->add_option("--threads", a->threads, "OpenMP threads of the engine, 0: chosen step by step from measured step times, up to all cores, fewer beside busy cores (solver.threads)")
      ->check(CLI::Range(0, 1024));
  cmd->add_flag("--fast", a->fast, "Step as fast as possible instead of in real time");
  cmd->add_option("--real-time-factor", a->o.real_time_factor, "Simulated seconds per wall second in real-time mode")
      ->check(CLI::Range(1e-6, 100.0))
      ->capture_default_str();
  cmd->add_option("--publish-hz", a->o.publish_hz, "Largest state publish rate, 1/s")->check(CLI::Range(1e-3, 1000.0))->capture_default_str();
  cmd->add_option("--status-hz", a->o.status_hz, "Status publish rate, 1/s")->check(CLI::Range(1e-3, 100.0))->capture_default_str();
  cmd->add_option("--until", a->o.until_s, "Stop at this simulation time, s (default: run until shut down)")->check(CLI::NonNegativeNumber);
  cmd->add_flag("--surface-only", a->o.surface_only, "States carry the boundary nodes only");
  cmd->add_flag("--paused", a->o.start_paused, "Start paused (resume or step by command)");
  cmd->add_option("--command-budget", a->o.command_budget_ms,
                  "Wall time for commands at one step boundary, ms (at least one is handled; the rest wait for the next)")
      ->check(CLI::Range(1e-3, 1e4))
      ->capture_default_str();
  cmd->add_option("--archive", a->archive, "Record the run into this HDF5 archive (docs/archive.md; the scene key archive.path)");
  cmd->add_option("--flush-frames", a->flush_frames, "Flush the archive every N frames (archive.flush_frames, default 10)")
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--flush-seconds", a->flush_seconds, "... or every S s of wall time, 0: off (archive.flush_seconds, default 1)")
      ->check(CLI::Range(0.0, 3600.0));
  cmd->add_option("--resume", a->resume, "Start from an archive's checkpoint at or before a time: RUN.h5[@t] (with the parameters it ran with)");
  cmd->callback([cmd, a, &exit_code] { exit_code = serve_command(*cmd, *a); });
}

}  // namespace fiberfem::app
