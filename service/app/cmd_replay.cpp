// `fiberfem replay RUN.h5`: an archived run republished on the service's topics
// (docs/replay.md, docs/options.md).

#include "service/app/commands.hpp"
#include "service/replay.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <memory>
#include <unistd.h>

namespace fiberfem::app {

void add_replay_command(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("replay", "Republish an archived run on DDS (as a live run, with a replay flag)");
  auto o = std::make_shared<service::ReplayOptions>();
  cmd->add_option("archive", o->path, "The run archive (HDF5, docs/archive.md)")->required();
  cmd->add_option("--run-id", o->run_id, "Run id (default replay-<scene>-<host>-<pid>)");
  cmd->add_option("--rate", o->rate, "Archive seconds per wall second")->check(CLI::Range(1e-3, 1000.0))->capture_default_str();
  cmd->add_flag("--loop", o->loop, "Start again at the end");
  cmd->add_flag("--paused", o->paused, "Start paused (step, seek or resume by command)");
  cmd->add_option("--from", o->from_s, "Start at this time, s")->check(CLI::NonNegativeNumber);
  cmd->add_flag("--exit-at-end", o->exit_at_end, "Exit after the last frame (unless looping)");
  cmd->add_flag("--follow", o->follow, "Follow an archive still being written (SWMR)");
  cmd->add_flag("--every-frame", o->every_frame, "Publish every frame, never skip to the newest due one (slower than --rate when behind)");
  cmd->add_option("--status-hz", o->status_hz, "Status publish rate, 1/s")->check(CLI::Range(1e-3, 100.0))->capture_default_str();
  cmd->callback([o, &exit_code] {
    o->status_line = isatty(fileno(stderr)) != 0;
    try {
      exit_code = service::replay(*o, std::cout);
    } catch (const std::exception& e) {
      std::cerr << "fiberfem replay: " << e.what() << "\n";
      exit_code = 1;
    }
  });
}

}  // namespace fiberfem::app
