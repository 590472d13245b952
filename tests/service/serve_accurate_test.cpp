// Accurate-tier scenes (material.law, mesh.order 2) on the service with real processes on
// loopback: `fiberfem serve` steps them and publishes the corner mesh's states, which match
// `fiberfem run` of the same scene; a law constant changed by command gives what a run with
// that constant gives; a run resumed from its archive continues bit for bit; the archive
// replays on the bus, exports to meshio as tetra10 and renders.

#include "clients/ctl/client.hpp"
#include "accurate_beam_scene.hpp"
#include "io/scene.hpp"
#include "process_support.hpp"
#include "service/archive/archive.hpp"
#if defined(FIBERFEM_HAVE_RENDER)
#include "clients/render/png_io.hpp"
#endif

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <thread>

namespace fiberfem::testing {
namespace {

using namespace std::chrono_literals;
using clients::Client;

class ServeAccurate : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { setenv("CYCLONEDDS_URI", FIBERFEM_DDS_URI, 1); }
  void SetUp() override { write_file(scene_file(), kAccurateBeamScene); }
  std::string scene_file() const { return dir_.file("beam.yaml"); }
  static std::string unique(const std::string& name) { return name + "-" + std::to_string(getpid()); }

  // `fiberfem run` of the scene for `steps` steps: the probe's final position, m.
  Eigen::Vector3d run_tip(int steps, const std::vector<std::string>& sets = {}) {
    std::vector<std::string> args = {FIBERFEM_BIN, "run", scene_file(), "--steps", std::to_string(steps), "--report", dir_.file("r.json")};
    for (const std::string& s : sets) args.insert(args.end(), {"--set", s});
    const ProcessResult r = run_process(args);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    const auto p = read_json(dir_.file("r.json"))["probes"][0]["final_m"];
    return {p[0].get<double>(), p[1].get<double>(), p[2].get<double>()};
  }

  // The published state at frame `frame` (waiting for it).
  clients::State state_at(Client& client, const std::string& run, unsigned long frame) {
    std::optional<clients::State> s;
    for (int i = 0; i < 200 && (!s || s->frame < frame); ++i) s = client.next_state(run, 5s, s ? static_cast<long>(s->frame) : -1);
    EXPECT_TRUE(s && s->frame == frame) << "no state at frame " << frame;
    return s ? *s : clients::State{};
  }

  TempDir dir_;
};

// The node at the probe point (a corner of the tip face) in the scene's corner mesh.
int tip_node(const io::Scene& sc) {
  int best = 0;
  const core::Positions& X = sc.model.mesh.rest_positions();
  for (int n = 0; n < X.cols(); ++n)
    if ((X.col(n) - sc.probes[0].point_m).norm() < (X.col(best) - sc.probes[0].point_m).norm()) best = n;
  return best;
}

TEST_F(ServeAccurate, StatesMatchFiberfemRunAndALawCommandGivesWhatTheSceneKeyGives) {
  const io::Scene sc = io::load_scene(scene_file());
  const int tip = tip_node(sc);
  ASSERT_LT((sc.model.mesh.rest_positions().col(tip) - sc.probes[0].point_m).norm(), 1e-12);
  const std::string run = unique("accurate");
  BackgroundProcess service({FIBERFEM_BIN, "serve", scene_file(), "--run-id", run, "--paused", "--fast", "--status-hz", "10"},
                            dir_.file("serve.log"));
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service.output();
  const auto topo = client.topology(run, 10s);
  ASSERT_TRUE(topo);
  EXPECT_EQ(topo->num_nodes, static_cast<unsigned>(sc.model.mesh.num_nodes()));  // the corner mesh
  EXPECT_EQ(topo->num_elements, static_cast<unsigned>(sc.model.mesh.num_elements()));

  // Ten steps on the bus against ten steps of `fiberfem run` (to float32 of the wire).
  ASSERT_TRUE(client.send(run, "step", R"({"count": 10})").accepted);
  const clients::State s10 = state_at(client, run, 10);
  ASSERT_EQ(s10.positions.size(), 3u * static_cast<size_t>(sc.model.mesh.num_nodes()));
  const Eigen::Vector3d served(s10.positions[3 * tip], s10.positions[3 * tip + 1], s10.positions[3 * tip + 2]);
  const Eigen::Vector3d ran = run_tip(10);
  const double lift = ran.z() - sc.probes[0].point_m.z();
  EXPECT_GT(lift, 5e-4);  // the beam bends up by half a millimetre and more
  EXPECT_LT((served - ran).cwiseAbs().maxCoeff(), 1e-6 * lift + 1e-8) << served.transpose() << " vs " << ran.transpose();
  const auto st = client.status(run, 5s);
  ASSERT_TRUE(st);
  EXPECT_EQ(st->frame, 10u);
  EXPECT_GT(st->solver_iterations, 0);  // Newton's iterations of the last step

  // A law constant by command, at rest: the run a scene with that constant gives.
  ASSERT_TRUE(client.send(run, "reset", "{}").accepted);
  const clients::Ack law = client.send(run, "set_material", R"({"C": 4000, "b_f": 6})");
  ASSERT_TRUE(law.accepted) << law.reason;
  const clients::Ack bad = client.send(run, "set_material", R"({"b_t": "stiff"})");
  EXPECT_FALSE(bad.accepted);
  EXPECT_NE(bad.reason.find("b_t"), std::string::npos) << bad.reason;
  ASSERT_TRUE(client.send(run, "step", R"({"count": 10})").accepted);
  const clients::State c10 = state_at(client, run, 10);
  const Eigen::Vector3d served_c(c10.positions[3 * tip], c10.positions[3 * tip + 1], c10.positions[3 * tip + 2]);
  EXPECT_GT(c10.parameter_version, s10.parameter_version);
  const Eigen::Vector3d ran_c = run_tip(10, {"regions[0].material.C=4000", "regions[0].material.b_f=6"});
  EXPECT_LT((served_c - ran_c).cwiseAbs().maxCoeff(), 1e-6 * lift + 1e-8) << served_c.transpose() << " vs " << ran_c.transpose();
  EXPECT_GT((served_c - served).norm(), 0.1 * lift);  // stiffer: clearly less bent
  ASSERT_TRUE(client.send(run, "shutdown", "{}").accepted);
  EXPECT_EQ(service.wait(30), 0) << service.output();
}

TEST_F(ServeAccurate, ArchivedRunResumesBitForBitReplaysAndExports) {
  const std::string whole = dir_.file("whole.h5"), tail = dir_.file("tail.h5");
  {  // 0.2 s recorded, a law command before the first step, checkpoints every 0.1 s
    const std::string run = unique("whole");
    BackgroundProcess service({FIBERFEM_BIN, "serve", scene_file(), "--run-id", run, "--fast", "--paused", "--until", "0.2", "--set",
                               "archive.path=" + whole, "--set", "archive.checkpoint_every=0.1"},
                              dir_.file("whole.log"));
    Client client;
    ASSERT_EQ(client.resolve_run(run, 20s), run) << service.output();
    ASSERT_TRUE(client.send(run, "set_material", R"({"C": 3000})").accepted);
    ASSERT_TRUE(client.send(run, "resume", "{}").accepted);
    ASSERT_EQ(service.wait(120), 0) << service.output();
  }
  {  // from the checkpoint at 0.1 s, with the parameters it had
    BackgroundProcess service({FIBERFEM_BIN, "serve", scene_file(), "--run-id", unique("tail"), "--fast", "--until", "0.2", "--resume",
                               whole + "@0.1", "--archive", tail},
                              dir_.file("tail.log"));
    ASSERT_EQ(service.wait(120), 0) << service.output();
    EXPECT_NE(service.output().find("resumed from"), std::string::npos) << service.output();
  }
  const archive::ArchiveReader a(whole), b(tail);
  const archive::ArchiveHeader& h = a.header();
  EXPECT_EQ(h.format_version, archive::kFormatVersionAccurate);
  EXPECT_EQ(h.tier, "accurate");
  ASSERT_EQ(h.order, 2);
  ASSERT_EQ(a.steps().back(), 20);
  ASSERT_EQ(b.steps().front(), 10);
  ASSERT_EQ(b.steps().back(), 20);
  // The last states equal to the bit: the frames (every node of the 10-node mesh) and the
  // final checkpoints (double precision, with the lagged factor).
  const archive::Frame fa = a.frame(a.frames() - 1), fb = b.frame(b.frames() - 1);
  ASSERT_EQ(fa.element_positions.cols(), h.element_rest_positions.cols());
  EXPECT_EQ((fa.element_positions - fb.element_positions).cwiseAbs().maxCoeff(), 0.0);
  const auto ca = std::get<core::hyperelastic::DynamicState>(a.read_engine_checkpoint(a.checkpoints().size() - 1));
  const auto cb = std::get<core::hyperelastic::DynamicState>(b.read_engine_checkpoint(b.checkpoints().size() - 1));
  EXPECT_EQ(ca.steps, 20);
  EXPECT_EQ((ca.x - cb.x).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((ca.v - cb.v).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((ca.p - cb.p).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(ca.linear.factored.nonZeros(), 0);
  EXPECT_GT((fa.positions - h.rest_positions).cwiseAbs().maxCoeff(), 5e-4);  // it moved
  // The 10-node elements in XDMF order: nodes 4..9 at the rest midpoints of edges
  // 01 12 02 03 13 23 (a straight-sided box mesh).
  const int edges[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}};
  for (const auto& t : h.element_tets)
    for (int k = 0; k < 6; ++k) {
      const core::Vec3 mid = 0.5 * (h.element_rest_positions.col(t[edges[k][0]]) + h.element_rest_positions.col(t[edges[k][1]]));
      ASSERT_LT((h.element_rest_positions.col(t[4 + k]) - mid).norm(), 1e-12) << "edge node " << 4 + k;
    }
  // The sidecar names the quadratic elements.
  EXPECT_NE(read_file(dir_.file("whole.xdmf")).find("Tetrahedron_10"), std::string::npos);

  // meshio reads the export as tetra10 with the archive's last positions.
  const std::string out = dir_.file("out.xdmf");
  const ProcessResult exp = run_process({FIBERFEM_BIN, "archive", "export-meshio", whole, out});
  ASSERT_EQ(exp.exit_code, 0) << exp.output;
  const std::string script = dir_.file("read.py");
  write_file(script, "import sys, meshio\n"
                     "with meshio.xdmf.TimeSeriesReader(sys.argv[1]) as r:\n"
                     "    pts, cells = r.read_points_cells()\n"
                     "    t, pd, cd = r.read_data(r.num_steps - 1)\n"
                     "    x = pd['positions']\n"
                     "    print(cells[0].type, cells[0].data.shape[0], pts.shape[0], r.num_steps, repr(float(x[-1, 2])))\n");
  const ProcessResult py = run_process({FIBERFEM_PYTHON, script, out});
  ASSERT_EQ(py.exit_code, 0) << py.output;
  std::istringstream words(py.output);
  std::string type;
  long cells = 0, points = 0, steps = 0;
  double last_z = 0;
  words >> type >> cells >> points >> steps >> last_z;
  EXPECT_EQ(type, "tetra10");
  EXPECT_EQ(cells, static_cast<long>(h.tets.size()));
  EXPECT_EQ(points, h.element_rest_positions.cols());
  EXPECT_EQ(steps, a.frames());
  EXPECT_EQ(last_z, static_cast<double>(static_cast<float>(fa.element_positions(2, fa.element_positions.cols() - 1))));

  // The replay publishes the corner mesh's frames as the archive has them.
  const std::string rrun = unique("replay");
  BackgroundProcess replay({FIBERFEM_BIN, "replay", whole, "--run-id", rrun, "--paused"}, dir_.file("replay.log"));
  Client client;
  ASSERT_EQ(client.resolve_run(rrun, 20s), rrun) << replay.output();
  const auto topo = client.topology(rrun, 10s);
  ASSERT_TRUE(topo);
  EXPECT_EQ(topo->num_nodes, static_cast<unsigned>(h.rest_positions.cols()));
  ASSERT_TRUE(client.send(rrun, "seek", R"({"frame": 20})").accepted);
  const clients::State last = state_at(client, rrun, 20);
  ASSERT_EQ(last.positions.size(), static_cast<size_t>(fa.positions.size()));
  for (Eigen::Index k = 0; k < fa.positions.size(); ++k)
    ASSERT_EQ(last.positions[static_cast<size_t>(k)], static_cast<float>(fa.positions.data()[k]));
  ASSERT_TRUE(client.send(rrun, "shutdown", "{}").accepted);
  EXPECT_EQ(replay.wait(20), 0) << replay.output();

#if defined(FIBERFEM_HAVE_RENDER)
  // A rendered frame of the accurate run: the bent beam, not the rest shape.
  for (const char* at : {"0", "0.2"})
    ASSERT_EQ(run_process({FIBERFEM_BIN, "render", whole, "--out", dir_.file(std::string("png") + at), "--at", at, "--width", "320",
                           "--height", "180", "--no-overlay", "--camera", "front"})
                  .exit_code,
              0);
  const render::Image rest = render::read_png(dir_.file("png0/frame-00000.png"));
  const render::Image bent = render::read_png(dir_.file("png0.2/frame-00000.png"));
  long changed = 0;
  for (size_t i = 0; i < rest.rgba.size(); i += 4)
    if (std::abs(int(rest.rgba[i]) - int(bent.rgba[i])) + std::abs(int(rest.rgba[i + 1]) - int(bent.rgba[i + 1])) > 48) ++changed;
  EXPECT_GT(static_cast<double>(changed) / (rest.rgba.size() / 4.0), 0.01);
#endif
}

}  // namespace
}  // namespace fiberfem::testing
