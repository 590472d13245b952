// Steering the closed-loop circulation of a served run (`set_circulation`, docs/circulation.md)
// with real processes on loopback: the real `fiberfem serve`, the C++ client and the real
// `fiberfem ctl`. A bad value is refused with its key named; an accepted one changes the run
// from the step boundary it arrives at (before it the run is the unsteered `fiberfem run`'s
// to the bit, after it the aortic pressure is higher), and `fiberfem run --resume` from a
// checkpoint after it continues with the steered values, bit for bit.
#include "clients/ctl/client.hpp"
#include "process_support.hpp"
#include "service/archive/archive.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>

#include <unistd.h>

namespace fiberfem::testing {
namespace {

using namespace std::chrono_literals;
using clients::Client;
namespace cc = core::circulation;

const std::string kScene = std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart-circulation-realtime.yaml";

class ServeCirculation : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { setenv("CYCLONEDDS_URI", FIBERFEM_DDS_URI, 1); }
  static std::string unique(const std::string& name) { return name + "-" + std::to_string(getpid()); }
  clients::State state_at(Client& client, const std::string& run, unsigned long frame) {
    std::optional<clients::State> s;
    for (int i = 0; i < 400 && (!s || s->frame < frame); ++i) s = client.next_state(run, 5s, s ? static_cast<long>(s->frame) : -1);
    EXPECT_TRUE(s && s->frame == frame) << "no state at frame " << frame;
    return s ? *s : clients::State{};
  }
  TempDir dir_;
};

TEST_F(ServeCirculation, SteeredResistanceActsAtTheStepBoundaryAndResumesFromTheArchive) {
  const std::string served = dir_.file("served.h5"), resumed = dir_.file("resumed.h5"), plain = dir_.file("plain.h5");
  {  // 45 steps (0.75 s); after step 15 the systemic resistance tripled and the heart rate 72 -> 90
    const std::string run = unique("circulation");
    // One engine thread: on a loaded machine an idle core is not to be counted on.
    BackgroundProcess service({FIBERFEM_BIN, "serve", kScene, "--run-id", run, "--fast", "--paused", "--threads", "1", "--until", "0.75", "--set",
                               "archive.path=" + served, "--set", "archive.checkpoint_every=0.25"},
                              dir_.file("serve.log"));
    Client client;
    ASSERT_EQ(client.resolve_run(run, 20s), run) << service.output();
    const ProcessResult bad = run_process({FIBERFEM_BIN, "ctl", "--run", run, "send", "set_circulation",
                                           R"({"systemic": {"arteries": {"compliance": -1.2}}})"});
    EXPECT_EQ(bad.exit_code, 3) << bad.output;
    EXPECT_NE(bad.output.find("'systemic.arteries.compliance'"), std::string::npos) << bad.output;
    ASSERT_TRUE(client.send(run, "step", R"({"count": 15})").accepted);
    state_at(client, run, 15);
    // With a new heart rate: the checkpoints must carry where the loop counts its beats from.
    const clients::Ack ok = client.send(run, "set_circulation", R"({"heart_rate": 90, "systemic": {"arteries": {"resistance": 2.4}}})");
    ASSERT_TRUE(ok.accepted) << ok.reason;
    EXPECT_EQ(ok.frame, 15u);
    ASSERT_TRUE(client.send(run, "resume", "{}").accepted);
    ASSERT_EQ(service.wait(120), 0) << service.output();
  }
  ProcessResult r = run_process(
      {FIBERFEM_BIN, "run", "--resume", served + "@0.55", "--archive", resumed, "--steps", "45", "--set", "solver.threads=1"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_process({FIBERFEM_BIN, "run", kScene, "--steps", "45", "--archive", plain, "--checkpoint-every", "0.25", "--set",
                   "solver.threads=1"});
  ASSERT_EQ(r.exit_code, 0) << r.output;

  const archive::ArchiveReader a(served), b(resumed), c(plain);
  ASSERT_EQ(a.steps().back(), 45);
  ASSERT_EQ(b.steps().front(), 30);
  // Up to the command the served run is the unsteered run; after it, not.
  EXPECT_TRUE(a.frame(15).positions == c.frame(15).positions);
  EXPECT_FALSE(a.frame(45).positions == c.frame(45).positions);
  // The resumed run continues the steered one to the bit.
  for (long i = 0; i < b.frames(); ++i) {
    const archive::Frame fb = b.frame(i), fa = a.frame(fb.step);
    EXPECT_TRUE(fb.positions == fa.positions) << "step " << fb.step;
  }
  const core::SimulatorCheckpoint ca = a.read_checkpoint(a.checkpoints().size() - 1);
  const core::SimulatorCheckpoint cb = b.read_checkpoint(b.checkpoints().size() - 1);
  const core::SimulatorCheckpoint cc_ = c.read_checkpoint(c.checkpoints().size() - 1);
  ASSERT_EQ(ca.step_count, 45);
  ASSERT_EQ(cb.step_count, 45);
  ASSERT_EQ(cc_.step_count, 45);
  EXPECT_TRUE(ca.circulation.pressure_pa == cb.circulation.pressure_pa);
  EXPECT_EQ(ca.circulation.previous_period_s, 60.0 / 72);  // changed in the first beat: the one before lasted 72/min's
  EXPECT_EQ(cb.circulation.previous_period_s, ca.circulation.previous_period_s);
  // A higher resistance holds the aortic pressure up.
  EXPECT_GT(ca.circulation.pressure_pa[cc::ar_sys], 1.05 * cc_.circulation.pressure_pa[cc::ar_sys])
      << ca.circulation.pressure_pa[cc::ar_sys] << " vs " << cc_.circulation.pressure_pa[cc::ar_sys];
}

}  // namespace
}  // namespace fiberfem::testing
