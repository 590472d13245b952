#pragma once
/// @file The sub-commands that hand over to the Python client package (`sweep`, `web`):
/// which interpreter, and replacing this process with it.

#include <cstdlib>
#include <string>
#include <unistd.h>
#include <vector>

namespace fiberfem::app {

/// The interpreter named by the environment variable `env` when set and not empty, else
/// `fallback` (a project virtual environment's python).
inline std::string python_interpreter(const char* env, const char* fallback) {
  const char* p = std::getenv(env);
  return p && *p ? p : fallback;
}

/// Replaces this process with `args[0]` run with `args`; returns only if that failed
/// (errno says why).
inline void exec_args(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (auto& s : args) argv.push_back(s.data());
  argv.push_back(nullptr);
  execv(argv[0], argv.data());
}

}  // namespace fiberfem::app
