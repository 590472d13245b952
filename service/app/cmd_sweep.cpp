// `fiberfem sweep SWEEP.yaml [options]` hands over to the Python client package
// (fiberfem_client.sweep, docs/sweeps.md): the sweep runs on Dask, whose scheduler and
// workers are Python, and each configuration runs this binary as `fiberfem run`. Every
// argument after `sweep` is passed on unchanged; the Python side parses them (one place
// for the options and their help). The interpreter: $FIBERFEM_PYTHON, else the project's
// .venv (FIBERFEM_VENV_PYTHON, set at configure time, made by scripts/setup.sh).

#include "service/app/commands.hpp"
#include "service/app/python_handover.hpp"

#include <CLI/CLI.hpp>

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <unistd.h>
#include <utility>
#include <vector>

namespace fiberfem::app {
namespace {

// This binary's own path: the workers run the same `fiberfem` the user called.
std::string own_binary() {
  char buf[PATH_MAX];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  return n > 0 ? std::string(buf, static_cast<size_t>(n)) : std::string();
}

int hand_over(const std::vector<std::string>& args) {
  const std::string python = python_interpreter("FIBERFEM_PYTHON", FIBERFEM_VENV_PYTHON);
  if (access(python.c_str(), X_OK) != 0) {
    std::cerr << "fiberfem sweep: no Python interpreter at " << python
              << " (run scripts/setup.sh to make the project's .venv, or set FIBERFEM_PYTHON to a Python"
                 " with the fiberfem_client package and scripts/requirements.txt installed)\n";
    return 1;
  }
  std::vector<std::string> argv_s = {python, "-m", "fiberfem_client.sweep"};
  const std::string self = own_binary();
  if (!self.empty()) argv_s.insert(argv_s.end(), {"--binary", self});
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  exec_args(std::move(argv_s));
  std::cerr << "fiberfem sweep: cannot start " << python << ": " << std::strerror(errno) << "\n";
  return 1;
}

}  // namespace

void add_sweep_command(CLI::App& app, int& exit_code) {
  auto* sweep = app.add_subcommand(
      "sweep", "Run a parameter sweep on Dask: SWEEP.yaml [--scheduler ADDRESS] [--workers N] [--out DIR] (docs/sweeps.md)");
  sweep->prefix_command();  // everything after `sweep` goes to the Python side, --help included
  sweep->set_help_flag();
  sweep->callback([sweep, &exit_code] { exit_code = hand_over(sweep->remaining()); });
}

}  // namespace fiberfem::app
