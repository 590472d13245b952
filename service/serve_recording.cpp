#include "service/serve_recording.hpp"

#include <ostream>

namespace fiberfem::service::detail {

ServeRecording::ServeRecording(RunDriver& run, std::string source, std::ostream& out)
    : run_(run), source_(std::move(source)), out_(out) {}

void ServeRecording::start_series(const io::ArchiveSettings& settings) {
  series_ = settings;
  part_ = 1;
  run_.start_recording(settings, source_);
}

long ServeRecording::stop() {
  const std::string path = run_.recording_path();
  const long frames = run_.stop_recording();
  out_ << "fiberfem serve: recorded " << frames << " frames to " << path << "\n" << std::flush;
  return frames;
}

CommandResult ServeRecording::command(const std::string& kind, const std::string& args) {
  if (!has_archive()) return {false, "this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5): no recording"};
  try {
    if (kind == "stop_recording") {
      if (!run_.recording()) return {false, "not recording"};
      if (!args.empty() && args.find_first_not_of(" {}\n\t") != std::string::npos) return {false, "stop_recording takes no arguments"};
      const std::string path = run_.recording_path();
      const long frames = stop();
      return {true, "recorded " + std::to_string(frames) + " frames to " + path};
    }
    if (run_.recording()) return {false, "already recording to " + run_.recording_path() + " (stop_recording first)"};
    const io::ArchiveSettings a = io::parse_archive_settings(args.empty() ? "{}" : args, "start_recording");
    start_series(a);
    return {true, "recording to " + a.path};
  } catch (const std::exception& e) {
    return {false, e.what()};
  }
}

void ServeRecording::after_command(long step, double time_s, const std::string& id, const std::string& kind,
                                   const std::string& args, CommandResult& result) {
  if (!run_.recording()) return;
  run_.record_command(step, time_s, id, kind, args, result);
  if (!result.accepted || (kind != "restore" && kind != "reset")) return;
  io::ArchiveSettings next = series_;
  const std::string base =
      next.path.size() > 3 && next.path.substr(next.path.size() - 3) == ".h5" ? next.path.substr(0, next.path.size() - 3) : next.path;
  next.path = base + "-" + std::to_string(++part_) + ".h5";
  stop();
  run_.start_recording(next, source_);
  result.reason += "; recording continues in " + next.path;
}

}  // namespace fiberfem::service::detail
