// bench_traffic: where a step stands against the machine's memory bandwidth. A program,
// not a timed test.
//
// Measures the bandwidth this machine sustains (a STREAM-style read, copy and triad over
// arrays far larger than the caches, on one thread and on all), then steps a scene and sets
// each phase's measured time against the bytes it has to move at least: every array the
// phase reads or writes counted once per step (per PCG iteration for the solver's), as if
// the caches kept everything else. The ratio of that traffic's time at the measured
// bandwidth to the measured time says how far a phase is from the memory limit: near 1 it
// is bound by memory traffic, far below 1 by arithmetic, latency or synchronisation.
//
//   bench_traffic --scene FILE [--steps 60] [--warmup 10] [--threads 1] [--stream-mb 512]

#include "core/corotated_linear_model.hpp"
#include "core/simulator.hpp"
#include "io/scene.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

namespace core = fiberfem::core;

namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

struct Stream {
  double read_gb_s = 0, copy_gb_s = 0, triad_gb_s = 0;
};

// Medians of `repeat` passes over arrays of `mb` MB each; bytes as STREAM counts them (a
// written array once, without the write-allocate read).
Stream measure_stream(int threads, size_t mb, int repeat) {
  const size_t n = mb * (1u << 20) / sizeof(double);
  std::vector<double> a(n, 1.0), b(n, 2.0), c(n, 0.5);
  omp_set_num_threads(threads);
  std::vector<double> tr, tc, tt;
  double sink = 0;
  const long ln = static_cast<long>(n);
  for (int r = 0; r < repeat; ++r) {
    auto t0 = Clock::now();
    double s = 0;
#pragma omp parallel reduction(+ : s)
    {
      // Eigen's sum: vectorised, several accumulators (a plain loop's one chain of additions
      // is bound by the adder's latency, not by memory).
      const size_t t = static_cast<size_t>(omp_get_thread_num()), T = static_cast<size_t>(omp_get_num_threads());
      const size_t begin = n * t / T, end = n * (t + 1) / T;
      s += Eigen::Map<const Eigen::VectorXd>(a.data() + begin, static_cast<Eigen::Index>(end - begin)).sum();
    }
    tr.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    sink += s;
    t0 = Clock::now();
#pragma omp parallel for schedule(static)
    for (long i = 0; i < ln; ++i) c[static_cast<size_t>(i)] = a[static_cast<size_t>(i)];
    tc.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    t0 = Clock::now();
#pragma omp parallel for schedule(static)
    for (long i = 0; i < ln; ++i) a[static_cast<size_t>(i)] = b[static_cast<size_t>(i)] + 0.5 * c[static_cast<size_t>(i)];
    tt.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  if (sink == 42.0) std::printf(" ");
  const double bytes = static_cast<double>(n * sizeof(double));
  return {bytes / median(tr) / 1e9, 2 * bytes / median(tc) / 1e9, 3 * bytes / median(tt) / 1e9};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_traffic: a step's memory traffic against the machine's bandwidth"};
  std::string scene_file;
  int steps = 60, warmup = 10, threads = 1, repeat = 5;
  size_t stream_mb = 512;
  app.add_option("--scene", scene_file, "Scene file (a real-time tier scene)")->required();
  app.add_option("--steps", steps, "Measured steps")->capture_default_str();
  app.add_option("--warmup", warmup, "Steps before measuring (the first factorisation, the release)")->capture_default_str();
  app.add_option("--threads", threads, "Engine threads")->capture_default_str();
  app.add_option("--stream-mb", stream_mb, "Size of each bandwidth array, MB")->capture_default_str();
  app.add_option("--repeat", repeat, "Bandwidth passes (the median is kept)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  const int cores = std::max(1, omp_get_max_threads());
  const Stream one = measure_stream(1, stream_mb, repeat), all = measure_stream(cores, stream_mb, repeat);

  fiberfem::io::Scene scene = fiberfem::io::load_scene(scene_file);
  scene.settings.threads = threads;
  // The first factor waited for (made beside the first steps, the default from 20,000
  // free DOFs, the steps would solve with block Jacobi until its turn whatever its cost).
  // Where block Jacobi runs first (solver.jacobi_first) its steps are counted apart from
  // the factor's: their iterations move different bytes.
  scene.settings.solver.first_factorisation = core::FirstFactorisation::wait;
  if (scene.settings.solver.method != core::LinearSolverKind::pcg ||
      scene.settings.solver.preconditioner == core::PreconditionerKind::amg) {
    std::fprintf(stderr, "bench_traffic: %s: the count covers PCG with the cholesky or block_jacobi preconditioner only\n",
                 scene_file.c_str());
    return 2;
  }
  core::Simulator sim(scene.model, scene.settings);
  for (int i = 0; i < warmup; ++i) sim.step();
  // Steady steps only: a step that factorises (dense BLAS-3 work, bound by arithmetic) or
  // retries with substeps is counted apart. Kind 0: the factor (the warp's node rotations
  // in use), 1: block Jacobi.
  struct Sums {
    double assembly_s = 0, solve_s = 0;
    long iterations = 0;
    int steps = 0;
  } sums[2];
  int left_out = 0;
  for (int i = 0; i < steps; ++i) {
    const core::StepReport r = sim.step();
    // A step that did not factorise used the factor if there is one (the first is waited
    // for), else block Jacobi (first, solver.jacobi_first, or as the preconditioner).
    const int kind = sim.linear_solver().factor_info().factored ? 0 : 1;
    if (r.solver_factorizations > 0 || r.attempts > 1) {
      ++left_out;
      continue;
    }
    Sums& m = sums[kind];
    m.assembly_s += r.time.assembly_s;
    m.solve_s += r.time.solve_s;
    m.iterations += r.solver_iterations;
    ++m.steps;
  }
  const int steady = sums[0].steps + sums[1].steps;
  if (steady == 0) {
    std::fprintf(stderr, "bench_traffic: every measured step factorised or retried; try more --steps\n");
    return 1;
  }
  // Sizes.
  const core::SparseSystem& sys = sim.system();
  const double E = sim.model().mesh.num_elements(), N = sim.model().mesh.num_nodes(), n = sys.num_free();
  const double nnz = static_cast<double>(sys.matrix().nonZeros());
  const double blocks = (nnz / 9 + n / 3) / 2;  // upper 3 x 3 node blocks, the diagonal ones included
  const core::FactorInfo f = sim.linear_solver().factor_info();
  const double factor_bytes = f.factored ? f.nonzeros * (scene.settings.solver.single_precision_preconditioner ? 4 : 8) : 0;
  // Bytes per step of the element pass: per element its stored data (rest shape, fiber,
  // law, damping, nodes), block scatter indices (10 ints), the rotation and the warm start
  // read and written; the block store written (read for ownership, written); positions
  // read and forces written per node; the mass terms and the right-hand side.
  const double per_element = core::CorotatedLinearModel::pass_bytes_per_element() + 40 + 2 * (72 + 32);
  const double assembly_bytes = E * per_element + 2 * 72 * blocks + N * (24 + 2 * 24) + n * (8 * 6);
  // Bytes per PCG iteration: the block product (blocks and their column indices, x read, y
  // written) and about eight vector passes of the iteration's updates and dot products;
  // then with the factor, the factor applied forward and back and the warp's node rotations
  // twice; with block Jacobi, the inverted diagonal blocks.
  const double product = (72 + 4) * blocks + 8 * n * 3 + 8 * 8 * n;
  const double per_iteration[2] = {product + 2 * factor_bytes + 2 * 72 * (n / 3), product + 72 * (n / 3)};
  // Per solve: the recycled-solution projection (A W and the n x 8 basis read twice).
  const double per_solve = (72 + 4) * blocks + 3 * 8 * 8 * n;
  const double bw = threads > 1 ? all.read_gb_s : one.read_gb_s;
  std::printf("machine: %d cores; bandwidth, %zu MB arrays, median of %d: one thread read %.1f copy %.1f triad %.1f GB/s; "
              "%d threads read %.1f copy %.1f triad %.1f GB/s\n",
              cores, stream_mb, repeat, one.read_gb_s, one.copy_gb_s, one.triad_gb_s, cores, all.read_gb_s, all.copy_gb_s,
              all.triad_gb_s);
  std::printf("scene %s: %.0f elements, %.0f nodes, %.0f free DOFs, %.0f upper blocks, nnz(L) %.3g; %d threads; %d steady "
              "steps of %d after %d (%d factorised or retried, left out): %d with the factor, %d with block Jacobi\n\n",
              scene_file.c_str(), E, N, n, blocks, f.nonzeros, threads, steady, steps, warmup, left_out, sums[0].steps,
              sums[1].steps);
  std::printf("| phase | ms per steady step (mean) | bytes moved at least, MB | GB/s achieved | time at %.1f GB/s, ms | share of the phase |\n",
              bw);
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  const auto row = [&](const std::string& name, double ms, double bytes) {
    std::printf("| %s | %.3f | %.2f | %.1f | %.3f | %.0f %% |\n", name.c_str(), ms, bytes / 1e6, bytes / (ms * 1e-3) / 1e9,
                bytes / (bw * 1e9) * 1e3, 100 * bytes / (bw * 1e9) / (ms * 1e-3));
  };
  const char* kind_name[2] = {"the factor", "block Jacobi"};
  for (int kind = 0; kind < 2; ++kind) {
    const Sums& m = sums[kind];
    if (m.steps == 0) continue;
    const double its = static_cast<double>(m.iterations) / m.steps;
    const double asm_ms = 1e3 * m.assembly_s / m.steps, solve_ms = 1e3 * m.solve_s / m.steps;
    const double solve_bytes = per_iteration[kind] * its + per_solve;
    char solve_name[96];
    std::snprintf(solve_name, sizeof solve_name, "solve, %s (%.1f iterations)", kind_name[kind], its);
    row(std::string("element pass (steps with ") + kind_name[kind] + ")", asm_ms, assembly_bytes);
    row(solve_name, solve_ms, solve_bytes);
    row(std::string("step, ") + kind_name[kind], asm_ms + solve_ms, assembly_bytes + solve_bytes);
  }
  return 0;
}
