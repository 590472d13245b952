#include "core/hyperelastic/tangent_solver.hpp"

#include "core/blas_threads.hpp"
#include "core/team_affinity.hpp"

#include <Eigen/SparseLU>
#ifdef FIBERFEM_HAVE_UMFPACK
#include <Eigen/UmfPackSupport>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>
#include <stdexcept>

#include <omp.h>

namespace fiberfem::core::hyperelastic {

namespace {

#ifdef FIBERFEM_HAVE_UMFPACK
// UMFPACK's LU with its numeric object in reach (for FloatLU), in its 64-bit-index form
// (umfpack_dl; the matrix copied to 64-bit indices at each factorisation): the 32-bit form
// runs out of its int-indexed workspace on mixed problems of about 150,000 unknowns (Land
// problem 3 on lv_ellipsoid 60 / 25 / 5 failed to factorise at the rest state).
using LongMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, SuiteSparse_long>;
class LU : public Eigen::UmfPackLU<LongMatrix> {
  using Base = Eigen::UmfPackLU<LongMatrix>;

 public:
  void* numeric() const { return m_numeric; }
  void analyzePattern(const SparseMatrix& A) {
    a_ = A;
    Base::analyzePattern(a_);
  }
  void factorize(const SparseMatrix& A) {  // A with the pattern analysed (UMFPACK's rule): its values copied
    if (A.isCompressed() && A.nonZeros() == a_.nonZeros() && A.rows() == a_.rows())
      std::copy(A.valuePtr(), A.valuePtr() + A.nonZeros(), a_.valuePtr());
    else
      a_ = A;
    Base::factorize(a_);
  }

 private:
  LongMatrix a_;  // the matrix in 64-bit indices; UMFPACK's solve reads it too
};

// A single-precision copy of UMFPACK's factors, P (R A) Q = L U (R the row scaling), to
// apply a lagged factor as GMRES's preconditioner: L by rows, U by columns, each
// substitution one pass over its values. UMFPACK's own solve walks its packed frontal
// form; on Land problem 2's shipped mesh (10,278 unknowns, 3.1 M entries in each of L and
// U) the copy applies in about half the time, and GMRES corrects the rounding.
//
// The factors are supernodal, so a row of L (a column of U) is a few runs of consecutive
// indices: about 78 entries a run on the Land meshes. Each run is kept as its first index
// and length, so a substitution reads 4 bytes an entry (not 8 with an index each) and its
// inner loops are dense dot products and updates, vectorised.
class FloatLU {
 public:
  bool build(const LU& lu, int n) {
    ok_ = false;
    using Long = SuiteSparse_long;
    Long lnz = 0, unz = 0, rows = 0, cols = 0, nz_udiag = 0;
    if (umfpack_dl_get_lunz(&lnz, &unz, &rows, &cols, &nz_udiag, lu.numeric()) != UMFPACK_OK || rows != n || cols != n)
      return false;
    // L and U: UMFPACK hands each out in double with 64-bit indices (16 bytes an entry).
    // On two threads they are copied side by side when both fit in kSideBySideBytes;
    // otherwise one after the other, so that only one factor's copy is alive at a time (on
    // Land problem 3 at 155,559 unknowns each is several GB).
    static constexpr double kSideBySideBytes = 1024.0 * 1024.0 * 1024.0;
    std::vector<Long> P(static_cast<size_t>(n)), Q(static_cast<size_t>(n));
    std::vector<double> Rs(static_cast<size_t>(n));
    auto copy_l = [&] {
      std::vector<Long> Lp(static_cast<size_t>(n) + 1), Lj(static_cast<size_t>(lnz));
      std::vector<double> Lx(static_cast<size_t>(lnz));
      Long do_recip = 0;
      if (umfpack_dl_get_numeric(Lp.data(), Lj.data(), Lx.data(), nullptr, nullptr, nullptr, P.data(), Q.data(), nullptr,
                                 &do_recip, Rs.data(), lu.numeric()) != UMFPACK_OK)
        return false;
      scale_.resize(static_cast<size_t>(n));
      for (int i = 0; i < n; ++i)
        scale_[static_cast<size_t>(i)] = do_recip ? Rs[static_cast<size_t>(i)] : 1.0 / Rs[static_cast<size_t>(i)];
      // Rows of L without their unit diagonal (stored last).
      l_.clear(n, static_cast<size_t>(lnz - n));
      for (int i = 0; i < n; ++i) {
        const Long k0 = Lp[static_cast<size_t>(i)], k1 = Lp[static_cast<size_t>(i) + 1] - 1;
        l_.add_line(Lj.data() + k0, Lx.data() + k0, k1 - k0);
      }
      p_.assign(P.begin(), P.end());
      q_.assign(Q.begin(), Q.end());
      return true;
    };
    auto copy_u = [&] {
      std::vector<Long> Up(static_cast<size_t>(n) + 1), Ui(static_cast<size_t>(unz));
      std::vector<double> Ux(static_cast<size_t>(unz));
      if (umfpack_dl_get_numeric(nullptr, nullptr, nullptr, Up.data(), Ui.data(), Ux.data(), nullptr, nullptr, nullptr,
                                 nullptr, nullptr, lu.numeric()) != UMFPACK_OK)
        return false;
      // Columns of U with the diagonal (stored last) kept apart as its reciprocal.
      u_.clear(n, static_cast<size_t>(unz - n));
      inv_diag_.resize(static_cast<size_t>(n));
      for (int j = 0; j < n; ++j) {
        const Long last = Up[static_cast<size_t>(j) + 1] - 1;
        if (last < Up[static_cast<size_t>(j)] || Ui[static_cast<size_t>(last)] != j || Ux[static_cast<size_t>(last)] == 0.0)
          return false;  // a zero pivot: UMFPACK's own solve reports it
        const Long k0 = Up[static_cast<size_t>(j)];
        u_.add_line(Ui.data() + k0, Ux.data() + k0, last - k0);
        inv_diag_[static_cast<size_t>(j)] = static_cast<float>(1.0 / Ux[static_cast<size_t>(last)]);
      }
      return true;
    };
    bool l_ok = false, u_ok = false;
    if (threads_ >= 2 && 16.0 * static_cast<double>(lnz + unz) <= kSideBySideBytes) {
      const int cpu = current_cpu();
#pragma omp parallel num_threads(2)
      {
        keep_team_apart(cpu);
        const int t = omp_get_thread_num(), team = omp_get_num_threads();
        if (t == 0) l_ok = copy_l();
        if (t == 1 || team == 1) u_ok = copy_u();
      }
    } else {
      l_ok = copy_l() && (u_ok = copy_u());
    }
    if (!l_ok || !u_ok) return false;
    w_.resize(static_cast<size_t>(n));
    plan_split();
    ok_ = true;
    return true;
  }
  bool ok() const { return ok_; }
  int parts() const { return !ok_ ? 0 : split_.a > 0 ? 2 : 1; }
  /// Substitutions on up to `threads` threads (two at most are used; one when the factor has
  /// no two independent parts worth splitting). The result does not depend on the count.
  void set_threads(int threads) { threads_ = threads; }
  template <typename Rhs>
  Eigen::VectorXd solve(const Rhs& b) const {
    const int n = static_cast<int>(p_.size());
    float* w = w_.data();
    auto rhs = [&](int k) {
      const int i = p_[static_cast<size_t>(k)];
      return static_cast<float>(scale_[static_cast<size_t>(i)] * b(i));
    };
    const Split& sp = split_;
    if (sp.a == 0) {
      // L y = P R b by rows, then U z = y by columns from the last.
      for (int k = 0; k < n; ++k) w[k] = rhs(k) - dot(l_, static_cast<size_t>(k), w);
      for (int j = n - 1; j >= 0; --j) {
        w[j] *= inv_diag_[static_cast<size_t>(j)];
        subtract(u_, static_cast<size_t>(j), w[j], w);
      }
    } else if (threads_ < 2) {
      for (int part = 0; part < 2; ++part) lower_part(rhs, part, w);
      for (int part = 0; part < 2; ++part) lower_rest(rhs, part, w);
      rest_triangles(w);
      for (int part = 0; part < 2; ++part) upper_part(part, w);
    } else {
      const int cpu = current_cpu();
#pragma omp parallel num_threads(2)
      {
        keep_team_apart(cpu);
        const int t = omp_get_thread_num(), team = omp_get_num_threads();
        for (int part = t; part < 2; part += team) lower_part(rhs, part, w);
#pragma omp barrier
        for (int part = t; part < 2; part += team) lower_rest(rhs, part, w);
#pragma omp barrier
#pragma omp master
        rest_triangles(w);
#pragma omp barrier
        for (int part = t; part < 2; part += team) upper_part(part, w);
      }
    }
    Eigen::VectorXd x(n);
    for (int k = 0; k < n; ++k) x(q_[static_cast<size_t>(k)]) = static_cast<double>(w[k]);
    return x;
  }

 private:
  struct Runs;
  using Span = Eigen::Map<Eigen::VectorXf>;
  using ConstSpan = Eigen::Map<const Eigen::VectorXf>;
  // Line k of `lines` dotted with w.
  static float dot(const Runs& lines, size_t k, const float* w) {
    float s = 0;
    const float* x = lines.x.data() + lines.first_value[k];
    for (size_t r = lines.first_run[k]; r < lines.first_run[k + 1]; ++r) {
      const int len = lines.run_length[r];
      s += ConstSpan(x, len).dot(ConstSpan(w + lines.run_start[r], len));
      x += len;
    }
    return s;
  }
  // w -= z (line k of `lines`).
  static void subtract(const Runs& lines, size_t k, float z, float* w) {
    const float* x = lines.x.data() + lines.first_value[k];
    for (size_t r = lines.first_run[k]; r < lines.first_run[k + 1]; ++r) {
      const int len = lines.run_length[r];
      Span(w + lines.run_start[r], len) -= z * ConstSpan(x, len);
      x += len;
    }
  }

  // The phases of a split solve (Split), each of part 0 or 1 on its own thread.
  // L's rows of the part: [0, a) or l_b.
  template <class Rhs>
  void lower_part(const Rhs& rhs, int part, float* w) const {
    if (part == 0)
      for (int k = 0; k < split_.a; ++k) w[k] = rhs(k) - dot(l_, static_cast<size_t>(k), w);
    else
      for (const int k : split_.l_b) w[k] = rhs(k) - dot(l_, static_cast<size_t>(k), w);
  }
  // L's rows l_s, their entries in the parts' columns: the first or second half of them.
  template <class Rhs>
  void lower_rest(const Rhs& rhs, int part, float* w) const {
    const Split& sp = split_;
    for (size_t i = part == 0 ? 0 : sp.l_s_half; i < (part == 0 ? sp.l_s_half : sp.l_s.size()); ++i)
      w[sp.l_s[i]] = rhs(sp.l_s[i]) - dot(sp.l_s_out, i, w);
  }
  // The rest's triangles: L's rows l_s on their own columns, U's columns u_s on their rows.
  void rest_triangles(float* w) const {
    const Split& sp = split_;
    for (size_t i = 0; i < sp.l_s.size(); ++i) w[sp.l_s[i]] -= dot(sp.l_s_in, i, w);
    for (size_t i = sp.u_s.size(); i-- > 0;) {
      const int j = sp.u_s[i];
      w[j] *= inv_diag_[static_cast<size_t>(j)];
      subtract(sp.u_s_in, i, w[j], w);
    }
  }
  // U's columns u_s on the part's rows, then the part's columns ([0, a) or u_b) from the last.
  void upper_part(int part, float* w) const {
    const Split& sp = split_;
    const Runs& rest = part == 0 ? sp.u_s_first : sp.u_s_second;
    for (size_t i = sp.u_s.size(); i-- > 0;) subtract(rest, i, w[sp.u_s[i]], w);
    auto column = [&](int j) {
      w[j] *= inv_diag_[static_cast<size_t>(j)];
      subtract(u_, static_cast<size_t>(j), w[j], w);
    };
    if (part == 0)
      for (int j = sp.a - 1; j >= 0; --j) column(j);
    else
      for (size_t i = sp.u_b.size(); i-- > 0;) column(sp.u_b[i]);
  }

  // Sparse lines (rows of L, columns of U) as runs of consecutive indices.
  struct Runs {
    std::vector<size_t> first_run, first_value;  // per line; may pass 2^31
    std::vector<int> run_start, run_length;      // per run
    std::vector<float> x;                        // the values, line after line
    int last_index = -2;
    void clear(int lines, size_t values) {
      first_run.assign(1, 0);
      first_value.assign(1, 0);
      first_run.reserve(static_cast<size_t>(lines) + 1);
      first_value.reserve(static_cast<size_t>(lines) + 1);
      run_start.clear();
      run_length.clear();
      x.clear();
      x.reserve(values);
      last_index = -2;
    }
    // A line of `count` entries in double: its runs (indices that follow one another) and its
    // values rounded to single precision.
    template <class Index>
    void add_line(const Index* index, const double* value, Index count) {
      size_t out = x.size();
      x.resize(out + static_cast<size_t>(count));
      for (Index k = 0; k < count;) {
        Index e = k + 1;
        while (e < count && index[e] == index[e - 1] + 1) ++e;
        run_start.push_back(static_cast<int>(index[k]));
        run_length.push_back(static_cast<int>(e - k));
        for (; k < e; ++k) x[out++] = static_cast<float>(value[k]);
      }
      close_line();
    }
    // Values v of the consecutive indices [start, start + len).
    void add_block(int start, int len, const float* v) {
      if (start == last_index + 1)
        run_length.back() += len;
      else {
        run_start.push_back(start);
        run_length.push_back(len);
      }
      last_index = start + len - 1;
      x.insert(x.end(), v, v + len);
    }
    void close_line() {
      first_run.push_back(run_start.size());
      first_value.push_back(x.size());
      last_index = -2;
    }
  };
  // The substitutions on two threads. L's rows [0, a) depend only on rows before them;
  // the rows from a whose dependences all lie in rows from a of the same kind (l_b) do not
  // depend on them: the two go side by side. The other rows (l_s: in a nested-dissection
  // order with a where the first half's subtree ends, the separator above both halves)
  // come after: their entries in columns of the two parts on two threads, then their
  // entries in l_s's own columns (a dense triangle) on one. U backwards alike: the columns
  // u_s first, on their rows in u_s only, then their entries in rows below a beside those
  // in rows of u_b, each thread going on with its part's columns. Every row takes the same
  // operations in the same order on one thread or two.
  struct Split {
    int a = 0;  // 0: no split
    std::vector<int> l_b, l_s, u_b, u_s;  // ascending
    size_t l_s_half = 0;                  // l_s's rows [0, half) on the first thread for l_s_out
    Runs l_s_out, l_s_in;                 // rows l_s (in that order): entries outside l_s, in l_s
    Runs u_s_in, u_s_first, u_s_second;   // columns u_s: entries in rows of u_s, below a, of u_b
  };

  // lo[k]: the first line that line k depends on through any chain of lines (k if none). The
  // lines from a that depend on no line below a are those with lo >= a.
  static std::vector<int> first_dependence(const Runs& lines, int n) {
    std::vector<int> lo(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) {
      int m = k;
      for (size_t r = lines.first_run[static_cast<size_t>(k)]; r < lines.first_run[static_cast<size_t>(k) + 1]; ++r)
        for (int c = lines.run_start[r]; c < lines.run_start[r] + lines.run_length[r]; ++c) m = std::min(m, lo[static_cast<size_t>(c)]);
      lo[static_cast<size_t>(k)] = m;
    }
    return lo;
  }

  // Appends the entries of `from`'s line k whose index passes `keep` as one line of `to`.
  template <class Keep>
  static void copy_line(const Runs& from, int k, Keep&& keep, Runs& to) {
    const float* x = from.x.data() + from.first_value[static_cast<size_t>(k)];
    for (size_t r = from.first_run[static_cast<size_t>(k)]; r < from.first_run[static_cast<size_t>(k) + 1]; ++r) {
      const int start = from.run_start[r], end = start + from.run_length[r];
      for (int c = start; c < end;) {
        if (!keep(c)) {
          ++c;
          continue;
        }
        int e = c + 1;
        while (e < end && keep(e)) ++e;
        to.add_block(c, e - c, x + (c - start));
        c = e;
      }
      x += end - start;
    }
    to.close_line();
  }

  // Empties the lines marked in `drop`, in place.
  static void drop_lines(Runs& lines, const std::vector<char>& drop) {
    const size_t n = lines.first_run.size() - 1;
    size_t run_out = 0, value_out = 0;
    for (size_t k = 0; k < n; ++k) {
      const size_t r0 = lines.first_run[k], r1 = lines.first_run[k + 1];
      const size_t v0 = lines.first_value[k], v1 = lines.first_value[k + 1];
      lines.first_run[k] = run_out;
      lines.first_value[k] = value_out;
      if (drop[k]) continue;
      for (size_t r = r0; r < r1; ++r, ++run_out) {
        lines.run_start[run_out] = lines.run_start[r];
        lines.run_length[run_out] = lines.run_length[r];
      }
      std::copy(lines.x.begin() + static_cast<std::ptrdiff_t>(v0), lines.x.begin() + static_cast<std::ptrdiff_t>(v1),
                lines.x.begin() + static_cast<std::ptrdiff_t>(value_out));
      value_out += v1 - v0;
    }
    lines.first_run[n] = run_out;
    lines.first_value[n] = value_out;
    lines.run_start.resize(run_out);
    lines.run_length.resize(run_out);
    lines.x.resize(value_out);
  }

  // Chooses a for the least estimated time on two threads and rearranges the factors for
  // it; no split unless that time is under kSplitGain of one thread's.
  void plan_split() {
    static constexpr int kMinSize = 2000;
    static constexpr double kSplitGain = 0.8;
    split_ = Split();
    const int n = static_cast<int>(p_.size());
    if (n < kMinSize) return;
    auto line_work = [n](const Runs& lines) {
      std::vector<double> work(static_cast<size_t>(n));
      for (size_t k = 0; k < static_cast<size_t>(n); ++k)  // values, plus a loop's set-up per run and per line
        work[k] = static_cast<double>(lines.first_value[k + 1] - lines.first_value[k]) +
                  8.0 * static_cast<double>(lines.first_run[k + 1] - lines.first_run[k]) + 8.0;
      return work;
    };
    const std::vector<double> wl = line_work(l_), wu = line_work(u_);
    const std::vector<int> lo_l = first_dependence(l_, n), lo_u = first_dependence(u_, n);
    // below[a]: work of lines below a; from[a]: work of lines with lo >= a.
    auto below_from = [n](const std::vector<double>& w, const std::vector<int>& lo, std::vector<double>& below,
                          std::vector<double>& from) {
      below.assign(static_cast<size_t>(n) + 1, 0.0);
      from.assign(static_cast<size_t>(n) + 1, 0.0);
      for (size_t k = 0; k < static_cast<size_t>(n); ++k) {
        below[k + 1] = below[k] + w[k];
        from[static_cast<size_t>(lo[k])] += w[k];
      }
      for (int a = n - 1; a >= 0; --a) from[static_cast<size_t>(a)] += from[static_cast<size_t>(a) + 1];
    };
    std::vector<double> below_l, from_l, below_u, from_u;
    below_from(wl, lo_l, below_l, from_l);
    below_from(wu, lo_u, below_u, from_u);
    const double total = below_l[static_cast<size_t>(n)] + below_u[static_cast<size_t>(n)];
    // The rest's lines: their entries in the two parts go on two threads, those among
    // themselves (about a dense triangle of m lines in each factor) on one.
    std::vector<int> lines_from(static_cast<size_t>(n) + 1, 0);  // lines with lo_l >= a
    for (size_t k = 0; k < static_cast<size_t>(n); ++k) ++lines_from[static_cast<size_t>(lo_l[k])];
    for (int a = n - 1; a >= 0; --a) lines_from[static_cast<size_t>(a)] += lines_from[static_cast<size_t>(a) + 1];
    double best = kSplitGain * total;
    int best_a = 0;
    for (int a = 1; a < n; ++a) {
      const size_t i = static_cast<size_t>(a);
      const double rest = total - below_l[i] - from_l[i] - below_u[i] - from_u[i];
      const double m = static_cast<double>(n - a - lines_from[i]);
      const double among = std::min(rest, m * m);
      const double time = std::max(below_l[i], from_l[i]) + std::max(below_u[i], from_u[i]) + 0.5 * (rest - among) + among;
      if (time < best) best = time, best_a = a;
    }
    if (best_a == 0) return;
    const int a = best_a;
    Split& sp = split_;
    sp.a = a;
    std::vector<char> in_l_s(static_cast<size_t>(n), 0), in_u_s(static_cast<size_t>(n), 0);
    for (int k = a; k < n; ++k) {
      const bool l_b = lo_l[static_cast<size_t>(k)] >= a, u_b = lo_u[static_cast<size_t>(k)] >= a;
      (l_b ? sp.l_b : sp.l_s).push_back(k);
      (u_b ? sp.u_b : sp.u_s).push_back(k);
      in_l_s[static_cast<size_t>(k)] = !l_b;
      in_u_s[static_cast<size_t>(k)] = !u_b;
    }
    // l_s's rows: their entries outside l_s (halved by work between the threads) and in it.
    double out_work = 0;
    sp.l_s_out.clear(static_cast<int>(sp.l_s.size()), 0);
    sp.l_s_in.clear(static_cast<int>(sp.l_s.size()), 0);
    for (const int k : sp.l_s) {
      copy_line(l_, k, [&](int c) { return !in_l_s[static_cast<size_t>(c)]; }, sp.l_s_out);
      copy_line(l_, k, [&](int c) { return static_cast<bool>(in_l_s[static_cast<size_t>(c)]); }, sp.l_s_in);
      out_work += static_cast<double>(sp.l_s_out.first_value.back() - sp.l_s_out.first_value[sp.l_s_out.first_value.size() - 2]);
    }
    double half = 0;
    for (sp.l_s_half = 0; sp.l_s_half < sp.l_s.size() && half < 0.5 * out_work; ++sp.l_s_half)
      half += static_cast<double>(sp.l_s_out.first_value[sp.l_s_half + 1] - sp.l_s_out.first_value[sp.l_s_half]);
    // u_s's columns: their entries in u_s's rows, in rows below a, in u_b's rows.
    for (Runs* r : {&sp.u_s_in, &sp.u_s_first, &sp.u_s_second}) r->clear(static_cast<int>(sp.u_s.size()), 0);
    for (const int j : sp.u_s) {
      copy_line(u_, j, [&](int c) { return static_cast<bool>(in_u_s[static_cast<size_t>(c)]); }, sp.u_s_in);
      copy_line(u_, j, [&](int c) { return c < a; }, sp.u_s_first);
      copy_line(u_, j, [&](int c) { return c >= a && !in_u_s[static_cast<size_t>(c)]; }, sp.u_s_second);
    }
    drop_lines(l_, in_l_s);
    drop_lines(u_, in_u_s);
  }

  bool ok_ = false;
  std::vector<int> p_, q_;  // permutations
  Runs l_, u_;
  std::vector<float> inv_diag_;
  std::vector<double> scale_;
  mutable std::vector<float> w_;
  Split split_;
  int threads_ = 1;
};
#else
using LU = Eigen::SparseLU<SparseMatrix>;
#endif

// GMRES preconditioned on the right by a lagged factor M, the preconditioned directions
// z = M^-1 v kept (flexible GMRES, so a factor applied in single precision still gives an
// exact residual): x = Z y minimises |K x - b| over the directions found, and that norm
// is known at each iteration from the Hessenberg system. One application of the factor
// and one product with K an iteration, where BiCGSTAB makes two of each, and the stopping
// test is on the true residual, as Newton's forcing asks. No restart: the caller factorises
// afresh when `max_iterations` do not suffice. @return whether |K x - b| <= tol |b|.
template <class Factor>
bool lagged_gmres(const SparseMatrix& K, const Eigen::VectorXd& b, const Factor& M, double tol, int max_iterations,
                  Eigen::VectorXd& x, int& iterations);

// The same from the guess x (from zero where the guess is no nearer): GMRES on the guess's
// residual to the same |K x - b| <= tol |b|, its correction added.
template <class Factor>
bool lagged_gmres_from(const SparseMatrix& K, const Eigen::VectorXd& b, const Factor& M, double tol, int max_iterations,
                       Eigen::VectorXd& x, int& iterations) {
  iterations = 0;
  const Eigen::VectorXd r = b - K * x;
  const double r_norm = r.norm(), b_norm = b.norm(), target = tol * b_norm;
  if (r_norm <= target) return true;
  if (!(r_norm < b_norm)) return lagged_gmres(K, b, M, tol, max_iterations, x, iterations);
  Eigen::VectorXd e;
  if (!lagged_gmres(K, r, M, target / r_norm, max_iterations, e, iterations)) return false;
  x += e;
  return x.allFinite();
}

template <class Factor>
bool lagged_gmres(const SparseMatrix& K, const Eigen::VectorXd& b, const Factor& M, double tol, int max_iterations,
                  Eigen::VectorXd& x, int& iterations) {
  const Eigen::Index n = b.size();
  const int m = max_iterations;
  iterations = 0;
  const double b_norm = b.norm();
  if (!(b_norm > 0.0)) {
    x.setZero(n);
    return b_norm == 0.0;
  }
  Eigen::MatrixXd V(n, m + 1), Z(n, m);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(m + 1, m);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(m + 1), cs(m), sn(m);
  V.col(0) = b / b_norm;
  g(0) = b_norm;
  Eigen::VectorXd w(n);
  for (int j = 0; j < m; ++j) {
    Z.col(j) = M.solve(V.col(j));
    w.noalias() = K * Z.col(j);
    for (int i = 0; i <= j; ++i) {  // modified Gram-Schmidt
      H(i, j) = V.col(i).dot(w);
      w.noalias() -= H(i, j) * V.col(i);
    }
    H(j + 1, j) = w.norm();
    for (int i = 0; i < j; ++i) {  // the earlier rotations on the new column
      const double t = cs(i) * H(i, j) + sn(i) * H(i + 1, j);
      H(i + 1, j) = -sn(i) * H(i, j) + cs(i) * H(i + 1, j);
      H(i, j) = t;
    }
    const double r = std::hypot(H(j, j), H(j + 1, j));
    if (!(r > 0.0) || !std::isfinite(r)) break;  // breakdown or a NaN: no solution from here
    cs(j) = H(j, j) / r;
    sn(j) = H(j + 1, j) / r;
    const double h_next = H(j + 1, j);
    H(j, j) = r;
    H(j + 1, j) = 0.0;
    g(j + 1) = -sn(j) * g(j);
    g(j) = cs(j) * g(j);
    iterations = j + 1;
    if (std::abs(g(j + 1)) <= tol * b_norm || h_next == 0.0) {
      const Eigen::VectorXd y =
          H.topLeftCorner(j + 1, j + 1).triangularView<Eigen::Upper>().solve(g.head(j + 1));
      x.noalias() = Z.leftCols(j + 1) * y;
      return x.allFinite();
    }
    V.col(j + 1) = w / h_next;
  }
  return false;
}
}  // namespace

struct TangentSolver::Factor {
  Factor();
  LU lu;
#ifdef FIBERFEM_HAVE_UMFPACK
  FloatLU lagged;  // lu's factors in single precision, for the lagged solves
#endif
  bool analysed = false;
  /// After lu.factorize: the single-precision copy (where there is one).
  void copy_factor(int n, int threads) {
#ifdef FIBERFEM_HAVE_UMFPACK
    lagged.set_threads(threads);
    if (lu.info() != Eigen::Success || !lagged.build(lu, n)) lagged = FloatLU();  // none: UMFPACK's own solve
#else
    (void)n;
    (void)threads;
#endif
  }
};

TangentSolver::Factor::Factor() {
#ifdef FIBERFEM_HAVE_UMFPACK
  // The tangent is symmetric in pattern (in value but for a follower load's stiffness):
  // UMFPACK's symmetric strategy orders A + A^T by nested dissection (METIS) instead of its
  // unsymmetric column ordering, which filled about twice as much on the Land beam.
  lu.umfpackControl()(UMFPACK_STRATEGY) = UMFPACK_STRATEGY_SYMMETRIC;
  lu.umfpackControl()(UMFPACK_ORDERING) = UMFPACK_ORDERING_METIS;
  // No iterative refinement inside a solve: GMRES refines (against the current tangent,
  // which a lagged factor's refinement would not), and Newton's forcing sets the accuracy.
  lu.umfpackControl()(UMFPACK_IRSTEP) = 0;
#endif
}

TangentSolver::TangentSolver(bool keeps_state) : factor_(std::make_unique<Factor>()), keeps_state_(keeps_state) {}

TangentSolver::~TangentSolver() = default;

int TangentSolver::lagged_parts() const {
#ifdef FIBERFEM_HAVE_UMFPACK
  return have_factor_ ? factor_->lagged.parts() : 0;
#else
  return 0;
#endif
}

bool TangentSolver::factorise(const SparseMatrix& K) {
  if (!factor_->analysed) {
    factor_->lu.analyzePattern(K);
    factor_->analysed = true;
    if (keeps_state_) analysed_ = K;
  }
  // OpenBLAS on the engine's threads for the dense fronts only (elsewhere it stays on one:
  // its threads spin after each call beside the engine's loops). The blocks of a front's
  // product are split between the threads whole, so the factor is the same on one thread
  // or two (checked: Land problem 2's probes equal to the last digit).
  blas::with_threads(threads_, [&] { factor_->lu.factorize(K); });
  factor_->copy_factor(static_cast<int>(K.rows()), threads_);
  ++factorisations_;
  have_factor_ = factor_->lu.info() == Eigen::Success;
  if (keeps_state_) factored_ = have_factor_ ? K : SparseMatrix();
  return have_factor_;
}

void TangentSolver::take_memory(TangentSolver& other) {
  std::swap(factor_, other.factor_);
  std::swap(have_factor_, other.have_factor_);
  std::swap(analysed_, other.analysed_);
  std::swap(factored_, other.factored_);
  other.factor_ = std::make_unique<Factor>();
  other.have_factor_ = false;
  other.analysed_ = SparseMatrix();
  other.factored_ = SparseMatrix();
}

// The symbolic analysis reads the values too (UMFPACK's pivot preferences), so it is made
// again from the very matrix it was made from, then the factor from its own.
void TangentSolver::restore(const State& state) {
  auto factor = std::make_unique<Factor>();
  bool have = false;
  if (state.analysed.rows() > 0) {
    factor->lu.analyzePattern(state.analysed);
    factor->analysed = true;
  }
  if (state.factored.rows() > 0) {
    if (!factor->analysed) throw std::invalid_argument("tangent solver state: a factor without its analysis");
    factor->lu.factorize(state.factored);
    if (factor->lu.info() != Eigen::Success) throw std::invalid_argument("tangent solver state: its matrix does not factorise");
    factor->copy_factor(static_cast<int>(state.factored.rows()), threads_);
    have = true;
  }
  factor_ = std::move(factor);
  have_factor_ = have;
  analysed_ = state.analysed;
  factored_ = state.factored;
}

bool TangentSolver::solve(const SparseMatrix& K, const Eigen::VectorXd& R, double forcing, bool fresh, Eigen::VectorXd& delta,
                          bool warm) {
  const auto t0 = std::chrono::steady_clock::now();
  bool ok = false;
  if (have_factor_ && !fresh) {
    int iterations = 0;
    warm = warm && delta.size() == R.size() && delta.allFinite();
    const auto gmres = [&](const auto& M) {
      return warm ? lagged_gmres_from(K, R, M, forcing, kMaxKrylovIterations, delta, iterations)
                  : lagged_gmres(K, R, M, forcing, kMaxKrylovIterations, delta, iterations);
    };
#ifdef FIBERFEM_HAVE_UMFPACK
    if (factor_->lagged.ok()) {
      factor_->lagged.set_threads(threads_);
      ok = gmres(factor_->lagged);
    } else
      ok = gmres(factor_->lu);
#else
    ok = gmres(factor_->lu);
#endif
    krylov_iterations_ += iterations;
  }
  if (!ok && factorise(K)) {
    delta = factor_->lu.solve(R);
    ok = delta.allFinite();
  }
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return ok;
}

}  // namespace fiberfem::core::hyperelastic
