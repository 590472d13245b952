#pragma once
/// @file One live run, the machinery the batch run, the service and scene rendering share:
/// the simulator (under a RunControl), its start from an archive checkpoint
/// (--resume RUN.h5[@t]), its recording into an HDF5 archive (docs/archive.md: frames at
/// the recording cadence with the cavity volumes, checkpoints, the parameter state, the
/// command log) and the step. What is each program's own (the report, commands, pacing,
/// the camera) composes around it.

#include "service/run_control.hpp"

#include "core/circulation/snapshot.hpp"
#include "core/simulator.hpp"
#include "io/scene.hpp"

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace fiberfem::archive {
class ArchiveWriter;
}

namespace fiberfem::service {

/// Whether this build records and reads archives (FIBERFEM_WITH_HDF5 and HDF5 found).
bool has_archive();

/// The scene stored in an archive (its YAML after the original overrides, looked up from
/// its original directory), with `overrides` applied. With `resume_s` (a resume from the
/// last checkpoint at or before it): the scene as the run had it at that checkpoint, when
/// the checkpoint carries one (a served run's: its parameter commands written in).
/// @throws std::runtime_error if the file is not a readable archive or the build has none.
io::Scene scene_from_archive(const std::string& h5_path, const std::vector<std::string>& overrides,
                             std::optional<double> resume_s = std::nullopt);

/// Where a run starts: from rest, or from an archive's checkpoint (--resume RUN.h5[@t]).
struct ResumeFrom {
  std::string path;          ///< The archive; empty: start from rest.
  double time_s = HUGE_VAL;  ///< The last checkpoint at or before this time, s; inf: the last.
  bool empty() const { return path.empty(); }
};

/// Reads "RUN.h5[@t]" (t in seconds). @throws std::invalid_argument naming the option.
ResumeFrom parse_resume(const std::string& text);

/// (name, volume in m^3) of each measured cavity (the scene's measure.cavities order).
using CavityVolumes = std::vector<std::pair<std::string, double>>;

/// Whether a run's parameters can change while it runs, and so what its archive carries.
enum class Parameters {
  /// The scene's throughout (a batch run): a resume takes only the checkpoint's state;
  /// checkpoints carry "{}".
  fixed,
  /// Changed by commands (the service): a resume also restores the parameters the
  /// archived run had; the archive records them with every checkpoint and the commands.
  commanded,
};

class RunDriver {
 public:
  /// Builds the engine of `scene`'s tier at rest. `files`: the in-memory files of a
  /// built-in scene. @throws std::invalid_argument as the engine does.
  RunDriver(const io::Scene& scene, Parameters parameters, const io::EmbeddedFiles* files = nullptr);
  ~RunDriver();
  RunDriver(const RunDriver&) = delete;
  RunDriver& operator=(const RunDriver&) = delete;

  /// Continues from the archive's checkpoint (with its parameters when `commanded` and
  /// the archive has them). @throws std::invalid_argument "--resume PATH: ..." when the
  /// archive is of another scene or mesh, std::runtime_error when it cannot be read.
  void resume(const ResumeFrom& from);

  RunControl& control() { return control_; }
  const RunControl& control() const { return control_; }
  /// The running engine (a command may replace it: do not keep the reference).
  Engine& engine() { return control_.engine(); }
  const Engine& engine() const { return control_.engine(); }
  /// The running real-time simulator. @throws std::logic_error on the accurate tier.
  core::Simulator& simulator() { return control_.simulator(); }
  const core::Simulator& simulator() const { return control_.simulator(); }

  /// One step at a step boundary: timed forces that expired are cleared, the simulator
  /// steps, and a recording records the new state (at its cadence). A failed step (its
  /// state rolled back, the frame marked failed) is recorded too unless `record_failure`
  /// is false (a batch run ends there instead).
  const core::StepReport& step(bool record_failure = true);
  /// The report of the last step (a default one before the first).
  const core::StepReport& last_step() const { return last_; }

  /// Activation of the current state, tension over its region's peak, 0..1, per element;
  /// empty when the contraction is off.
  std::vector<double> activation() const;
  /// The cavity volumes of the current state (measured once per state).
  const CavityVolumes& cavity_volumes();
  /// The circulation of the current state (pressures, volumes, flows, and the figures of
  /// the last complete beat this driver stepped through), or nullptr when the scene has none.
  const core::circulation::Snapshot* circulation();

  /// Starts recording into `settings.path`: the header (the running scene), a checkpoint
  /// and the current state as the first frame. `source` is the header's source.
  /// @throws std::invalid_argument for bad settings, std::runtime_error when the file
  /// cannot be written or the build has no HDF5. Recording must be off.
  void start_recording(const io::ArchiveSettings& settings, const std::string& source);
  bool recording() const { return writer_ != nullptr; }
  /// The archive being recorded (empty when not recording).
  const std::string& recording_path() const { return recording_path_; }
  /// Frames recorded so far into the current archive (0 when not recording).
  long recorded_frames() const;
  /// Records a command (when recording) with the step it took effect at; an accepted one
  /// also updates the parameter state the checkpoints carry.
  void record_command(long step, double time_s, const std::string& id, const std::string& kind, const std::string& args,
                      const CommandResult& result);
  /// Ends the recording: a last checkpoint (a run can be continued past its end), then
  /// the file is closed and its XDMF sidecar written. @return the frames recorded.
  long stop_recording();
  /// Wall time of each frame recorded since the last call, ms (measuring the cavities
  /// and writing the frame).
  std::vector<double> take_record_ms();

 private:
  void record(const core::StepReport& r);
  std::string checkpoint_parameters() const;

  RunControl control_;
  Parameters parameters_;
  core::StepReport last_{};
  CavityVolumes cavities_;
  bool cavities_valid_ = false;
  core::circulation::Monitor circulation_;  // fed every step of a run with a circulation
  bool circulation_valid_ = false;
  std::unique_ptr<archive::ArchiveWriter> writer_;
  std::string recording_path_;
  std::vector<double> record_ms_;
};

}  // namespace fiberfem::service
