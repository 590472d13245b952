#pragma once
/// @file `fiberfem replay RUN.h5`: republishes an archived run on the service's topics
/// (topology first, then states) at real time, a rate factor, or frame by frame, and
/// takes pause, resume, step, seek, rate and loop commands on the same command topic
/// (docs/replay.md). Clients tell it from a live run only by the replay flag.

#include <iosfwd>
#include <string>

namespace fiberfem::service {

struct ReplayOptions {
  std::string path;           ///< The archive (docs/archive.md).
  std::string run_id;         ///< Default "replay-<scene>-<host>-<pid>".
  double rate = 1.0;          ///< Archive seconds per wall second, in (0, 1000]. Default 1.
  bool loop = false;          ///< Start again at the end. Default off.
  bool paused = false;        ///< Start paused (step or resume by command). Default off.
  double from_s = 0.0;        ///< Start at the first frame at or after this time, s. Default 0.
  bool exit_at_end = false;   ///< Exit after the last frame (not looping). Default: keep serving.
  bool follow = false;        ///< Follow a file still being written (SWMR): wait for new frames at the end.
  /// Publish every frame in order even when behind the clock (then the replay runs slower
  /// than `rate`); default: skip to the newest due frame, as a live run would.
  bool every_frame = false;
  double status_hz = 2.0;     ///< Status rate, 1/s, in (0, 100]. Default 2.
  bool status_line = false;   ///< Redraw one status line on stderr.
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

/// @return 0 after a clean stop, 1 when the archive cannot be read or DDS cannot start.
int replay(const ReplayOptions& options, std::ostream& out);

}  // namespace fiberfem::service
