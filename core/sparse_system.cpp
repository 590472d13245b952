#include "core/sparse_system.hpp"

#include <boost/graph/compressed_sparse_row_graph.hpp>
#include <boost/graph/cuthill_mckee_ordering.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <mutex>
#include <string>
#include <omp.h>
#include <cstdint>
#include <cstring>
#include <stdexcept>

namespace fiberfem::core {

namespace {

// parallel_for for the constructor's loops, whose lookups throw std::logic_error when the
// pattern does not hold an entry: an exception may not leave a parallel region, so the
// first one is caught there and thrown again after the loop.
template <class Body>
void parallel_for_checked(int n, Body&& body) {
  std::atomic<bool> failed{false};
  std::string what;
  std::mutex m;
  parallel_for(n, [&](int i) {
    if (failed.load(std::memory_order_relaxed)) return;
    try {
      body(i);
    } catch (const std::logic_error& e) {
      const std::lock_guard<std::mutex> lock(m);
      if (!failed.exchange(true)) what = e.what();
    }
  });
  if (failed) throw std::logic_error(what);
}

// Node adjacency through elements, compressed: each node's row is the nodes of its
// elements (itself included), each taken once (marked) and then sorted. (Sorting every
// element's four nodes into each row and dropping the repeats sorted four times as many
// entries: 70 ms at 252,368 tets.)
detail::NodeGraph node_graph(int num_nodes, const std::vector<Tet>& tets) {
  const size_t n = static_cast<size_t>(num_nodes);
  std::vector<int> elem_start(n + 1, 0);  // the elements of each node, compressed
  for (const Tet& t : tets)
    for (int a : t) ++elem_start[static_cast<size_t>(a) + 1];
  for (size_t v = 0; v < n; ++v) elem_start[v + 1] += elem_start[v];
  std::vector<int> elems(static_cast<size_t>(elem_start[n])), fill(elem_start.begin(), elem_start.end() - 1);
  for (size_t e = 0; e < tets.size(); ++e)
    for (int a : tets[e]) elems[static_cast<size_t>(fill[static_cast<size_t>(a)]++)] = static_cast<int>(e);
  // Row v into raw from 4 elem_start[v] (room for every element's four nodes).
  std::vector<int> raw(4 * static_cast<size_t>(elem_start[n])), count(n);
  constexpr int kParts = 16;  // each with its marks (the last node that took each node)
  parallel_for(kParts, [&](int part) {
    std::vector<int> mark(n, -1);
    const int begin = static_cast<int>(static_cast<long>(num_nodes) * part / kParts);
    const int end = static_cast<int>(static_cast<long>(num_nodes) * (part + 1) / kParts);
    for (int v = begin; v < end; ++v) {
      int* first = raw.data() + 4 * static_cast<size_t>(elem_start[static_cast<size_t>(v)]);
      int* last = first;
      for (int k = elem_start[static_cast<size_t>(v)]; k < elem_start[static_cast<size_t>(v) + 1]; ++k)
        for (int b : tets[static_cast<size_t>(elems[static_cast<size_t>(k)])])
          if (mark[static_cast<size_t>(b)] != v) {
            mark[static_cast<size_t>(b)] = v;
            *last++ = b;
          }
      std::sort(first, last);
      count[static_cast<size_t>(v)] = static_cast<int>(last - first);
    }
  });
  detail::NodeGraph g;
  g.start.assign(n + 1, 0);
  for (size_t v = 0; v < n; ++v) g.start[v + 1] = g.start[v] + count[v];
  g.nodes.resize(static_cast<size_t>(g.start[n]));
  parallel_for(num_nodes, [&](int v) {
    std::copy_n(raw.begin() + 4 * static_cast<long>(elem_start[static_cast<size_t>(v)]), count[static_cast<size_t>(v)],
                g.nodes.begin() + g.start[static_cast<size_t>(v)]);
  });
  return g;
}

// An unsigned key in the order of a double's (-0 as +0; no NaNs here), and a key as itself.
std::uint64_t sort_key(std::uint64_t k) { return k; }
std::uint64_t sort_key(double d) {
  std::uint64_t u;
  d += 0.0;  // -0 -> +0: equal keys, as for operator<
  std::memcpy(&u, &d, sizeof u);
  return (u >> 63) ? ~u : u | (std::uint64_t{1} << 63);
}

// std::stable_sort of order[begin, end) by key[order[i]], as one sort of (key, position)
// pairs: the keys side by side instead of gathered through the order at every
// comparison, by Boost's spreadsort (a radix sort on the key: at 252,368 elements about
// three times faster than std::sort of the pairs). The pairs are distinct, so the order
// is the one any sort of them gives.
template <class Key>
void stable_sort_by_key(std::vector<int>& order, int begin, int end, const std::vector<Key>& key) {
  using Pair = std::pair<std::uint64_t, int>;
  std::vector<Pair> pairs(static_cast<size_t>(end - begin));
  for (int i = begin; i < end; ++i)
    pairs[static_cast<size_t>(i - begin)] = {sort_key(key[static_cast<size_t>(order[static_cast<size_t>(i)])]), i};
  detail::sort_keyed(pairs);  // ties: by position, as stable
  std::vector<int> sorted(pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) sorted[k] = order[static_cast<size_t>(pairs[k].second)];
  std::copy(sorted.begin(), sorted.end(), order.begin() + begin);
}

Vec3 centroid(const TetMesh& mesh, const Tet& t) {
  Vec3 c = Vec3::Zero();
  for (int v : t) c += 0.25 * mesh.rest_positions().col(v);
  return c;
}

// The Morton key of each element's centroid in the mesh's bounding box, computed into
// `keys` when first needed (empty) and kept there.
const std::vector<std::uint64_t>& morton_keys(const TetMesh& mesh, const std::vector<Tet>& tets,
                                              std::vector<std::uint64_t>& keys) {
  const int ne = static_cast<int>(tets.size());
  if (!keys.empty() || ne == 0) return keys;
  auto spread = [](std::uint64_t v) {  // 21 bits -> every third of 63
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
  };
  const auto bounds = mesh.bounding_box();
  const Vec3 lo = bounds.first, span = (bounds.second - bounds.first).cwiseMax(1e-300);
  keys.resize(static_cast<size_t>(ne));
  for (int e = 0; e < ne; ++e) {
    const Vec3 q = ((centroid(mesh, tets[static_cast<size_t>(e)]) - lo).array() / span.array()).cwiseMax(0.0).cwiseMin(1.0) *
                   2097151.0;
    keys[static_cast<size_t>(e)] = spread(static_cast<std::uint64_t>(q.x())) | spread(static_cast<std::uint64_t>(q.y())) << 1 |
                                   spread(static_cast<std::uint64_t>(q.z())) << 2;
  }
  return keys;
}

}  // namespace

SparseSystem::SparseSystem(const TetMesh& mesh, const std::vector<std::uint8_t>& fixed_dofs,
                           int chunk_size, LoopSchedule schedule, DofOrder dof_order)
    : tets_(mesh.tets()), chunk_size_(std::max(1, chunk_size)) {
  const detail::NodeGraph graph = node_graph(mesh.num_nodes(), tets_);
  number_free_dofs(mesh.num_nodes(), fixed_dofs, graph, dof_order);
  const detail::BlockRows rows = block_rows(graph);
  build_pattern(rows);
  build_blocks(rows);
  std::vector<std::uint64_t> morton;  // per element, computed when first needed
  order_chunks(mesh, morton);
  if (schedule != LoopSchedule::chunks) order_runs(mesh, schedule, morton);
  plan_zeroing(mesh.num_nodes());
  store_in_loop_order();
  // Per loop position from here, the elements' nodes close together in memory.
  build_scatter(rows);
}

void SparseSystem::store_in_loop_order() {
  std::vector<Tet> tets(order_.size());
  for (size_t k = 0; k < order_.size(); ++k) tets[k] = tets_[static_cast<size_t>(order_[k])];
  tets_ = std::move(tets);
}

namespace {

// Reverse Cuthill-McKee order of the nodes in `nodes` (the graph restricted to them):
// the nodes, first to last. The graph goes to Boost as a compressed graph with both
// directions of every edge, each vertex's edges in increasing order.
std::vector<int> reverse_cuthill_mckee(const std::vector<int>& nodes, const std::vector<int>& position,
                                       const detail::NodeGraph& graph) {
  using Graph = boost::compressed_sparse_row_graph<boost::directedS>;
  std::vector<std::pair<int, int>> edges;
  edges.reserve(graph.nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i) {
    const size_t v = static_cast<size_t>(nodes[i]);
    for (int k = graph.start[v]; k < graph.start[v + 1]; ++k) {
      const int j = position[static_cast<size_t>(graph.nodes[static_cast<size_t>(k)])];
      if (j >= 0 && j != static_cast<int>(i)) edges.emplace_back(static_cast<int>(i), j);
    }
  }
  // Sources in order, and each one's targets too (positions follow the node order).
  const Graph g(boost::edges_are_sorted, edges.begin(), edges.end(), nodes.size());
  std::vector<int> degree(nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i) degree[i] = static_cast<int>(boost::out_degree(i, g));
  std::vector<boost::default_color_type> colour(nodes.size());
  const auto index = boost::get(boost::vertex_index, g);
  std::vector<Graph::vertex_descriptor> order(nodes.size());
  boost::cuthill_mckee_ordering(g, order.rbegin(), boost::make_iterator_property_map(colour.begin(), index),
                                boost::make_iterator_property_map(degree.begin(), index));
  std::vector<int> out(nodes.size());
  for (size_t k = 0; k < order.size(); ++k) out[k] = nodes[order[k]];
  return out;
}

// Envelope of a node numbering (`rank` per node, -1 for nodes left out): the sum over
// numbered nodes of how far back their earliest numbered neighbour lies.
long envelope(const std::vector<int>& rank, const detail::NodeGraph& graph) {
  long sum = 0;
  for (size_t v = 0; v + 1 < graph.start.size(); ++v) {
    if (rank[v] < 0) continue;
    int lo = rank[v];
    for (int k = graph.start[v]; k < graph.start[v + 1]; ++k) {
      const int w = rank[static_cast<size_t>(graph.nodes[static_cast<size_t>(k)])];
      if (w >= 0) lo = std::min(lo, w);
    }
    sum += rank[v] - lo;
  }
  return sum;
}

}  // namespace

void SparseSystem::number_free_dofs(int num_nodes, const std::vector<std::uint8_t>& fixed_dofs, const detail::NodeGraph& graph,
                                    DofOrder order) {
  num_dofs_ = 3 * num_nodes;
  const auto is_free = [&](int d) { return fixed_dofs.empty() || !fixed_dofs[static_cast<size_t>(d)]; };
  std::vector<int> nodes;  // nodes with a free DOF, in the mesh's order
  std::vector<int> position(static_cast<size_t>(num_nodes), -1);
  for (int v = 0; v < num_nodes; ++v)
    if (is_free(3 * v) || is_free(3 * v + 1) || is_free(3 * v + 2)) {
      position[static_cast<size_t>(v)] = static_cast<int>(nodes.size());
      nodes.push_back(v);
    }
  dof_order_ = DofOrder::nodes;
  block_nodes_ = nodes;
  if (order == DofOrder::bandwidth && nodes.size() > 1) {
    std::vector<int> rcm = reverse_cuthill_mckee(nodes, position, graph);
    std::vector<int> rank(static_cast<size_t>(num_nodes), -1);
    for (size_t k = 0; k < rcm.size(); ++k) rank[static_cast<size_t>(rcm[k])] = static_cast<int>(k);
    if (2 * envelope(rank, graph) < envelope(position, graph)) {
      dof_order_ = DofOrder::bandwidth;
      block_nodes_ = std::move(rcm);
    }
  }
  free_index_.assign(static_cast<size_t>(num_dofs_), -1);
  num_free_ = 0;
  for (int v : block_nodes_)
    for (int c = 0; c < 3; ++c)
      if (is_free(3 * v + c)) free_index_[static_cast<size_t>(3 * v + c)] = num_free_++;
}

int detail::BlockRows::find(int K, int J) const {
  const auto first = block.begin() + start[static_cast<size_t>(K)], last = block.begin() + start[static_cast<size_t>(K) + 1];
  const auto it = std::lower_bound(first, last, J);
  if (it == last || *it != J) throw std::logic_error("sparse pattern lookup failed");
  return static_cast<int>(it - block.begin());
}

detail::BlockRows SparseSystem::block_rows(const detail::NodeGraph& graph) const {
  const int nb = static_cast<int>(block_nodes_.size());
  detail::BlockRows rows;
  rows.row_of_node.assign(graph.start.size() - 1, -1);
  for (int K = 0; K < nb; ++K) rows.row_of_node[static_cast<size_t>(block_nodes_[static_cast<size_t>(K)])] = K;
  const auto neighbours = [&](int K) {
    const size_t v = static_cast<size_t>(block_nodes_[static_cast<size_t>(K)]);
    return std::make_pair(graph.nodes.begin() + graph.start[v], graph.nodes.begin() + graph.start[v + 1]);
  };
  rows.start.assign(static_cast<size_t>(nb) + 1, 0);
  for (int K = 0; K < nb; ++K) {
    const auto [first, last] = neighbours(K);
    rows.start[static_cast<size_t>(K) + 1] =
        rows.start[static_cast<size_t>(K)] +
        static_cast<int>(std::count_if(first, last, [&](int w) { return rows.row_of_node[static_cast<size_t>(w)] >= 0; }));
  }
  rows.block.resize(static_cast<size_t>(rows.start.back()));
  rows.column.resize(rows.block.size());
  rows.self.resize(static_cast<size_t>(nb));
  const auto free_count = [&](int J) {
    const int v = block_nodes_[static_cast<size_t>(J)];
    int c = 0;
    for (int d = 0; d < 3; ++d) c += free_index_[static_cast<size_t>(3 * v + d)] >= 0;
    return c;
  };
  parallel_for(nb, [&](int K) {
    const auto [first, last] = neighbours(K);
    int* out = rows.block.data() + rows.start[static_cast<size_t>(K)];
    for (auto it = first; it != last; ++it)
      if (const int J = rows.row_of_node[static_cast<size_t>(*it)]; J >= 0) *out++ = J;
    const int begin = rows.start[static_cast<size_t>(K)], end = rows.start[static_cast<size_t>(K) + 1];
    std::sort(rows.block.begin() + begin, rows.block.begin() + end);
    rows.self[static_cast<size_t>(K)] =
        static_cast<int>(std::lower_bound(rows.block.begin() + begin, rows.block.begin() + end, K) - rows.block.begin());
    int column = 0;
    for (int k = begin; k < end; ++k) {
      rows.column[static_cast<size_t>(k)] = column;
      column += free_count(rows.block[static_cast<size_t>(k)]);
    }
  });
  return rows;
}

const NaturalOrder& SparseSystem::natural_order() const {
  if (natural_done_) return natural_;
  natural_ = NaturalOrder{};
  natural_done_ = true;
  if (dof_order_ == DofOrder::nodes) return natural_;
  natural_.identity = false;
  // DOFs and node blocks: counted in the mesh's node order.
  natural_.free.assign(static_cast<size_t>(num_free_), -1);
  int next = 0;
  for (int d = 0; d < num_dofs_; ++d)
    if (free_index_[static_cast<size_t>(d)] >= 0) natural_.free[static_cast<size_t>(free_index_[static_cast<size_t>(d)])] = next++;
  std::vector<int> sorted = block_nodes_;
  std::sort(sorted.begin(), sorted.end());
  std::vector<int> natural_block(static_cast<size_t>(num_dofs_ / 3), -1);
  for (size_t k = 0; k < sorted.size(); ++k) natural_block[static_cast<size_t>(sorted[k])] = static_cast<int>(k);
  natural_.block.resize(block_nodes_.size());
  for (size_t k = 0; k < block_nodes_.size(); ++k) natural_.block[k] = natural_block[static_cast<size_t>(block_nodes_[k])];
  // Non-zeros: the natural matrix has the same rows (renumbered), each with its columns sorted
  // by their natural numbers.
  const int* outer = A_.outerIndexPtr();
  const int* inner = A_.innerIndexPtr();
  std::vector<int> natural_row_start(static_cast<size_t>(num_free_) + 1, 0);
  for (int r = 0; r < num_free_; ++r)
    natural_row_start[static_cast<size_t>(natural_.free[static_cast<size_t>(r)]) + 1] = outer[r + 1] - outer[r];
  for (int r = 0; r < num_free_; ++r) natural_row_start[static_cast<size_t>(r) + 1] += natural_row_start[static_cast<size_t>(r)];
  natural_.value.assign(static_cast<size_t>(A_.nonZeros()), -1);
  std::vector<std::pair<int, int>> row;  // (natural column, position)
  for (int r = 0; r < num_free_; ++r) {
    row.clear();
    for (int p = outer[r]; p < outer[r + 1]; ++p) row.emplace_back(natural_.free[static_cast<size_t>(inner[p])], p);
    std::sort(row.begin(), row.end());
    const int base = natural_row_start[static_cast<size_t>(natural_.free[static_cast<size_t>(r)])];
    for (size_t k = 0; k < row.size(); ++k) natural_.value[static_cast<size_t>(row[k].second)] = base + static_cast<int>(k);
  }
  return natural_;
}

// The pattern: each block row's neighbours expanded to their free DOFs, written straight
// into the compressed arrays (rows in free order are block rows in order, and each of a
// node's rows has the same columns).
void SparseSystem::build_pattern(const detail::BlockRows& rows) {
  const int nb = static_cast<int>(block_nodes_.size());
  std::vector<int> first_row(static_cast<size_t>(nb) + 1);  // free rows of block K: first_row[K] ..
  for (int K = 0, r = 0; K < nb; ++K) {
    first_row[static_cast<size_t>(K)] = r;
    for (int c = 0; c < 3; ++c) r += free_index_[static_cast<size_t>(3 * block_nodes_[static_cast<size_t>(K)] + c)] >= 0;
    first_row[static_cast<size_t>(K) + 1] = r;
  }
  const auto row_length = [&](int K) {  // the columns of each of block K's rows
    const int last = rows.start[static_cast<size_t>(K) + 1] - 1;
    const int v = block_nodes_[static_cast<size_t>(rows.block[static_cast<size_t>(last)])];
    int n = rows.column[static_cast<size_t>(last)];
    for (int d = 0; d < 3; ++d) n += free_index_[static_cast<size_t>(3 * v + d)] >= 0;
    return n;
  };
  A_.resize(num_free_, num_free_);
  int* outer = A_.outerIndexPtr();
  outer[0] = 0;
  for (int K = 0; K < nb; ++K)
    for (int r = first_row[static_cast<size_t>(K)]; r < first_row[static_cast<size_t>(K) + 1]; ++r) outer[r + 1] = outer[r] + row_length(K);
  A_.resizeNonZeros(outer[num_free_]);
  int* inner = A_.innerIndexPtr();
  std::fill(A_.valuePtr(), A_.valuePtr() + A_.nonZeros(), 0.0);
  parallel_for(nb, [&](int K) {
    const int r0 = first_row[static_cast<size_t>(K)];
    int* out = inner + outer[r0];
    for (int k = rows.start[static_cast<size_t>(K)]; k < rows.start[static_cast<size_t>(K) + 1]; ++k) {
      const int w = block_nodes_[static_cast<size_t>(rows.block[static_cast<size_t>(k)])];
      for (int d = 0; d < 3; ++d)
        if (const int col = free_index_[static_cast<size_t>(3 * w + d)]; col >= 0) *out++ = col;
    }
    for (int r = r0 + 1; r < first_row[static_cast<size_t>(K) + 1]; ++r) std::copy(inner + outer[r0], inner + outer[r0 + 1], inner + outer[r]);
  });
}

int SparseSystem::value_index(int r, int col) const {
  const int* outer = A_.outerIndexPtr();
  const int* inner = A_.innerIndexPtr();
  const int* p = std::lower_bound(inner + outer[r], inner + outer[r + 1], col);
  if (p == inner + outer[r + 1] || *p != col) throw std::logic_error("sparse pattern lookup failed");
  return static_cast<int>(p - inner);
}

// Where each element's entries go, by loop position: in the values (block_scatter_,
// general_scatter_) and in the block store (element_blocks_, build_blocks first), and each
// free DOF's diagonal entry. An element whose DOFs are all free finds each node pair's block
// through the block rows (one search in a node's neighbours; a node's three rows have the
// same columns, and pair (b, a) gives the transposed block of (a, b)); one with a fixed DOF
// searches the pattern entry by entry.
void SparseSystem::build_scatter(const detail::BlockRows& rows) {
  diag_.resize(static_cast<size_t>(num_free_));
  parallel_for_checked(num_free_, [&](int r) { diag_[static_cast<size_t>(r)] = value_index(r, r); });
  const size_t ne = tets_.size();
  // The values' scatter of all-free elements: the block store takes their blocks when it
  // is kept, and assemble() (the static solver's per-element loop) makes it when first
  // needed (ensure_block_scatter; 48 indices per element, 48 MB at 252,368 tets).
  block_scatter_.assign(block_ok_ ? 0 : ne * kBlockIndices, 0);
  general_offset_.assign(ne, -1);
  element_blocks_.assign(block_ok_ ? ne * 10 : 0, -1);
  int general = 0;
  for (size_t e = 0; e < ne; ++e) {
    bool all_free = true;
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 3; ++c) all_free = all_free && free_index_[static_cast<size_t>(3 * tets_[e][a] + c)] >= 0;
    if (!all_free) {
      general_offset_[e] = general;
      general += 144;
    }
  }
  general_scatter_.assign(static_cast<size_t>(general), -1);
  const int* outer = A_.outerIndexPtr();
  parallel_for_checked(static_cast<int>(ne), [&](int ei) {
    const size_t e = static_cast<size_t>(ei);
    const Tet& t = tets_[e];
    int K[4];
    for (int a = 0; a < 4; ++a) K[a] = rows.row_of_node[static_cast<size_t>(t[a])];
    if (general_offset_[e] < 0) {
      if (block_ok_) {  // each pair's upper block: one search, in the row of the smaller K
        for (int a = 0; a < 4; ++a)
          for (int b = a; b < 4; ++b) {
            const int lo = std::min(K[a], K[b]), hi = std::max(K[a], K[b]);
            const int index = a == b ? rows.self[static_cast<size_t>(lo)] : rows.find(lo, hi);
            element_blocks_[e * 10 + static_cast<size_t>(ElementBatch::block_index(a, b))] =
                2 * upper_block(rows, lo, index) + (K[a] <= K[b] ? 0 : 1);
          }
        return;
      }
      for (int a = 0; a < 4; ++a) {
        const int r0 = free_index_[static_cast<size_t>(3 * t[a])];
        for (int b = 0; b < 4; ++b) {  // node b's block in node a's row
          const int index = a == b ? rows.self[static_cast<size_t>(K[a])] : rows.find(K[a], K[b]);
          const int offset = rows.column[static_cast<size_t>(index)];
          for (int i = 0; i < 3; ++i) block_scatter_[e * kBlockIndices + static_cast<size_t>((4 * a + b) * 3 + i)] = outer[r0 + i] + offset;
        }
      }
      return;
    }
    int* s = &general_scatter_[static_cast<size_t>(general_offset_[e])];
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 3; ++c)
        for (int b = 0; b < 4; ++b)
          for (int d = 0; d < 3; ++d) {
            const int r = free_index_[static_cast<size_t>(3 * t[a] + c)];
            const int col = free_index_[static_cast<size_t>(3 * t[b] + d)];
            if (r < 0 || col < 0) continue;
            s[(3 * b + d) * 12 + 3 * a + c] = value_index(r, col);
          }
    if (block_ok_)  // pairs of free nodes (a node is wholly free or wholly fixed here)
      for (int a = 0; a < 4; ++a)
        for (int b = a; b < 4; ++b) {
          if (K[a] < 0 || K[b] < 0) continue;
          const int I = std::min(K[a], K[b]), J = std::max(K[a], K[b]);
          element_blocks_[e * 10 + static_cast<size_t>(ElementBatch::block_index(a, b))] =
              2 * upper_block(rows, I, rows.find(I, J)) + (K[a] <= K[b] ? 0 : 1);
        }
  });
}

// block_scatter_ when the block store stood in for it (build_scatter): a node's three rows
// have the same columns, so each node pair's offset is one search in its first row.
void SparseSystem::ensure_block_scatter() {
  const size_t ne = tets_.size();
  if (block_scatter_.size() == ne * kBlockIndices) return;
  block_scatter_.assign(ne * kBlockIndices, 0);
  const int* outer = A_.outerIndexPtr();
  parallel_for_checked(static_cast<int>(ne), [&](int ei) {
    const size_t e = static_cast<size_t>(ei);
    if (general_offset_[e] >= 0) return;
    const Tet& t = tets_[e];
    for (int a = 0; a < 4; ++a) {
      const int r0 = free_index_[static_cast<size_t>(3 * t[a])];
      for (int b = 0; b < 4; ++b) {
        const int offset = value_index(r0, free_index_[static_cast<size_t>(3 * t[b])]) - outer[r0];
        for (int i = 0; i < 3; ++i) block_scatter_[e * kBlockIndices + static_cast<size_t>((4 * a + b) * 3 + i)] = outer[r0 + i] + offset;
      }
    }
  });
}

// Chunks of consecutive elements, coloured so that no two chunks of a colour share a
// node. The mesh's own element order is kept when it is local (the box generator's,
// cell by cell, which also follows its node numbering); an order that scatters chunks
// over the body (a mesh generator's Delaunay order: measured 33 ms instead of 1.5 ms to
// assemble a 7,105-tet heart, nearly every chunk in its own colour) is replaced by the
// Morton order of the element centroids.
void SparseSystem::order_chunks(const TetMesh& mesh, std::vector<std::uint64_t>& morton) {
  const int n = mesh.num_nodes();
  const int ne = static_cast<int>(tets_.size());
  order_.resize(static_cast<size_t>(ne));
  for (int e = 0; e < ne; ++e) order_[static_cast<size_t>(e)] = e;
  colour_chunks(n);
  if (colour_chunks_.size() <= 16) return;
  const std::vector<int> natural_order = order_;
  const size_t natural_colours = colour_chunks_.size();
  const std::vector<std::uint64_t>& key = morton_keys(mesh, tets_, morton);
  stable_sort_by_key(order_, 0, ne, key);
  colour_chunks(n);
  if (colour_chunks_.size() >= natural_colours) {  // keep whichever needs fewer colours
    order_ = natural_order;
    colour_chunks(n);
  }
}

// Long runs instead of chunks (LoopSchedule): kRuns runs, each a contiguous range of the
// chunk order, coloured as wholes. In a local order along the body run r shares nodes
// with r - 1 and r + 1 only: two colours of kRuns / 2 runs. Each thread walks its
// runs in order, so the blocks of a node are written by its elements close together in
// time instead of once per colour from memory (the 245,760-tet beam's element pass on one
// thread: 85-100 ms coloured by chunks, 64-72 ms in order). An order whose runs meet in
// more places (Morton's octants all share the centre) is replaced by slabs across the
// longest side of the bounding box, one per run, each in Morton order.
void SparseSystem::order_runs(const TetMesh& mesh, LoopSchedule schedule, std::vector<std::uint64_t>& morton) {
  const int n = mesh.num_nodes();
  const int ne = static_cast<int>(tets_.size());
  const int num_chunks = (ne + chunk_size_ - 1) / chunk_size_;
  // kRuns runs (fewer on a mesh of fewer chunks) whose lengths differ by one chunk at
  // most: of equal length but the last, the two colours of 180 chunks held 8 and 7 runs
  // of 12 chunks, and on two threads one thread waited for a whole run in the second.
  const int num_runs = std::min(kRuns, num_chunks);
  const int run_chunks = std::max(1, (num_chunks + num_runs - 1) / num_runs);
  const bool large = static_cast<long>(ne) >= static_cast<long>(kRunMinElements) * num_runs;
  if (!(schedule == LoopSchedule::runs || (large && run_chunks > 1))) return;
  const auto chunk_order = order_;
  colour_chunks(n, num_runs);
  if (colour_chunks_.size() > 2) {
    const auto run_order = order_;
    const size_t run_colours = colour_chunks_.size();
    const auto bounds = mesh.bounding_box();
    const Vec3 span = (bounds.second - bounds.first).cwiseMax(1e-300);
    int axis = 0;
    span.maxCoeff(&axis);
    std::vector<double> along(static_cast<size_t>(ne));
    for (int e = 0; e < ne; ++e) along[static_cast<size_t>(e)] = centroid(mesh, tets_[static_cast<size_t>(e)])(axis);
    for (int e = 0; e < ne; ++e) order_[static_cast<size_t>(e)] = e;
    stable_sort_by_key(order_, 0, ne, along);
    const std::vector<std::uint64_t>& key = morton_keys(mesh, tets_, morton);
    for (int u = 0; u < num_runs; ++u)
      stable_sort_by_key(order_, std::min(unit_first_chunk(u, num_runs, num_chunks) * chunk_size_, ne),
                         std::min(unit_first_chunk(u + 1, num_runs, num_chunks) * chunk_size_, ne), key);
    colour_chunks(n, num_runs);
    if (colour_chunks_.size() >= run_colours) {
      order_ = run_order;
      colour_chunks(n, num_runs);
    }
  }
  if (schedule == LoopSchedule::automatic && colour_chunks_.size() > static_cast<size_t>(kRunMaxColours)) {  // chunks after all
    order_ = chunk_order;
    colour_chunks(n);
  }
}

void SparseSystem::plan_zeroing(int n) {
  // Each node's rows are zeroed by the first chunk, in the loop's order (colour by colour),
  // that holds the node: no chunk of that colour or an earlier one writes them, and later
  // colours start after it. A free node's rows are consecutive, so its values are one range.
  const int* outer = A_.outerIndexPtr();
  std::vector<int> first_chunk(static_cast<size_t>(n), -1);
  for (const std::vector<int>& chunks : colour_chunks_)
    for (int ch : chunks) {
      const int begin = ch * chunk_size_, end = std::min(begin + chunk_size_, static_cast<int>(tets_.size()));
      for (int k = begin; k < end; ++k)
        for (int v : tets_[static_cast<size_t>(order_[static_cast<size_t>(k)])])
          if (first_chunk[static_cast<size_t>(v)] < 0) first_chunk[static_cast<size_t>(v)] = ch;
    }
  const int num_chunks = (static_cast<int>(tets_.size()) + chunk_size_ - 1) / chunk_size_;
  std::vector<std::vector<std::pair<int, int>>> per_chunk(static_cast<size_t>(num_chunks)), per_chunk_blocks(static_cast<size_t>(num_chunks));
  for (int v : block_nodes_) {  // in free order, so that consecutive nodes' rows merge
    int lo = -1, hi = -1;  // free rows of node v
    for (int c = 0; c < 3; ++c) {
      const int r = free_index_[static_cast<size_t>(3 * v + c)];
      if (r < 0) continue;
      if (lo < 0) lo = r;
      hi = r;
    }
    if (lo < 0) continue;
    const int ch = first_chunk[static_cast<size_t>(v)];
    if (ch < 0) throw std::logic_error("sparse pattern: a free node in no element");
    auto& ranges = per_chunk[static_cast<size_t>(ch)];
    auto& branges = per_chunk_blocks[static_cast<size_t>(ch)];
    // The node's block row (when blocks are kept): the same ranges, in block_values_.
    const int I = block_ok_ ? node_block_[static_cast<size_t>(v)] : -1;
    const std::pair<int, int> brow = I >= 0 ? std::pair<int, int>(9 * block_start_[static_cast<size_t>(I)],
                                                                   9 * block_start_[static_cast<size_t>(I) + 1])
                                            : std::pair<int, int>(0, 0);
    if (!ranges.empty() && ranges.back().second == outer[lo] && (!block_ok_ || branges.back().second == brow.first)) {
      ranges.back().second = outer[hi + 1];  // merge with the previous node's rows
      if (block_ok_) branges.back().second = brow.second;
    } else {
      ranges.emplace_back(outer[lo], outer[hi + 1]);
      if (block_ok_) branges.push_back(brow);
    }
  }
  zero_begin_.assign(static_cast<size_t>(num_chunks) + 1, 0);
  zero_ranges_.clear();
  block_zero_ranges_.clear();
  for (int ch = 0; ch < num_chunks; ++ch) {
    zero_begin_[static_cast<size_t>(ch)] = static_cast<int>(zero_ranges_.size());
    zero_ranges_.insert(zero_ranges_.end(), per_chunk[static_cast<size_t>(ch)].begin(), per_chunk[static_cast<size_t>(ch)].end());
    block_zero_ranges_.insert(block_zero_ranges_.end(), per_chunk_blocks[static_cast<size_t>(ch)].begin(),
                              per_chunk_blocks[static_cast<size_t>(ch)].end());
  }
  zero_begin_[static_cast<size_t>(num_chunks)] = static_cast<int>(zero_ranges_.size());
}

void SparseSystem::build_blocks(const detail::BlockRows& rows) {
  // Only when every node is wholly free or wholly fixed: then node block I owns free DOFs
  // 3I..3I+2 and a block is a whole 3 x 3 of the CSR matrix; block row I's neighbours are
  // then rows.block of row I, three columns each.
  node_block_.assign(rows.row_of_node.size(), -1);
  for (int v : block_nodes_)
    for (int c = 0; c < 3; ++c)
      if (free_index_[static_cast<size_t>(3 * v + c)] < 0) return;  // partly fixed: the CSR path
  node_block_ = rows.row_of_node;
  const int nb = static_cast<int>(block_nodes_.size());
  // Row I's blocks: the diagonal, then its neighbours above it (those after I in its sorted
  // row), so block (I, J >= I) is block_start_[I] + (index of J - index of I) in row I.
  const std::vector<int>& self = rows.self;
  block_start_.assign(static_cast<size_t>(nb) + 1, 0);
  for (int I = 0; I < nb; ++I) {
    block_start_[static_cast<size_t>(I) + 1] =
        block_start_[static_cast<size_t>(I)] + rows.start[static_cast<size_t>(I) + 1] - self[static_cast<size_t>(I)];
  }
  block_col_.resize(static_cast<size_t>(block_start_.back()));
  parallel_for(nb, [&](int I) {
    std::copy(rows.block.begin() + self[static_cast<size_t>(I)], rows.block.begin() + rows.start[static_cast<size_t>(I) + 1],
              block_col_.begin() + block_start_[static_cast<size_t>(I)]);
  });
  block_values_.assign(9 * block_col_.size(), 0.0);
  // Each CSR value's block entry: row 3I + i's columns are row I's neighbours J, three each.
  csr_from_block_.assign(static_cast<size_t>(A_.nonZeros()), 0);
  const int* outer = A_.outerIndexPtr();
  parallel_for_checked(nb, [&](int I) {
    for (int k = rows.start[static_cast<size_t>(I)]; k < rows.start[static_cast<size_t>(I) + 1]; ++k) {
      const int J = rows.block[static_cast<size_t>(k)];
      const int column = rows.column[static_cast<size_t>(k)];
      const bool upper = J >= I;
      const int blk = upper ? upper_block(rows, I, k) : upper_block(rows, J, rows.find(J, I));
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          csr_from_block_[static_cast<size_t>(outer[3 * I + i] + column + j)] = upper ? 9 * blk + 3 * i + j : 9 * blk + 3 * j + i;
    }
  });
  block_ok_ = true;
}

int SparseSystem::upper_block(const detail::BlockRows& rows, int I, int k) const {
  return block_start_[static_cast<size_t>(I)] + k - rows.self[static_cast<size_t>(I)];
}

void SparseSystem::sync_matrix() {
  if (!blocks_current_) return;
  double* v = A_.valuePtr();
  const int nnz = static_cast<int>(A_.nonZeros());
  const double* b = block_values_.data();
  const int* src = csr_from_block_.data();
  parallel_for(nnz, [&](int p) { v[p] = b[src[p]]; }, nnz > 20000);
  blocks_current_ = false;
}

namespace {
// Block rows [begin, end) of the symmetric block product, K right-hand sides side by side
// (x, y: 3K values per block row, row-major). Each stored block (I, J), J > I, adds B x_J
// to row I and B^T x_I to row J: into y when J < end (rows this call owns, or earlier
// ones), else into `spill` (rows of a later part; its first value is row `end`'s).
template <int K>
void block_rows(const int* start, const int* col, const double* val, const double* x, double* y, double* spill,
                int begin, int end) {
  if constexpr (K > 1) {
    // K columns side by side (the recycled solutions): each of a block row's three rows is
    // K consecutive values, so both products are sums of whole rows times single entries
    // of the block (broadcast), vectorised along the K columns. (Eigen's 3 x 3 transpose
    // times 3 x K here compiled to scalar code: the projection's A W took as long as five
    // single products.)
    using Row = Eigen::Matrix<double, 1, K>;
    constexpr size_t S = 3 * K;
    for (int I = begin; I < end; ++I) {
      const double* xp = x + S * static_cast<size_t>(I);
      const Row x0 = Eigen::Map<const Row>(xp), x1 = Eigen::Map<const Row>(xp + K), x2 = Eigen::Map<const Row>(xp + 2 * K);
      const double* d = val + 9 * static_cast<size_t>(start[I]);
      Row a0 = d[0] * x0 + d[1] * x1 + d[2] * x2;
      Row a1 = d[3] * x0 + d[4] * x1 + d[5] * x2;
      Row a2 = d[6] * x0 + d[7] * x1 + d[8] * x2;
      for (int k = start[I] + 1; k < start[I + 1]; ++k) {
        const double* b = val + 9 * static_cast<size_t>(k);
        const int J = col[k];
        const double* xj = x + S * static_cast<size_t>(J);
        const Eigen::Map<const Row> j0(xj), j1(xj + K), j2(xj + 2 * K);
        a0 += b[0] * j0 + b[1] * j1 + b[2] * j2;
        a1 += b[3] * j0 + b[4] * j1 + b[5] * j2;
        a2 += b[6] * j0 + b[7] * j1 + b[8] * j2;
        double* out = J < end ? y + S * static_cast<size_t>(J) : spill + S * static_cast<size_t>(J - end);
        Eigen::Map<Row>(out) += b[0] * x0 + b[3] * x1 + b[6] * x2;
        Eigen::Map<Row>(out + K) += b[1] * x0 + b[4] * x1 + b[7] * x2;
        Eigen::Map<Row>(out + 2 * K) += b[2] * x0 + b[5] * x1 + b[8] * x2;
      }
      double* yi = y + S * static_cast<size_t>(I);
      Eigen::Map<Row>(yi) += a0;
      Eigen::Map<Row>(yi + K) += a1;
      Eigen::Map<Row>(yi + 2 * K) += a2;
    }
  } else {
    using B3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
    using V3 = Eigen::Vector3d;
    for (int I = begin; I < end; ++I) {
      const Eigen::Map<const V3> xi(x + 3 * static_cast<size_t>(I));
      V3 acc = Eigen::Map<const B3>(val + 9 * static_cast<size_t>(start[I])) * xi;
      for (int k = start[I] + 1; k < start[I + 1]; ++k) {
        const Eigen::Map<const B3> b(val + 9 * static_cast<size_t>(k));
        const int J = col[k];
        acc.noalias() += b * Eigen::Map<const V3>(x + 3 * static_cast<size_t>(J));
        double* out = J < end ? y + 3 * static_cast<size_t>(J) : spill + 3 * static_cast<size_t>(J - end);
        Eigen::Map<V3>(out).noalias() += b.transpose() * xi;
      }
      Eigen::Map<V3>(y + 3 * static_cast<size_t>(I)) += acc;
    }
  }
}

// y = A x (K columns) over the block rows, in parts fixed by the matrix (not one per thread,
// so the sums round the same on any number of threads; SparseSystem::kProductPartRows). Part p owns block rows
// [bounds[p], bounds[p + 1]) of y (zeroes them, writes them); its contributions to later
// parts' rows go to its spill, which covers rows [bounds[p + 1], hi[p]) (the reach of its
// blocks). After all parts, each part adds the earlier parts' spills over its rows, in part
// order, and zeroes them again (so the spills stay zero between calls). Serial when not
// `parallel` (a small matrix): one part, no spill.
template <int K>
void symmetric_block_product(const std::vector<int>& start_v, const std::vector<int>& col_v, const std::vector<double>& val_v,
                             const double* x, double* y, bool parallel, SparseSystem::ProductSpills& sp) {
  const int nb = static_cast<int>(start_v.size()) - 1;
  constexpr size_t S = 3 * K;
  if (!parallel) {
    std::fill(y, y + S * static_cast<size_t>(nb), 0.0);
    block_rows<K>(start_v.data(), col_v.data(), val_v.data(), x, y, nullptr, 0, nb);
    return;
  }
  if (sp.block_rows != nb) {  // the parts and the reach of their blocks (once per pattern)
    sp.block_rows = nb;
    sp.parts = std::clamp(nb / SparseSystem::kProductPartRows, 2, SparseSystem::kMaxProductParts);
    for (int p = 0; p <= sp.parts; ++p)
      sp.bounds[static_cast<size_t>(p)] = static_cast<int>(static_cast<long>(nb) * p / sp.parts);
    for (int p = 0; p < sp.parts; ++p) {
      int hi = sp.bounds[static_cast<size_t>(p) + 1];
      for (int I = sp.bounds[static_cast<size_t>(p)]; I < sp.bounds[static_cast<size_t>(p) + 1]; ++I)
        for (int k = start_v[static_cast<size_t>(I)]; k < start_v[static_cast<size_t>(I) + 1]; ++k)
          hi = std::max(hi, col_v[static_cast<size_t>(k)] + 1);
      sp.hi[static_cast<size_t>(p)] = hi;
      sp.spill[static_cast<size_t>(p)].setZero(static_cast<Eigen::Index>(S * static_cast<size_t>(hi - sp.bounds[static_cast<size_t>(p) + 1])));
    }
  }
  const int P = sp.parts;
  const auto own = [&](int p) {
    const int begin = sp.bounds[static_cast<size_t>(p)], end = sp.bounds[static_cast<size_t>(p) + 1];
    std::fill(y + S * static_cast<size_t>(begin), y + S * static_cast<size_t>(end), 0.0);
    block_rows<K>(start_v.data(), col_v.data(), val_v.data(), x, y, sp.spill[static_cast<size_t>(p)].data(), begin, end);
  };
  const auto gather = [&](int q) {
    const int begin = sp.bounds[static_cast<size_t>(q)], end = sp.bounds[static_cast<size_t>(q) + 1];
    for (int u = 0; u < q; ++u) {
      const int base = sp.bounds[static_cast<size_t>(u) + 1];
      const int from = std::max(begin, base), to = std::min(end, sp.hi[static_cast<size_t>(u)]);
      double* s = sp.spill[static_cast<size_t>(u)].data();
      for (size_t r = S * static_cast<size_t>(from); r < S * static_cast<size_t>(std::max(to, from)); ++r) {
        y[r] += s[r - S * static_cast<size_t>(base)];
        s[r - S * static_cast<size_t>(base)] = 0.0;
      }
    }
  };
  if (threaded()) {
    const int cpu = current_cpu();
#pragma omp parallel
    {
      keep_team_apart(cpu);
#pragma omp for schedule(static)
      for (int p = 0; p < P; ++p) own(p);
#pragma omp for schedule(static)
      for (int q = 0; q < P; ++q) gather(q);
    }
  } else {
    for (int p = 0; p < P; ++p) own(p);
    for (int q = 0; q < P; ++q) gather(q);
  }
}
}  // namespace

void SparseSystem::block_product8(const double* W, double* AW, bool parallel) const {
  symmetric_block_product<8>(block_start_, block_col_, block_values_, W, AW, parallel, spills8_);
}

double SparseSystem::block_product(const Eigen::VectorXd& x, Eigen::VectorXd& y, bool parallel) const {
  y.resize(num_free_);
  symmetric_block_product<1>(block_start_, block_col_, block_values_, x.data(), y.data(), parallel, spills1_);
  return x.dot(y);
}

void SparseSystem::colour_chunks(int n, int num_units) {
  // Greedy, unit by unit (a unit is a range of consecutive chunks of the order,
  // unit_first_chunk): a unit takes the lowest colour not used by any unit sharing one of
  // its nodes. Units that find none of 64 colours run one at a time, each its own colour.
  const int ne = static_cast<int>(tets_.size());
  const int num_chunks = (ne + chunk_size_ - 1) / chunk_size_;
  if (num_units <= 0 || num_units > num_chunks) num_units = num_chunks;
  run_chunks_ = (num_chunks + num_units - 1) / num_units;
  const auto first_chunk = [&](int u) { return unit_first_chunk(u, num_units, num_chunks); };
  std::vector<std::uint64_t> node_colours(static_cast<size_t>(n), 0);
  std::vector<int> unit_colour(static_cast<size_t>(num_units));
  bool serial_bucket_used = false;
  for (int u = 0; u < num_units; ++u) {
    std::uint64_t used = 0;
    const int begin = first_chunk(u) * chunk_size_, end = std::min(first_chunk(u + 1) * chunk_size_, ne);
    for (int k = begin; k < end; ++k)
      for (int v : tets_[static_cast<size_t>(order_[static_cast<size_t>(k)])]) used |= node_colours[static_cast<size_t>(v)];
    int colour = 0;
    while (colour < 64 && (used >> colour) & 1u) ++colour;
    if (colour == 64) {
      serial_bucket_used = true;
      unit_colour[static_cast<size_t>(u)] = -1;
      continue;
    }
    unit_colour[static_cast<size_t>(u)] = colour;
    for (int k = begin; k < end; ++k)
      for (int v : tets_[static_cast<size_t>(order_[static_cast<size_t>(k)])])
        node_colours[static_cast<size_t>(v)] |= (std::uint64_t{1} << colour);
  }
  int num_colours = 0;
  for (int c : unit_colour) num_colours = std::max(num_colours, c + 1);
  colour_chunks_.assign(static_cast<size_t>(num_colours), {});
  colour_tasks_.assign(static_cast<size_t>(num_colours), {0});
  auto add_unit = [&](size_t colour, int u) {
    for (int ch = first_chunk(u); ch < first_chunk(u + 1); ++ch) colour_chunks_[colour].push_back(ch);
    colour_tasks_[colour].push_back(static_cast<int>(colour_chunks_[colour].size()));
  };
  for (int u = 0; u < num_units; ++u)
    if (unit_colour[static_cast<size_t>(u)] >= 0) add_unit(static_cast<size_t>(unit_colour[static_cast<size_t>(u)]), u);
  if (serial_bucket_used)
    for (int u = 0; u < num_units; ++u)
      if (unit_colour[static_cast<size_t>(u)] < 0) {
        colour_chunks_.emplace_back();
        colour_tasks_.push_back({0});
        add_unit(colour_chunks_.size() - 1, u);
      }
}

std::vector<int> SparseSystem::node_block_starts() const {
  std::vector<int> starts;
  starts.reserve(block_nodes_.size() + 1);
  for (int v : block_nodes_)
    for (int c = 0; c < 3; ++c) {
      const int f = free_index_[static_cast<size_t>(3 * v + c)];
      if (f >= 0) {
        starts.push_back(f);
        break;
      }
    }
  starts.push_back(num_free_);
  return starts;
}

void SparseSystem::zero_matrix() { std::fill(A_.valuePtr(), A_.valuePtr() + A_.nonZeros(), 0.0); }

Eigen::VectorXd SparseSystem::restrict_to_free(const Eigen::VectorXd& full) const {
  Eigen::VectorXd r(num_free_);
  for (int d = 0; d < num_dofs_; ++d) {
    const int f = free_index_[static_cast<size_t>(d)];
    if (f >= 0) r(f) = full(d);
  }
  return r;
}

void SparseSystem::scatter_free(const Eigen::VectorXd& free, Eigen::VectorXd& full) const {
  for (int d = 0; d < num_dofs_; ++d) {
    const int f = free_index_[static_cast<size_t>(d)];
    if (f >= 0) full(d) = free(f);
  }
}

}  // namespace fiberfem::core
