#pragma once
/// @file The HDF5 run archive (docs/archive.md): one self-describing file per run, written
/// once (mesh, fibers, materials, scene) and then appended frame by frame under SWMR, so a
/// crash loses at most the frames since the last flush; periodic double-precision
/// checkpoints seed bit-for-bit resumes; XDMF sidecars open it in ParaView and meshio.

#include "core/circulation/snapshot.hpp"
#include "core/simulator.hpp"
#include "io/scene.hpp"
#include "service/engine.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace fiberfem::archive {

/// Name and version of the file format (root attributes `format`, `format_version`).
inline constexpr const char* kFormatName = "fiberfem-archive";
/// The version of a real-time tier run's archive.
inline constexpr int kFormatVersion = 1;
/// The version of an accurate tier run's archive (version 1 plus the element mesh, frames
/// on all its nodes, accurate-tier checkpoints): readers of version 1 refuse it by name.
inline constexpr int kFormatVersionAccurate = 2;

/// How a run is recorded. Every field has a default; validate() names a bad one.
struct ArchiveOptions {
  std::string path;                ///< The .h5 file (created, truncating). Required.
  /// Flush (make readable after a crash) after this many recorded frames, in [1, 100000].
  /// Default 10.
  int flush_frames = 10;
  /// ... or when this much wall time has passed since the last flush, s, in [0, 3600];
  /// 0: by frames only. Checked when a frame is recorded. Default 1.
  double flush_seconds = 1.0;
  int every_steps = 1;             ///< Record every K-th step, in [1, 1000000]. Default 1.
  bool velocities = false;         ///< Also record velocities (float32). Default false.
  /// Also record the displacement from rest (float32; the XDMF sidecar's point data, as
  /// ParaView's Xdmf3 reader cannot subtract the rest positions itself). Default true.
  bool displacement = true;
  /// A checkpoint (double precision, resumable) every this much simulated time, s, in
  /// [0, 1e9]; 0: only the first and the last. Default 1.
  double checkpoint_every_s = 1.0;
  /// Deflate level (with byte shuffle) of the per-frame node arrays (positions,
  /// displacement, velocities, activation), in [0, 9]; 0 stores them raw. Default 0
  /// (docs/archive.md: level 1 saves 20% (heart) to 41% (100k-node box) of the bytes for
  /// 4x to 30x the recording time).
  int compression = 0;
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

/// Per-frame values the caller measures (the writer computes the rest from the simulator).
struct FrameExtras {
  /// (name, volume in m^3) of each measured cavity, in the scene's measure.cavities order.
  std::vector<std::pair<std::string, double>> cavity_volumes_m3;
  /// The circulation of the frame's state (service::RunDriver::circulation()); required
  /// when the engine has a circulation, ignored otherwise.
  const core::circulation::Snapshot* circulation = nullptr;
};

/// A command the service applied or refused.
struct CommandRecord {
  long step = 0;         ///< Step count at which it took effect (applied before that step).
  double time_s = 0;     ///< Simulation time then, s.
  std::string id;        ///< The client's command id.
  std::string kind;      ///< Command kind (e.g. "set_material").
  std::string text;      ///< The command itself, JSON.
  bool accepted = false; ///< Its acknowledgement.
  std::string reason;    ///< Why it was refused (empty when accepted).
};

namespace detail {
struct WriterFile;
}

/// Records a run. The constructor writes the header (mesh, fibers, materials, scene,
/// solver settings) and a first checkpoint, creates every per-frame dataset and starts
/// SWMR writing; after that readers may follow the file live.
class ArchiveWriter {
 public:
  /// @param source where the scene came from (file path, "builtin:NAME", "resume:RUN.h5").
  /// @throws std::invalid_argument for bad options, h5::Error if the file cannot be written.
  ArchiveWriter(ArchiveOptions options, const io::Scene& scene, const service::Engine& engine, std::string source);
  ~ArchiveWriter();
  ArchiveWriter(const ArchiveWriter&) = delete;
  ArchiveWriter& operator=(const ArchiveWriter&) = delete;

  /// Records the engine's current state as a frame when its step count is a multiple
  /// of every_steps (else does nothing); `r` is the report of the step just taken. Flushes
  /// on the frame or wall-time cadence; writes a checkpoint every checkpoint_every_s.
  void record_frame(const service::Engine& engine, const core::StepReport& r, const FrameExtras& x);
  /// Records a command (applied or refused).
  void record_command(const CommandRecord& c);
  /// Writes a resumable checkpoint of `engine` now; `parameter_state_json` is kept opaque
  /// (the service stores the applied parameter commands; batch runs pass "{}"). The same
  /// step, state and parameters as the last checkpoint are not written twice.
  void checkpoint(const service::Engine& engine, const std::string& parameter_state_json);
  /// The parameter state the periodic checkpoints of record_frame carry (default "{}";
  /// the service sets its running scene and forces after every accepted command).
  void set_parameter_state(std::string parameter_state_json);
  /// Makes everything recorded so far durable against a crash of this process.
  void flush();
  /// Frames recorded so far.
  long frames() const;
  /// Flushes, closes the file and writes the XDMF sidecar. Idempotent; the destructor
  /// calls it (swallowing errors).
  void close();

 private:
  std::unique_ptr<detail::WriterFile> f_;
};

/// What the header holds (written once).
struct ArchiveHeader {
  int format_version = 0;                      ///< kFormatVersion or kFormatVersionAccurate.
  std::string software_version;                ///< fiberfem version that wrote it.
  std::string git_commit;                      ///< Its git commit, or "unknown".
  std::string created_utc;                     ///< ISO 8601 UTC.
  std::string source;                          ///< Scene file, "builtin:NAME" or "resume:RUN.h5".
  std::string scene_name;                      ///< The scene's name.
  std::string scene_yaml;                      ///< io::Scene::yaml_text.
  std::string scene_sha256;                    ///< io::Scene::hash_sha256.
  std::string scene_base_dir;                  ///< Where the scene's relative paths resolve (absolute).
  core::Positions rest_positions;              ///< 3 x N, m.
  std::vector<core::Tet> tets;                 ///< Node indices per element.
  std::vector<int> regions;                    ///< Per element.
  std::vector<core::Tri> boundary_triangles;   ///< Outward-oriented boundary faces.
  std::vector<std::uint8_t> fixed_dofs;        ///< 3N, 1 = fixed.
  std::vector<core::Vec3> fibers;              ///< Per element, unit.
  std::vector<core::Mat6> stiffness_pa;        ///< Per region, Voigt, Pa.
  std::vector<double> density_kg_m3;           ///< Per region.
  double dt_s = 0;                             ///< Time step, s.
  std::vector<std::string> cavity_names;       ///< Columns of Frame::cavity_volumes_m3.
  std::vector<std::string> probe_names;        ///< Columns of Frame::probe_displacements_m.
  /// Columns of `/frames/circulation` (core::circulation::snapshot_columns() when written by
  /// this fiberfem); empty when the run had no circulation (or the archive is older).
  std::vector<std::string> circulation_columns;
  bool has_velocities = false;                 ///< Frames carry velocities.
  bool has_displacement = false;               ///< Frames carry displacements.
  int every_steps = 1;                         ///< Every K-th step was recorded.
  /// "real_time" or "accurate" (version 1 archives: real_time).
  std::string tier = "real_time";
  /// Element order, 1 or 2 (version 1 archives: 1).
  int order = 1;
  /// Order 2: every node of the 10-node mesh, corners first (the first columns are
  /// rest_positions), 3 x M, m; empty at order 1.
  core::Positions element_rest_positions;
  /// Order 2: the 10-node elements in XDMF's and VTK's node order (corners, then the
  /// edges 01 12 02 03 13 23); empty at order 1.
  std::vector<std::array<int, 10>> element_tets;
};

/// One recorded frame.
struct Frame {
  long step = 0;                               ///< Step count.
  double time_s = 0;                           ///< Simulation time, s.
  core::Positions positions;                   ///< 3 x N (the corner mesh), m (stored float32).
  /// Order 2: every node of the 10-node mesh, 3 x M, m (stored float32); else empty.
  core::Positions element_positions;
  core::Positions velocities;                  ///< 3 x N, m/s, or empty.
  core::Positions displacement;                ///< 3 x N, m (stored float32), or empty.
  std::vector<double> activation_pa;           ///< Per element (stored float32), empty when off.
  std::vector<double> cavity_volumes_m3;       ///< Per cavity.
  std::vector<core::Vec3> probe_displacements_m;  ///< Per probe.
  /// The circulation after the step (header().circulation_columns not empty), else none.
  std::optional<core::circulation::Snapshot> circulation;
  /// Kinetic and elastic energy of the state the step started from (StepReport), J.
  double kinetic_energy_j = 0, elastic_energy_j = 0;
  int solver_iterations = 0;                   ///< PCG iterations of the step (0: a starting frame).
  int substeps = 1;                            ///< Substeps of the accepted attempt.
  int inverted_elements = 0;                   ///< Elements with det F <= 0.
  double solver_residual = 0;                  ///< Largest relative residual.
  std::string status;                          ///< "ok", "recovered" or "failed".
};

/// A checkpoint's place in the archive.
struct CheckpointInfo {
  long step = 0;      ///< Step count.
  double time_s = 0;  ///< Simulation time, s.
};

/// Reads an archive, closed or live. As a SWMR reader (`follow`) refresh() picks up the
/// frames a live writer has flushed since.
class ArchiveReader {
 public:
  /// @throws std::runtime_error naming the file and what is wrong (not HDF5, not an
  /// archive, unsupported version, missing dataset).
  explicit ArchiveReader(const std::string& path, bool follow = false);
  ~ArchiveReader();
  ArchiveReader(ArchiveReader&&) noexcept;
  ArchiveReader& operator=(ArchiveReader&&) noexcept;

  /// What was written once (read at open).
  const ArchiveHeader& header() const { return header_; }
  /// Complete frames (every per-frame dataset has them), as of the last refresh.
  long frames() const { return frames_; }
  /// Re-reads the extents written by a live writer (SWMR). @return frames().
  long refresh();
  /// Simulation time of each frame, s.
  std::vector<double> times() const;
  /// Step count of each frame.
  std::vector<long> steps() const;
  /// Frame `i` in [0, frames()). @throws std::out_of_range.
  Frame frame(long i) const;
  /// Every complete command record, in order (refreshed when following).
  std::vector<CommandRecord> commands() const;
  /// Every complete checkpoint, in order (refreshed when following).
  std::vector<CheckpointInfo> checkpoints() const;
  /// Index of the last checkpoint at or before `time_s` (with 1e-9 s slack; +inf: the last).
  /// @throws std::invalid_argument listing the checkpoint times when there is none.
  size_t checkpoint_at_or_before(double time_s) const;
  /// Reads checkpoint `k` of either tier; its parameter-state JSON into `parameter_state`
  /// if given.
  service::EngineCheckpoint read_engine_checkpoint(size_t k, std::string* parameter_state = nullptr) const;
  /// Reads checkpoint `k` of a real-time run. @throws std::runtime_error for an accurate one.
  core::SimulatorCheckpoint read_checkpoint(size_t k, std::string* parameter_state = nullptr) const;
  /// The file as opened.
  const std::string& path() const { return path_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_;
  ArchiveHeader header_;
  long frames_ = 0;
};

/// Writes RUN.xdmf beside RUN.h5 (time series: geometry per frame by hyperslab,
/// displacement and activation per frame, region), readable by ParaView's Xdmf3 reader.
/// Opens the archive as a SWMR reader, so it works on live files too.
void write_xdmf(const std::string& h5_path);

/// Makes a file whose SWMR writer died openable by ordinary readers (clears the file's
/// consistency flags), checks that its frames read, and regenerates the sidecar.
/// @return the number of intact frames.
long recover(const std::string& h5_path);

/// Writes `out_xdmf` and beside it OUT.h5 with one dataset per step (the layout meshio's
/// XDMF TimeSeriesReader reads): the rest mesh, and per step point data `positions` and
/// `displacement` (m), cell data `activation` (Pa).
void export_meshio(const std::string& h5_path, const std::string& out_xdmf);

/// Writes the circulation of every frame of a run with one as CSV: a header line `step,`
/// then the archive's column names (SI units, docs/archive.md), a line per frame; numbers
/// with 17 significant digits (the archive's doubles come back exactly).
/// @return the frames written. @throws std::runtime_error when the archive has no
/// circulation or `out_csv` cannot be written.
long export_circulation_csv(const std::string& h5_path, const std::string& out_csv);

/// `fiberfem` version and the git commit it was built from ("unknown" outside a repo).
std::string software_version();
/// The git commit this fiberfem was configured from, or "unknown".
std::string git_commit();

}  // namespace fiberfem::archive
