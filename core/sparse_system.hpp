#pragma once
/// @file The one sparse assembly of the engine: a fixed sparsity pattern over the free
/// degrees of freedom, per-element scatter indices, and a parallel assembly over chunks of
/// neighbouring elements coloured so that no two chunks of a colour share a node.

#include "core/mesh.hpp"
#include "core/parallel.hpp"

#include <Eigen/SparseCore>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <utility>
#include <vector>

namespace fiberfem::core {

/// Row-major sparse matrix type of the engine's linear systems.
using SparseMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

/// Element matrices of up to kWidth elements side by side (structure of arrays), for
/// kernels that compute several elements at once in SIMD lanes (SparseSystem::
/// assemble_batched): the ten upper node blocks (a, b), b >= a, of each symmetric 12 x 12
/// matrix, block k = the k-th pair in the order (0,0), (0,1), .., (0,3), (1,1), .., (3,3),
/// entry (i, j) of a block at upper[9 k + 3 i + j][lane]; and each element's forces.
struct ElementBatch {
  /// Eight: one AVX-512 vector of doubles (two AVX2 vectors elsewhere). Against four, the
  /// element pass of the 5,663-tet TetGen beam took 0.81-0.84 ms instead of 0.92-0.96 on one
  /// thread (docs/performance.md); the polar rotations stay four lanes wide, since every
  /// lane waits for the slowest one's updates.
  static constexpr int kWidth = 8;
  /// The chunk these elements belong to (SparseSystem::num_chunks()): per-chunk sums,
  /// added in chunk order afterwards, round the same on any number of threads.
  int chunk = 0;
  /// Loop position of lane 0: lane l is element SparseSystem::element_order()[first + l]
  /// (per-element data stored in loop order is read at first + l, in sequence).
  int first = 0;
  alignas(64) double upper[90][kWidth];
  Eigen::Matrix<double, 12, 1> force[kWidth];
  /// Index of block (a, b), b >= a, in the order above.
  static constexpr int block_index(int a, int b) { return a * 4 - a * (a - 1) / 2 + (b - a); }
};

/// How the element loop is laid out on the threads (SparseSystem::for_each_element_coloured).
enum class LoopSchedule {
  /// `runs` when the mesh has at least kRunMinElements elements per run and its runs colour
  /// in at most kRunMaxColours colours, else `chunks`.
  automatic,
  /// Chunks of `chunk_size` neighbouring elements, coloured, each chunk its own task
  /// (balanced, but a colour's chunks are spread over the whole body: on a mesh whose
  /// matrix outgrows the caches every colour streams it from memory again).
  chunks,
  /// kRuns runs of consecutive chunks, coloured as wholes (two colours on a mesh in a
  /// local order), each run one task walked in order by one thread: a node's blocks are
  /// written by the elements around it close together in time.
  runs,
};

/// How the free DOFs are numbered (the rows of the step's matrix and of every solver vector).
enum class DofOrder {
  /// Node by node in the mesh's numbering.
  nodes,
  /// Node by node in reverse Cuthill-McKee order of the free nodes' graph (Boost.Graph), taken
  /// when it at least halves the envelope of the mesh's numbering (the sum over nodes of how
  /// far back their earliest neighbour is numbered), else the mesh's order is kept: a node's
  /// matrix rows then sit near its neighbours', so the solver's products, substitutions and
  /// warps stay in cache. A mesh generator's numbering (TetGen's: envelope 14-23 times the
  /// RCM order's; gmsh's heart: 4.6) scatters them; the box and ventricle generators' cell by
  /// cell numbering is local already (1.06 and 1.5 times) and is kept, since the element loop
  /// follows it too.
  bandwidth,
};

/// The engine's free-DOF numbering against the mesh's node order (DofOrder::nodes), for
/// data kept outside the engine (checkpoints): each array maps an index of this system to
/// the same item's index under DofOrder::nodes.
struct NaturalOrder {
  bool identity = true;        ///< Both numberings agree (the maps are then empty).
  std::vector<int> free;       ///< Per free DOF.
  std::vector<int> block;      ///< Per node block (SparseSystem::block_nodes()).
  std::vector<int> value;      ///< Per non-zero of the CSR matrix (row-major, sorted columns).
};

namespace detail {

/// The nodes sharing an element with each node (itself included), sorted, as the rows
/// of a compressed graph: node v's at nodes[start[v] .. start[v + 1]).
struct NodeGraph {
  std::vector<int> start, nodes;
};
/// The constructor's view of the pattern by node blocks: for block row K (the K-th of
/// block_nodes_), the blocks of its neighbours with a free DOF, sorted (itself included),
/// at block[start[K] .. start[K + 1]), and where each one's columns start in the node's
/// rows (column, same indices).
struct BlockRows {
  std::vector<int> row_of_node;  // K of each node, -1 for a node without a free DOF
  std::vector<int> start, block, column;
  std::vector<int> self;  // per row K: the index of K itself in it
  /// Index of block J in row K (into block and column). @throws std::logic_error if absent.
  int find(int K, int J) const;
};

/// Sorts (key, position) pairs ascending, by Boost's spreadsort (a radix sort on the key;
/// core/keyed_sort.cpp, apart because Boost.Sort's namespace clashes with Boost.Graph's
/// headers in one translation unit). Distinct pairs come out as any sort leaves them.
void sort_keyed(std::vector<std::pair<std::uint64_t, int>>& pairs);

/// out[0..8] += lane l of the batch block blk (row-major, or transposed), read and written
/// as eight values and one: the next lane of a batch often adds to the same block (its
/// elements share nodes), and its load is then forwarded from this store whole. Written
/// value by value, the compiler merged the eight stores into one vector store and the next
/// lane's single-value loads waited for it to reach the cache.
inline void add_block(double* out, const double (*blk)[ElementBatch::kWidth], int l, bool transposed) {
  using V8 = double __attribute__((vector_size(8 * sizeof(double))));
  V8 o, b;
  std::memcpy(&o, out, sizeof o);
  if (transposed)
    b = V8{blk[0][l], blk[3][l], blk[6][l], blk[1][l], blk[4][l], blk[7][l], blk[2][l], blk[5][l]};
  else
    b = V8{blk[0][l], blk[1][l], blk[2][l], blk[3][l], blk[4][l], blk[5][l], blk[6][l], blk[7][l]};
  o += b;
  std::memcpy(out, &o, sizeof o);
  out[8] += blk[8][l];
}

}  // namespace detail

class SparseSystem {
 public:
  /// Fewest elements per run for LoopSchedule::automatic to choose runs (meshes of 2,048
  /// elements and more): runs keep each node's blocks in cache from its first element to
  /// its last, which pays from a few thousand elements on (docs/performance.md).
  static constexpr int kRunMinElements = 128;
  /// Most colours of the runs for LoopSchedule::automatic to keep them (four runs per
  /// colour, two per thread on two cores); more, and the loop takes chunks.
  static constexpr int kRunMaxColours = 4;
  /// Runs of LoopSchedule::runs: a fixed count, so that the element order (and with it
  /// the assembly's rounding) does not depend on the thread count; 8 per colour, four per
  /// thread on two cores.
  static constexpr int kRuns = 16;

  /// @param fixed_dofs per-DOF fixed flags (3N) or empty; fixed DOFs are left out.
  /// @param chunk_size elements per chunk of the coloured loop (at least 1).
  /// @param schedule the loop's layout on the threads.
  /// @param dof_order how the free DOFs are numbered.
  SparseSystem(const TetMesh& mesh, const std::vector<std::uint8_t>& fixed_dofs,
               int chunk_size = 32, LoopSchedule schedule = LoopSchedule::automatic,
               DofOrder dof_order = DofOrder::bandwidth);

  int num_dofs() const { return num_dofs_; }
  int num_free() const { return num_free_; }
  /// Free index of each DOF (3N), -1 for fixed ones. A node's free DOFs are consecutive, in
  /// component order; the nodes follow the DofOrder.
  const std::vector<int>& free_index() const { return free_index_; }
  /// The DofOrder kept (DofOrder::nodes when the mesh's numbering was the more local).
  DofOrder dof_order() const { return dof_order_; }
  /// Node of each node block (a node with a free DOF), in free-DOF order.
  const std::vector<int>& block_nodes() const { return block_nodes_; }
  /// This numbering against DofOrder::nodes (computed on the first call, then kept).
  const NaturalOrder& natural_order() const;
  /// The system matrix over free DOFs (full symmetric pattern, both triangles stored). After
  /// assemble_batched its values are stale while blocks_current(): sync_matrix() first.
  SparseMatrix& matrix() { return A_; }
  const SparseMatrix& matrix() const { return A_; }
  /// Position of each free DOF's diagonal entry in the matrix values.
  const std::vector<int>& diagonal_index() const { return diag_; }
  /// Node blocks of the free DOFs: rows starts[k] .. starts[k+1]-1 are the free components
  /// of node block_nodes()[k].
  std::vector<int> node_block_starts() const;
  /// Number of colours of the parallel assembly.
  int num_colours() const { return static_cast<int>(colour_chunks_.size()); }
  /// Whether the loop runs in long runs of chunks (LoopSchedule::runs) rather than chunks.
  bool runs_in_runs() const { return run_chunks_ > 1; }
  /// The element at each position of the loop (chunk after chunk): per-element data kept
  /// in this order is read in sequence by assemble_batched.
  const std::vector<int>& element_order() const { return order_; }
  /// Chunks of the element loop (ElementBatch::chunk is below this).
  int num_chunks() const { return (static_cast<int>(tets_.size()) + chunk_size_ - 1) / chunk_size_; }

  /// Zeros the matrix values (pattern kept).
  void zero_matrix();
  /// Restriction of a full DOF vector to the free DOFs.
  Eigen::VectorXd restrict_to_free(const Eigen::VectorXd& full) const;
  /// Writes free values into a full DOF vector (fixed entries untouched).
  void scatter_free(const Eigen::VectorXd& free, Eigen::VectorXd& full) const;

  /// Parallel element loop. For each element `e`, `kernel(e, Ke, fe)` fills a symmetric
  /// 12x12 matrix (its upper 3x3 node blocks, b >= a, are read: the lower ones may be left
  /// unset) and a 12 force vector (and may accumulate per-thread data indexed by
  /// `omp_get_thread_num`); Ke is added into the matrix (free x free entries) and fe into
  /// `f_full` (3N). Elements of one colour run concurrently; no two of them share a node.
  template <class Kernel>
  void assemble(Kernel&& kernel, Eigen::VectorXd& f_full) {
    assemble_impl<true>(kernel, f_full);
  }
  /// As assemble, for element matrices that are not symmetric (the static solver's
  /// consistent tangent): all sixteen node blocks of Ke are read.
  template <class Kernel>
  void assemble_unsymmetric(Kernel&& kernel, Eigen::VectorXd& f_full) {
    assemble_impl<false>(kernel, f_full);
  }

  /// As assemble, several elements at a time: `kernel(elems, n, batch)` fills the upper
  /// blocks and forces of elements elems[0..n-1] (n <= ElementBatch::kWidth; consecutive
  /// elements of one chunk) into lanes 0..n-1 of `batch`. The matrix values are replaced,
  /// not added to (no zero_matrix() first): each node's rows are zeroed in the parallel
  /// loop, by the first chunk that writes them, just before it does (a separate memset of
  /// the values is a single-threaded pass over the whole matrix, 1.2 MB at 5,760 tets).
  template <class BatchKernel>
  void assemble_batched(BatchKernel&& kernel, Eigen::VectorXd& f_full);

  /// The symmetric block store (upper node blocks only), used by assemble_batched and the
  /// PCG solver's products when every node is wholly free or wholly fixed (has_blocks()).
  /// Block row I is node block I (free DOFs 3I..3I+2, node block_nodes()[I]); it holds the
  /// blocks (I, J), J >= I, each 9 doubles row-major, the diagonal block first. Half the
  /// values of the CSR matrix and one index per block instead of one per entry: the sparse
  /// product takes half the time (bench_symmetric_product). After assemble_batched the
  /// blocks are current and the CSR values are not, until sync_matrix().
  bool has_blocks() const { return block_ok_; }
  bool blocks_current() const { return blocks_current_; }
  /// Fills the CSR values from the blocks (when they are current and it is not); for the
  /// consumers that read the CSR matrix (factorisations, block Jacobi, the direct solver).
  void sync_matrix();
  /// Adds `d` to the diagonal entry of free DOF k (in the blocks when they are current).
  void add_to_diagonal(int k, double d) {
    if (blocks_current_)
      block_values_[9 * static_cast<size_t>(block_start_[static_cast<size_t>(k / 3)]) + 4 * static_cast<size_t>(k % 3)] += d;
    else
      A_.valuePtr()[diag_[static_cast<size_t>(k)]] += d;
  }
  /// Block row I's diagonal block (I, I): 9 doubles, row-major (when has_blocks()).
  const double* diagonal_block(int I) const { return block_values_.data() + 9 * static_cast<size_t>(block_start_[static_cast<size_t>(I)]); }
  /// y = A x from the blocks (current), on the OpenMP threads when `parallel`; returns x . A x.
  double block_product(const Eigen::VectorXd& x, Eigen::VectorXd& y, bool parallel) const;
  /// AW = A W for an n x 8 row-major W (the PCG's recycled solutions), from the blocks.
  void block_product8(const double* W, double* AW, bool parallel) const;
  /// A threaded block product splits its block rows into parts: one per kProductPartRows
  /// rows, at least 2 and at most kMaxProductParts (the most threads it uses). The count
  /// depends on the matrix only, never on the thread count, so the product rounds the
  /// same on any number of threads. (Measured at the paper's 5,760 tets, 1,470 block rows:
  /// 8 parts instead of 2 cost 3-8 % of the solve; large meshes want more parts.)
  static constexpr int kProductPartRows = 2048;
  static constexpr int kMaxProductParts = 64;
  /// A threaded block product's parts and their spills (see sparse_system.cpp).
  struct ProductSpills {
    int block_rows = -1;  // the pattern's block rows these were laid out for
    int parts = 0;
    std::array<int, kMaxProductParts + 1> bounds{};
    std::array<int, kMaxProductParts> hi{};
    std::array<Eigen::VectorXd, kMaxProductParts> spill;  // zero between products
  };

  /// Same chunked, coloured loop without a matrix: `kernel(e)` for each element; safe to
  /// write per-node data of the element's nodes.
  template <class Kernel>
  void for_each_element_coloured(Kernel&& kernel) const;

 private:
  template <bool Symmetric, class Kernel>
  void assemble_impl(Kernel&& kernel, Eigen::VectorXd& f_full);
  /// The coloured loop over chunks: `kernel(begin, end)` for positions [begin, end) of
  /// order_; chunks of one colour run concurrently.
  template <class ChunkKernel>
  void for_each_chunk_coloured(ChunkKernel&& kernel) const;
  int num_dofs_ = 0;
  int num_free_ = 0;
  std::vector<int> free_index_;
  DofOrder dof_order_ = DofOrder::nodes;
  std::vector<int> block_nodes_;
  mutable NaturalOrder natural_;
  mutable bool natural_done_ = false;
  std::vector<Tet> tets_;   // by element while the constructor orders them, then by loop position
  std::vector<int> order_;  // elements in chunk order (the mesh's, or Morton order of centroids)
  /// tets_ into loop order, once order_ is final (the scatter indices are then built so).
  void store_in_loop_order();
  // The constructor's steps, in order (sparse_system.cpp).
  void number_free_dofs(int num_nodes, const std::vector<std::uint8_t>& fixed_dofs, const detail::NodeGraph& graph,
                        DofOrder order);
  detail::BlockRows block_rows(const detail::NodeGraph& graph) const;
  void build_pattern(const detail::BlockRows& rows);
  void build_scatter(const detail::BlockRows& rows);
  void ensure_block_scatter();
  /// Chunk order: the mesh's element order, or Morton order when that needs fewer colours.
  void order_chunks(const TetMesh& mesh, std::vector<std::uint64_t>& morton);
  /// Runs of chunks instead (LoopSchedule::runs, or automatic on large meshes).
  void order_runs(const TetMesh& mesh, LoopSchedule schedule, std::vector<std::uint64_t>& morton);
  /// Position of entry (r, col) in the values. @throws std::logic_error if not in the pattern.
  int value_index(int r, int col) const;
  /// Greedy colouring of `num_units` units of consecutive chunks (a unit is one task; 0:
  /// one unit per chunk); fills colour_chunks_ and colour_tasks_.
  void colour_chunks(int num_nodes, int num_units = 0);
  /// First chunk of unit u of `num_units` over `num_chunks` chunks (u = num_units: the end):
  /// units whose lengths differ by one chunk at most.
  static int unit_first_chunk(int u, int num_units, int num_chunks) {
    return static_cast<int>(static_cast<long>(u) * num_chunks / num_units);
  }
  void plan_zeroing(int num_nodes);
  // Value ranges [first, second) that chunk c zeroes before its elements:
  // zero_ranges_[zero_begin_[c] .. zero_begin_[c + 1]).
  std::vector<std::pair<int, int>> zero_ranges_;
  std::vector<int> zero_begin_;
  // The block store (see has_blocks()).
  void build_blocks(const detail::BlockRows& rows);
  /// Block (I, J) of the block store for J >= I, J at index k of block row I (into
  /// rows.block): row I's blocks are the diagonal, then its neighbours above it.
  int upper_block(const detail::BlockRows& rows, int I, int k) const;
  bool block_ok_ = false;
  bool blocks_current_ = false;
  std::vector<int> node_block_;                 // per node: its block row, or -1 (fixed)
  std::vector<int> block_start_, block_col_;     // block rows: blocks block_start_[I] .. [I+1]-1
  std::vector<double> block_values_;             // 9 per block
  std::vector<int> element_blocks_;              // 10 per loop position: 2 * block + transposed, or -1
  std::vector<int> csr_from_block_;              // per CSR value: its index in block_values_
  std::vector<std::pair<int, int>> block_zero_ranges_;  // as zero_ranges_, in block_values_
  mutable ProductSpills spills1_, spills8_;  // of block_product and block_product8
  SparseMatrix A_;
  std::vector<int> diag_;
  // Where each element's entries go. An element whose 12 DOFs are all free (nearly all)
  // has 48 indices: for node blocks (a, b) and row i of the block, the value index of
  // (row 3 t[a] + i, column 3 t[b]); the block row's 3 columns are consecutive in the
  // pattern. An element with a fixed DOF has 144 (value index of entry (i, j), column-major,
  // or -1) further on, at general_offset_[e].
  static constexpr int kBlockIndices = 48;
  std::vector<int> block_scatter_;     // 48 per loop position (unused for elements with a fixed DOF; empty until assemble() when the blocks are kept)
  std::vector<int> general_offset_;    // per loop position: offset into general_scatter_, or -1
  std::vector<int> general_scatter_;   // 144 per element with a fixed DOF
  int chunk_size_ = 32;
  std::vector<std::vector<int>> colour_chunks_;  // chunk ids per colour, task by task
  // Per colour: task t walks colour_chunks_[c][colour_tasks_[c][t] .. colour_tasks_[c][t + 1]).
  std::vector<std::vector<int>> colour_tasks_;
  int run_chunks_ = 1;  // most chunks per task (1: LoopSchedule::chunks)
};

template <class ChunkKernel>
void SparseSystem::for_each_chunk_coloured(ChunkKernel&& kernel) const {
  const int ne = static_cast<int>(tets_.size());
  for (size_t c = 0; c < colour_chunks_.size(); ++c) {
    const std::vector<int>& chunks = colour_chunks_[c];
    const std::vector<int>& tasks = colour_tasks_[c];
    const int nt = static_cast<int>(tasks.size()) - 1;
    const auto task = [&](int t) {
      for (int ci = tasks[static_cast<size_t>(t)]; ci < tasks[static_cast<size_t>(t) + 1]; ++ci) {
        const int begin = chunks[static_cast<size_t>(ci)] * chunk_size_;
        kernel(begin, std::min(begin + chunk_size_, ne));
      }
    };
    if (threaded()) {
      const int cpu = current_cpu();
#pragma omp parallel
      {
        keep_team_apart(cpu);
#pragma omp for schedule(dynamic, 1)
        for (int t = 0; t < nt; ++t) task(t);
      }
    } else {
      for (int t = 0; t < nt; ++t) task(t);
    }
  }
}

template <class Kernel>
void SparseSystem::for_each_element_coloured(Kernel&& kernel) const {
  for_each_chunk_coloured([&](int begin, int end) {
    for (int k = begin; k < end; ++k) kernel(order_[static_cast<size_t>(k)]);
  });
}

template <class BatchKernel>
void SparseSystem::assemble_batched(BatchKernel&& kernel, Eigen::VectorXd& f_full) {
  double* values = A_.valuePtr();
  constexpr int W = ElementBatch::kWidth;
  const bool blocks = block_ok_;
  double* bvals = block_values_.data();
  for_each_chunk_coloured([&](int begin, int end) {
      const size_t chunk = static_cast<size_t>(begin / chunk_size_);
      for (int z = zero_begin_[chunk]; z < zero_begin_[chunk + 1]; ++z) {
        const auto [first, last] = blocks ? block_zero_ranges_[static_cast<size_t>(z)] : zero_ranges_[static_cast<size_t>(z)];
        std::fill((blocks ? bvals : values) + first, (blocks ? bvals : values) + last, 0.0);
      }
      ElementBatch batch;
      batch.chunk = static_cast<int>(chunk);
      for (int k0 = begin; k0 < end; k0 += W) {
        const int n = std::min(W, end - k0);
        const int* elems = &order_[static_cast<size_t>(k0)];
        batch.first = k0;
        kernel(elems, n, batch);
        for (int l = 0; l < n; ++l) {
          const size_t pos = static_cast<size_t>(k0 + l);
          const int general = general_offset_[pos];
          if (blocks) {
            // Ten 3 x 3 blocks into the upper block store (transposed where the element's
            // node order runs against the block order); pairs with a fixed node are skipped.
            const int* eb = &element_blocks_[pos * 10];
            for (int k = 0; k < 10; ++k) {
              if (eb[k] < 0) continue;
              const double(*blk)[W] = &batch.upper[9 * k];
              double* out = bvals + 9 * static_cast<size_t>(eb[k] >> 1);
              detail::add_block(out, blk, l, (eb[k] & 1) != 0);
            }
          } else if (general < 0) {
            const int* s = &block_scatter_[pos * kBlockIndices];
            for (int a = 0; a < 4; ++a)
              for (int b = a; b < 4; ++b) {
                const double(*blk)[W] = &batch.upper[9 * ElementBatch::block_index(a, b)];
                for (int i = 0; i < 3; ++i) {
                  double* up = values + s[(4 * a + b) * 3 + i];
                  for (int j = 0; j < 3; ++j) up[j] += blk[3 * i + j][l];
                  if (b != a) {
                    double* lo = values + s[(4 * b + a) * 3 + i];
                    for (int j = 0; j < 3; ++j) lo[j] += blk[3 * j + i][l];
                  }
                }
              }
          } else {
            const int* s = &general_scatter_[static_cast<size_t>(general)];
            for (int c = 0; c < 12; ++c)
              for (int r = 0; r < 12; ++r) {
                const int idx = s[c * 12 + r];
                if (idx < 0) continue;
                const int a = std::min(r / 3, c / 3), b = std::max(r / 3, c / 3);
                const int i = r / 3 <= c / 3 ? r % 3 : c % 3, j = r / 3 <= c / 3 ? c % 3 : r % 3;
                values[idx] += batch.upper[9 * ElementBatch::block_index(a, b) + 3 * i + j][l];
              }
          }
          const Tet& t = tets_[pos];
          for (int a = 0; a < 4; ++a)
            f_full.segment<3>(3 * t[static_cast<size_t>(a)]) += batch.force[l].segment<3>(3 * a);
        }
      }
  });
  blocks_current_ = blocks;
}

template <bool Symmetric, class Kernel>
void SparseSystem::assemble_impl(Kernel&& kernel, Eigen::VectorXd& f_full) {
  ensure_block_scatter();
  double* values = A_.valuePtr();
  for_each_chunk_coloured([&](int begin, int end) {
   for (int position = begin; position < end; ++position) {
    const size_t pos = static_cast<size_t>(position);
    Eigen::Matrix<double, 12, 12> Ke;
    Eigen::Matrix<double, 12, 1> fe;
    kernel(order_[pos], Ke, fe);
    const double* k = Ke.data();  // column-major: entry (i, j) at j * 12 + i
    const int general = general_offset_[pos];
    if (general < 0 && !Symmetric) {
      const int* s = &block_scatter_[pos * kBlockIndices];
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b)
          for (int i = 0; i < 3; ++i) {
            double* row = values + s[(4 * a + b) * 3 + i];
            for (int j = 0; j < 3; ++j) row[j] += k[(3 * b + j) * 12 + 3 * a + i];
          }
    } else if (general < 0) {
      const int* s = &block_scatter_[pos * kBlockIndices];
      for (int a = 0; a < 4; ++a)
        for (int b = a; b < 4; ++b)
          for (int i = 0; i < 3; ++i) {
            // Block (a, b), row i: Ke(3a + i, 3b + j), j = 0..2 (stride 12).
            double* up = values + s[(4 * a + b) * 3 + i];
            for (int j = 0; j < 3; ++j) up[j] += k[(3 * b + j) * 12 + 3 * a + i];
            if (b != a) {
              // Block (b, a), row i: Ke(3b + i, 3a + j) = Ke(3a + j, 3b + i), consecutive in j.
              double* lo = values + s[(4 * b + a) * 3 + i];
              const double* col = k + (3 * b + i) * 12 + 3 * a;
              for (int j = 0; j < 3; ++j) lo[j] += col[j];
            }
          }
    } else {
      const int* s = &general_scatter_[static_cast<size_t>(general)];
      for (int j = 0; j < 12; ++j)
        for (int i = 0; i < 12; ++i) {
          const int idx = s[j * 12 + i];
          if (idx < 0) continue;
          // Symmetric: upper blocks as given, lower ones from their transposes.
          values[idx] += (!Symmetric || j / 3 >= i / 3) ? k[j * 12 + i] : k[i * 12 + j];
        }
    }
    const Tet& t = tets_[pos];
    for (int a = 0; a < 4; ++a) f_full.segment<3>(3 * t[static_cast<size_t>(a)]) += fe.segment<3>(3 * a);
   }
  });
}

}  // namespace fiberfem::core
