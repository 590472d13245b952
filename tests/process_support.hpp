#pragma once
// Running the real `fiberfem` binary from tests: a command line, its exit code and output.

#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace fiberfem::testing {

struct ProcessResult {
  int exit_code = -1;  ///< The exit status, or 128 + signal if it died of a signal.
  std::string output;  ///< stdout and stderr together.
};

inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// Runs `args` (args[0] the program) through /bin/sh, capturing stdout and stderr.
inline ProcessResult run_process(const std::vector<std::string>& args) {
  std::string cmd;
  for (const std::string& a : args) cmd += shell_quote(a) + " ";
  cmd += "2>&1";
  ProcessResult r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n = 0;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : WIFSIGNALED(status) ? 128 + WTERMSIG(status) : -1;
  return r;
}

/// A fresh directory under the system temp dir, removed with the object.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "fiberfem-test-XXXXXX").string();
    path_ = mkdtemp(tmpl.data()) ? tmpl : std::string();
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

inline nlohmann::json read_json(const std::string& path) {
  std::ifstream f(path);
  return nlohmann::json::parse(f, nullptr, /*allow_exceptions=*/false);
}

inline void write_file(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

inline std::string read_file(const std::string& path) {
  std::ifstream f(path);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

}  // namespace fiberfem::testing

namespace fiberfem::testing {

/// A child process running in the background (the service, a client), its stdout and
/// stderr in a file. Stopped with SIGTERM (then SIGKILL) when the object goes.
class BackgroundProcess {
 public:
  /// Starts args[0] with args, environment += `env` ("NAME=value"), output to `log_path`.
  BackgroundProcess(const std::vector<std::string>& args, const std::string& log_path,
                    const std::vector<std::string>& env = {})
      : log_path_(log_path) {
    pid_ = fork();
    if (pid_ == 0) {
      FILE* log = std::fopen(log_path.c_str(), "w");
      if (log) {
        dup2(fileno(log), 1);
        dup2(fileno(log), 2);
      }
      for (const std::string& e : env) putenv(const_cast<char*>(e.c_str()));
      std::vector<char*> argv;
      for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
  }
  ~BackgroundProcess() { stop(); }
  BackgroundProcess(const BackgroundProcess&) = delete;
  BackgroundProcess& operator=(const BackgroundProcess&) = delete;

  pid_t pid() const { return pid_; }
  /// Sends `sig`.
  void signal(int sig) const {
    if (pid_ > 0) ::kill(pid_, sig);
  }
  /// Whether it is still running (reaps it if it ended).
  bool running() {
    if (pid_ <= 0 || exited_) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      return false;
    }
    return true;
  }
  /// Waits up to `timeout_s` for it to end; returns its exit code (128 + signal), or -1
  /// if it is still running.
  int wait(double timeout_s) {
    for (double t = 0; t < timeout_s; t += 0.02) {
      if (!running()) return exit_code_;
      usleep(20000);
    }
    return running() ? -1 : exit_code_;
  }
  /// SIGTERM, a grace period, then SIGKILL; returns the exit code.
  int stop(double grace_s = 5) {
    if (pid_ <= 0) return exit_code_;
    if (running()) {
      signal(SIGTERM);
      if (wait(grace_s) < 0) {
        signal(SIGKILL);
        wait(5);
      }
    }
    return exit_code_;
  }
  std::string output() const { return read_file(log_path_); }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  int exit_code_ = -1;
  std::string log_path_;
};

}  // namespace fiberfem::testing
