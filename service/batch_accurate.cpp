// A static solve on the accurate tier (material.law, mesh.order 2): Newton with load steps
// on the scene's element mesh, its probes interpolated with the element's shape functions,
// in the same report sections as the real-time tier's static solve.

#include "service/batch_report.hpp"

#include "io/scene_accurate.hpp"

#include <chrono>
#include <cstdio>
#include <ostream>

namespace fiberfem::service::detail {

int run_static_accurate(const io::Scene& sc, json& report, std::ostream& out) {
  char line[512];
  const auto t0 = std::chrono::steady_clock::now();
  const io::AccurateProblem ap = io::accurate_problem(sc);
  const core::hyperelastic::ElementMesh& mesh = *ap.mesh;
  std::snprintf(line, sizeof line, "static: accurate tier, order %d, %d nodes, %d quadrature points per element%s\n",
                mesh.order(), mesh.num_nodes(), ap.problem->points(),
                ap.problem->mixed() ? ", incompressible (mixed displacement-pressure)" : "");
  out << line;
  if (!ap.problem->active_tension_pa.empty()) out << "static: the contraction is held at its peak tension\n";
  core::Positions x;
  Eigen::VectorXd p;
  const core::hyperelastic::NewtonReport r = core::hyperelastic::solve_static(*ap.problem, x, p, ap.newton);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::snprintf(line, sizeof line,
                "static: %s after %d Newton iterations in %d load steps (%d cut-backs), relative residual %.2e, %d "
                "unknowns, %.2f s (assembly %.2f s, linear solves %.2f s: %d factorisations, %d BiCGSTAB iterations on "
                "lagged factors)\n",
                r.converged ? "converged" : "NOT converged", r.iterations, r.load_steps, r.cutbacks, r.relative_residual,
                r.equations, wall, r.assembly_s, r.factor_s, r.factorisations, r.krylov_iterations);
  out << line;
  if (!r.converged) out << "static: " << r.message << "\n";
  json probes = json::array();
  for (const io::Probe& pr : sc.probes) {
    const core::Vec3 u = io::accurate_probe_displacement(mesh, pr, x);
    std::snprintf(line, sizeof line, "probe %s: displacement [%+.6e, %+.6e, %+.6e] m (|u| %.6e m)\n", pr.name.c_str(), u.x(),
                  u.y(), u.z(), u.norm());
    out << line;
    probes.push_back({{"name", pr.name}, {"rest_m", vec_json(pr.point_m)}, {"final_m", vec_json(pr.point_m + u)}, {"displacement_m", vec_json(u)}});
  }
  report["status"] = r.converged ? "completed" : "failed";
  report["reason"] = r.converged ? "" : r.message;
  report["static"] = {{"converged", r.converged},
                      {"tier", "accurate"},
                      {"order", mesh.order()},
                      {"quadrature_points", ap.problem->points()},
                      {"unknowns", r.equations},
                      {"load_factor", r.load_factor},
                      {"newton_iterations", r.iterations},
                      {"load_steps", r.load_steps},
                      {"cutbacks", r.cutbacks},
                      {"factorisations", r.factorisations},
                      {"krylov_iterations", r.krylov_iterations},
                      {"relative_residual", r.relative_residual},
                      {"residual_history", r.residual_history}};
  report["timing"] = {{"wall_s", wall}, {"assembly_s", r.assembly_s}, {"linear_solve_s", r.factor_s}};
  report["probes"] = probes;
  return r.converged ? 0 : 1;
}

}  // namespace fiberfem::service::detail
