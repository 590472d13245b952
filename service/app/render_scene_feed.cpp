// `fiberfem render SCENE.yaml`: the scene simulated here as `fiberfem run` does (a
// RunDriver stepped frame by frame, on either tier: the corner mesh of an order-2 scene is
// drawn), or a static scene's rest state and equilibrium.

#include "service/app/render_feed.hpp"

#include "clients/render/surface.hpp"
#include "io/scene.hpp"
#include "io/scene_accurate.hpp"
#include "service/batch_run.hpp"
#include "service/run_driver.hpp"

#include <algorithm>
#include <chrono>
#include <stdexcept>

namespace fiberfem::app {
namespace {

// The rest state (t = 0), then the equilibrium (t = 1; Newton as `fiberfem run --static`,
// which has no active stress: activation zero).
void static_frames(Feed& f, std::shared_ptr<const io::Scene> sc, std::shared_ptr<service::RunDriver> run) {
  f.total = 2;
  f.caption = [name = sc->name](double t, double) { return name + (t > 0 ? "    static equilibrium" : "    rest"); };
  const bool contracting = sc->model.contraction.enabled();
  long i = 0;
  f.next = [sc, run, contracting, i](core::Positions& x, std::vector<double>& act, double& t, long& step) mutable {
    if (i >= 2) return false;
    act.assign(contracting ? static_cast<size_t>(sc->model.mesh.num_elements()) : 0, 0.0);
    if (i == 0) {
      x = run->engine().positions();
    } else if (sc->accurate()) {  // Newton on the element mesh; its corner nodes drawn
      const io::AccurateProblem ap = io::accurate_problem(*sc);
      core::Positions xe;
      Eigen::VectorXd p;
      const core::hyperelastic::NewtonReport r = core::hyperelastic::solve_static(*ap.problem, xe, p, ap.newton);
      if (!r.converged) throw std::runtime_error("static solve did not converge: " + r.message);
      x = xe.leftCols(ap.mesh->num_corner_nodes());
    } else {
      const core::StaticReport r = service::static_equilibrium(*sc, x);
      if (!r.converged) throw std::runtime_error("static solve did not converge: " + r.message);
    }
    t = static_cast<double>(i), step = i;
    ++i;
    return true;
  };
}

// The initial state, then a state per step; a failed step ends the render with an error.
void dynamic_frames(Feed& f, std::shared_ptr<service::RunDriver> run, long steps) {
  f.total = steps + 1;
  f.step_s = std::make_shared<std::vector<double>>();
  const bool contracting = run->control().scene().model.contraction.enabled();
  long s = 0;
  f.next = [run, steps, contracting, s, step_s = f.step_s](core::Positions& x, std::vector<double>& act, double& t, long& step) mutable {
    if (s > steps) return false;
    if (s > 0) {
      const auto t0 = std::chrono::steady_clock::now();
      const core::StepReport& r = run->step();
      step_s->push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      if (r.status == core::StepStatus::failed)
        throw std::runtime_error("step " + std::to_string(s) + " failed at t = " + std::to_string(run->engine().time_s()) + " s: " + r.message);
    }
    const service::Engine& sim = run->engine();
    x = sim.positions();
    act = contracting ? run->activation() : std::vector<double>{};
    t = sim.time_s(), step = s;
    ++s;
    return true;
  };
}

}  // namespace

Feed scene_feed(const RenderArgs& a) {
  auto sc = std::make_shared<const io::Scene>(io::load_scene(a.scene_file, a.overrides));
  const core::Model& model = sc->model;
  const bool contracting = model.contraction.enabled();
  const bool is_static = a.force_static || sc->mode == io::Mode::static_;
  if (is_static && !a.strip.empty()) throw std::invalid_argument("--strip: a static scene has no beat to show");
  const double dt = sc->settings.dt_s;
  std::vector<double> at = a.at;  // --at: render only the steps nearest these times
  std::sort(at.begin(), at.end());
  const double until = a.until > 0 ? a.until : !at.empty() ? std::max(at.back(), dt) : sc->until_s;
  const long steps = a.steps > 0 ? a.steps : std::max(1L, std::lround(until / dt));
  if (!at.empty() && at.back() > (steps + 0.5) * dt)
    throw std::invalid_argument("--at " + std::to_string(at.back()) + " s is after the end of the run (" + std::to_string(steps * dt) + " s)");
  if (steps > 100000000L) throw std::invalid_argument("render: over 1e8 steps");
  // The strip: N panels evenly over one beat (the first; the whole run without a contraction).
  Feed f;
  f.strip_span_s = contracting ? model.contraction.period_s : steps * dt;
  if (!a.strip.empty() && steps * dt < f.strip_span_s * (1 - 1.0 / a.strip_panels) - 0.5 * dt)
    throw std::invalid_argument("--strip: the run (" + std::to_string(steps * dt) + " s) is shorter than one beat (" +
                                std::to_string(f.strip_span_s) + " s); raise --until");
  f.name = sc->name;
  f.origin = "scene '" + sc->name + "'";
  f.title = f.origin + ", " + std::to_string(model.mesh.num_nodes()) + " nodes, " + std::to_string(model.mesh.boundary_triangles().size()) +
            " surface triangles";
  f.every_unit = "steps (" + std::to_string(steps) + " steps)";
  f.mesh.emplace(model.mesh);
  f.fibers = model.fibers;
  f.contraction = model.contraction;
  f.has_activation = contracting;
  f.no_activation = "scene '" + sc->name + "' has no contraction";
  f.frame_dt_s = dt;
  f.to_draw = a.last ? 1 : is_static ? 2 : !at.empty() ? static_cast<long>(at.size()) : steps / a.every + 1;
  auto run = std::make_shared<service::RunDriver>(*sc, service::Parameters::fixed);
  // The simulator's rest-shape inverses (the accurate tier has none: the renderer makes its own).
  if (is_static) static_frames(f, sc, run);
  else dynamic_frames(f, run, steps);
  if (!is_static && run->circulation())  // the state next() gave last
    f.circulation = [run] { return std::vector<core::circulation::Snapshot>{*run->circulation()}; };
  return f;
}

}  // namespace fiberfem::app
