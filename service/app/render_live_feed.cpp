// `fiberfem render --live`: a running service (or replay) on the bus, its newest state
// each time (docs/rendering.md); the renderer joined to the client library's live feed.

#include "service/app/render_feed.hpp"

#include "clients/ctl/client.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <deque>
#include <memory>
#include <optional>
#include <stdexcept>

namespace fiberfem::app {
namespace {

using namespace std::chrono_literals;

// The rest mesh, regions and fibers of a published topology.
void take_topology(Feed& f, const clients::Topology& topo) {
  core::Positions rest(3, topo.num_nodes);
  for (unsigned n = 0; n < topo.num_nodes; ++n)
    for (int d = 0; d < 3; ++d) rest(d, n) = topo.rest_positions[3 * n + d];
  std::vector<core::Tet> tets(topo.num_elements);
  for (unsigned e = 0; e < topo.num_elements; ++e)
    for (int k = 0; k < 4; ++k) tets[e][static_cast<size_t>(k)] = topo.tets[4 * e + k];
  f.mesh.emplace(rest, tets, std::vector<int>(topo.element_regions.begin(), topo.element_regions.end()));
  for (unsigned e = 0; e < topo.num_elements; ++e) f.fibers.emplace_back(topo.fibers[3 * e], topo.fibers[3 * e + 1], topo.fibers[3 * e + 2]);
}

// The run's states as they come, following the run across restarts of its service (the
// rule of clients::RunFollower, docs/ctl.md: the run id given, else the only live run and
// then the only one of the same scene): a run that comes back with the same mesh is drawn
// on; one with another mesh, or none within kComeBack, ends the render.
class LiveStates {
 public:
  static constexpr auto kComeBack = std::chrono::seconds(60);

  LiveStates(std::shared_ptr<clients::Client> client, const std::string& run, const clients::Topology& topo)
      : client_(std::move(client)), follower_(*client_, run), num_nodes_(topo.num_nodes), num_elements_(topo.num_elements) {}

  // The next state; none when the run is gone or came back with another mesh.
  std::optional<clients::State> next() {
    auto give_up = std::chrono::steady_clock::now() + kComeBack;
    std::optional<clients::State> s;
    while (!s) {
      const auto ev = follower_.next(500ms);
      if (!ev) {
        if (std::chrono::steady_clock::now() > give_up) {
          std::printf("render: no run to follow for %lld s\n", static_cast<long long>(kComeBack.count()));
          return std::nullopt;
        }
        continue;
      }
      switch (ev->kind) {
        case clients::RunFollower::Event::Kind::found:
          if (!found(*ev)) return std::nullopt;
          break;
        case clients::RunFollower::Event::Kind::lost:
          std::printf("lost run %s: %s\n", ev->run_id.c_str(), ev->message.c_str());
          give_up = std::chrono::steady_clock::now() + kComeBack;
          break;
        case clients::RunFollower::Event::Kind::state:
          s = ev->state;
          break;
      }
      std::fflush(stdout);
    }
    if (last_ >= 0 && static_cast<long>(s->frame) > last_ + 1) skipped_ += static_cast<long>(s->frame) - last_ - 1;
    last_ = static_cast<long>(s->frame);
    return s;
  }
  // States published but not drawn (the service never waits for the renderer).
  long skipped() const { return skipped_; }

 private:
  // The first run found is the one whose topology is drawn; a later one is a restart,
  // with a topology of its own. @return whether to go on.
  bool found(const clients::RunFollower::Event& ev) {
    if (founds_++ > 0) {
      const auto t2 = client_->topology(ev.run_id, 10s);
      if (!t2 || t2->num_nodes != num_nodes_ || t2->num_elements != num_elements_) {
        std::printf("render: run %s has another mesh: stopping (start the render anew)\n", ev.run_id.c_str());
        return false;
      }
    }
    std::printf("following run %s: %s\n", ev.run_id.c_str(), ev.message.c_str());
    last_ = -1;
    return true;
  }

  std::shared_ptr<clients::Client> client_;
  clients::RunFollower follower_;
  unsigned num_nodes_, num_elements_;
  int founds_ = 0;
  long last_ = -1, skipped_ = 0;
};

// The circulation samples of the states drawn: those up to the current state's frame,
// oldest first (samples of later frames wait for their state).
class LiveCirculation {
 public:
  explicit LiveCirculation(std::shared_ptr<clients::Client> client) : client_(std::move(client)) {}
  // Whether the run publishes a circulation: a sample within `wait` (one comes with every
  // state, and a service publishes a state at least once a second).
  bool published(const std::string& run, std::chrono::milliseconds wait) {
    for (clients::Circulation& c : client_->circulation(run, wait)) pending_.push_back(std::move(c));
    return !pending_.empty();
  }
  void at(const clients::State& s) { run_ = s.run_id, frame_ = static_cast<long>(s.frame); }
  std::vector<core::circulation::Snapshot> take() {
    for (clients::Circulation& c : client_->circulation(run_, 0ms)) pending_.push_back(std::move(c));
    std::vector<core::circulation::Snapshot> out;
    std::deque<clients::Circulation> later;
    for (clients::Circulation& c : pending_) {
      if (c.run_id != run_) continue;  // a run followed before
      if (static_cast<long>(c.frame) <= frame_) out.push_back(c.snapshot);
      else later.push_back(std::move(c));
    }
    pending_ = std::move(later);
    return out;
  }

 private:
  std::shared_ptr<clients::Client> client_;
  std::deque<clients::Circulation> pending_;
  std::string run_;
  long frame_ = -1;
};

}  // namespace

// The live bus: the run's topology, then the newest state each time (the service never
// waits for the renderer: states it publishes while a frame is drawn are skipped).
Feed live_feed(const RenderArgs& a) {
  auto client = std::make_shared<clients::Client>();
  const bool circulation_readable = client->listen_circulation();  // matched while the run is looked for
  if (!circulation_readable) std::printf("render: no pressure-volume inset: %s\n", client->circulation_refused().c_str());
  const std::string run = client->resolve_run(a.run_id, 20s);
  const auto topo = client->topology(run, 20s);
  if (!topo) throw std::runtime_error("no topology from run '" + run + "'");
  Feed f;
  f.name = topo->scene_name;
  f.origin = "run " + run + (topo->replay ? " (replay)" : "");
  take_topology(f, *topo);
  const auto st = client->status(run, 10s);
  if (st && st->heart_rate_bpm > 0) {  // beats in the caption and the strip
    f.contraction.period_s = 60.0 / st->heart_rate_bpm;
    f.contraction.region_peak_pa.assign(static_cast<size_t>(f.mesh->num_regions()), 1.0);
  }
  f.has_activation = st && st->heart_rate_bpm > 0;
  f.frame_dt_s = st && st->dt_s > 0 ? st->dt_s : 1.0 / 30;
  auto states = std::make_shared<LiveStates>(client, a.run_id.empty() ? run : a.run_id, *topo);
  auto circulation = std::make_shared<LiveCirculation>(client);
  if (circulation_readable && circulation->published(run, 2500ms)) f.circulation = [circulation] { return circulation->take(); };
  f.next = [states, circulation, rest = f.mesh->rest_positions(), state_nodes = topo->state_nodes, until = a.until, max_frames = a.live_frames,
            shown = 0L](core::Positions& x, std::vector<double>& act, double& t, long& step) mutable {
    if (max_frames > 0 && shown >= max_frames) return false;
    const std::optional<clients::State> s = states->next();
    if (!s) return false;
    circulation->at(*s);
    x = rest;
    if (state_nodes.empty()) {
      for (Eigen::Index i = 0; i < x.size() && static_cast<size_t>(i) < s->positions.size(); ++i) x.data()[i] = s->positions[static_cast<size_t>(i)];
    } else {
      for (size_t k = 0; k < state_nodes.size(); ++k)
        for (int d = 0; d < 3; ++d) x(d, state_nodes[k]) = s->positions[3 * k + d];
    }
    act.assign(s->activation.begin(), s->activation.end());
    t = s->time_s, step = static_cast<long>(s->frame);
    ++shown;
    std::printf("frame %ld t=%.4f s\n", step, t);
    std::fflush(stdout);
    return until <= 0 || t <= until + 1e-9;
  };
  f.finish = [states] {
    std::printf("render: %ld published frames skipped while drawing (the service never waits for the renderer)\n", states->skipped());
  };
  return f;
}

}  // namespace fiberfem::app
