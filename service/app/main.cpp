// The `fiberfem` command: one subcommand per job (service/app/commands.hpp), each in its own
// file. `fiberfem run SCENE.yaml` runs a scene in batch (docs/options.md); `fiberfem render`
// draws one off-screen (docs/rendering.md).

#include "core/blas_threads.hpp"
#include "service/app/commands.hpp"

#include <CLI/CLI.hpp>

#include <cstdlib>

namespace {

// The engine calls BLAS on one thread only (core/solvers/cholesky_factor.cpp), but the
// pthread OpenBLAS starts a thread per core when it is loaded, and those spin for about
// 0.1 s before they sleep: a step in that time runs its parallel loops beside them, and
// on two cores the paper-size beam's first step took 65 ms instead of 3. So OpenBLAS is
// set to one thread and its threads are stopped here, before anything runs beside them,
// and the processes this one starts (sweep workers) inherit OPENBLAS_NUM_THREADS=1 (a
// value the user set is kept, threads and all). This replaced starting the process again
// with the variable set, which cost a second load of every library (about 60 ms).
void without_blas_threads() {
  if (std::getenv("OPENBLAS_NUM_THREADS") != nullptr) return;
  setenv("OPENBLAS_NUM_THREADS", "1", 1);
  fiberfem::core::blas::set_threads(1);
  fiberfem::core::blas::stop_threads();
}

}  // namespace

int main(int argc, char** argv) {
  without_blas_threads();
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
