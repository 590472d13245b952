#include "service/run_endpoints.hpp"

#include "idl/command_sample.hpp"

#include <unistd.h>

#include <chrono>
#include <cstring>
#include <thread>

namespace fiberfem::service {
namespace {

std::string hostname() {
  char host[256] = "host";
  gethostname(host, sizeof host - 1);
  return host;
}

}  // namespace

std::string default_run_id(const std::string& scene) { return scene + "-" + hostname() + "-" + std::to_string(getpid()); }

RunEndpoints::RunEndpoints(std::string run_id)
    : run_id_(std::move(run_id)), host_(hostname()), pp_(), topology_(pp_), state_(pp_), status_(pp_), ack_(pp_), commands_(pp_) {}

RunEndpoints::~RunEndpoints() {
  // While the last command's sender is there (its command writer still matched) and no
  // ack reader of its participant is matched yet.
  const auto end = std::chrono::steady_clock::now() + kLastAnswerWait;
  while (last_sender_writer_ != 0 && std::chrono::steady_clock::now() < end) {
    dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(commands_.get(), last_sender_writer_);
    if (ep == nullptr) break;  // the sender has gone
    const dds_guid_t participant = ep->participant_key;
    dds_builtintopic_free_endpoint(ep);
    if (ack_reader_matched(participant)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  dds_wait_for_acks(ack_.get(), DDS_SECS(1));
}

bool RunEndpoints::ack_reader_matched(const dds_guid_t& participant) const {
  dds_instance_handle_t handles[256];
  const dds_return_t n = dds_get_matched_subscriptions(ack_.get(), handles, 256);
  for (dds_return_t i = 0; i < n && i < 256; ++i) {
    dds_builtintopic_endpoint_t* ep = dds_get_matched_subscription_data(ack_.get(), handles[i]);
    if (!ep) continue;
    const bool same = std::memcmp(ep->participant_key.v, participant.v, sizeof participant.v) == 0;
    dds_builtintopic_free_endpoint(ep);
    if (same) return true;
  }
  return false;
}

void RunEndpoints::publish_topology(const TopologyData& t) {
  TopologyData mine = t;
  mine.run_id = run_id_;
  dds::with_sample(mine, [&](const fiberfem_MeshTopology& m) { topology_.write(m); });
}

void RunEndpoints::publish_state(unsigned long frame, double time_s, unsigned parameter_version, std::vector<float>& positions,
                                 std::vector<float>& activation) {
  fiberfem_MeshState s{};
  s.run_id = run_id_.data();
  s.frame = frame;
  s.time_s = time_s;
  s.parameter_version = parameter_version;
  s.positions = dds::borrow<dds_sequence_float>(positions);
  s.activation = dds::borrow<dds_sequence_float>(activation);
  state_.write(s);
}

void RunEndpoints::publish_state(unsigned long frame, double time_s, unsigned parameter_version,
                                 const Eigen::Ref<const core::Positions>& x, const std::vector<int>& nodes,
                                 const std::vector<double>& activation) {
  if (nodes.empty()) {
    positions_.resize(static_cast<size_t>(x.size()));
    for (Eigen::Index i = 0; i < x.cols(); ++i)
      for (int d = 0; d < 3; ++d) positions_[3 * static_cast<size_t>(i) + d] = static_cast<float>(x(d, i));
  } else {
    positions_.resize(3 * nodes.size());
    for (size_t k = 0; k < nodes.size(); ++k)
      for (int d = 0; d < 3; ++d) positions_[3 * k + d] = static_cast<float>(x(d, nodes[k]));
  }
  activation_.assign(activation.begin(), activation.end());
  publish_state(frame, time_s, parameter_version, positions_, activation_);
}

void RunEndpoints::publish_status(const StatusData& d) {
  StatusData mine = d;
  mine.run_id = run_id_;
  mine.host = host_;
  mine.pid = getpid();
  dds::with_sample(mine, [&](const fiberfem_ServiceStatus& m) { status_.write(m); });
}

std::string RunEndpoints::enable_circulation() {
  if (circulation_ || !circulation_refused_.empty()) return circulation_refused_;
  try {
    circulation_.emplace(pp_);
  } catch (const dds::DdsError& e) {
    if (e.code() != DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) throw;
    circulation_refused_ = std::string("the circulation is not published: ") + e.what() +
                           " (permissions made before the topic fiberfem_circulation existed: remake them with scripts/make_security.sh)";
  }
  return circulation_refused_;
}

void RunEndpoints::publish_circulation(unsigned long frame, const core::circulation::Snapshot& s) {
  enable_circulation();  // a run whose engine gained a circulation after the start
  if (!circulation_) return;
  dds::with_sample(dds::Circulation{run_id_, frame, s}, [&](const fiberfem_CirculationState& m) { circulation_->write(m); });
}

void RunEndpoints::write_ack(const std::string& command_id, const std::string& client_id, const Answer& a) {
  std::string cid = command_id, client = client_id, reason = a.reason;
  fiberfem_CommandAck ack{};
  ack.run_id = run_id_.data();
  ack.command_id = cid.data();
  ack.client_id = client.data();
  ack.accepted = a.accepted;
  ack.reason = reason.data();
  ack.frame = a.frame;
  ack.parameter_version = a.parameter_version;
  ack_.write(ack);
}

int RunEndpoints::handle_commands(const std::function<CommandReply(const std::string&, const std::string&, const std::string&)>& apply,
                                  const std::function<std::pair<unsigned long, unsigned>()>& stamp,
                                  std::chrono::nanoseconds budget) {
  int n = 0;
  const auto t0 = std::chrono::steady_clock::now();
  auto handle = [&](const fiberfem_Command& c, const dds_sample_info_t& info) {
    if (dds::str(c.run_id) != run_id_) return;  // another run's
    const std::string id = dds::str(c.command_id);
    ++n;
    last_sender_writer_ = info.publication_handle;  // its participant is looked up at exit
    // Exactly once: a command id seen before (a client's resend) gets its first answer again.
    if (const auto seen = answered_.find(id); seen != answered_.end()) {
      ++duplicates_;
      write_ack(id, dds::str(c.client_id), seen->second);
      return;
    }
    // A malformed sample is refused here, unseen by the run (and so not recorded).
    CommandReply r;
    try {
      const dds::DecodedCommand d = dds::decode_command(c);
      r = apply(d.kind, d.args, d.command_id);
    } catch (const dds::CommandSampleError& e) {
      r = {false, e.what()};
    }
    const auto [frame, version] = stamp();
    const Answer a{r.accepted, r.reason, frame, version};
    answered_[id] = a;
    answered_order_.push_back(id);
    if (answered_order_.size() > kRememberedCommands) {
      answered_.erase(answered_order_.front());
      answered_order_.pop_front();
    }
    write_ack(id, dds::str(c.client_id), a);
  };
  // One at a time, so that the budget is checked between commands.
  while (commands_.take(handle, false, 1) > 0 && std::chrono::steady_clock::now() - t0 < budget) {
  }
  return n;
}

}  // namespace fiberfem::service
