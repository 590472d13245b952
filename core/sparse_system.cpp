#include "core/sparse_system.hpp"

#include <algorithm>
#include <cstdint>
#include <stdexcept>

namespace fiberfem::core {

SparseSystem::SparseSystem(const TetMesh& mesh, const std::vector<std::uint8_t>& fixed_dofs,
                           int chunk_size)
    : tets_(mesh.tets()), chunk_size_(std::max(1, chunk_size)) {
  const int n = mesh.num_nodes();
  num_dofs_ = 3 * n;
  free_index_.assign(static_cast<size_t>(num_dofs_), -1);
  for (int d = 0; d < num_dofs_; ++d)
    if (fixed_dofs.empty() || !fixed_dofs[static_cast<size_t>(d)]) free_index_[static_cast<size_t>(d)] = num_free_++;

  // Pattern: node adjacency through elements, expanded to 3x3 blocks over free DOFs.
  std::vector<std::vector<int>> adj(static_cast<size_t>(n));
  for (const Tet& t : tets_)
    for (int a : t)
      for (int b : t) adj[static_cast<size_t>(a)].push_back(b);
  for (auto& l : adj) {
    std::sort(l.begin(), l.end());
    l.erase(std::unique(l.begin(), l.end()), l.end());
  }
  A_.resize(num_free_, num_free_);
  Eigen::VectorXi nnz_per_row = Eigen::VectorXi::Zero(num_free_);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const int r = free_index_[static_cast<size_t>(3 * i + c)];
      if (r < 0) continue;
      int count = 0;
      for (int j : adj[static_cast<size_t>(i)])
        for (int d = 0; d < 3; ++d) count += free_index_[static_cast<size_t>(3 * j + d)] >= 0;
      nnz_per_row(r) = count;
    }
  A_.reserve(nnz_per_row);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const int r = free_index_[static_cast<size_t>(3 * i + c)];
      if (r < 0) continue;
      for (int j : adj[static_cast<size_t>(i)])
        for (int d = 0; d < 3; ++d) {
          const int col = free_index_[static_cast<size_t>(3 * j + d)];
          if (col >= 0) A_.insert(r, col) = 0.0;
        }
    }
  A_.makeCompressed();

  auto value_index = [&](int r, int col) {
    const int* outer = A_.outerIndexPtr();
    const int* inner = A_.innerIndexPtr();
    const int* p = std::lower_bound(inner + outer[r], inner + outer[r + 1], col);
    if (p == inner + outer[r + 1] || *p != col) throw std::logic_error("sparse pattern lookup failed");
    return static_cast<int>(p - inner);
  };
  diag_.resize(static_cast<size_t>(num_free_));
  for (int r = 0; r < num_free_; ++r) diag_[static_cast<size_t>(r)] = value_index(r, r);
  scatter_.assign(tets_.size() * 144, -1);
  for (size_t e = 0; e < tets_.size(); ++e)
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 3; ++c)
        for (int b = 0; b < 4; ++b)
          for (int d = 0; d < 3; ++d) {
            const int r = free_index_[static_cast<size_t>(3 * tets_[e][a] + c)];
            const int col = free_index_[static_cast<size_t>(3 * tets_[e][b] + d)];
            if (r < 0 || col < 0) continue;
            scatter_[e * 144 + static_cast<size_t>((3 * b + d) * 12 + 3 * a + c)] = value_index(r, col);
          }

  // Greedy colouring of chunks of consecutive elements: a chunk takes the lowest colour
  // not used by any chunk sharing one of its nodes. Colours beyond 63 share one serial bucket.
  const int ne = static_cast<int>(tets_.size());
  const int num_chunks = (ne + chunk_size_ - 1) / chunk_size_;
  std::vector<std::uint64_t> node_colours(static_cast<size_t>(n), 0);
  std::vector<int> chunk_colour(static_cast<size_t>(num_chunks));
  int serial_bucket_used = 0;
  for (int ch = 0; ch < num_chunks; ++ch) {
    std::uint64_t used = 0;
    const int begin = ch * chunk_size_, end = std::min(begin + chunk_size_, ne);
    for (int e = begin; e < end; ++e)
      for (int v : tets_[static_cast<size_t>(e)]) used |= node_colours[static_cast<size_t>(v)];
    int colour = 0;
    while (colour < 64 && (used >> colour) & 1u) ++colour;
    if (colour == 64) {
      serial_bucket_used = 1;
      chunk_colour[static_cast<size_t>(ch)] = -1;
      continue;
    }
    chunk_colour[static_cast<size_t>(ch)] = colour;
    for (int e = begin; e < end; ++e)
      for (int v : tets_[static_cast<size_t>(e)]) node_colours[static_cast<size_t>(v)] |= (std::uint64_t{1} << colour);
  }
  int num_colours = 0;
  for (int c : chunk_colour) num_colours = std::max(num_colours, c + 1);
  colour_chunks_.assign(static_cast<size_t>(num_colours), {});
  for (int ch = 0; ch < num_chunks; ++ch)
    if (chunk_colour[static_cast<size_t>(ch)] >= 0)
      colour_chunks_[static_cast<size_t>(chunk_colour[static_cast<size_t>(ch)])].push_back(ch);
  // Chunks that found no colour run one at a time: each as its own single-chunk colour.
  if (serial_bucket_used)
    for (int ch = 0; ch < num_chunks; ++ch)
      if (chunk_colour[static_cast<size_t>(ch)] < 0) colour_chunks_.push_back({ch});
}

std::vector<int> SparseSystem::node_block_starts() const {
  std::vector<int> starts;
  for (int i = 0; 3 * i < num_dofs_; ++i) {
    for (int c = 0; c < 3; ++c) {
      const int f = free_index_[static_cast<size_t>(3 * i + c)];
      if (f >= 0) {
        starts.push_back(f);
        break;
      }
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
