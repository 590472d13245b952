#include "clients/ctl/client.hpp"

#include <atomic>
#include <cstring>
#include <cstdio>
#include <stdexcept>
#include <thread>
#include <unistd.h>

namespace fiberfem::clients {
namespace {

using Clock = std::chrono::steady_clock;

template <class Seq, class V>
std::vector<V> copy(const Seq& s) {
  return std::vector<V>(s._buffer, s._buffer + s._length);
}

RunStatus to_status(const fiberfem_ServiceStatus& s) {
  RunStatus r;
  r.run_id = dds::str(s.run_id);
  r.scene_name = dds::str(s.scene_name);
  r.host = dds::str(s.host);
  r.state = dds::str(s.state);
  r.mode = dds::str(s.mode);
  r.last_message = dds::str(s.last_message);
  r.recording = dds::str(s.recording);
  r.pid = s.pid;
  r.replay = s.replay;
  r.frame = s.frame;
  r.time_s = s.time_s;
  r.frames_per_second = s.frames_per_second;
  r.real_time_factor = s.real_time_factor;
  r.step_ms = s.step_ms;
  r.solve_ms = s.solve_ms;
  r.publish_ms = s.publish_ms;
  r.solver_iterations = s.solver_iterations;
  r.inverted_elements = s.inverted_elements;
  r.solver_residual = s.solver_residual;
  r.kinetic_energy_j = s.kinetic_energy_j;
  r.elastic_energy_j = s.elastic_energy_j;
  r.recovered_steps = s.recovered_steps;
  r.failed_steps = s.failed_steps;
  r.parameter_version = s.parameter_version;
  r.heart_rate_bpm = s.heart_rate_bpm;
  r.peak_tension_pa = s.peak_tension_pa;
  r.dt_s = s.dt_s;
  r.recorded_frames = s.recorded_frames;
  return r;
}

std::chrono::nanoseconds left(Clock::time_point deadline) {
  return std::max(std::chrono::nanoseconds(0), std::chrono::duration_cast<std::chrono::nanoseconds>(deadline - Clock::now()));
}

}  // namespace

// Unique per Client object (acks are transient-local: a client must not take another's
// answer for its own): pid, a counter, and the clock.
std::string unique_client_id() {
  static std::atomic<int> counter{0};
  char buf[96];
  std::snprintf(buf, sizeof buf, "ctl-%d-%d-%llx", static_cast<int>(getpid()), ++counter,
                static_cast<unsigned long long>(std::chrono::system_clock::now().time_since_epoch().count() & 0xffffff));
  return buf;
}

Client::Client(std::string client_id)
    : client_id_(client_id.empty() ? unique_client_id() : std::move(client_id)), status_reader_(pp_) {
  // Made up front so discovery of the command path runs while the client looks for runs.
  // In secure mode an observer's identity is refused both: it can still watch.
  try {
    command_writer_.emplace(pp_);
    ack_reader_.emplace(pp_);
  } catch (const dds::DdsError& e) {
    if (e.code() != DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) throw;
    command_writer_.reset();
    commands_refused_ = e.what();
  }
}

void Client::poll_status() {
  status_reader_.take([&](const fiberfem_ServiceStatus& s, const dds_sample_info_t& info) {
    const std::string id = dds::str(s.run_id);
    runs_[id] = to_status(s);
    if (!participants_.count(id))
      if (dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(status_reader_.get(), info.publication_handle)) {
        participants_[id] = ep->participant_key;
        dds_builtintopic_free_endpoint(ep);
      }
  });
}

bool Client::command_reader_matched(const std::string& run_id) const {
  const auto p = participants_.find(run_id);
  if (!command_writer_) return false;
  dds_instance_handle_t handles[256];
  const dds_return_t n = dds_get_matched_subscriptions(command_writer_->get(), handles, 256);
  for (dds_return_t i = 0; i < n && i < 256; ++i) {
    if (p == participants_.end()) return true;  // the run's participant unknown: any reader will do
    dds_builtintopic_endpoint_t* ep = dds_get_matched_subscription_data(command_writer_->get(), handles[i]);
    if (!ep) continue;
    const bool same = std::memcmp(ep->participant_key.v, p->second.v, sizeof p->second.v) == 0;
    dds_builtintopic_free_endpoint(ep);
    if (same) return true;
  }
  return false;
}

std::map<std::string, RunStatus> Client::discover(std::chrono::milliseconds wait) {
  const auto deadline = Clock::now() + wait;
  runs_.clear();
  while (Clock::now() < deadline) {
    status_reader_.wait(left(deadline));
    poll_status();
  }
  return runs_;
}

std::string Client::resolve_run(const std::string& run_id, std::chrono::milliseconds wait) {
  const auto deadline = Clock::now() + wait;
  for (;;) {
    poll_status();
    if (!run_id.empty() && runs_.count(run_id)) return run_id;
    if (run_id.empty() && runs_.size() == 1) {
      // Give other runs a moment to show up before calling this one the only one.
      if (Clock::now() + std::chrono::milliseconds(600) < deadline || Clock::now() >= deadline) {
        std::this_thread::sleep_for(std::chrono::milliseconds(600));
        poll_status();
        if (runs_.size() == 1) return runs_.begin()->first;
      }
    }
    if (Clock::now() >= deadline) break;
    status_reader_.wait(std::min(left(deadline), std::chrono::nanoseconds(std::chrono::milliseconds(100))));
  }
  if (!run_id.empty()) throw std::runtime_error("no run '" + run_id + "' seen on the domain (is the service running, with the same CYCLONEDDS_URI?)");
  if (runs_.empty()) throw std::runtime_error("no fiberfem service seen on the domain (is one running, with the same CYCLONEDDS_URI?)");
  std::string ids;
  for (const auto& kv : runs_) ids += " " + kv.first;
  throw std::runtime_error("several runs on the domain, choose one with --run:" + ids);
}

std::optional<RunStatus> Client::status(const std::string& run_id, std::chrono::milliseconds wait) {
  const auto deadline = Clock::now() + wait;
  const unsigned long seen_frame = runs_.count(run_id) ? runs_[run_id].frame : 0;
  bool fresh = false;
  do {
    status_reader_.take([&](const fiberfem_ServiceStatus& s, const dds_sample_info_t&) {
      runs_[dds::str(s.run_id)] = to_status(s);
      if (dds::str(s.run_id) == run_id) fresh = true;
    });
    if (fresh) return runs_[run_id];
  } while (status_reader_.wait(left(deadline)) || Clock::now() < deadline);
  (void)seen_frame;
  return std::nullopt;
}

std::optional<Topology> Client::topology(const std::string& run_id, std::chrono::milliseconds wait) {
  if (!topology_reader_) topology_reader_.emplace(pp_);
  const auto deadline = Clock::now() + wait;
  std::optional<Topology> out;
  do {
    topology_reader_->take([&](const fiberfem_MeshTopology& t, const dds_sample_info_t&) {
      if (dds::str(t.run_id) != run_id) return;
      Topology r;
      r.run_id = run_id;
      r.scene_name = dds::str(t.scene_name);
      r.scene_hash = dds::str(t.scene_hash);
      r.replay = t.replay;
      r.num_nodes = t.num_nodes;
      r.num_elements = t.num_elements;
      r.rest_positions = copy<dds_sequence_float, float>(t.rest_positions);
      r.fibers = copy<dds_sequence_float, float>(t.fibers);
      r.tets = copy<dds_sequence_int32, int>(t.tets);
      r.triangles = copy<dds_sequence_int32, int>(t.triangles);
      r.triangle_elements = copy<dds_sequence_int32, int>(t.triangle_elements);
      r.state_nodes = copy<dds_sequence_int32, int>(t.state_nodes);
      r.fixed_nodes = copy<dds_sequence_int32, int>(t.fixed_nodes);
      r.element_regions = copy<dds_sequence_int16, int>(t.element_regions);
      for (uint32_t i = 0; i < t.region_names._length; ++i) r.region_names.push_back(dds::str(t.region_names._buffer[i]));
      out = std::move(r);
    });
    if (out) return out;
  } while (topology_reader_->wait(left(deadline)) || Clock::now() < deadline);
  return std::nullopt;
}

std::optional<State> Client::next_state(const std::string& run_id, std::chrono::milliseconds wait, long after_frame) {
  if (!state_reader_) state_reader_.emplace(pp_);
  const auto deadline = Clock::now() + wait;
  std::optional<State> out;
  do {
    state_reader_->take([&](const fiberfem_MeshState& s, const dds_sample_info_t& info) {
      if (dds::str(s.run_id) != run_id || static_cast<long>(s.frame) <= after_frame) return;
      State r;
      r.run_id = run_id;
      r.frame = s.frame;
      r.time_s = s.time_s;
      r.parameter_version = s.parameter_version;
      r.source_time_s = static_cast<double>(info.source_timestamp) * 1e-9;
      r.positions = copy<dds_sequence_float, float>(s.positions);
      r.activation = copy<dds_sequence_float, float>(s.activation);
      out = std::move(r);  // the newest wins
    });
    if (out) return out;
  } while (state_reader_->wait(left(deadline)) || Clock::now() < deadline);
  return std::nullopt;
}

Ack Client::send(const std::string& run_id, const std::string& kind, const std::string& args_json,
                 std::chrono::milliseconds wait) {
  if (!command_writer_ || !ack_reader_)
    throw NotPermitted("not permitted to send commands (observer identity: commands need the operator role, "
                       "docs/security.md): " + commands_refused_);
  const auto deadline = Clock::now() + wait;
  // Commands are volatile: write only once the command reader of the run's own participant
  // (known from its status) is matched.
  poll_status();
  if (!participants_.count(run_id)) resolve_run(run_id, std::chrono::duration_cast<std::chrono::milliseconds>(left(deadline)));
  while (!command_reader_matched(run_id) && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  if (!command_reader_matched(run_id))
    throw std::runtime_error("the command reader of run '" + run_id + "' was not matched within the timeout (is it running?)");
  std::string id = client_id_ + "-" + std::to_string(++next_command_);
  std::string rid = run_id, cid = client_id_, k = kind, args = args_json.empty() ? "{}" : args_json;
  fiberfem_Command c{};
  c.run_id = rid.data();
  c.command_id = id.data();
  c.client_id = cid.data();
  c.kind = k.data();
  c.args = args.data();
  command_writer_->write(c);
  std::optional<Ack> ack;
  do {
    ack_reader_->take([&](const fiberfem_CommandAck& a, const dds_sample_info_t&) {
      if (dds::str(a.run_id) != run_id || dds::str(a.command_id) != id) return;
      ack = Ack{a.accepted, dds::str(a.reason), a.frame, a.parameter_version};
    });
    if (ack) return *ack;
  } while (ack_reader_->wait(left(deadline)) || Clock::now() < deadline);
  throw std::runtime_error("no acknowledgement of '" + kind + "' (command " + id + ") from run '" + run_id + "' within the timeout");
}

}  // namespace fiberfem::clients
