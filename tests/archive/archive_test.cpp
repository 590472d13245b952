// The run archive in-process: what the writer records reads back equal to what the
// Simulator held at the time (positions as its own float32 cast, checkpoints exactly),
// and bad files are refused with a message naming what is wrong.

#include "service/archive/archive.hpp"
#include "service/archive/hdf5.hpp"

#include "core/cavity.hpp"
#include "io/scene.hpp"
#include "process_support.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace fiberfem {
namespace {

using testing::TempDir;

io::Scene heart() { return io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart.yaml"); }

template <class F>
void expect_error(F&& f, std::initializer_list<std::string> fragments) {
  try {
    f();
    ADD_FAILURE() << "expected an error mentioning " << *fragments.begin();
  } catch (const std::exception& e) {
    const std::string msg = e.what();
    for (const auto& frag : fragments) EXPECT_NE(msg.find(frag), std::string::npos) << "'" << msg << "' lacks '" << frag << "'";
  }
}

TEST(Archive, FramesCheckpointsAndCommandsReadBackAsRecorded) {
  TempDir dir;
  const io::Scene sc = heart();
  core::Simulator sim(sc.model, sc.settings);
  archive::ArchiveOptions o;
  o.path = dir.file("run.h5");
  o.velocities = true;
  o.every_steps = 2;
  o.checkpoint_every_s = 0.1;
  std::vector<Eigen::Matrix<float, 3, Eigen::Dynamic>> expected_x;
  std::vector<std::vector<float>> expected_a;
  std::vector<std::vector<double>> expected_vol;
  std::vector<long> expected_steps;
  core::SimulatorCheckpoint at_step_12;
  {
    service::RealTimeEngine engine(sim);
    archive::ArchiveWriter w(o, sc, engine, "test");
    for (int s = 1; s <= 20; ++s) {
      const core::StepReport r = sim.step();
      archive::FrameExtras x;
      for (const auto& c : sc.cavities) x.cavity_volumes_m3.emplace_back(c.name, core::cavity_volume(c.surface, sim.positions()));
      w.record_frame(engine, r, x);
      if (s % 2 == 0) {
        expected_x.push_back(sim.positions().cast<float>());
        expected_a.emplace_back(sim.active_tension().begin(), sim.active_tension().end());
        std::vector<double> v;
        for (const auto& [n, vol] : x.cavity_volumes_m3) v.push_back(vol);
        expected_vol.push_back(v);
        expected_steps.push_back(s);
      }
      if (s == 12) at_step_12 = sim.checkpoint();
      if (s == 5) w.record_command({5, sim.time_s(), "c-1", "set_gravity", R"({"gravity": [0, 0, -9.81]})", true, ""});
      if (s == 7) w.record_command({7, sim.time_s(), "c-2", "set_material", "not json", false, "E_L must be > 0"});
    }
    EXPECT_EQ(w.frames(), 10);
  }
  ASSERT_TRUE(std::filesystem::exists(dir.file("run.xdmf")));
  archive::ArchiveReader r(o.path);
  const archive::ArchiveHeader& h = r.header();
  EXPECT_EQ(h.format_version, archive::kFormatVersion);
  EXPECT_EQ(h.scene_sha256, sc.hash_sha256);
  EXPECT_EQ(h.scene_yaml, sc.yaml_text);
  EXPECT_EQ(io::parse_scene(h.scene_yaml, "archive", h.scene_base_dir).hash_sha256, sc.hash_sha256);
  EXPECT_TRUE(h.rest_positions == sc.model.mesh.rest_positions());
  EXPECT_EQ(h.tets, sc.model.mesh.tets());
  EXPECT_EQ(h.regions, sc.model.mesh.regions());
  EXPECT_EQ(h.boundary_triangles.size(), sc.model.mesh.boundary_triangles().size());
  EXPECT_EQ(h.fibers.size(), static_cast<size_t>(sc.model.mesh.num_elements()));
  EXPECT_TRUE(h.fibers[17] == sim.model().fibers[17]);
  EXPECT_TRUE(h.stiffness_pa.at(0) == sc.model.region_materials[0].stiffness());
  EXPECT_EQ(h.cavity_names, (std::vector<std::string>{"lv", "rv"}));
  EXPECT_TRUE(h.has_velocities);
  ASSERT_EQ(r.frames(), 10);
  EXPECT_EQ(r.steps(), expected_steps);
  for (long i = 0; i < r.frames(); ++i) {
    const archive::Frame f = r.frame(i);
    EXPECT_TRUE(f.positions.cast<float>() == expected_x[static_cast<size_t>(i)]) << "frame " << i;
    EXPECT_EQ(std::vector<float>(f.activation_pa.begin(), f.activation_pa.end()), expected_a[static_cast<size_t>(i)]);
    EXPECT_EQ(f.cavity_volumes_m3, expected_vol[static_cast<size_t>(i)]);
    EXPECT_EQ(f.status, "ok");
    EXPECT_GT(f.solver_iterations, 0);
    EXPECT_NEAR(f.time_s, expected_steps[static_cast<size_t>(i)] * sc.settings.dt_s, 1e-12);
  }
  EXPECT_THROW(r.frame(10), std::out_of_range);
  const auto cmds = r.commands();
  ASSERT_EQ(cmds.size(), 2u);
  EXPECT_EQ(cmds[0].id, "c-1");
  EXPECT_EQ(cmds[0].step, 5);
  EXPECT_TRUE(cmds[0].accepted);
  EXPECT_EQ(nlohmann::json::parse(cmds[0].text)["gravity"][2], -9.81);
  EXPECT_EQ(cmds[1].text, "not json");
  EXPECT_FALSE(cmds[1].accepted);
  EXPECT_EQ(cmds[1].reason, "E_L must be > 0");
  // Checkpoints every 0.1 s: steps 0, 6, 12, 18 (the step that reaches each time).
  const auto cps = r.checkpoints();
  ASSERT_EQ(cps.size(), 4u);
  EXPECT_EQ(cps[2].step, 12);
  const size_t k = r.checkpoint_at_or_before(0.21);
  EXPECT_EQ(k, 2u);
  std::string params;
  const core::SimulatorCheckpoint c = r.read_checkpoint(k, &params);
  EXPECT_EQ(params, "{}");
  EXPECT_TRUE(c.x == at_step_12.x);
  EXPECT_TRUE(c.v == at_step_12.v);
  EXPECT_TRUE(c.vfree_prev == at_step_12.vfree_prev);
  EXPECT_EQ(c.q.size(), at_step_12.q.size());
  EXPECT_TRUE(c.q[100].coeffs() == at_step_12.q[100].coeffs());
  EXPECT_TRUE(c.R[100] == at_step_12.R[100]);
  EXPECT_TRUE(c.solver.history == at_step_12.solver.history);
  EXPECT_EQ(c.solver.jacobi_first, at_step_12.solver.jacobi_first);
  EXPECT_EQ(c.solver.jacobi_first_excess, at_step_12.solver.jacobi_first_excess);
  ASSERT_EQ(c.solver.factors.size(), at_step_12.solver.factors.size());
  EXPECT_TRUE(c.solver.factors[0].matrix_values == at_step_12.solver.factors[0].matrix_values);
  EXPECT_EQ(c.time_s, at_step_12.time_s);
  expect_error([&] { r.checkpoint_at_or_before(-1.0); }, {"no checkpoint at or before t = -1", "checkpoints at: 0"});
}

TEST(Archive, OptionsAreValidatedByName) {
  const auto bad = [](auto mutate, const std::string& field) {
    archive::ArchiveOptions o;
    o.path = "x.h5";
    mutate(o);
    testing::expect_invalid([&] { o.validate(); }, {field});
  };
  bad([](archive::ArchiveOptions& o) { o.path.clear(); }, "path");
  bad([](archive::ArchiveOptions& o) { o.flush_frames = 0; }, "flush_frames");
  bad([](archive::ArchiveOptions& o) { o.flush_seconds = -1; }, "flush_seconds");
  bad([](archive::ArchiveOptions& o) { o.every_steps = 0; }, "every");
  bad([](archive::ArchiveOptions& o) { o.checkpoint_every_s = std::nan(""); }, "checkpoint_every");
  bad([](archive::ArchiveOptions& o) { o.compression = 10; }, "compression");
}

TEST(Archive, BadFilesAreRefusedWithAClearMessage) {
  TempDir dir;
  testing::write_file(dir.file("text.h5"), "not an HDF5 file at all\n");
  expect_error([&] { archive::ArchiveReader r(dir.file("text.h5")); }, {"text.h5", "not an HDF5 file"});
  expect_error([&] { archive::ArchiveReader r(dir.file("missing.h5")); }, {"missing.h5"});
  {  // an HDF5 file that is not an archive
    archive::h5::File f = archive::h5::File::create(dir.file("other.h5"));
    archive::h5::write_attribute(f.id(), "title", std::string("something else"));
  }
  expect_error([&] { archive::ArchiveReader r(dir.file("other.h5")); }, {"other.h5", "not a fiberfem archive"});

  const io::Scene sc = heart();
  core::Simulator sim(sc.model, sc.settings);
  archive::ArchiveOptions o;
  o.path = dir.file("run.h5");
  {
    service::RealTimeEngine engine(sim);
    archive::ArchiveWriter w(o, sc, engine, "test");
    for (int s = 0; s < 3; ++s) {
      const core::StepReport r = sim.step();
      archive::FrameExtras x;
      for (const auto& c : sc.cavities) x.cavity_volumes_m3.emplace_back(c.name, 0.0);
      w.record_frame(engine, r, x);
    }
  }
  std::filesystem::copy_file(o.path, dir.file("v99.h5"));
  {  // a future format version
    archive::h5::File f = archive::h5::File::open(dir.file("v99.h5"), archive::h5::Mode::write);
    H5Adelete(f.id(), "format_version");
    archive::h5::write_attribute<std::int64_t>(f.id(), "format_version", 99);
  }
  expect_error([&] { archive::ArchiveReader r(dir.file("v99.h5")); }, {"format version 99", "reads version 1"});
  {  // truncated to half
    const auto size = std::filesystem::file_size(o.path);
    std::ifstream in(o.path, std::ios::binary);
    std::string bytes(size / 2, '\0');
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    std::ofstream(dir.file("half.h5"), std::ios::binary) << bytes;
  }
  expect_error([&] { archive::ArchiveReader r(dir.file("half.h5")); }, {"half.h5"});
  // The intact one still reads.
  archive::ArchiveReader r(o.path);
  EXPECT_EQ(r.frames(), 3);
}

}  // namespace
}  // namespace fiberfem
