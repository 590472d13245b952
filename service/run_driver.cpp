#include "service/run_driver.hpp"

#include "core/cavity.hpp"
#ifdef FIBERFEM_HAVE_ARCHIVE
#include "service/archive/archive.hpp"
#else
namespace fiberfem::archive {
class ArchiveWriter {};  // never made: recording refuses in a build without HDF5
}  // namespace fiberfem::archive
#endif

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdlib>
#include <stdexcept>

namespace fiberfem::service {
#ifndef FIBERFEM_HAVE_ARCHIVE
namespace {

[[noreturn]] void no_archive(const std::string& what) {
  throw std::runtime_error(what + "this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5)");
}

}  // namespace
#endif

bool has_archive() {
#ifdef FIBERFEM_HAVE_ARCHIVE
  return true;
#else
  return false;
#endif
}

io::Scene scene_from_archive(const std::string& h5_path, const std::vector<std::string>& overrides,
                             std::optional<double> resume_s) {
#ifdef FIBERFEM_HAVE_ARCHIVE
  const archive::ArchiveReader r(h5_path);
  std::string yaml = r.header().scene_yaml;
  if (resume_s) {  // a served run's checkpoint holds its running scene (RunControl::parameter_state_json)
    std::string params;
    r.read_engine_checkpoint(r.checkpoint_at_or_before(*resume_s), &params);
    const nlohmann::json state = nlohmann::json::parse(params, nullptr, false);
    if (state.is_object() && state.contains("scene_yaml")) yaml = state["scene_yaml"].get<std::string>();
  }
  return io::parse_scene(yaml, "archive:" + h5_path, r.header().scene_base_dir, overrides);
#else
  (void)overrides;
  (void)resume_s;
  throw std::runtime_error("cannot read '" + h5_path + "': this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5)");
#endif
}

ResumeFrom parse_resume(const std::string& text) {
  ResumeFrom r;
  const size_t at = text.rfind('@');
  r.path = text.substr(0, at);
  if (at != std::string::npos) {
    const std::string t = text.substr(at + 1);
    char* end = nullptr;
    r.time_s = std::strtod(t.c_str(), &end);
    if (t.empty() || *end != '\0' || !std::isfinite(r.time_s))
      throw std::invalid_argument("--resume " + text + ": '" + t + "' is not a time in seconds (RUN.h5@1.5)");
  }
  return r;
}

RunDriver::RunDriver(const io::Scene& scene, Parameters parameters, const io::EmbeddedFiles* files)
    : control_(scene, files), parameters_(parameters) {}

RunDriver::~RunDriver() = default;

void RunDriver::resume(const ResumeFrom& from) {
  if (from.empty()) return;
#ifdef FIBERFEM_HAVE_ARCHIVE
  const archive::ArchiveReader reader(from.path);
  const size_t k = reader.checkpoint_at_or_before(from.time_s);  // inf: the last
  // A served run's checkpoints carry the running scene and forces; a batch run's, none
  // (its scene is the archived one).
  std::string params;
  const EngineCheckpoint cp = reader.read_engine_checkpoint(k, &params);
  try {
    if (parameters_ == Parameters::commanded && params.find("scene_yaml") != std::string::npos)
      control_.restore_parameter_state(params);
    engine().restore(cp);
  } catch (const std::invalid_argument& e) {  // another scene's archive, or its parameters
    throw std::invalid_argument("--resume " + from.path + ": " + e.what() + " (the archive is of another scene or mesh)");
  }
  cavities_valid_ = false;
#else
  no_archive("--resume: ");
#endif
}

const core::StepReport& RunDriver::step(bool record_failure) {
  control_.before_step();
  last_ = engine().step();
  cavities_valid_ = false;
  const Engine& e = engine();
  if (e.circulation_state() && last_.status != core::StepStatus::failed) {
    circulation_.update(e.model().circulation, *e.circulation_state(), e.coupled_cavity_volumes(), e.circulation_iterations(),
                        e.dt_s(), /*after_step=*/true);
    circulation_valid_ = true;
  }
  if (writer_ && (record_failure || last_.status != core::StepStatus::failed)) record(last_);
  return last_;
}

std::vector<double> RunDriver::activation() const {
  const Engine& e = engine();
  if (e.active_tension().empty()) return {};
  return e.model().contraction.activation(e.model().mesh.regions(), e.active_tension());
}

const CavityVolumes& RunDriver::cavity_volumes() {
  if (!cavities_valid_) {
    cavities_.clear();
    for (const io::CavityMeasure& c : control_.scene().cavities)
      cavities_.emplace_back(c.name, core::cavity_volume(c.surface, engine().positions()));
    cavities_valid_ = true;
  }
  return cavities_;
}

const core::circulation::Snapshot* RunDriver::circulation() {
  const Engine& e = engine();
  if (!e.circulation_state()) return nullptr;
  // A state not reached by a step here (the start, a resume, a reset or restore command).
  if (!circulation_valid_ || circulation_.snapshot().time_s != e.circulation_state()->time_s) {
    circulation_.update(e.model().circulation, *e.circulation_state(), e.coupled_cavity_volumes(), 0, e.dt_s(), /*after_step=*/false);
    circulation_valid_ = true;
  }
  return &circulation_.snapshot();
}

std::string RunDriver::checkpoint_parameters() const {
  return parameters_ == Parameters::commanded ? control_.parameter_state_json() : "{}";
}

#ifdef FIBERFEM_HAVE_ARCHIVE

void RunDriver::start_recording(const io::ArchiveSettings& a, const std::string& source) {
  if (writer_) throw std::logic_error("start_recording: already recording to " + recording_path_);
  archive::ArchiveOptions ao;
  ao.path = a.path;
  ao.flush_frames = a.flush_frames;
  ao.flush_seconds = a.flush_seconds;
  ao.every_steps = a.every_steps;
  ao.velocities = a.velocities;
  ao.displacement = a.displacement;
  ao.checkpoint_every_s = a.checkpoint_every_s;
  ao.compression = a.compression;
  ao.validate();
  try {
    // The header holds the scene as it runs now (commands merged in).
    const RunControl& rc = control_;
    const io::Scene running = rc.parameter_version() == 0 ? rc.scene() : rc.running_scene();
    writer_ = std::make_unique<archive::ArchiveWriter>(ao, running, engine(), source);
    recording_path_ = a.path;
    if (parameters_ == Parameters::commanded) {
      const std::string params = rc.parameter_state_json();
      writer_->set_parameter_state(params);
      writer_->checkpoint(engine(), params);
    }
    core::StepReport initial;
    initial.time_s = engine().time_s();
    cavities_valid_ = false;
    record(initial);
  } catch (...) {
    writer_.reset();
    recording_path_.clear();
    throw;
  }
}

long RunDriver::recorded_frames() const { return writer_ ? writer_->frames() : 0; }

void RunDriver::record(const core::StepReport& r) {
  const auto t0 = std::chrono::steady_clock::now();
  archive::FrameExtras extras{cavity_volumes()};
  extras.circulation = circulation();
  writer_->record_frame(engine(), r, extras);
  record_ms_.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}

void RunDriver::record_command(long step, double time_s, const std::string& id, const std::string& kind, const std::string& args,
                               const CommandResult& result) {
  if (!writer_) return;
  writer_->record_command({step, time_s, id, kind, args, result.accepted, result.accepted ? "" : result.reason});
  if (result.accepted && parameters_ == Parameters::commanded) writer_->set_parameter_state(control_.parameter_state_json());
}

long RunDriver::stop_recording() {
  if (!writer_) return 0;
  // Not recording any more, whatever the last checkpoint or the close throw.
  const std::unique_ptr<archive::ArchiveWriter> writer = std::move(writer_);
  recording_path_.clear();
  writer->checkpoint(engine(), checkpoint_parameters());
  const long frames = writer->frames();
  writer->close();
  return frames;
}

#else  // no HDF5: nothing records

void RunDriver::start_recording(const io::ArchiveSettings&, const std::string&) { no_archive(""); }
long RunDriver::recorded_frames() const { return 0; }
void RunDriver::record(const core::StepReport&) {}
void RunDriver::record_command(long, double, const std::string&, const std::string&, const std::string&, const CommandResult&) {}
long RunDriver::stop_recording() { return 0; }

#endif

std::vector<double> RunDriver::take_record_ms() { return std::exchange(record_ms_, {}); }

}  // namespace fiberfem::service
