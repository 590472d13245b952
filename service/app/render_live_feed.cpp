// `fiberfem render --live`: a running service (or replay) on the bus, its newest state
// each time (docs/rendering.md); the renderer joined to the client library's live feed.

#include "service/app/render_feed.hpp"

#include "clients/ctl/client.hpp"

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>

namespace fiberfem::app {

// The live bus: the run's topology, then the newest state each time (the service never
// waits for the renderer: states it publishes while a frame is drawn are skipped).
Feed live_feed(const RenderArgs& a) {
  using namespace std::chrono_literals;
  auto client = std::make_shared<clients::Client>();
  const std::string run = client->resolve_run(a.run_id, 20s);
  const auto topo = client->topology(run, 20s);
  if (!topo) throw std::runtime_error("no topology from run '" + run + "'");
  Feed f;
  f.name = topo->scene_name;
  f.origin = "run " + run + (topo->replay ? " (replay)" : "");
  core::Positions rest(3, topo->num_nodes);
  for (unsigned n = 0; n < topo->num_nodes; ++n)
    for (int d = 0; d < 3; ++d) rest(d, n) = topo->rest_positions[3 * n + d];
  std::vector<core::Tet> tets(topo->num_elements);
  for (unsigned e = 0; e < topo->num_elements; ++e)
    for (int k = 0; k < 4; ++k) tets[e][static_cast<size_t>(k)] = topo->tets[4 * e + k];
  f.mesh.emplace(rest, tets, std::vector<int>(topo->element_regions.begin(), topo->element_regions.end()));
  for (unsigned e = 0; e < topo->num_elements; ++e) f.fibers.emplace_back(topo->fibers[3 * e], topo->fibers[3 * e + 1], topo->fibers[3 * e + 2]);
  const auto st = client->status(run, 10s);
  if (st && st->heart_rate_bpm > 0) {  // beats in the caption and the strip
    f.contraction.period_s = 60.0 / st->heart_rate_bpm;
    f.contraction.region_peak_pa.assign(static_cast<size_t>(f.mesh->num_regions()), 1.0);
  }
  f.has_activation = st && st->heart_rate_bpm > 0;
  f.frame_dt_s = st && st->dt_s > 0 ? st->dt_s : 1.0 / 30;
  auto skipped = std::make_shared<long>(0);
  long last = -1, shown = 0;
  const auto state_nodes = topo->state_nodes;
  const double until = a.until;
  const long max_frames = a.live_frames;
  // Follows the run across restarts of its service (the rule of clients::RunFollower,
  // docs/ctl.md: the run id given, else the only live run and then the only one of the
  // same scene): a run that comes back with the same mesh is drawn on; one with another
  // mesh, or none within kComeBack, ends the render.
  static constexpr auto kComeBack = std::chrono::seconds(60);
  auto follower = std::make_shared<clients::RunFollower>(*client, a.run_id.empty() ? run : a.run_id);
  const unsigned num_nodes = topo->num_nodes, num_elements = topo->num_elements;
  int founds = 0;
  f.next = [client, follower, rest, state_nodes, last, shown, until, max_frames, skipped, num_nodes, num_elements, founds](
               core::Positions& x, std::vector<double>& act, double& t, long& step) mutable {
    if (max_frames > 0 && shown >= max_frames) return false;
    auto give_up = std::chrono::steady_clock::now() + kComeBack;
    std::optional<clients::State> s;
    while (!s) {
      const auto ev = follower->next(500ms);
      if (!ev) {
        if (std::chrono::steady_clock::now() > give_up) {
          std::printf("render: no run to follow for %lld s\n", static_cast<long long>(kComeBack.count()));
          return false;
        }
        continue;
      }
      switch (ev->kind) {
        case clients::RunFollower::Event::Kind::found: {
          // The first is the run whose topology is drawn; a later one is a restart, with
          // a topology of its own.
          const auto t2 = founds++ == 0 ? std::optional<clients::Topology>() : client->topology(ev->run_id, 10s);
          if (founds > 1 && (!t2 || t2->num_nodes != num_nodes || t2->num_elements != num_elements)) {
            std::printf("render: run %s has another mesh: stopping (start the render anew)\n", ev->run_id.c_str());
            return false;
          }
          std::printf("following run %s: %s\n", ev->run_id.c_str(), ev->message.c_str());
          last = -1;
          break;
        }
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
    if (last >= 0 && static_cast<long>(s->frame) > last + 1) *skipped += static_cast<long>(s->frame) - last - 1;
    last = static_cast<long>(s->frame);
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
  f.finish = [skipped] {
    std::printf("render: %ld published frames skipped while drawing (the service never waits for the renderer)\n", *skipped);
  };
  return f;
}


}  // namespace fiberfem::app
