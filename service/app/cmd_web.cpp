// `fiberfem web`: hands over to the bridge that serves the browser page (docs/web.md), the
// Python package clients/python/fiberfem_client/web in the project's .venv, with the page
// bundled at build time (clients/web, CMake target fiberfem_web_page). This file only
// checks the options, finds both and execs the bridge, so the bridge's process is the one
// the user started (signals and exit status go straight to it).

#include "service/app/commands.hpp"
#include "service/app/python_handover.hpp"

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <utility>
#include <vector>

namespace fiberfem::app {
namespace {

struct WebArgs {
  int port = 8080;
  std::string listen = "127.0.0.1";
  std::string run_id;
  bool read_only = false;
};

int exec_bridge(const WebArgs& a) {
  namespace fs = std::filesystem;
  // FIBERFEM_WEB_PYTHON overrides the interpreter (another environment with the client
  // package, e.g. one whose cyclonedds binding has DDS Security).
  const std::string python = python_interpreter("FIBERFEM_WEB_PYTHON", FIBERFEM_WEB_PYTHON_DEFAULT);
  const std::string page = FIBERFEM_WEB_PAGE_DIR;
  if (access(python.c_str(), X_OK) != 0) {
    std::fprintf(stderr, "fiberfem web: no Python environment at %s (run scripts/setup.sh, which makes .venv-web)\n",
                 python.c_str());
    return 3;
  }
  if (!fs::exists(fs::path(page) / "index.html") || !fs::exists(fs::path(page) / "app.js")) {
    std::fprintf(stderr, "fiberfem web: the page is not built at %s (run scripts/setup.sh: npm ci in clients/web, then the build)\n",
                 page.c_str());
    return 3;
  }
  std::vector<std::string> args = {python, "-m", "fiberfem_client.web", "--static", page, "--port",
                                   std::to_string(a.port), "--listen", a.listen};
  if (!a.run_id.empty()) args.insert(args.end(), {"--run", a.run_id});
  if (a.read_only) args.emplace_back("--read-only");
  exec_args(std::move(args));
  std::fprintf(stderr, "fiberfem web: cannot run %s: %s\n", python.c_str(), std::strerror(errno));
  return 3;
}

}  // namespace

void add_web_command(CLI::App& app, int& exit_code) {
  auto a = std::make_shared<WebArgs>();
  auto* cmd = app.add_subcommand("web", "Serve a page that shows and steers the runs on the DDS domain (docs/web.md)");
  cmd->add_option("--port", a->port, "TCP port of the page and its WebSocket (default 8080)")->check(CLI::Range(1, 65535));
  cmd->add_option("--listen", a->listen,
                  "Address to listen on (default 127.0.0.1; any other needs the token printed at start for commands)");
  cmd->add_option("--run", a->run_id, "Run shown first (default: the first run seen)");
  cmd->add_flag("--read-only", a->read_only, "Pages watch only: every command is refused");
  cmd->callback([a, &exit_code] { exit_code = exec_bridge(*a); });
}

}  // namespace fiberfem::app
