#include "core/hyperelastic/element_mesh.hpp"

#include "core/hyperelastic/quadrature.hpp"
#include "core/hyperelastic/shape_functions.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace fiberfem::core::hyperelastic {

namespace {

using Edge = std::pair<int, int>;  // corner indices, first < second

Edge edge_of(int a, int b) { return a < b ? Edge{a, b} : Edge{b, a}; }

// Edge -> edge node, sorted by edge for binary search.
using EdgeTable = std::vector<std::pair<Edge, int>>;

int find_edge_node(const EdgeTable& table, int a, int b) {
  const Edge e = edge_of(a, b);
  const auto it = std::lower_bound(table.begin(), table.end(), e,
                                   [](const std::pair<Edge, int>& x, const Edge& key) { return x.first < key; });
  if (it == table.end() || it->first != e) throw std::logic_error("element_mesh: edge missing from the table");
  return it->second;
}

EdgeTable table_of(const std::vector<std::array<int, 2>>& edge_ends, int num_corners) {
  EdgeTable t;
  t.reserve(edge_ends.size());
  for (size_t i = 0; i < edge_ends.size(); ++i)
    t.emplace_back(Edge{edge_ends[i][0], edge_ends[i][1]}, num_corners + static_cast<int>(i));
  std::sort(t.begin(), t.end());
  return t;
}

std::vector<TetShape> shapes_at(const TetRule& rule, int order) {
  std::vector<TetShape> s;
  for (const Eigen::Vector3d& p : rule.points) s.push_back(tet_shape(order, p));
  return s;
}

std::string pair_text(const Edge& e) { return std::to_string(e.first) + "-" + std::to_string(e.second); }

}  // namespace

ElementMesh::ElementMesh(const TetMesh& corners, int order, const EdgePlacement& place)
    : order_(order), num_corners_(corners.num_nodes()) {
  if (order != 1 && order != 2)
    throw std::invalid_argument("element mesh: order must be 1 or 2, got " + std::to_string(order));
  elements_.reserve(static_cast<size_t>(corners.num_elements()));
  for (const Tet& t : corners.tets()) {
    std::array<int, 10> el;
    el.fill(-1);
    std::copy(t.begin(), t.end(), el.begin());
    elements_.push_back(el);
  }
  rest_ = corners.rest_positions();
  if (order == 2) {
    // Every edge once, in lexicographic order of its corner pair: independent of the order
    // of the elements and of their local numbering.
    std::vector<Edge> edges;
    edges.reserve(6 * elements_.size());
    for (const Tet& t : corners.tets())
      for (const auto& [a, b] : kTetEdges) edges.push_back(edge_of(t[static_cast<size_t>(a)], t[static_cast<size_t>(b)]));
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    rest_.conservativeResize(3, num_corners_ + static_cast<Eigen::Index>(edges.size()));
    for (size_t i = 0; i < edges.size(); ++i) {
      const auto [a, b] = edges[i];
      const Vec3 mid = 0.5 * (rest_.col(a) + rest_.col(b));
      const Vec3 x = place ? place(a, b, mid) : mid;
      if (!x.allFinite())
        throw std::invalid_argument("element mesh: the edge placement gave a non-finite position for edge " +
                                    pair_text(edges[i]));
      rest_.col(num_corners_ + static_cast<Eigen::Index>(i)) = x;
      edge_ends_.push_back({a, b});
    }
    const EdgeTable table = table_of(edge_ends_, num_corners_);
    for (std::array<int, 10>& el : elements_)
      for (size_t k = 0; k < kTetEdges.size(); ++k)
        el[4 + k] = find_edge_node(table, el[static_cast<size_t>(kTetEdges[k][0])], el[static_cast<size_t>(kTetEdges[k][1])]);
  }
  build_faces(corners);
  check_jacobians();
}

// The file's element e may list the TetMesh's corners in another order (TetMesh swaps the
// last two corners of an inverted element), so each edge node is matched to its corner
// pair first and placed by the TetMesh's order second. Node n's pair is fixed by the
// first element that uses it; any other pair for n, or another node for the same pair,
// is a file whose elements do not share their edges.
ElementMesh::ElementMesh(const TetMesh& corners, const std::vector<std::array<int, 10>>& elements,
                         const Positions& edge_positions)
    : order_(2), num_corners_(corners.num_nodes()) {
  const int num_edges = static_cast<int>(edge_positions.cols());
  if (static_cast<int>(elements.size()) != corners.num_elements())
    throw std::invalid_argument("element mesh: " + std::to_string(elements.size()) + " 10-node elements for " +
                                std::to_string(corners.num_elements()) + " tetrahedra");
  if (!edge_positions.allFinite()) throw std::invalid_argument("element mesh: non-finite edge node position");
  edge_ends_.assign(static_cast<size_t>(num_edges), {-1, -1});
  std::vector<int> first_user(static_cast<size_t>(num_edges), -1);  // element that placed each edge node
  for (size_t e = 0; e < elements.size(); ++e) {
    const std::array<int, 10>& in = elements[e];
    const std::string name = "element mesh: element " + std::to_string(e);
    std::array<int, 4> given{in[0], in[1], in[2], in[3]}, expected = corners.tets()[e];
    std::sort(given.begin(), given.end());
    std::sort(expected.begin(), expected.end());
    if (given != expected) throw std::invalid_argument(name + ": its corners differ from the tetrahedron's");
    EdgeTable local;
    for (size_t k = 0; k < kTetEdges.size(); ++k) {
      const int node = in[4 + k];
      const std::string which = name + ": its node " + std::to_string(4 + k) + " (of 0..9, edge node " + std::to_string(node);
      const Edge pair = edge_of(in[static_cast<size_t>(kTetEdges[k][0])], in[static_cast<size_t>(kTetEdges[k][1])]);
      if (node < num_corners_ || node >= num_corners_ + num_edges)
        throw std::invalid_argument(which + ") is out of range [" + std::to_string(num_corners_) + ", " +
                                    std::to_string(num_corners_ + num_edges) + ")");
      const size_t i = static_cast<size_t>(node - num_corners_);
      std::array<int, 2>& ends = edge_ends_[i];
      if (ends[0] < 0) {
        ends = {pair.first, pair.second};
        first_user[i] = static_cast<int>(e);
      }
      if (Edge{ends[0], ends[1]} != pair)
        throw std::invalid_argument(which + ") sits on corners " + pair_text(pair) + " here but on corners " +
                                    pair_text({ends[0], ends[1]}) + " in element " + std::to_string(first_user[i]));
      local.emplace_back(pair, node);
    }
    std::sort(local.begin(), local.end());
    std::array<int, 10> el;
    std::copy(corners.tets()[e].begin(), corners.tets()[e].end(), el.begin());
    for (size_t k = 0; k < kTetEdges.size(); ++k)
      el[4 + k] = find_edge_node(local, el[static_cast<size_t>(kTetEdges[k][0])], el[static_cast<size_t>(kTetEdges[k][1])]);
    elements_.push_back(el);
  }
  for (int i = 0; i < num_edges; ++i)
    if (edge_ends_[static_cast<size_t>(i)][0] < 0)
      throw std::invalid_argument("element mesh: edge node " + std::to_string(num_corners_ + i) + " is used by no element");
  const EdgeTable table = table_of(edge_ends_, num_corners_);
  for (size_t i = 1; i < table.size(); ++i)
    if (table[i].first == table[i - 1].first)
      throw std::invalid_argument("element mesh: the edge between corners " + pair_text(table[i].first) +
                                  " has two edge nodes, " + std::to_string(table[i - 1].second) + " (in element " +
                                  std::to_string(first_user[static_cast<size_t>(table[i - 1].second - num_corners_)]) +
                                  ") and " + std::to_string(table[i].second) + " (in element " +
                                  std::to_string(first_user[static_cast<size_t>(table[i].second - num_corners_)]) + ")");
  rest_.resize(3, num_corners_ + num_edges);
  rest_.leftCols(num_corners_) = corners.rest_positions();
  rest_.rightCols(num_edges) = edge_positions;
  build_faces(corners);
  check_jacobians();
}

void ElementMesh::build_faces(const TetMesh& corners) {
  const EdgeTable table = table_of(edge_ends_, num_corners_);
  faces_.reserve(corners.boundary_triangles().size());
  for (const Tri& t : corners.boundary_triangles()) {
    std::array<int, 6> f;
    f.fill(-1);
    std::copy(t.begin(), t.end(), f.begin());
    if (order_ == 2)
      for (size_t k = 0; k < kTriangleEdges.size(); ++k)
        f[3 + k] = find_edge_node(table, t[static_cast<size_t>(kTriangleEdges[k][0])], t[static_cast<size_t>(kTriangleEdges[k][1])]);
    faces_.push_back(f);
  }
}

// det J of the 10-node element is a cubic in xi; positive at the nodes and the 14 points
// of the degree-5 rule is the practical test of an untangled curved element (a linear
// element has a constant, positive det J by TetMesh's construction).
void ElementMesh::check_jacobians() const {
  if (order_ == 1) return;
  static const std::vector<TetShape> shapes = [] {
    std::vector<TetShape> s = shapes_at(tetrahedron_rule(14), 2);
    const Eigen::Vector3d corner[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (const auto& c : corner) s.push_back(tet_shape(2, c));
    for (const auto& [a, b] : kTetEdges) s.push_back(tet_shape(2, 0.5 * (corner[a] + corner[b])));
    return s;
  }();
  for (int e = 0; e < num_elements(); ++e) {
    const Eigen::Matrix<double, 3, 10> X = element_positions(e);
    for (const TetShape& s : shapes)
      if (!((X * s.dN).determinant() > 0))
        throw std::invalid_argument("element mesh: element " + std::to_string(e) +
                                    " is tangled by its edge nodes (det J <= 0 inside it)");
  }
}

Eigen::Matrix<double, 3, 10> ElementMesh::element_positions(int e) const {
  Eigen::Matrix<double, 3, 10> X = Eigen::Matrix<double, 3, 10>::Zero();
  const std::array<int, 10>& el = elements_[static_cast<size_t>(e)];
  for (int a = 0; a < nodes_per_element(); ++a) X.col(a) = rest_.col(el[static_cast<size_t>(a)]);
  return X;
}

std::vector<std::uint8_t> ElementMesh::fixed_dofs(const std::vector<std::uint8_t>& corner_fixed_dofs) const {
  std::vector<std::uint8_t> out(3 * static_cast<size_t>(num_nodes()), 0);
  if (corner_fixed_dofs.empty()) return out;
  if (corner_fixed_dofs.size() != 3 * static_cast<size_t>(num_corners_))
    throw std::invalid_argument("element mesh: fixed_dofs needs 3 x " + std::to_string(num_corners_) +
                                " corner flags, got " + std::to_string(corner_fixed_dofs.size()));
  std::copy(corner_fixed_dofs.begin(), corner_fixed_dofs.end(), out.begin());
  for (size_t i = 0; i < edge_ends_.size(); ++i)
    for (size_t c = 0; c < 3; ++c)
      out[3 * (static_cast<size_t>(num_corners_) + i) + c] =
          corner_fixed_dofs[3 * static_cast<size_t>(edge_ends_[i][0]) + c] && corner_fixed_dofs[3 * static_cast<size_t>(edge_ends_[i][1]) + c];
  return out;
}

std::vector<double> element_volumes(const ElementMesh& mesh) {
  const TetRule& rule = tetrahedron_rule(14);
  const std::vector<TetShape> shapes = shapes_at(rule, mesh.order());
  std::vector<double> v(static_cast<size_t>(mesh.num_elements()), 0.0);
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const Eigen::Matrix<double, 3, 10> X = mesh.element_positions(e);
    for (size_t q = 0; q < shapes.size(); ++q) v[static_cast<size_t>(e)] += rule.weights[q] * (X * shapes[q].dN).determinant();
  }
  return v;
}

// HRZ lumping (Hinton, Rock and Zienkiewicz 1976): m_a = M_aa * (rho V) / sum_b M_bb with
// M_aa = int rho N_a^2 dV. Row sums of the 10-node element's consistent mass are negative
// at the corners; the diagonal is positive, so every lumped mass is.
Eigen::VectorXd lumped_masses(const ElementMesh& mesh, const std::vector<double>& rho_kg_m3) {
  if (static_cast<int>(rho_kg_m3.size()) != mesh.num_elements())
    throw std::invalid_argument("lumped masses: " + std::to_string(rho_kg_m3.size()) + " densities for " +
                                std::to_string(mesh.num_elements()) + " elements");
  for (size_t e = 0; e < rho_kg_m3.size(); ++e)
    if (!(std::isfinite(rho_kg_m3[e]) && rho_kg_m3[e] > 0))
      throw std::invalid_argument("lumped masses: the density of element " + std::to_string(e) + " must be > 0, got " +
                                  std::to_string(rho_kg_m3[e]));
  const TetRule& rule = tetrahedron_rule(14);
  const std::vector<TetShape> shapes = shapes_at(rule, mesh.order());
  const int n = mesh.nodes_per_element();
  Eigen::VectorXd m = Eigen::VectorXd::Zero(mesh.num_nodes());
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const Eigen::Matrix<double, 3, 10> X = mesh.element_positions(e);
    Eigen::Matrix<double, 10, 1> diagonal = Eigen::Matrix<double, 10, 1>::Zero();
    double volume = 0;
    for (size_t q = 0; q < shapes.size(); ++q) {
      const double dv = rule.weights[q] * (X * shapes[q].dN).determinant();
      volume += dv;
      diagonal += dv * shapes[q].N.cwiseAbs2();
    }
    const double scale = rho_kg_m3[static_cast<size_t>(e)] * volume / diagonal.sum();
    const std::array<int, 10>& el = mesh.elements()[static_cast<size_t>(e)];
    for (int a = 0; a < n; ++a) m(el[static_cast<size_t>(a)]) += scale * diagonal(a);
  }
  return m;
}

}  // namespace fiberfem::core::hyperelastic
