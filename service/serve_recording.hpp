#pragma once
/// @file Recording in the service (docs/archive.md): from the start or by the
/// start_recording and stop_recording commands, every command logged with the step it
/// took effect at, and a new file of the series (RUN-2.h5, RUN-3.h5, ...) after a
/// restore or reset, since an archive's frames run forward in time.

#include "service/run_driver.hpp"

#include <iosfwd>
#include <string>

namespace fiberfem::service::detail {

class ServeRecording {
 public:
  /// `source`: the archives' source ("FILE (served as RUN)").
  ServeRecording(RunDriver& run, std::string source, std::ostream& out);
  /// Starts the first file of a series. @throws as RunDriver::start_recording.
  void start_series(const io::ArchiveSettings& settings);
  /// start_recording {path, flush_frames, flush_seconds, every, velocities,
  /// checkpoint_every, compression} and stop_recording {} (RunControl's recording handler).
  CommandResult command(const std::string& kind, const std::string& args);
  /// After a command was applied at `step` and `time_s`: logs it; an accepted restore or
  /// reset continues the recording in the series' next file (and says so in `result`).
  void after_command(long step, double time_s, const std::string& id, const std::string& kind, const std::string& args,
                     CommandResult& result);
  /// Ends the recording, printing what it recorded. @return the frames recorded.
  long stop();

 private:
  RunDriver& run_;
  std::string source_;
  std::ostream& out_;
  io::ArchiveSettings series_;  // of the series' first file
  int part_ = 1;
};

}  // namespace fiberfem::service::detail
