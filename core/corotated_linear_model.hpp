#pragma once
/// @file The corotated linear tetrahedron as an ElementModel: the engine's element family
/// (PHYSICS.md sections 2 to 6), in the closed form of core/spencer_element.hpp, several
/// elements per SIMD pass with the rotations fused in.

#include "core/element_model.hpp"
#include "core/model.hpp"
#include "core/spencer_element.hpp"

#include <vector>

namespace fiberfem::core {

class CorotatedLinearModel final : public ElementModel {
  // One cache line per chunk of the element loop for its sums (chunks of one colour run
  // on different threads at once).
  struct alignas(64) ChunkAcc {
    double energy = 0;
    int inverted = 0;
  };

 public:
  /// From a validated model (the rest shape of each element from its mesh). `block_nodes`:
  /// the node of each free node block, in block order
  /// (update_node_rotations). `element_order`: the assembly loop's order
  /// (SparseSystem::element_order()), in which the model stores what the pass reads per
  /// element, so that the pass reads it in sequence. Keeps a reference to model.mesh,
  /// which must outlive it.
  CorotatedLinearModel(const Model& model, std::vector<int> block_nodes,
                       const std::vector<int>& element_order);

  double assemble(const ElementPass& pass, SimulatorState& st, SparseSystem& sys, Eigen::VectorXd& f,
                  Eigen::VectorXd& f_active) override;
  double elastic_energy(const Eigen::VectorXd& x, bool corotation) const override;
  int count_inverted(const Eigen::VectorXd& x) const override;
  void seed_rotations(SimulatorState& st, bool corotation) const override;
  void update_node_rotations(SimulatorState& st, bool corotation) const override;
  void set_region_material(int region, const Material& material) override;
  void set_region_stiffness_damping(int region, double beta_s) override;
  void set_fiber(int e, const Vec3& unit_fiber) override;
  /// Bytes of stored data the pass reads per element (rest shape, fiber, law, damping,
  /// nodes), for traffic counts.
  static constexpr size_t pass_bytes_per_element() { return sizeof(ElementLanes) / 8; }

 private:
  /// Ds - Dm and F of the element at loop position k.
  Mat3 element_edges(const Eigen::VectorXd& x, size_t k) const;
  Mat3 element_gradient(const Eigen::VectorXd& x, size_t k) const;
  static int rotate_elements(const ElementPass& pass, SimulatorState& st, int first, int n, const Mat3* F);
  /// The pass's lanes of volume times the region law's constants, from elements_, region_
  /// and region_law_ (after a material changes).
  void refresh_lane_laws();
  struct ElementLanes;
  /// Lanes of loop positions pos[0..7] copied from lanes_.
  void lanes_copy(const size_t* pos, ElementLanes& out) const;
  /// fn(block, lane) for each slot of lanes_ that holds loop position k: its own, and
  /// when k is the last element the padding slots after it, which repeat it.
  template <class Fn>
  void for_each_slot(size_t k, Fn&& fn) {
    const size_t end = k + 1 == elements_.size() ? 8 * lanes_.size() : k + 1;
    for (size_t p = k; p < end; ++p) fn(lanes_[p / 8], p % 8);
  }

  // What the pass reads of each element, eight loop positions side by side: lane l of
  // block b is loop position 8 b + l (the pass's batches start at multiples of eight),
  // read with vector loads instead of one value per lane. The last block's lanes past the
  // last element repeat it. Values as in elements_ (the same bits).
  struct alignas(64) ElementLanes {
    double Dm[9][8];      // rest edges, row-major: Dm(r, c) at [3 r + c]
    double Dm_inv[9][8];  // rest-shape inverse, row-major
    double fiber[3][8];
    double law[5][8];     // volume times lambda, mu_T, alpha, gamma, beta of the region
    double volume[8];     // rest volume, m^3
    double beta[8];       // stiffness damping, s
    int node3[4][8];      // 3 x the node of each corner (its first coordinate in x)
  };

  const TetMesh& mesh_;
  // Per element, stored by loop position (position_[e] of element e, order_[k] at k).
  std::vector<int> order_, position_;
  std::vector<SpencerElement> elements_;      // what the pass reads
  std::vector<Tet> tets_;                     // nodes
  std::vector<int> region_;                   // region (the damping is in lanes_)
  std::vector<SpencerConstants> region_law_;  // per region
  std::vector<ElementLanes> lanes_;           // what the pass reads, by blocks of eight positions
  // Node blocks of the free DOFs (for the warp preconditioner): node of each block, and
  // the elements around each node (CSR, by loop position, in element order).
  std::vector<int> block_node_;
  std::vector<int> node_elem_start_, node_elems_;
  std::vector<ChunkAcc> acc_;  // per chunk of the pass (sized once)
};

}  // namespace fiberfem::core
