#pragma once
/// @file The subcommands of `fiberfem`, one registration function each (one file each:
/// cmd_run.cpp, ...). Each adds its subcommand to the app with a callback that runs it
/// and stores the process exit code in `exit_code`.

namespace CLI {
class App;
}

namespace fiberfem::app {

/// `fiberfem run`: a scene in batch, without the bus (cmd_run.cpp).
void add_run_command(CLI::App& app, int& exit_code);

/// `fiberfem serve`: the service on DDS (cmd_serve.cpp; built with FIBERFEM_WITH_DDS).
void add_serve_command(CLI::App& app, int& exit_code);

/// `fiberfem ctl`: the command-line client (clients/ctl; built with FIBERFEM_WITH_DDS).
void add_ctl_command(CLI::App& app, int& exit_code);
/// `fiberfem replay RUN.h5`: an archive republished on DDS (cmd_replay.cpp; DDS and HDF5).
void add_replay_command(CLI::App& app, int& exit_code);

/// `fiberfem archive info|recover|export-meshio`: run archives (cmd_archive.cpp; built
/// with FIBERFEM_WITH_HDF5).
void add_archive_command(CLI::App& app, int& exit_code);

/// `fiberfem render`: simulate a scene and render it off-screen (cmd_render.cpp); built
/// when FIBERFEM_WITH_OSMESA is on (compile definition FIBERFEM_HAVE_RENDER).
void add_render_command(CLI::App& app, int& exit_code);

/// `fiberfem sweep SWEEP.yaml`: a parameter sweep on Dask, handed over to the Python
/// client package (cmd_sweep.cpp, docs/sweeps.md).
void add_sweep_command(CLI::App& app, int& exit_code);
/// `fiberfem web`: execs the browser bridge (cmd_web.cpp; docs/web.md).
void add_web_command(CLI::App& app, int& exit_code);

}  // namespace fiberfem::app
