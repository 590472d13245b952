#include "clients/ctl/client.hpp"

#include <algorithm>
#include <atomic>
#include <set>
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
  // In secure mode an observer's identity is refused it: it can still watch.
  try {
    command_writer_.emplace(pp_);
  } catch (const dds::DdsError& e) {
    if (e.code() != DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) throw;
    commands_refused_ = e.what();
  }
}

std::vector<std::string> Client::poll_status() {
  std::vector<std::string> fresh;
  status_reader_.take(
      [&](const fiberfem_ServiceStatus& s, const dds_sample_info_t& info) {
        const std::string id = dds::str(s.run_id);
        if (!info.valid_data) {  // the key only: the instance lost its writers or was disposed
          if (info.instance_state == DDS_NOT_ALIVE_DISPOSED_INSTANCE_STATE) gone_[id] = "its status was disposed (by the service, or by DDS when its writer's lease expired)";
          else if (info.instance_state == DDS_NOT_ALIVE_NO_WRITERS_INSTANCE_STATE) gone_[id] = "its status writer is gone (liveliness lost)";
          return;
        }
        runs_[id] = dds::to_record(s);
        seen_[id] = Clock::now();
        fresh.push_back(id);
        if (runs_[id].state == "stopped") gone_[id] = "it stopped";
        else gone_.erase(id);
        // The newest writer's participant: a restarted service under the same run id is another.
        if (dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(status_reader_.get(), info.publication_handle)) {
          participants_[id] = ep->participant_key;
          dds_builtintopic_free_endpoint(ep);
        }
      },
      /*with_invalid=*/true);
  return fresh;
}

bool Client::live(const std::string& run_id, std::chrono::milliseconds lost_after, std::string* why) {
  poll_status();
  if (const auto g = gone_.find(run_id); g != gone_.end()) {
    if (why) *why = g->second;
    return false;
  }
  const auto t = seen_.find(run_id);
  if (t == seen_.end()) {
    if (why) *why = "no status seen";
    return false;
  }
  const double age_s = std::chrono::duration<double>(Clock::now() - t->second).count();
  if (age_s * 1e3 > static_cast<double>(lost_after.count())) {
    if (why) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "no status for %.1f s", age_s);
      *why = buf;
    }
    return false;
  }
  return true;
}

std::map<std::string, RunStatus> Client::live_runs(std::chrono::milliseconds lost_after) {
  poll_status();
  std::map<std::string, RunStatus> out;
  for (const auto& [id, s] : runs_)
    if (live(id, lost_after)) out[id] = s;
  return out;
}

void Client::drop_states(const std::string& run_id) {
  if (state_reader_) state_reader_->take([&](const fiberfem_MeshState&, const dds_sample_info_t&) {});
  (void)run_id;  // the reader is shared by every run this client reads; each takes the newest anew
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
  do {
    const std::vector<std::string> fresh = poll_status();
    if (std::find(fresh.begin(), fresh.end(), run_id) != fresh.end()) return runs_[run_id];
  } while (status_reader_.wait(left(deadline)) || Clock::now() < deadline);
  return std::nullopt;
}

std::optional<Topology> Client::topology(const std::string& run_id, std::chrono::milliseconds wait) {
  if (!topology_reader_) topology_reader_.emplace(pp_);
  const auto deadline = Clock::now() + wait;
  std::optional<Topology> out;
  do {
    topology_reader_->take([&](const fiberfem_MeshTopology& t, const dds_sample_info_t&) {
      if (dds::str(t.run_id) != run_id) return;
      Topology r = dds::to_record(t);
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

bool Client::listen_circulation() {
  if (circulation_reader_ || !circulation_refused_.empty()) return circulation_reader_.has_value();
  try {
    circulation_reader_.emplace(pp_);
  } catch (const dds::DdsError& e) {
    if (e.code() != DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) throw;
    circulation_refused_ = std::string("this identity may not read the circulation (its permissions do not grant ") +
                           "fiberfem_circulation: remake them with scripts/make_security.sh): " + e.what();
  }
  return circulation_reader_.has_value();
}

std::vector<Circulation> Client::circulation(const std::string& run_id, std::chrono::milliseconds wait, long after_frame) {
  if (!listen_circulation()) return {};
  const auto deadline = Clock::now() + wait;
  std::vector<Circulation> out;
  do {
    circulation_reader_->take([&](const fiberfem_CirculationState& s, const dds_sample_info_t&) {
      if (dds::str(s.run_id) == run_id && static_cast<long>(s.frame) > after_frame) out.push_back(dds::to_record(s));
    });
    if (!out.empty()) return out;
  } while (circulation_reader_->wait(left(deadline)) || Clock::now() < deadline);
  return out;
}

void Client::await_command_reader(const std::string& run_id, Clock::time_point deadline) {
  // Commands are volatile: write only once the command reader of the run's own participant
  // (known from its newest status) is matched.
  poll_status();
  if (!participants_.count(run_id)) resolve_run(run_id, std::chrono::duration_cast<std::chrono::milliseconds>(left(deadline)));
  while (!command_reader_matched(run_id) && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    poll_status();
  }
  if (!command_reader_matched(run_id))
    throw std::runtime_error("the command reader of run '" + run_id + "' was not matched within the timeout (is it running?)");
  // ... and once this client's ack reader has matched the run's ack writer: an answer
  // written just before the service exits (shutdown) is kept only while it runs.
  while (!ack_writer_matched(run_id) && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(5));
}

bool Client::ack_writer_matched(const std::string& run_id) const {
  const auto p = participants_.find(run_id);
  if (!ack_reader_ || p == participants_.end()) return false;
  dds_instance_handle_t handles[256];
  const dds_return_t n = dds_get_matched_publications(ack_reader_->get(), handles, 256);
  for (dds_return_t i = 0; i < n && i < 256; ++i) {
    dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(ack_reader_->get(), handles[i]);
    if (!ep) continue;
    const bool same = std::memcmp(ep->participant_key.v, p->second.v, sizeof p->second.v) == 0;
    dds_builtintopic_free_endpoint(ep);
    if (same) return true;
  }
  return false;
}

void Client::post(const std::string& run_id, const std::string& command_id, const std::string& kind, const std::string& args_json) {
  std::string id = command_id, rid = run_id, cid = client_id_, k = kind, args = args_json.empty() ? "{}" : args_json;
  fiberfem_Command c{};
  c.run_id = rid.data();
  c.command_id = id.data();
  c.client_id = cid.data();
  c.kind = k.data();
  c.args = args.data();
  command_writer_->write(c);
}

void Client::ensure_command_path() {
  if (!command_writer_)
    throw NotPermitted("not permitted to send commands (observer identity: commands need the operator role, "
                       "docs/security.md): " + commands_refused_);
  if (ack_reader_) return;
  try {
    ack_reader_.emplace(pp_);  // transient-local: an ack written before it matched still arrives
  } catch (const dds::DdsError& e) {
    if (e.code() != DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) throw;
    throw NotPermitted(std::string("not permitted to read command acknowledgements (docs/security.md): ") + e.what());
  }
}

Ack Client::send(const std::string& run_id, const std::string& kind, const std::string& args_json,
                 std::chrono::milliseconds wait) {
  const auto deadline = Clock::now() + wait;
  ensure_command_path();
  await_command_reader(run_id, deadline);
  const std::string id = next_id();
  post(run_id, id, kind, args_json);
  auto written = Clock::now();
  std::optional<Ack> ack;
  do {
    ack_reader_->take([&](const fiberfem_CommandAck& a, const dds_sample_info_t&) {
      if (dds::str(a.run_id) != run_id || dds::str(a.command_id) != id) return;
      ack = Ack{a.accepted, dds::str(a.reason), a.frame, a.parameter_version};
    });
    if (ack) return *ack;
    if (Clock::now() - written >= kResendAfter) {
      post(run_id, id, kind, args_json);
      written = Clock::now();
    }
  } while (ack_reader_->wait(std::min(left(deadline), std::chrono::nanoseconds(std::chrono::milliseconds(100)))) ||
           Clock::now() < deadline);
  throw std::runtime_error("no acknowledgement of '" + kind + "' (command " + id + ") from run '" + run_id + "' within the timeout");
}

FloodReport Client::flood(const std::string& run_id, const std::string& kind, const std::string& args_json, int count, int window,
                          std::chrono::milliseconds wait) {
  if (count < 1) throw std::invalid_argument("flood: count must be at least 1, got " + std::to_string(count));
  // The service keeps the last 64 acks per run for late readers: more in flight could
  // push an answer out before its reader has it.
  if (window < 1 || window > 64) throw std::invalid_argument("flood: window must be in [1, 64], got " + std::to_string(window));
  const auto deadline = Clock::now() + wait;
  ensure_command_path();
  await_command_reader(run_id, deadline);
  FloodReport r;
  std::map<std::string, Clock::time_point> outstanding;
  std::set<std::string> answered;
  std::map<std::string, Clock::time_point> written;  // of the outstanding commands, last written
  auto take_acks = [&] {
    ack_reader_->take([&](const fiberfem_CommandAck& a, const dds_sample_info_t&) {
      if (dds::str(a.run_id) != run_id) return;
      const std::string id = dds::str(a.command_id);
      if (answered.count(id)) {
        ++r.duplicate_acks;
        return;
      }
      const auto o = outstanding.find(id);
      if (o == outstanding.end()) return;  // another client's
      r.latencies_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - o->second).count());
      outstanding.erase(o);
      written.erase(id);
      answered.insert(id);
      ++r.acked;
      if (a.accepted) ++r.accepted, r.versions.push_back(a.parameter_version);
    });
  };
  const auto t0 = Clock::now();
  auto t_last = t0;
  while ((r.sent < count || !outstanding.empty()) && Clock::now() < deadline) {
    while (r.sent < count && static_cast<int>(outstanding.size()) < window) {
      const std::string id = next_id();
      post(run_id, id, kind, args_json);
      outstanding[id] = written[id] = Clock::now();
      ++r.sent;
    }
    for (auto& [id, t] : written)
      if (outstanding.count(id) && Clock::now() - t >= kResendAfter) {
        post(run_id, id, kind, args_json);
        t = Clock::now();
        ++r.resent;
      }
    const int before = r.acked;
    take_acks();
    if (r.acked > before) t_last = Clock::now();
    else ack_reader_->wait(std::min(left(deadline), std::chrono::nanoseconds(std::chrono::milliseconds(100))));
  }
  r.seconds = std::chrono::duration<double>(t_last - t0).count();
  // A moment more for any second answer to a command already answered.
  const auto linger = Clock::now() + std::chrono::milliseconds(300);
  while (Clock::now() < linger) {
    take_acks();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return r;
}

RunFollower::RunFollower(Client& client, std::string run_id, std::chrono::milliseconds lost_after)
    : client_(client), wanted_(std::move(run_id)), lost_after_(lost_after) {}

std::optional<RunFollower::Event> RunFollower::next(std::chrono::milliseconds wait) {
  const auto deadline = Clock::now() + wait;
  do {
    if (run_.empty()) {  // look for the run to follow (the rule in client.hpp)
      std::string pick;
      const std::map<std::string, RunStatus> live = client_.live_runs(lost_after_);
      if (!wanted_.empty()) {
        if (live.count(wanted_)) pick = wanted_;
      } else {
        std::vector<std::string> candidates;
        for (const auto& [id, s] : live)
          if (scene_.empty() || s.scene_name == scene_) candidates.push_back(id);
        if (candidates.size() == 1) pick = candidates.front();
      }
      if (!pick.empty()) {
        const RunStatus& s = live.at(pick);
        run_ = pick, scene_ = s.scene_name, pid_ = s.pid, host_ = s.host, last_frame_ = -1;
        Event e;
        e.kind = Event::Kind::found;
        e.run_id = run_;
        e.message = "scene " + s.scene_name + " on " + s.host + " (pid " + std::to_string(s.pid) + "), " + s.state + " at t = " +
                    std::to_string(s.time_s) + " s";
        return e;
      }
      std::this_thread::sleep_for(std::min(left(deadline), std::chrono::nanoseconds(std::chrono::milliseconds(50))));
      continue;
    }
    std::string why;
    bool lost = !client_.live(run_, lost_after_, &why);
    if (!lost) {
      const RunStatus& s = client_.runs().at(run_);
      if (s.pid != pid_ || s.host != host_) {  // restarted before its silence was noticed
        lost = true;
        why = "restarted (pid " + std::to_string(pid_) + " on " + host_ + ", now pid " + std::to_string(s.pid) + " on " + s.host + ")";
      }
    }
    if (lost) {
      Event e;
      e.kind = Event::Kind::lost;
      e.run_id = run_;
      e.message = why;
      client_.drop_states(run_);
      run_.clear();
      return e;
    }
    auto st = client_.next_state(run_, std::chrono::duration_cast<std::chrono::milliseconds>(
                                           std::min(left(deadline), std::chrono::nanoseconds(std::chrono::milliseconds(200)))),
                                 last_frame_);
    if (st) {
      last_frame_ = static_cast<long>(st->frame);
      Event e;
      e.kind = Event::Kind::state;
      e.run_id = run_;
      e.state = std::move(st);
      return e;
    }
  } while (Clock::now() < deadline);
  return std::nullopt;
}

}  // namespace fiberfem::clients
