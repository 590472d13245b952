// bench_symmetric_product: what storing only the upper half of the step's matrix saves in
// its sparse products (docs/performance.md, "The block product and the warm-start
// projection"; the engine stores upper 3 x 3 blocks, the bsr-upper form below). On the
// paper-size benchmark beam's pattern (the SparseSystem of bench_step's small beam, all
// free DOFs but the clamped end), with symmetric values, it times y = A x four ways:
//   csr        both triangles stored, a row at a time (Eigen's product; the reference);
//   csr-upper  the same arrays with only the upper triangle kept, each entry used twice;
//   bsr-upper  3 x 3 node blocks, upper blocks only (one index per block, not per entry);
// on one thread, and the symmetric ones also on two (each thread with its own y, summed).
// Each is checked against the csr product (relative difference printed) and timed as the
// median of many repetitions; the figures are for deciding, not asserted.
//   bench_symmetric_product [--repeat N]

#include "core/builtin_scenes.hpp"
#include "core/sparse_system.hpp"

#include <CLI/CLI.hpp>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

namespace core = fiberfem::core;

namespace {

template <class F>
double median_us(int repeat, F&& f) {
  std::vector<double> t(static_cast<size_t>(repeat));
  for (double& v : t) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    v = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  }
  std::nth_element(t.begin(), t.begin() + repeat / 2, t.end());
  return t[static_cast<size_t>(repeat / 2)];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_symmetric_product: the sparse product with both triangles against the upper half"};
  int repeat = 2000;
  app.add_option("--repeat", repeat, "Repetitions per variant (the median is printed)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  repeat = std::max(repeat, 1);

  core::CantileverSpec spec;
  spec.box.size_m = {0.1, 0.01, 0.01};
  spec.box.cells = {48, 5, 4};  // bench_step's small beam: 5,760 tetrahedra
  const core::Model model = core::make_cantilever(spec);
  core::SparseSystem sys(model.mesh, model.fixed_dofs);
  core::SparseMatrix& A = sys.matrix();
  const int n = static_cast<int>(A.rows());
  const int* outer = A.outerIndexPtr();
  const int* inner = A.innerIndexPtr();
  double* val = A.valuePtr();
  // Symmetric values, distinct per entry pair, diagonally dominant.
  for (int r = 0; r < n; ++r)
    for (int p = outer[r]; p < outer[r + 1]; ++p) {
      const int c = inner[p], lo = std::min(r, c), hi = std::max(r, c);
      val[p] = r == c ? 100.0 : 1.0 / (1.0 + (lo * 7 + hi * 13) % 17);
    }

  // Upper triangle in CSR (diagonal first in each row).
  std::vector<int> uo(static_cast<size_t>(n) + 1), ui;
  std::vector<double> uv;
  for (int r = 0; r < n; ++r) {
    uo[static_cast<size_t>(r)] = static_cast<int>(ui.size());
    for (int p = outer[r]; p < outer[r + 1]; ++p)
      if (inner[p] >= r) {
        ui.push_back(inner[p]);
        uv.push_back(val[p]);
      }
  }
  uo[static_cast<size_t>(n)] = static_cast<int>(ui.size());
  // Upper node blocks (the free DOFs of a free node are consecutive; this beam's fixed
  // nodes are fixed in all three, so n is a multiple of 3 and free row 3I+i is node I's).
  if (n % 3 != 0) {
    std::fprintf(stderr, "bench_symmetric_product: expected whole free nodes\n");
    return 1;
  }
  const int nb = n / 3;
  std::vector<int> bo(static_cast<size_t>(nb) + 1), bi;
  std::vector<double> bv;
  for (int I = 0; I < nb; ++I) {
    bo[static_cast<size_t>(I)] = static_cast<int>(bi.size());
    const int r0 = 3 * I;
    for (int p = outer[r0]; p < outer[r0 + 1]; p += 3) {
      const int J = inner[p] / 3;
      if (J < I) continue;
      bi.push_back(J);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) bv.push_back(A.coeff(3 * I + i, 3 * J + j));
    }
  }
  bo[static_cast<size_t>(nb)] = static_cast<int>(bi.size());

  const Eigen::VectorXd x = Eigen::VectorXd::Random(n);
  Eigen::VectorXd y_ref(n), y(n);
  std::vector<Eigen::VectorXd> priv(2, Eigen::VectorXd::Zero(n));

  auto csr = [&](Eigen::VectorXd& out, int threads) {
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int r = 0; r < n; ++r) {
      double s = 0;
      for (int p = outer[r]; p < outer[r + 1]; ++p) s += val[p] * x[inner[p]];
      out[r] = s;
    }
  };
  auto csr_upper_rows = [&](Eigen::VectorXd& out, int begin, int end) {
    for (int r = begin; r < end; ++r) {
      const double xr = x[r];
      double s = uv[static_cast<size_t>(uo[static_cast<size_t>(r)])] * xr;
      for (int p = uo[static_cast<size_t>(r)] + 1; p < uo[static_cast<size_t>(r) + 1]; ++p) {
        const int c = ui[static_cast<size_t>(p)];
        s += uv[static_cast<size_t>(p)] * x[c];
        out[c] += uv[static_cast<size_t>(p)] * xr;
      }
      out[r] += s;
    }
  };
  auto bsr_upper_rows = [&](Eigen::VectorXd& out, int begin, int end) {
    for (int I = begin; I < end; ++I) {
      const double* xi = &x[3 * I];
      double s0 = 0, s1 = 0, s2 = 0;
      for (int k = bo[static_cast<size_t>(I)]; k < bo[static_cast<size_t>(I) + 1]; ++k) {
        const int J = bi[static_cast<size_t>(k)];
        const double* b = &bv[9 * static_cast<size_t>(k)];
        const double* xj = &x[3 * J];
        s0 += b[0] * xj[0] + b[1] * xj[1] + b[2] * xj[2];
        s1 += b[3] * xj[0] + b[4] * xj[1] + b[5] * xj[2];
        s2 += b[6] * xj[0] + b[7] * xj[1] + b[8] * xj[2];
        if (J != I) {
          double* yj = &out[3 * J];
          yj[0] += b[0] * xi[0] + b[3] * xi[1] + b[6] * xi[2];
          yj[1] += b[1] * xi[0] + b[4] * xi[1] + b[7] * xi[2];
          yj[2] += b[2] * xi[0] + b[5] * xi[1] + b[8] * xi[2];
        }
      }
      out[3 * I] += s0;
      out[3 * I + 1] += s1;
      out[3 * I + 2] += s2;
    }
  };
  // Symmetric products on two threads: each its half of the rows into its own y, then summed.
  auto two_threads = [&](auto&& rows, int count, int unit) {
#pragma omp parallel num_threads(2)
    {
      const int t = omp_get_thread_num(), nt = omp_get_num_threads();
      Eigen::VectorXd& mine = priv[static_cast<size_t>(t)];
      mine.setZero();
      rows(mine, count * t / nt, count * (t + 1) / nt);
#pragma omp barrier
      const int begin = unit * (count * t / nt), end = unit * (count * (t + 1) / nt);
      for (int r = begin; r < end; ++r) y[r] = nt == 2 ? priv[0][r] + priv[1][r] : mine[r];
    }
  };

  csr(y_ref, 1);
  std::printf("beam of %d tets: %d free DOFs, %ld stored entries (both triangles), %zu upper entries, %zu upper node blocks\n",
              model.mesh.num_elements(), n, static_cast<long>(A.nonZeros()), ui.size(), bi.size());
  std::printf("| product | threads | median us | relative difference from csr |\n|---|---:|---:|---:|\n");
  // One table row: the median time of `product` and its result's difference from csr's.
  auto row = [&](const char* name, int threads, auto&& product) {
    const double us = median_us(repeat, product);
    std::printf("| %s | %d | %.1f | %.1e |\n", name, threads, us, (y - y_ref).norm() / y_ref.norm());
  };
  row("csr", 1, [&] { csr(y, 1); });
  row("csr", 2, [&] { csr(y, 2); });
  row("csr-upper", 1, [&] {
    y.setZero();
    csr_upper_rows(y, 0, n);
  });
  row("csr-upper", 2, [&] { two_threads(csr_upper_rows, n, 1); });
  row("bsr-upper", 1, [&] {
    y.setZero();
    bsr_upper_rows(y, 0, nb);
  });
  row("bsr-upper", 2, [&] { two_threads(bsr_upper_rows, nb, 3); });
  return 0;
}
