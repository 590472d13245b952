// bench_step: speed of the dynamic step. A program, not a timed test.
//
// A cantilever beam (10 x 1 x 1 cm, clamped at x = 0, gravity -z, lambda = 40 kPa,
// mu = 10 kPa, rho = 1000 kg/m^3, mass damping 1/s, dt = 1/60 s) at three resolutions
// (about 5,700, 50,000 and 250,000 tetrahedra), falling from rest. For each solver
// (PCG at the given relative tolerance, sparse direct) and rotation method it measures
// steps per second, the per-phase breakdown, the PCG iterations, and the peak resident
// memory; and the fiber model (the paper's C33 x fiber_factor 3 along x, C55 = C66 x 2)
// against the isotropic model with the same Lame constants, in the same run.
//
//   bench_step                    # full table to stdout (about ten minutes on 2 cores)
//   bench_step --out docs/benchmarks.md
//   bench_step --quick            # the small beam only, few steps (the ctest entry)

#include "benchmark_ventricle.hpp"
#include "core/amg_preconditioner.hpp"
#include "core/builtin_scenes.hpp"
#include "core/simulator.hpp"

#include <CLI/CLI.hpp>
#include <omp.h>
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define FIBERFEM_HAVE_CALLGRIND 1
#endif

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <functional>
#include <fstream>
#include <iostream>
#include <limits>
#include <malloc.h>
#include <numeric>
#include <sstream>
#include <string>
#include <sys/utsname.h>
#include <vector>

namespace core = fiberfem::core;
namespace bench = fiberfem::bench;

namespace {

struct Size {
  std::string name;
  std::array<int, 3> cells;
  int warmup;
  int steps;
};

struct Case {
  bool fiber = true;
  core::LinearSolverKind solver = core::LinearSolverKind::pcg;
  core::RotationMethod rotation = core::RotationMethod::polar;
  core::PreconditionerKind preconditioner = core::PreconditionerKind::cholesky;
  bool energy_check = true;   // false: max_energy_gain = inf
  bool on_large = true;       // run on the large beam too
};

struct Result {
  int tets = 0, nodes = 0;
  double median_step_s = 0, mean_step_s = 0, max_step_s = 0;
  double factorizations = 0;                             // per step
  double rotations_s = 0, assembly_s = 0, solve_s = 0;  // medians
  double iterations = 0;                                 // mean per step
  double peak_rss_mb = 0;
  int failed = 0;
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Peak resident set since the last reset (Linux: writing 5 to clear_refs resets VmHWM to
// the current RSS). The heap freed by earlier cases is returned to the system first: glibc
// keeps it mapped otherwise, and a small case after a large one reported the large one's
// leftover heap as its own peak (128 MB for the 5,760-tet beam after the 245,760-tet runs).
void reset_peak_rss() {
  malloc_trim(0);
  std::ofstream f("/proc/self/clear_refs");
  f << "5";
}
double peak_rss_mb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}

core::Model make_beam(const Size& size, bool fiber) {
  core::CantileverSpec spec;
  spec.box.size_m = {0.1, 0.01, 0.01};
  spec.box.cells = size.cells;
  spec.damping.mass_1_s = 1.0;
  core::Model m = core::make_cantilever(spec);
  core::LameFiberConstants c;  // lambda 40 kPa, mu 10 kPa
  if (fiber) {
    c.fiber_factor = 3.0;
    c.shear_factor = 2.0;
  }
  m.region_materials[0] = core::Material::from_lame(c, 1000.0);
  m.validate();
  return m;
}

int g_refresh = 8;
double g_refresh_budget = 0.0;
int g_recycled = fiberfem::core::SolverSettings{}.recycled_solutions;
bool g_double_preconditioner = false;
bool g_node_order = false;
double g_energy_gain = core::SimulatorSettings{}.max_energy_gain;
double g_dt = 1.0 / 60.0;
// The lagged, warped preconditioner of the rows that name cholesky (--preconditioner amg swaps it).
core::PreconditionerKind g_lagged = core::PreconditionerKind::cholesky;

core::SimulatorSettings settings_for(const Case& c, double tol) {
  core::SimulatorSettings st;
  st.dt_s = g_dt;
  st.solver.method = c.solver;
  st.solver.tolerance = tol;
  st.solver.max_iterations = 2000;
  st.rotation = c.rotation;
  st.solver.preconditioner = c.preconditioner == core::PreconditionerKind::cholesky ? g_lagged : c.preconditioner;
  st.solver.refresh_iterations = g_refresh;
  st.solver.refresh_budget = g_refresh_budget;
  st.solver.recycled_solutions = g_recycled;
  st.solver.single_precision_preconditioner = !g_double_preconditioner;
  if (g_node_order) st.dof_order = core::DofOrder::nodes;
  st.max_energy_gain = c.energy_check ? g_energy_gain : std::numeric_limits<double>::infinity();
  return st;
}

struct Samples {
  std::vector<double> total, rot, asm_, sol;
  double its = 0, factorizations = 0;
  int failed = 0;
  void add(const core::StepReport& rep) {
    total.push_back(rep.time.total_s);
    rot.push_back(rep.time.rotations_s);
    asm_.push_back(rep.time.assembly_s);
    sol.push_back(rep.time.solve_s);
    its += rep.solver_iterations;
    factorizations += rep.solver_factorizations;
    if (rep.status == core::StepStatus::failed) ++failed;
  }
  void fill(Result& r) const {
    const double n = static_cast<double>(total.size());
    r.median_step_s = median(total);
    r.mean_step_s = std::accumulate(total.begin(), total.end(), 0.0) / n;
    r.max_step_s = *std::max_element(total.begin(), total.end());
    r.rotations_s = median(rot);
    r.assembly_s = median(asm_);
    r.solve_s = median(sol);
    r.iterations = its / n;
    r.factorizations = factorizations / n;
    r.failed = failed;
  }
};

// The fiber and the isotropic beam stepped alternately, so that both see the same
// machine (these machines are shared and noisy): the like-for-like cost ratio.
std::pair<Result, Result> run_pair(const Size& size, const Case& fiber, const Case& iso, double tol) {
  core::Simulator a(make_beam(size, true), settings_for(fiber, tol));
  core::Simulator b(make_beam(size, false), settings_for(iso, tol));
  for (int i = 0; i < size.warmup; ++i) {
    a.step();
    b.step();
  }
  Samples sa, sb;
  for (int i = 0; i < size.steps; ++i) {
    sa.add(a.step());
    sb.add(b.step());
  }
  std::pair<Result, Result> r;
  sa.fill(r.first);
  sb.fill(r.second);
  return r;
}

Result run_model(core::Model model, const core::SimulatorSettings& st, const Size& size) {
  reset_peak_rss();
  Result r;
  r.tets = model.mesh.num_elements();
  r.nodes = model.mesh.num_nodes();
  core::Simulator sim(std::move(model), st);
  for (int i = 0; i < size.warmup; ++i) sim.step();
  Samples smp;
  for (int i = 0; i < size.steps; ++i) smp.add(sim.step());
  smp.fill(r);
  r.peak_rss_mb = peak_rss_mb();
  return r;
}

Result run_case(const Size& size, const Case& c, double tol) {
  return run_model(make_beam(size, c.fiber), settings_for(c, tol), size);
}

std::string solver_name(const Case& c, double tol) {
  if (c.solver == core::LinearSolverKind::direct)
    return core::direct_solver_uses_cholmod() ? "direct (CHOLMOD)" : "direct (LLT)";
  std::ostringstream s;
  s << "PCG " << tol << " "
    << core::to_string(c.preconditioner == core::PreconditionerKind::cholesky ? g_lagged : c.preconditioner);
  return s.str();
}

std::string format_row(const Size& size, const Case& c, double tol, const Result& r) {
  std::ostringstream row;
  row.setf(std::ios::fixed);
  row.precision(2);
  row << "| " << size.name << " | " << r.tets << " | " << (c.fiber ? "fiber" : "isotropic") << " | "
      << solver_name(c, tol) << (c.energy_check ? "" : ", energy check off") << " | "
      << (c.rotation == core::RotationMethod::svd ? "svd" : "polar") << " | ";
  row.precision(1);
  row << 1.0 / r.mean_step_s << " | ";
  row.precision(2);
  row << 1e3 * r.median_step_s << " | " << 1e3 * r.max_step_s << " | " << 1e3 * r.rotations_s << " | "
      << 1e3 * r.assembly_s << " | " << 1e3 * r.solve_s << " | ";
  row.precision(1);
  row << r.iterations << " | ";
  row.precision(3);
  row << r.factorizations << " | ";
  row.precision(1);
  row << r.peak_rss_mb << " |" << (r.failed ? " (failed steps!)" : "") << "\n";
  return row.str();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_step: steps per second of the dynamic step on cantilever beams"};
  bool quick = false;
  std::string out;
  double tol = 1e-6;
  int threads = 0;
  int refresh = core::SolverSettings{}.refresh_iterations;
  double refresh_budget = core::SolverSettings{}.refresh_budget;
  std::vector<std::string> only;
  app.add_flag("--quick", quick, "Small beam only, few steps (a smoke run)");
  app.add_option("--out", out, "Also write the Markdown report to this file");
  app.add_option("--tolerance", tol, "PCG relative tolerance")->capture_default_str();
  app.add_option("--refresh-iterations", refresh, "Cholesky preconditioner refresh threshold")->capture_default_str();
  app.add_option("--refresh-budget", refresh_budget,
                 "Cholesky preconditioner refresh budget, in factorisations (0: the threshold alone)")
      ->capture_default_str();
  app.add_flag("--double-preconditioner", g_double_preconditioner, "Apply the Cholesky preconditioner in double precision");
  app.add_flag("--node-order", g_node_order, "Number the free DOFs in the mesh's node order (SimulatorSettings::dof_order nodes)");
  app.add_option("--recycled-solutions", g_recycled, "PCG warm start: previous solutions projected on (0: extrapolation)")
      ->capture_default_str();
  app.add_option("--max-energy-gain", g_energy_gain, "SimulatorSettings::max_energy_gain (inf: off)")
      ->capture_default_str();
  app.add_option("--dt", g_dt, "Time step, s (the fidelity presets: interactive 1/30, balanced 1/60, accurate 1/120)")
      ->capture_default_str();
  app.add_option("--threads", threads, "OpenMP threads (0 = chosen by the engine from measured step times, up to all cores)")->capture_default_str();
  app.add_option("--sizes", only, "Subset of sizes: small medium large");
  int only_case = -1;
  app.add_option("--case", only_case, "Run only this row of each size (0-based; for profiling)");
  int callgrind_steps = 0;
  app.add_option("--callgrind", callgrind_steps,
                 "Under valgrind --tool=callgrind --instr-atstart=no --collect-atstart=no: step --case on the "
                 "first --sizes past the warm-up this many times, each step collected and dumped on its own "
                 "(named steady or not), then exit");
  int trace = 0;
  app.add_option("--trace", trace,
                 "Print one line per step (time, phases, iterations, factorisations, substeps, retry reason) "
                 "for this many steps of --case on the first --sizes, then exit");
  std::string lagged = "cholesky";
  app.add_option("--preconditioner", lagged,
                 "The lagged, warped preconditioner of the PCG rows (cholesky or amg; block Jacobi rows stay)")
      ->check(CLI::IsMember({"cholesky", "amg"}))
      ->capture_default_str();
  std::vector<int> ventricle;
  app.add_option("--trace-ventricle", ventricle,
                 "With --trace: step the benchmark ventricle at this lv_ellipsoid resolution (circumferential "
                 "longitudinal transmural; 100 40 14: 257,544 tets) instead of a beam")
      ->expected(3);
  CLI11_PARSE(app, argc, argv);
  if (threads > 0) omp_set_num_threads(threads);
  g_lagged = lagged == "amg" ? core::PreconditionerKind::amg : core::PreconditionerKind::cholesky;
  g_refresh = refresh;
  g_refresh_budget = refresh_budget;

  std::vector<Size> sizes = {{"small", {48, 5, 4}, 10, 120},
                             {"medium", {96, 9, 10}, 3, 20},
                             {"large", {160, 16, 16}, 2, 6}};
  if (quick) sizes = {{"small", {48, 5, 4}, 5, 30}};
  if (!only.empty())
    sizes.erase(std::remove_if(sizes.begin(), sizes.end(),
                               [&](const Size& s) { return std::find(only.begin(), only.end(), s.name) == only.end(); }),
                sizes.end());

  const std::vector<Case> cases = {
      {true, core::LinearSolverKind::pcg, core::RotationMethod::polar},
      {false, core::LinearSolverKind::pcg, core::RotationMethod::polar},
      {true, core::LinearSolverKind::pcg, core::RotationMethod::svd, core::PreconditionerKind::cholesky, true, false},
      {true, core::LinearSolverKind::pcg, core::RotationMethod::polar, core::PreconditionerKind::block_jacobi, true, false},
      {true, core::LinearSolverKind::direct, core::RotationMethod::polar},
      {false, core::LinearSolverKind::direct, core::RotationMethod::polar},
      {true, core::LinearSolverKind::pcg, core::RotationMethod::polar, core::PreconditionerKind::cholesky, false},
      {false, core::LinearSolverKind::pcg, core::RotationMethod::polar, core::PreconditionerKind::cholesky, false},
  };

  if (callgrind_steps > 0) {
#ifdef FIBERFEM_HAVE_CALLGRIND
    const Size& size = sizes.front();
    const Case& c = cases[static_cast<size_t>(std::max(only_case, 0))];
    core::Simulator sim(make_beam(size, c.fiber), settings_for(c, tol));
    for (int i = 0; i < size.warmup; ++i) sim.step();
    // Each step is collected and dumped on its own (callgrind.out.PID.K, K from 1), named
    // by whether it was steady (no refactorisation, no retry): compare steady dumps.
    CALLGRIND_START_INSTRUMENTATION;
    for (int i = 0; i < callgrind_steps; ++i) {
      CALLGRIND_TOGGLE_COLLECT;
      const core::StepReport r = sim.step();
      CALLGRIND_TOGGLE_COLLECT;
      const bool steady = r.solver_factorizations == 0 && r.attempts == 1;
      const std::string label = "step " + std::to_string(i + 1) + (steady ? " steady" : " refactorised-or-retried") +
                                " iterations " + std::to_string(r.solver_iterations);
      CALLGRIND_DUMP_STATS_AT(label.c_str());
      std::printf("dump %d: %s\n", i + 1, label.c_str());
    }
    CALLGRIND_STOP_INSTRUMENTATION;
    std::printf("%d steps of %d tets (%s)\n", callgrind_steps, sim.model().mesh.num_elements(),
                RUNNING_ON_VALGRIND ? "under valgrind" : "not under valgrind: nothing collected");
    return 0;
#else
    std::fprintf(stderr, "bench_step: built without valgrind/callgrind.h (Debian package valgrind)\n");
    return 2;
#endif
  }

  if (trace > 0) {
    const Size& size = sizes.front();
    const Case& c = cases[static_cast<size_t>(std::max(only_case, 0))];
    core::Model model = make_beam(size, c.fiber);
    if (ventricle.size() == 3) {
      model = bench::beating_ventricle({ventricle[0], ventricle[1], ventricle[2]});
      std::printf("ventricle %d x %d x %d: %d tets\n", ventricle[0], ventricle[1], ventricle[2], model.mesh.num_elements());
    }
    core::Simulator sim(std::move(model), settings_for(c, tol));
    std::printf("step ms_total ms_rot ms_asm ms_solve iterations factorisations substeps attempts message\n");
    double sum = 0;
    for (int i = 0; i < trace; ++i) {
      const core::StepReport r = sim.step();
      sum += r.time.total_s;
      std::printf("%d %.3f %.3f %.3f %.3f %d %d %d %d %s\n", i, 1e3 * r.time.total_s, 1e3 * r.time.rotations_s,
                  1e3 * r.time.assembly_s, 1e3 * r.time.solve_s, r.solver_iterations, r.solver_factorizations,
                  r.substeps, r.attempts, r.message.c_str());
    }
    std::printf("mean %.3f ms (%.1f steps/s)\n", 1e3 * sum / trace, trace / sum);
    return 0;
  }

  std::ostringstream md;
  utsname u{};
  uname(&u);
  const std::time_t now = std::time(nullptr);
  char date[32];
  std::strftime(date, sizeof date, "%Y-%m-%d", std::gmtime(&now));
  md << "| beam | tets | model | solver | rotation | steps/s (mean) | ms/step median | ms/step max | "
        "rotations ms | assembly ms | solve ms | iterations/step | factorisations/step | peak RSS MB |\n"
     << "|---|---:|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  std::ostringstream ratios;
  ratios << "| beam | solver | fiber/isotropic step time (median) | fiber/isotropic rotations+assembly | "
            "fiber/isotropic solve time per iteration | iterations/step fiber / isotropic | "
            "factorisations/step fiber / isotropic |\n|---|---|---:|---:|---:|---:|---:|\n";
  // The speed targets at the `interactive` preset's step and tolerance (1/30 s, 1e-3) on
  // the same beams, in the same run: the default configuration and the energy check off
  // on the paper-size beam, the check off on the larger ones. Each size's rows run right
  // after its main rows (the paper-size ones before any large beam has been allocated:
  // after a few GB are freed this machine runs the small beam up to 30 % slower for a
  // while, docs/performance.md), the ventricle's last.
  std::ostringstream interactive;
  const bool with_interactive = !quick && only_case < 0;
  interactive << "| beam | tets | model | solver | rotation | steps/s (mean) | ms/step median | ms/step max | "
                 "rotations ms | assembly ms | solve ms | iterations/step | factorisations/step | peak RSS MB |\n"
              << "|---|---:|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  std::vector<core::PreconditionerKind> lagged_kinds{core::PreconditionerKind::cholesky};
  if (core::has_amg()) lagged_kinds.push_back(core::PreconditionerKind::amg);
  // Runs `rows` with the preset's step and refresh rule, then restores the run's.
  auto at_interactive_preset = [&](const std::function<void()>& rows) {
    const double saved_dt = g_dt;
    const int saved_refresh = g_refresh;
    const double saved_budget = g_refresh_budget;
    const core::PreconditionerKind saved_lagged = g_lagged;
    g_dt = 1.0 / 30.0;
    const core::SolverSettings preset = core::with_cost_refresh({});  // the preset's refresh rule
    g_refresh = preset.refresh_iterations;
    g_refresh_budget = preset.refresh_budget;
    rows();
    g_dt = saved_dt;
    g_refresh = saved_refresh;
    g_refresh_budget = saved_budget;
    g_lagged = saved_lagged;
  };
  auto interactive_rows = [&](const Size& size) {
    at_interactive_preset([&] {
      for (int k : {0, 6}) {
        if (k == 0 && size.name != "small") continue;
        const Case& c = cases[static_cast<size_t>(k)];
        // Beyond the paper's size, with each lagged preconditioner (the amg where built).
        for (const core::PreconditionerKind lagged : lagged_kinds) {
          if (lagged == core::PreconditionerKind::amg && size.name == "small") continue;
          g_lagged = lagged;
          const std::string row = format_row(size, c, 1e-3, run_case(size, c, 1e-3));
          interactive << row;
          std::cout << "interactive " << row << std::flush;
          // Six steps of the large beam are the start of its fall; over 60 steps (2 s
          // simulated) the rate includes the swing settling and any refactorisation the
          // refresh rule calls for (2.5-3.5 s each).
          if (size.name == "large" && k == 6) {
            const Size sustained{"large, 60 steps", size.cells, size.warmup, 60};
            const std::string long_row = format_row(sustained, c, 1e-3, run_case(sustained, c, 1e-3));
            interactive << long_row;
            std::cout << "interactive " << long_row << std::flush;
          }
        }
      }
    });
  };
  for (const Size& size : sizes) {
    std::vector<Result> res;
    for (const Case& c : cases) {
      if ((only_case >= 0 && &c != &cases[static_cast<size_t>(only_case)]) || (size.name == "large" && !c.on_large)) {
        res.push_back({});
        continue;
      }
      const Result r = run_case(size, c, tol);
      res.push_back(r);
      const std::string row = format_row(size, c, tol, r);
      md << row;
      std::cout << row << std::flush;
    }
    if (with_interactive) interactive_rows(size);
    if (only_case >= 0 || size.name == "large") continue;
    const Case pairs[][2] = {
        {{true, core::LinearSolverKind::direct, core::RotationMethod::polar, core::PreconditionerKind::cholesky, false},
         {false, core::LinearSolverKind::direct, core::RotationMethod::polar, core::PreconditionerKind::cholesky, false}},
        {{true, core::LinearSolverKind::pcg, core::RotationMethod::polar, core::PreconditionerKind::cholesky, false},
         {false, core::LinearSolverKind::pcg, core::RotationMethod::polar, core::PreconditionerKind::cholesky, false}},
        {{true, core::LinearSolverKind::pcg, core::RotationMethod::polar},
         {false, core::LinearSolverKind::pcg, core::RotationMethod::polar}}};
    for (const auto& pr : pairs) {
      const auto [f, i] = run_pair(size, pr[0], pr[1], tol);
      std::ostringstream row;
      row.setf(std::ios::fixed);
      row.precision(3);
      row << "| " << size.name << " | " << solver_name(pr[0], tol) << (pr[0].energy_check ? "" : ", energy check off")
          << " | " << f.median_step_s / i.median_step_s << " | "
          << (f.rotations_s + f.assembly_s) / (i.rotations_s + i.assembly_s) << " | "
          << (f.solve_s / std::max(f.iterations, 1.0)) / (i.solve_s / std::max(i.iterations, 1.0)) << " | ";
      row.precision(1);
      row << f.iterations << " / " << i.iterations << " | ";
      row.precision(3);
      row << f.factorizations << " / " << i.factorizations << " |\n";
      ratios << row.str();
      std::cout << row.str() << std::flush;
    }
  }
  if (with_interactive)
    at_interactive_preset([&] {
      // A mesh of over 250,000 tetrahedra that beats rather than falls: the benchmark
      // ventricle (lv_ellipsoid 100 x 40 x 14, base held, helix-rule fibers, active stress
      // paced from the apex, mass damping), from rest over 60 steps (2 s, about two beats).
      if (std::find_if(sizes.begin(), sizes.end(), [](const Size& z) { return z.name == "large"; }) != sizes.end()) {
        const core::Model model = bench::beating_ventricle({100, 40, 14});
        const Case& c = cases[6];
        const Size ventricle{"ventricle 100x40x14, 60 steps", {0, 0, 0}, 2, 60};
        for (const core::PreconditionerKind lagged : lagged_kinds) {
          g_lagged = lagged;
          const std::string row = format_row(ventricle, c, 1e-3, run_model(model, settings_for(c, 1e-3), ventricle));
          interactive << row;
          std::cout << "interactive " << row << std::flush;
        }
      }
    });
  std::ostringstream doc;
  doc << "# Step benchmark\n\n"
      << "Made by `build/release/tests/bench/bench_step" << (quick ? " --quick" : "")
      << (out.empty() ? "" : " --out " + out) << "` on " << date << ", " << u.machine << ", "
      << (threads > 0 ? std::to_string(threads) + " OpenMP threads"
                      : "threads chosen by the engine (up to " + std::to_string(omp_get_max_threads()) + ")")
      << ". Cantilever 10 x 1 x 1 cm clamped at x = 0 under gravity, lambda 40 kPa, mu 10 kPa, "
         "rho 1000 kg/m^3, mass damping 1/s, dt "
      << g_dt << " s, falling from rest; timings are medians over "
      << "the measured steps after a warm-up (small: 120 steps after 10, medium: 20 after 3, large: 6 "
         "after 2). The fiber model multiplies C33 by 3 and C55 = C66 by 2 along x (the paper's "
         "parameterisation); the isotropic model has the same Lame constants.\n\n"
      << md.str()
      << "\nFiber versus isotropic cost (the paper's claim: no extra cost per step), measured with the two "
         "beams stepped alternately in one process so both see the same machine. With the direct solver and "
         "no energy check both do identical work per step; with PCG the iteration counts (and with the "
         "energy check the substeps) differ because the stiffer fiber beam moves differently, so the "
         "per-element (rotations + assembly) and per-iteration ratios are the like-for-like ones:\n\n"
      << ratios.str();
  if (with_interactive)
    doc << "\nThe `interactive` preset's step, tolerance and factor refresh (dt 1/30 s, PCG 1e-3, "
           "refresh_budget 1, refresh_iterations 32; target: 1,000 steps/s at the paper's size), same "
           "beams, warm-ups and step counts, the energy check on (the default) on the paper-size beam and off on "
           "all three; the large beam also over 60 steps (2 s simulated), so that its refactorisations count; and a "
           "257,544-tet ventricle that beats (bench::ventricle_model: lv_ellipsoid 100 x 40 x 14, base held, helix-rule "
           "fibers, active stress 5 kPa paced from the apex, mass damping 10/s) from rest over 60 steps. Beyond the paper's size each "
           "row is run with both lagged, warped preconditioners: the Cholesky factor and the amg hierarchy (AMGCL):\n\n"
        << interactive.str();
  std::cout << "\n" << ratios.str();
  if (!out.empty()) {
    std::ofstream f(out);
    if (!f) {
      std::cerr << "bench_step: cannot write " << out << "\n";
      return 1;
    }
    f << doc.str();
    std::cout << "wrote " << out << "\n";
  }
  return 0;
}
