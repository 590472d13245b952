// Secure mode (docs/security.md) with real processes on loopback: scripts/make_security.sh
// makes the CAs, identities, signed documents and profiles into a temporary directory;
// the real `fiberfem serve` runs with the service identity, the real `fiberfem ctl` with
// the observer, operator and rogue identities, and this test process is a participant
// without security (configs/dds/loopback.xml). Debian's DDS Security plugins do the work.

#include "clients/ctl/client.hpp"
#include "process_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <regex>
#include <thread>

namespace fiberfem::testing {
namespace {

using namespace std::chrono_literals;

const std::string kScript = std::string(FIBERFEM_SOURCE_DIR) + "/scripts/make_security.sh";

class SecureMode : public ::testing::Test {
 protected:
  // This process: the plain loopback profile, no security.
  static void SetUpTestSuite() { setenv("CYCLONEDDS_URI", FIBERFEM_DDS_URI, 1); }

  void SetUp() override {
    const ProcessResult made = run_process({kScript, dir_.file("sec"), "--rogue"});
    ASSERT_EQ(made.exit_code, 0) << made.output;
    service_ = std::make_unique<BackgroundProcess>(
        std::vector<std::string>{FIBERFEM_BIN, "serve", "--builtin", "cantilever", "--run-id", run_, "--status-hz", "10"},
        dir_.file("service.log"), std::vector<std::string>{"CYCLONEDDS_URI=" + uri("service")});
    // Up once an observer sees its status.
    const ProcessResult up = ctl("observer", {"--timeout", "20", "status", "--count", "1"});
    ASSERT_EQ(up.exit_code, 0) << up.output << "\nservice:\n" << service_->output();
  }

  std::string uri(const std::string& identity) const { return "file://" + dir_.file("sec/profiles/" + identity + ".xml"); }

  // `fiberfem ctl --run RUN ARGS...` with `identity`'s profile.
  ProcessResult ctl(const std::string& identity, const std::vector<std::string>& args) const {
    std::vector<std::string> cmd = {"env", "CYCLONEDDS_URI=" + uri(identity), "timeout", "40", FIBERFEM_BIN, "ctl", "--run", run_};
    cmd.insert(cmd.end(), args.begin(), args.end());
    return run_process(cmd);
  }

  // The parameter version and state of the run, as the observer reads its status.
  std::pair<int, std::string> observed_status() const {
    const ProcessResult st = ctl("observer", {"status", "--table", "--count", "1"});
    std::smatch v, s;
    if (st.exit_code != 0 || !std::regex_search(st.output, v, std::regex("parameter version (\\d+)")) ||
        !std::regex_search(st.output, s, std::regex(", (running|paused|starting|stopped|failed|recovered), ")))
      return {-1, st.output};
    return {std::stoi(v[1]), s[1]};
  }

  TempDir dir_;
  const std::string run_ = "secure-" + std::to_string(getpid());
  std::unique_ptr<BackgroundProcess> service_;
};

// (1) Without security a participant gets nothing from the secure service (no status, no
// state, and its commands find no reader), while an authenticated observer receives states.
TEST_F(SecureMode, PlainParticipantSeesNoDataWhileAnAuthenticatedObserverDoes) {
  BackgroundProcess observer({"/usr/bin/env", "CYCLONEDDS_URI=" + uri("observer"), FIBERFEM_BIN, "ctl", "--run", run_, "echo", "--count", "60"},
                             dir_.file("observer.log"));
  clients::Client plain("plain-client");
  EXPECT_FALSE(plain.next_state(run_, 5s)) << "a participant without security received a state of the secure run";
  EXPECT_EQ(plain.discover(1s).count(run_), 0u);
  EXPECT_THROW(plain.send(run_, "pause", "{}", 2s), std::runtime_error);
  EXPECT_EQ(observer.wait(20), 0) << observer.output();
  const std::string frames = observer.output();
  size_t n = 0;
  for (size_t p = frames.find("frame "); p != std::string::npos; p = frames.find("frame ", p + 1)) ++n;
  EXPECT_EQ(n, 60u) << frames;
  EXPECT_TRUE(service_->running()) << service_->output();
}

// (2) An identity signed by another CA (with the observer's name and the real, signed
// permissions) fails the handshake: it sees no run, and the service logs why.
TEST_F(SecureMode, IdentityFromAnotherAuthorityFailsToAuthenticate) {
  const ProcessResult rogue = ctl("rogue", {"--timeout", "6", "echo", "--count", "1"});
  EXPECT_EQ(rogue.exit_code, 4) << rogue.output;
  EXPECT_NE(rogue.output.find("no run '" + run_ + "' seen"), std::string::npos) << rogue.output;
  EXPECT_EQ(rogue.output.find("frame "), std::string::npos) << rogue.output;
  EXPECT_EQ(rogue.output.find("dds_create_participant"), std::string::npos) << "the rogue profile itself is broken:\n" << rogue.output;
  // Cyclone's own words in the service's log: the certificate does not chain to its CA.
  const std::string log = service_->output();
  EXPECT_NE(log.find("handshake"), std::string::npos) << log;
  EXPECT_NE(log.find("Certificate not valid"), std::string::npos) << log;
  // The genuine observer still gets in.
  EXPECT_EQ(ctl("observer", {"echo", "--count", "1"}).exit_code, 0);
}

// (3) An observer's command writer is refused by access control: a clear error and exit 5,
// and the service's state is unchanged (running, parameter version 0).
TEST_F(SecureMode, ObserverIsRefusedACommandWriterAndTheRunIsUnchanged) {
  const ProcessResult refused = ctl("observer", {"send", "pause"});
  EXPECT_EQ(refused.exit_code, 5) << refused.output;
  EXPECT_NE(refused.output.find("not permitted to send commands (observer identity"), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find("refused by DDS Security access control"), std::string::npos) << refused.output;
  const ProcessResult play_refused = ctl("observer", {"send", "set_gravity", R"({"gravity": [0, 0, 5]})"});
  EXPECT_EQ(play_refused.exit_code, 5) << play_refused.output;
  std::this_thread::sleep_for(500ms);
  const auto [version, state] = observed_status();
  EXPECT_EQ(version, 0) << state;
  EXPECT_EQ(state, "running");
  EXPECT_TRUE(service_->running()) << service_->output();
}

// (4) An operator steers: its pause is applied (acknowledged, the observer sees the run
// paused at parameter version 1 and its frames stop), then it shuts the service down.
TEST_F(SecureMode, OperatorSteersTheRun) {
  const ProcessResult pause = ctl("operator", {"send", "pause"});
  ASSERT_EQ(pause.exit_code, 0) << pause.output << "\nservice:\n" << service_->output();
  EXPECT_NE(pause.output.find("pause accepted"), std::string::npos) << pause.output;
  EXPECT_NE(pause.output.find("parameter version 1"), std::string::npos) << pause.output;
  const auto [version, state] = observed_status();
  EXPECT_EQ(version, 1) << state;
  EXPECT_EQ(state, "paused");
  const ProcessResult a = ctl("observer", {"echo", "--count", "1"});
  std::this_thread::sleep_for(1200ms);
  const ProcessResult b = ctl("observer", {"echo", "--count", "1"});
  std::smatch fa, fb;
  ASSERT_TRUE(std::regex_search(a.output, fa, std::regex("frame (\\d+) .* v1:"))) << a.output;
  ASSERT_TRUE(std::regex_search(b.output, fb, std::regex("frame (\\d+) .* v1:"))) << b.output;
  EXPECT_EQ(fa[1], fb[1]) << "frames went on while paused";
  const ProcessResult down = ctl("operator", {"send", "shutdown"});
  EXPECT_EQ(down.exit_code, 0) << down.output;
  EXPECT_EQ(service_->wait(20), 0) << service_->output();
}

// The script: idempotent (a second call keeps the CAs and keys), more identities by role,
// arguments checked, and documents that openssl verifies against the permissions CA.
TEST(MakeSecurity, IdempotentChecksItsArgumentsAndSignsVerifiably) {
  TempDir dir;
  const std::string out = dir.file("sec");
  ASSERT_EQ(run_process({kScript, out}).exit_code, 0);
  const std::string ca = read_file(out + "/ca/identity_ca.pem"), key = read_file(out + "/identities/operator/key.pem");
  const ProcessResult more = run_process({kScript, out, "--client", "alice", "--role", "operator"});
  ASSERT_EQ(more.exit_code, 0) << more.output;
  EXPECT_EQ(read_file(out + "/ca/identity_ca.pem"), ca);
  EXPECT_EQ(read_file(out + "/identities/operator/key.pem"), key);
  EXPECT_NE(read_file(out + "/permissions.xml").find("<subject_name>CN=alice,O=fiberfem,C=NL</subject_name>"), std::string::npos);
  EXPECT_NE(read_file(out + "/profiles/alice.xml").find("/identities/alice/cert.pem"), std::string::npos);
  for (const std::string doc : {"governance", "permissions"}) {
    const ProcessResult v = run_process({"openssl", "smime", "-verify", "-text", "-in", out + "/" + doc + ".p7s", "-CAfile",
                                         out + "/ca/permissions_ca.pem", "-out", dir.file(doc + ".out")});
    EXPECT_EQ(v.exit_code, 0) << doc << ": " << v.output;
    std::string signed_text = read_file(dir.file(doc + ".out"));  // S/MIME text is canonical CRLF
    signed_text.erase(std::remove(signed_text.begin(), signed_text.end(), '\r'), signed_text.end());
    EXPECT_EQ(signed_text, read_file(out + "/" + doc + ".xml")) << doc;
  }
  const ProcessResult cert = run_process({"openssl", "verify", "-CAfile", out + "/ca/identity_ca.pem", out + "/identities/alice/cert.pem"});
  EXPECT_EQ(cert.exit_code, 0) << cert.output;
  const ProcessResult bad_role = run_process({kScript, out, "--client", "bob", "--role", "admin"});
  EXPECT_NE(bad_role.exit_code, 0);
  EXPECT_NE(bad_role.output.find("role 'admin'"), std::string::npos) << bad_role.output;
  const ProcessResult bad_name = run_process({kScript, out, "--client", "bob smith", "--role", "observer"});
  EXPECT_NE(bad_name.exit_code, 0);
  EXPECT_NE(bad_name.output.find("client name 'bob smith'"), std::string::npos) << bad_name.output;
}

}  // namespace
}  // namespace fiberfem::testing
