#pragma once
/// @file Per-element precomputed data (STYLE.md habit 2): rest shape, K^e, g^e. Built once;
/// a parameter change rebuilds only the elements it touches.

#include "core/model.hpp"

#include <vector>

namespace fiberfem::core {

struct ElementCaches {
  std::vector<Vec12> X;       ///< Rest positions of the four nodes, metres.
  std::vector<Mat3> Dm_inv;   ///< Rest-shape inverse, 1/m.
  std::vector<Mat12> K;       ///< Precomputed stiffness K^e in global components, N/m.
  std::vector<Vec12> g;       ///< Active-stress vectors g^e, m^2 (empty until needed).

  /// Builds everything but g from a validated model.
  void build(const Model& model);
  /// Rebuilds K^e (and g^e if present) of the listed elements.
  void rebuild(const Model& model, const std::vector<int>& elements);
  /// Builds g^e for every element.
  void build_active(const Model& model);
};

}  // namespace fiberfem::core
