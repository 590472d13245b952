// `fiberfem serve [SCENE.yaml]`: the service on DDS (docs/dds.md, docs/options.md). Without
// a scene file it serves the embedded default heart (configs/scenes/heart.yaml).

#include "service/builtin_scenes.hpp"
#include "service/commands.hpp"
#include "service/serve.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <memory>
#include <unistd.h>

namespace fiberfem::service {
namespace {

struct ServeArgs {
  std::string scene_file, builtin = "heart";
  std::vector<std::string> overrides;
  bool fast = false;
  ServeOptions o;
};

int serve_command(ServeArgs& a) {
  a.o.realtime = !a.fast;
  a.o.status_line = isatty(fileno(stderr)) != 0;
  try {
    if (!a.scene_file.empty()) {
      a.o.source = a.scene_file;
      return serve(io::load_scene(a.scene_file, a.overrides), a.o, std::cout);
    }
    a.o.source = "builtin:" + a.builtin;
    return serve(load_builtin_scene(a.builtin, a.overrides), a.o, std::cout);
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
  cmd->add_flag("--fast", a->fast, "Step as fast as possible instead of in real time");
  cmd->add_option("--real-time-factor", a->o.real_time_factor, "Simulated seconds per wall second in real-time mode")
      ->check(CLI::Range(1e-6, 100.0))
      ->capture_default_str();
  cmd->add_option("--publish-hz", a->o.publish_hz, "Largest state publish rate, 1/s")->check(CLI::Range(1e-3, 1000.0))->capture_default_str();
  cmd->add_option("--status-hz", a->o.status_hz, "Status publish rate, 1/s")->check(CLI::Range(1e-3, 100.0))->capture_default_str();
  cmd->add_option("--until", a->o.until_s, "Stop at this simulation time, s (default: run until shut down)")->check(CLI::NonNegativeNumber);
  cmd->add_flag("--surface-only", a->o.surface_only, "States carry the boundary nodes only");
  cmd->add_flag("--paused", a->o.start_paused, "Start paused (resume or step by command)");
  cmd->callback([a, &exit_code] { exit_code = serve_command(*a); });
}

}  // namespace fiberfem::service
