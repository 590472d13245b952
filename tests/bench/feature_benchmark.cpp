// bench_features: what each model term costs per step (issue 4, "model only what the scene
// requires"). A program, not a timed test.
//
// The benchmark ventricle (lv_ellipsoid, base held) as a baseline (isotropic, no damping,
// no gravity, no contraction) and with one term turned on at a time, then all of them.
// All variants are stepped in turn in one process, so they see the same machine, and
// each is started with the same small velocity field so that every one moves (a body at
// rest solves in no iterations). A term's cost lives in the per-element phases
// (rotations and assembly); the solve depends on the motion each term causes, so it is
// reported, with its iterations, but not counted as the term's cost.
//
//   bench_features [--steps 150] [--resolution 36 14 3] [--out docs/feature-costs.md]

#include "benchmark_ventricle.hpp"
#include "core/simulator.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <limits>
#include <memory>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace core = fiberfem::core;
namespace bench = fiberfem::bench;

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

struct Variant {
  std::string name;
  bench::VentricleTerms terms;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_features: per-step cost of each model term"};
  int steps = 150;
  std::vector<int> res{36, 14, 3};
  std::string out;
  app.add_option("--steps", steps, "Measured steps per variant")->capture_default_str();
  app.add_option("--resolution", res, "lv_ellipsoid circumferential longitudinal transmural")->expected(3)->capture_default_str();
  app.add_option("--out", out, "Also write the Markdown table here");
  CLI11_PARSE(app, argc, argv);

  const core::TetMesh mesh = bench::ventricle_mesh({res[0], res[1], res[2]});
  const std::vector<core::Vec3> fibers = bench::ventricle_fibers(mesh);
  const std::vector<Variant> variants = {
      {"baseline: isotropic, no damping, gravity or contraction", {}},
      {"+ fibers (helix rule)", {true}},
      {"+ mass damping", {false, true}},
      {"+ stiffness damping", {false, false, true}},
      {"+ gravity", {false, false, false, true}},
      {"+ contraction, active stress (paced)", {false, false, false, false, 1}},
      {"+ contraction, nodal forces (paper)", {false, false, false, false, 2}},
      {"all of them (fibers, both dampings, gravity, active stress)", {true, true, true, true, 1}},
  };
  // A small swirl about the long axis, the same for every variant, so every one moves.
  core::Positions v0(3, mesh.num_nodes());
  for (int n = 0; n < mesh.num_nodes(); ++n) {
    const core::Vec3 p = mesh.rest_positions().col(n);
    v0.col(n) = 0.05 * core::Vec3(-p.y(), p.x(), 0.0) / 0.02 * (0.005 - p.z()) / 0.025;
  }
  std::vector<std::unique_ptr<core::Simulator>> sims;
  for (const Variant& v : variants) {
    core::SimulatorSettings st;
    st.max_energy_gain = std::numeric_limits<double>::infinity();  // no retries: same work per step
    sims.push_back(std::make_unique<core::Simulator>(bench::ventricle_model(mesh, fibers, v.terms), st));
    sims.back()->set_state(mesh.rest_positions(), v0);
  }
  const size_t nv = variants.size();
  std::vector<std::vector<double>> elem(nv), solve(nv), total(nv);
  std::vector<double> iters(nv, 0);
  const int warmup = 10;
  for (int s = 0; s < warmup + steps; ++s)
    for (size_t k = 0; k < nv; ++k) {
      const core::StepReport r = sims[k]->step();
      if (s < warmup) continue;
      elem[k].push_back(r.time.rotations_s + r.time.assembly_s);
      solve[k].push_back(r.time.solve_s);
      total[k].push_back(r.time.total_s);
      iters[k] += r.solver_iterations;
    }
  std::ostringstream md;
  char date[32];
  const std::time_t now = std::time(nullptr);
  std::strftime(date, sizeof date, "%Y-%m-%d", std::localtime(&now));
  md << "# Cost of each model term\n\nMade by `build/release/tests/bench/bench_features" << (out.empty() ? "" : " --out " + out)
     << "` on " << date << ": the benchmark ventricle (lv_ellipsoid " << res[0] << ", " << res[1] << ", " << res[2] << ": "
     << mesh.num_elements() << " tets), base held, PCG 1e-6, energy check off, " << steps
     << " steps per variant after " << warmup
     << ", all variants stepped in turn in one process, each started with the same small swirl. The term's own cost is "
        "in the per-element phases (rotations + assembly); the solve follows the motion the term causes.\n\n"
     << "| variant | rotations + assembly ms (median) | vs baseline | solve ms (median) | iterations/step | step ms (median) |\n"
     << "|---|---:|---:|---:|---:|---:|\n";
  const double base = median(elem[0]);
  for (size_t k = 0; k < nv; ++k) {
    char row[512];
    std::snprintf(row, sizeof row, "| %s | %.3f | %.3f | %.3f | %.1f | %.3f |\n", variants[k].name.c_str(), 1e3 * median(elem[k]),
                  median(elem[k]) / base, 1e3 * median(solve[k]), iters[k] / steps, 1e3 * median(total[k]));
    md << row;
  }
  std::cout << md.str();
  if (!out.empty()) {
    std::ofstream f(out);
    f << md.str();
    std::cerr << "wrote " << out << "\n";
  }
  return 0;
}
