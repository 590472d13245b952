#include "clients/render/video_writer.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <fstream>
#include <sstream>
#include <spawn.h>
#include <stdexcept>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace fiberfem::render {

void VideoSettings::validate() const {
  if (path.empty()) throw std::invalid_argument("video path: empty");
  if (width < 2 || width > 8192 || height < 2 || height > 8192)
    throw std::invalid_argument("video size " + std::to_string(width) + "x" + std::to_string(height) + " is outside [2, 8192]");
  if (!(fps > 0 && fps <= 240)) throw std::invalid_argument("video fps: " + std::to_string(fps) + " is outside (0, 240]");
  if (codec != "libx264" && codec != "mpeg4") throw std::invalid_argument("video codec '" + codec + "': use libx264 or mpeg4");
  if (quality < 0 || quality > 51) throw std::invalid_argument("video quality: " + std::to_string(quality) + " is outside [0, 51]");
}

bool find_program(const std::string& program) {
  if (program.find('/') != std::string::npos) return access(program.c_str(), X_OK) == 0;
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string p = (dir.empty() ? "." : dir) + "/" + program;
    struct stat st {};
    if (stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode) && access(p.c_str(), X_OK) == 0) return true;
  }
  return false;
}

VideoWriter::VideoWriter(VideoSettings settings) : settings_(std::move(settings)) {
  settings_.validate();
  if (!find_program(settings_.ffmpeg))
    throw std::runtime_error("cannot write " + settings_.path + ": '" + settings_.ffmpeg +
                             "' not found on PATH (install ffmpeg, or leave out --mp4)");
  if (FILE* f = std::fopen(settings_.path.c_str(), "wb")) {
    std::fclose(f);
  } else {
    throw std::runtime_error("cannot write " + settings_.path + ": " + std::strerror(errno));
  }
  // A write to a pipe whose reader has died raises SIGPIPE, which would kill the whole
  // process; ignored, the write returns EPIPE and we report ffmpeg's log instead.
  std::signal(SIGPIPE, SIG_IGN);
  int pipefd[2];
  if (pipe2(pipefd, O_CLOEXEC) != 0) throw std::runtime_error(std::string("video: pipe: ") + std::strerror(errno));
  const std::string log = settings_.path + ".log";
  char size[32], rate[32], q[16];
  std::snprintf(size, sizeof size, "%dx%d", settings_.width, settings_.height);
  std::snprintf(rate, sizeof rate, "%.6g", settings_.fps);
  std::snprintf(q, sizeof q, "%d", settings_.quality);
  // yuv420p needs even sizes: pad an odd width or height by one pixel.
  std::vector<std::string> args = {settings_.ffmpeg, "-nostdin", "-y", "-loglevel", "error", "-f", "rawvideo",
                                   "-pix_fmt", "rgba", "-s", size, "-r", rate, "-i", "-",
                                   "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p", "-c:v", settings_.codec};
  if (settings_.codec == "libx264") {
    for (const std::string a : {"-preset", "veryfast", "-crf"}) args.push_back(a);
    args.emplace_back(q);
  } else {
    const int qscale = std::max(1, std::min(31, settings_.quality / 4 + 1));
    args.emplace_back("-q:v");
    args.push_back(std::to_string(qscale));
  }
  args.push_back(settings_.path);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, pipefd[0], 0);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  const int rc = posix_spawnp(&pid_, settings_.ffmpeg.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  ::close(pipefd[0]);
  if (rc != 0) {
    ::close(pipefd[1]);
    pid_ = -1;
    throw std::runtime_error("cannot start " + settings_.ffmpeg + ": " + std::strerror(rc));
  }
  fd_ = pipefd[1];
}

VideoWriter::~VideoWriter() {
  try {
    close();
  } catch (...) {
  }
}

std::string VideoWriter::log_tail() const {
  std::ifstream f(settings_.path + ".log");
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (text.size() > 600) text = "..." + text.substr(text.size() - 600);
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text.empty() ? "(no message)" : text;
}

void VideoWriter::write(const Image& frame) {
  if (frame.width != settings_.width || frame.height != settings_.height)
    throw std::invalid_argument("video: frame " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                                " differs from the video's " + std::to_string(settings_.width) + "x" + std::to_string(settings_.height));
  if (fd_ < 0) throw std::runtime_error("video: " + settings_.path + " is already closed");
  const std::uint8_t* p = frame.rgba.data();
  size_t left = frame.rgba.size();
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = std::strerror(errno);
      close();  // throws with ffmpeg's log
      throw std::runtime_error("video: writing to ffmpeg failed: " + why);
    }
    p += n, left -= static_cast<size_t>(n);
  }
  ++frames_;
}

void VideoWriter::close() {
  if (fd_ >= 0) ::close(fd_), fd_ = -1;
  if (pid_ <= 0) return;
  int status = 0;
  while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  pid_ = -1;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error("ffmpeg failed writing " + settings_.path + ": " + log_tail());
  std::remove((settings_.path + ".log").c_str());
}

}  // namespace fiberfem::render
