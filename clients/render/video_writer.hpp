#pragma once
/// @file MP4 (or any container ffmpeg knows by the file name) from raw RGBA frames piped
/// into an `ffmpeg` child process: no PNG encoding on the way.

#include "clients/render/image.hpp"

#include <string>
#include <sys/types.h>

namespace fiberfem::render {

/// How to encode. Every field has a default; validate() names a bad one.
struct VideoSettings {
  std::string path;                  ///< Output file (.mp4); required.
  int width = 0;                     ///< Frame width, pixels, in [2, 8192]; every frame must match.
  int height = 0;                    ///< Frame height, pixels, in [2, 8192].
  double fps = 30.0;                 ///< Playback frame rate, frames per second, in (0, 240]. Default 30.
  /// ffmpeg video encoder: libx264 (H.264, Debian's ffmpeg has it) or mpeg4. Default libx264.
  std::string codec = "libx264";
  /// Quality, lower is better, in [0, 51]: libx264's CRF (23 is its default), for mpeg4
  /// mapped to qscale quality / 4 + 1. Default 20.
  int quality = 20;
  std::string ffmpeg = "ffmpeg";     ///< The program, looked up on PATH. Default "ffmpeg".
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

/// An ffmpeg child reading raw RGBA frames from a pipe. Its own messages go to
/// `path + ".log"` (removed on success). Not copyable.
class VideoWriter {
 public:
  /// Starts ffmpeg. @throws std::invalid_argument for bad settings; std::runtime_error if
  /// ffmpeg is not found on PATH or cannot start.
  explicit VideoWriter(VideoSettings settings);
  /// Closes the pipe and waits for ffmpeg (errors are swallowed; call close() to see them).
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;

  /// Sends one frame. @throws std::invalid_argument for a frame of another size;
  /// std::runtime_error (with the tail of ffmpeg's log) if ffmpeg has gone.
  void write(const Image& frame);
  /// Finishes the file: closes the pipe, waits for ffmpeg.
  /// @throws std::runtime_error with the tail of ffmpeg's log if it failed.
  void close();
  /// Frames written so far.
  long frames() const { return frames_; }

 private:
  std::string log_tail() const;
  VideoSettings settings_;
  pid_t pid_ = -1;
  int fd_ = -1;
  long frames_ = 0;
};

/// Whether `program` is an executable file, or one found on PATH.
bool find_program(const std::string& program);

}  // namespace fiberfem::render
