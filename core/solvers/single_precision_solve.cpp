#include "core/solvers/single_precision_solve.hpp"

#ifdef FIBERFEM_HAVE_CHOLMOD
#include <algorithm>

namespace fiberfem::core::detail {

bool SinglePrecisionSupernodalSolve::build(const cholmod_factor* L) {
  ok_ = false;
  if (!L || !L->is_super || !L->is_ll || L->xtype != CHOLMOD_REAL || L->dtype != CHOLMOD_DOUBLE) return false;
  const auto index = [&](const void* p, size_t k) -> long {
    return L->itype == CHOLMOD_LONG ? static_cast<long>(static_cast<const SuiteSparse_long*>(p)[k])
                                    : static_cast<long>(static_cast<const int*>(p)[k]);
  };
  n_ = static_cast<int>(L->n);
  const size_t ns = L->nsuper;
  super_.resize(ns + 1);
  pi_.resize(ns + 1);
  px_.resize(ns + 1);
  for (size_t k = 0; k <= ns; ++k) {
    super_[k] = index(L->super, k);
    pi_[k] = index(L->pi, k);
    px_[k] = index(L->px, k);
  }
  rows_.resize(static_cast<size_t>(pi_[ns]));
  for (size_t k = 0; k < rows_.size(); ++k) rows_[k] = static_cast<int>(index(L->s, k));
  perm_.resize(static_cast<size_t>(n_));
  for (size_t k = 0; k < perm_.size(); ++k) perm_[k] = static_cast<int>(index(L->Perm, k));
  const double* x = static_cast<const double*>(L->x);
  values_.assign(x, x + px_[ns]);
  split_tree();
  w_.resize(n_ + 2 * static_cast<Eigen::Index>(top_cols_.size()));
  for (auto& t : t_) t.resize(n_);
  ok_ = true;
  return true;
}

// Splits the supernodal elimination tree (postordered: a subtree is a contiguous range
// of supernodes ending at its root) into two parts of disjoint subtrees plus the top,
// greedily: starting from the roots, the heaviest subtree is moved to the top and
// replaced by its children while that lowers top + the larger part (weights: entries of
// L, the memory a solve reads). Kept only if it would cut the solve below 0.85 of serial.
void SinglePrecisionSupernodalSolve::split_tree() {
  for (auto& r : ranges_) r.clear();
  top_.clear();
  top_cols_.clear();
  target_.clear();
  const int ns = static_cast<int>(super_.size()) - 1;
  if (ns < 4) return;
  std::vector<int> col_super(static_cast<size_t>(n_)), parent(static_cast<size_t>(ns), -1),
      first(static_cast<size_t>(ns)), count(static_cast<size_t>(ns), 1);
  std::vector<double> w(static_cast<size_t>(ns)), W(static_cast<size_t>(ns));
  double total = 0;
  for (int s = 0; s < ns; ++s) {
    const Shape sh = shape(s);
    for (int c = sh.first; c < sh.first + sh.columns; ++c) col_super[static_cast<size_t>(c)] = s;
    w[static_cast<size_t>(s)] = static_cast<double>(sh.columns) * (sh.columns + sh.below);
    total += w[static_cast<size_t>(s)];
    first[static_cast<size_t>(s)] = s;
  }
  W = w;
  std::vector<std::vector<int>> children(static_cast<size_t>(ns));
  std::vector<int> list;
  for (int s = 0; s < ns; ++s) {
    const Shape sh = shape(s);
    if (sh.below > 0) {
      const int p = col_super[static_cast<size_t>(rows_[static_cast<size_t>(pi_[static_cast<size_t>(s)] + sh.columns)])];
      if (p <= s) return;  // not postordered: stay serial
      parent[static_cast<size_t>(s)] = p;
      children[static_cast<size_t>(p)].push_back(s);
      W[static_cast<size_t>(p)] += W[static_cast<size_t>(s)];
      first[static_cast<size_t>(p)] = std::min(first[static_cast<size_t>(p)], first[static_cast<size_t>(s)]);
      count[static_cast<size_t>(p)] += count[static_cast<size_t>(s)];
    } else {
      list.push_back(s);
    }
  }
  for (int s = 0; s < ns; ++s)
    if (s - first[static_cast<size_t>(s)] + 1 != count[static_cast<size_t>(s)]) return;  // subtrees not contiguous
  // Greedy split, keeping the best assignment seen.
  const auto assign = [&](std::vector<int> l, std::array<std::vector<int>, 2>& parts) {
    std::sort(l.begin(), l.end(), [&](int x, int y) { return W[static_cast<size_t>(x)] > W[static_cast<size_t>(y)]; });
    double load[2] = {0, 0};
    for (auto& p : parts) p.clear();
    for (int x : l) {
      const int k = load[0] <= load[1] ? 0 : 1;
      load[k] += W[static_cast<size_t>(x)];
      parts[static_cast<size_t>(k)].push_back(x);
    }
    return std::max(load[0], load[1]);
  };
  double top = 0, best = total;
  std::array<std::vector<int>, 2> parts, best_parts;
  for (int it = 0; it < 256 && !list.empty() && top < 0.5 * total; ++it) {
    const double cost = top + assign(list, parts);
    if (cost < best) {
      best = cost;
      best_parts = parts;
    }
    const auto h = std::max_element(list.begin(), list.end(), [&](int x, int y) {
      return W[static_cast<size_t>(x)] < W[static_cast<size_t>(y)];
    });
    const int root = *h;
    list.erase(h);
    top += w[static_cast<size_t>(root)];
    for (int c : children[static_cast<size_t>(root)]) list.push_back(c);
  }
  if (best > 0.85 * total || best_parts[0].empty() || best_parts[1].empty()) return;
  // Ranges per part (ascending), the owner of each supernode (-1: top), top ranges.
  std::vector<int> owner(static_cast<size_t>(ns), -1);
  for (int k = 0; k < 2; ++k) {
    auto& r = ranges_[static_cast<size_t>(k)];
    for (int root : best_parts[static_cast<size_t>(k)]) {
      r.emplace_back(first[static_cast<size_t>(root)], root);
      for (int s = first[static_cast<size_t>(root)]; s <= root; ++s) owner[static_cast<size_t>(s)] = k;
    }
    std::sort(r.begin(), r.end());
  }
  for (int s = 0; s < ns; ++s) {
    if (owner[static_cast<size_t>(s)] >= 0) continue;
    if (!top_.empty() && top_.back().second == s - 1)
      top_.back().second = s;
    else
      top_.emplace_back(s, s);
  }
  // Top columns get a slot in each part's copy; row-list entries of a part's supernodes
  // point at the row (own subtree) or at the part's copy of the top row.
  std::vector<int> slot(static_cast<size_t>(n_), -1);
  for (const auto& [a, z] : top_)
    for (int c = shape(a).first; c < super_[static_cast<size_t>(z) + 1]; ++c) {
      slot[static_cast<size_t>(c)] = static_cast<int>(top_cols_.size());
      top_cols_.push_back(c);
    }
  const int ntop = static_cast<int>(top_cols_.size());
  target_ = rows_;
  for (int s = 0; s < ns; ++s) {
    const int k = owner[static_cast<size_t>(s)];
    if (k < 0) continue;
    for (long p = pi_[static_cast<size_t>(s)]; p < pi_[static_cast<size_t>(s) + 1]; ++p) {
      const int r = rows_[static_cast<size_t>(p)];
      const int o = owner[static_cast<size_t>(col_super[static_cast<size_t>(r)])];
      if (o == k) continue;
      if (o >= 0 || slot[static_cast<size_t>(r)] < 0) {  // another part's row: the split is wrong
        for (auto& rr : ranges_) rr.clear();
        return;
      }
      target_[static_cast<size_t>(p)] = n_ + k * ntop + slot[static_cast<size_t>(r)];
    }
  }
}

}  // namespace fiberfem::core::detail
#endif
