// The `fiberfem` command: one subcommand per job (service/app/commands.hpp), each in its own
// file. `fiberfem run SCENE.yaml` runs a scene in batch (docs/options.md); `fiberfem render`
// draws one off-screen (docs/rendering.md).

#include "service/app/commands.hpp"

#include <CLI/CLI.hpp>

int main(int argc, char** argv) {
  CLI::App app{"fiberfem: fiber-incorporated corotational FEM"};
  app.require_subcommand(1);
  int exit_code = 0;
  fiberfem::app::add_run_command(app, exit_code);
#ifdef FIBERFEM_WITH_DDS
  fiberfem::app::add_serve_command(app, exit_code);
  fiberfem::app::add_ctl_command(app, exit_code);
#endif
#ifdef FIBERFEM_HAVE_ARCHIVE
  fiberfem::app::add_archive_command(app, exit_code);
#if defined(FIBERFEM_WITH_DDS)
  fiberfem::app::add_replay_command(app, exit_code);
#endif
#endif
#ifdef FIBERFEM_HAVE_RENDER
  fiberfem::app::add_render_command(app, exit_code);
#endif
  fiberfem::app::add_sweep_command(app, exit_code);
#ifdef FIBERFEM_HAVE_WEB
  fiberfem::app::add_web_command(app, exit_code);
#endif
  CLI11_PARSE(app, argc, argv);
  return exit_code;
}
