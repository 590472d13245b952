#include "core/box_generator.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

namespace fiberfem::core {

void BoxSpec::validate() const {
  static const char* kAxis[3] = {"x", "y", "z"};
  for (int d = 0; d < 3; ++d) {
    if (!(std::isfinite(size_m[d]) && size_m[d] > 0))
      throw std::invalid_argument(std::string("box: size_m.") + kAxis[d] + " must be > 0, got " +
                                  std::to_string(size_m[d]));
    if (cells[static_cast<size_t>(d)] < 1)
      throw std::invalid_argument(std::string("box: cells.") + kAxis[d] + " must be >= 1, got " +
                                  std::to_string(cells[static_cast<size_t>(d)]));
    if (!std::isfinite(origin_m[d]))
      throw std::invalid_argument(std::string("box: origin_m.") + kAxis[d] + " must be finite");
  }
  const double n = static_cast<double>(cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1);
  if (n > 2.0e8) throw std::invalid_argument("box: too many nodes (" + std::to_string(n) + ")");
}

TetMesh make_box(const BoxSpec& spec) {
  spec.validate();
  const std::array<int, 3> nc = spec.cells;
  const std::array<int, 3> nn{nc[0] + 1, nc[1] + 1, nc[2] + 1};
  // Axis order: slowest axis first (the one with the most cells).
  std::array<int, 3> order{0, 1, 2};
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return nc[a] > nc[b]; });
  const int s0 = order[0], s1 = order[1], s2 = order[2];
  auto node_id = [&](std::array<int, 3> ijk) {
    return (ijk[s0] * nn[s1] + ijk[s1]) * nn[s2] + ijk[s2];
  };
  const int num_nodes = nn[0] * nn[1] * nn[2];
  Positions x(3, num_nodes);
  for (int i = 0; i < nn[0]; ++i)
    for (int j = 0; j < nn[1]; ++j)
      for (int k = 0; k < nn[2]; ++k) {
        const Vec3 p(spec.origin_m.x() + spec.size_m.x() * i / nc[0],
                     spec.origin_m.y() + spec.size_m.y() * j / nc[1],
                     spec.origin_m.z() + spec.size_m.z() * k / nc[2]);
        x.col(node_id({i, j, k})) = p;
      }
  // Kuhn subdivision: one tet per permutation (p, q, r) of the axes, walking from the
  // minimum corner along p, then q, then r to the maximum corner.
  static constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                      {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  std::vector<Tet> tets;
  tets.reserve(static_cast<size_t>(nc[0]) * nc[1] * nc[2] * 6);
  std::array<int, 3> c{};
  for (c[s0] = 0; c[s0] < nc[s0]; ++c[s0])
    for (c[s1] = 0; c[s1] < nc[s1]; ++c[s1])
      for (c[s2] = 0; c[s2] < nc[s2]; ++c[s2])
        for (const auto& p : kPerm) {
          std::array<int, 3> v = c;
          Tet t{};
          t[0] = node_id(v);
          for (int s = 0; s < 3; ++s) {
            v[static_cast<size_t>(p[s])] += 1;
            t[static_cast<size_t>(s + 1)] = node_id(v);
          }
          if (signed_volume(x.col(t[0]), x.col(t[1]), x.col(t[2]), x.col(t[3])) < 0)
            std::swap(t[2], t[3]);
          tets.push_back(t);
        }
  TetMesh mesh(std::move(x), std::move(tets));
  static const char* kName[3] = {"x", "y", "z"};
  for (int d = 0; d < 3; ++d) {
    std::vector<int> lo, hi;
    for (int i = 0; i < nn[0]; ++i)
      for (int j = 0; j < nn[1]; ++j)
        for (int k = 0; k < nn[2]; ++k) {
          const std::array<int, 3> ijk{i, j, k};
          if (ijk[static_cast<size_t>(d)] == 0) lo.push_back(node_id(ijk));
          if (ijk[static_cast<size_t>(d)] == nc[static_cast<size_t>(d)]) hi.push_back(node_id(ijk));
        }
    mesh.set_node_set(std::string(kName[d]) + "min", std::move(lo));
    mesh.set_node_set(std::string(kName[d]) + "max", std::move(hi));
  }
  return mesh;
}

}  // namespace fiberfem::core
