#pragma once
/// @file Per-element precomputed data (STYLE.md habit 2): rest shape, K^e, g^e. Built once;
/// a parameter change rebuilds only the elements it touches.

#include "core/model.hpp"

#include <vector>

namespace fiberfem::core {

struct ElementCaches {
  std::vector<Vec12> X;       ///< Rest positions of the four nodes, metres.
  std::vector<Mat3> Dm_inv;   ///< Rest-shape inverse, 1/m.
  std::vector<Mat12> K;       ///< Precomputed stiffness K^e in global components, N/m (empty unless built with it).
  std::vector<Vec12> g;       ///< Active-stress vectors g^e, m^2 (empty until needed).

  /// Builds everything but g from a validated model; K only `with_stiffness` (the static
  /// solver reads it; the dynamic step uses the closed form, core/spencer_element.hpp).
  void build(const Model& model, bool with_stiffness = true);
  /// Rebuilds K^e and g^e (those that are present) of the listed elements.
  void rebuild(const Model& model, const std::vector<int>& elements);
  /// Builds g^e for every element.
  void build_active(const Model& model);
};

}  // namespace fiberfem::core
