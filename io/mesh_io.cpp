#include "io/mesh_io.hpp"

#include "io/input_file.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <istream>
#include <map>
#include <numeric>
#include <ostream>
#include <set>
#include <sstream>
#include <string_view>
#include <type_traits>
#include <unordered_map>
#include <vector>

namespace fiberfem::io {
namespace {

// Line reader that knows where it is, for "<file>:<line>: " errors.
class Lines {
 public:
  Lines(std::istream& in, std::string origin) : in_(in), origin_(std::move(origin)) {}
  bool next(std::string& line) {
    if (!std::getline(in_, line)) return false;
    ++number_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }
  std::string need(const std::string& what) {
    std::string line;
    if (!next(line)) fail("unexpected end of file, expected " + what);
    return line;
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw MeshFileError(origin_ + ":" + std::to_string(number_) + ": " + what);
  }
  const std::string& origin() const { return origin_; }

 private:
  std::istream& in_;
  std::string origin_;
  int number_ = 0;
};

// A number read from a file and used as an integer (id, count, tag): refused unless it is
// whole and within [lo, hi] (casting an out-of-range double is undefined behaviour).
template <class Source>
long whole(Source& src, double v, const std::string& what, double lo = -9007199254740992.0,
           double hi = 9007199254740992.0) {
  if (!(v >= lo && v <= hi) || v != std::floor(v)) {
    std::ostringstream m;
    m << what << " must be an integer in [" << lo << ", " << hi << "], got " << v;
    src.fail(m.str());
  }
  return static_cast<long>(v);
}
constexpr double kIntMax = 2147483647.0;

// One number of type T from a whole token, as `istream >> v` reads it (a leading '+'
// allowed; no "inf" or "nan", which a stream refuses too); false if any of it is left.
template <class T>
bool parse_token(std::string_view tok, T& v) {
  if (tok.size() > 1 && tok[0] == '+' && tok[1] != '-' && tok[1] != '+') tok.remove_prefix(1);
  if constexpr (std::is_floating_point_v<T>) {
    const char c = tok.empty() ? '\0' : tok[tok[0] == '-' ? 1 : 0];
    if (c == 'i' || c == 'I' || c == 'n' || c == 'N') return false;
  }
  const auto [end, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
  return ec == std::errc() && end == tok.data() + tok.size();
}

// Parses all whitespace-separated fields of a line as numbers of type T (from_chars: a
// 250,000-tet TetGen mesh reads in a quarter of the time of a string stream per token).
template <class T>
void fields_into(Lines& lines, std::string_view text, const std::string& what, std::vector<T>& out) {
  out.clear();
  size_t at = 0;
  // (A loop per character: find_first_of runs memchr over the set for each one.)
  const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r'; };
  const size_t size = text.size();
  while (true) {
    while (at < size && space(text[at])) ++at;
    if (at == size) break;
    size_t end = at;
    while (end < size && !space(text[end])) ++end;
    const std::string_view tok = text.substr(at, end - at);
    T v{};
    if (!parse_token(tok, v)) lines.fail("'" + printable(std::string(tok)) + "' is not a valid " + what);
    out.push_back(v);
    at = end;
  }
}
template <class T>
std::vector<T> fields(Lines& lines, const std::string& line, const std::string& what) {
  std::vector<T> out;
  fields_into(lines, line, what, out);
  return out;
}

long count_line(Lines& lines, const std::string& what) {
  const std::vector<long> n = fields<long>(lines, lines.need(what), "count");
  if (n.size() != 1 || n[0] < 0) lines.fail("expected one non-negative count of " + what);
  return n[0];
}

void expect(Lines& lines, const std::string& tag) {
  if (lines.need(tag) != tag) lines.fail("expected " + tag);
}

}  // namespace

namespace {

// What a gmsh file holds, before it becomes a mesh: nodes in file order, tetrahedra of one
// order (4 or 10 nodes, gmsh order; indices into `points`), node sets by physical tag.
struct GmshContent {
  std::vector<core::Vec3> points;
  std::vector<long> ids;  // the file's node id of each point
  int order = 0;  // 1 or 2 once a tetrahedron is read
  std::vector<std::array<int, 10>> cells;
  std::vector<int> regions;
  std::map<int, std::string> physical_names;       // tag -> name (dim < 3)
  std::map<int, std::set<int>> nodes_of_physical;  // tag -> nodes of lower-dim elements
};

// Nodes per element type: point, 2- and 3-node lines, 3- and 6-node triangles, 4- and
// 10-node tetrahedra. Other types (hexahedra, quadrangles, ...) are ignored unless they
// are volumes (below).
int nodes_of_type(long type) {
  static const std::map<long, int> kNodes = {{15, 1}, {1, 2}, {8, 3}, {2, 3}, {9, 6}, {4, 4}, {11, 10}};
  const auto it = kNodes.find(type);
  return it == kNodes.end() ? 0 : it->second;
}

// Refuses volume elements that are not tetrahedra of order 1 or 2 (hexahedra 5 and 12,
// prisms 6 and 13, pyramids 7 and 14, higher-order tetrahedra 29, 30, 31), quadrangles
// (3, 10), and (when `allow_quadratic` is false) 10-node tetrahedra.
void check_type(Lines& lines, long type, bool allow_quadratic) {
  static const std::set<long> kRefused = {3, 5, 6, 7, 10, 12, 13, 14, 29, 30, 31};
  if (kRefused.count(type))
    lines.fail("element type " + std::to_string(type) + " is not a tetrahedron of order 1 or 2 (types 4, 11)");
  if (type == 11 && !allow_quadratic)
    lines.fail("element type 11 is a 10-node tetrahedron; this reader takes linear ones (type 4): read the file "
               "with mesh order 2 (mesh.order: 2)");
}

// Adds a read element: a tetrahedron to the cells (one order per file), any other type to
// the node sets of its physical tags.
void add_element(Lines& lines, GmshContent& c, long type, const std::vector<int>& nodes,
                 const std::vector<int>& physicals, int region) {
  if (type == 4 || type == 11) {
    const int order = type == 4 ? 1 : 2;
    if (c.order != 0 && c.order != order)
      lines.fail("the file mixes linear (type 4) and 10-node (type 11) tetrahedra");
    if (region < 0) lines.fail("negative physical tag");
    c.order = order;
    std::array<int, 10> cell;
    cell.fill(-1);
    std::copy(nodes.begin(), nodes.end(), cell.begin());
    c.cells.push_back(cell);
    c.regions.push_back(region);
  } else {
    for (int t : physicals) c.nodes_of_physical[t].insert(nodes.begin(), nodes.end());
  }
}

GmshContent parse_gmsh(std::istream& in, const std::string& origin, double scale, bool allow_quadratic) {
  if (!(scale > 0 && std::isfinite(scale))) throw MeshFileError(origin + ": scale must be > 0");
  Lines lines(in, origin);
  GmshContent c;
  std::map<long, int> index_of_id;  // node id -> index
  std::vector<core::Vec3>& points = c.points;
  std::map<int, std::string>& physical_names = c.physical_names;
  bool have_format = false, have_nodes = false, have_elements = false;
  int major = 0;
  // MSH 4.1: physical tags hang on entities, (dim, entity tag) -> physical tags.
  std::map<std::pair<int, int>, std::vector<int>> entity_physicals;
  std::string line;
  while (lines.next(line)) {
    if (line.empty()) continue;
    if (line == "$MeshFormat") {
      const std::vector<double> f = fields<double>(lines, lines.need("version line"), "number");
      if (f.size() != 3) lines.fail("expected 'version file-type data-size'");
      if (!((f[0] >= 2.0 && f[0] < 3.0) || std::abs(f[0] - 4.1) < 1e-9))
        lines.fail("MSH version " + std::to_string(f[0]) + " is not supported (2.2 or 4.1 ASCII)");
      major = static_cast<int>(f[0]);
      if (f[1] != 0) lines.fail("binary MSH files are not supported (save as ASCII)");
      expect(lines, "$EndMeshFormat");
      have_format = true;
    } else if (line == "$PhysicalNames") {
      const long n = count_line(lines, "physical names");
      for (long i = 0; i < n; ++i) {
        const std::string l = lines.need("a physical name");
        std::istringstream s(l);
        int dim = 0, tag = 0;
        if (!(s >> dim >> tag)) lines.fail("expected 'dimension tag \"name\"'");
        const size_t q0 = l.find('"'), q1 = l.rfind('"');
        if (q0 == std::string::npos || q1 == q0) lines.fail("the physical name must be quoted");
        if (dim < 3) physical_names[tag] = l.substr(q0 + 1, q1 - q0 - 1);
      }
      expect(lines, "$EndPhysicalNames");
    } else if (line == "$Entities" && major == 4) {
      const std::vector<long> n = fields<long>(lines, lines.need("entity counts"), "integer");
      if (n.size() != 4) lines.fail("expected 'numPoints numCurves numSurfaces numVolumes'");
      for (int dim = 0; dim < 4; ++dim)
        for (long i = 0; i < n[static_cast<size_t>(dim)]; ++i) {
          const std::vector<double> f = fields<double>(lines, lines.need("an entity"), "number");
          // point: tag x y z nphys phys...; others: tag 6 bounds nphys phys... nbound bound...
          const size_t at = dim == 0 ? 4 : 7;
          if (f.size() < at + 1) lines.fail("entity line too short");
          const long nphys = whole(lines, f[at], "the physical tag count", 0, kIntMax);
          if (nphys < 0 || f.size() < at + 1 + static_cast<size_t>(nphys)) lines.fail("bad physical tag count");
          std::vector<int>& ph = entity_physicals[{dim, static_cast<int>(whole(lines, f[0], "the entity tag", -kIntMax, kIntMax))}];
          for (long k = 0; k < nphys; ++k)
            ph.push_back(static_cast<int>(whole(lines, f[at + 1 + static_cast<size_t>(k)], "a physical tag", -kIntMax, kIntMax)));
        }
      expect(lines, "$EndEntities");
    } else if (line == "$Nodes" && major == 4) {
      const std::vector<long> h = fields<long>(lines, lines.need("node header"), "integer");
      if (h.size() != 4) lines.fail("expected 'numEntityBlocks numNodes minNodeTag maxNodeTag'");
      for (long b = 0; b < h[0]; ++b) {
        const std::vector<long> bh = fields<long>(lines, lines.need("a node block header"), "integer");
        if (bh.size() != 4) lines.fail("expected 'entityDim entityTag parametric numNodesInBlock'");
        const long count = bh[3];
        std::vector<long> ids;
        for (long i = 0; i < count; ++i) {
          const std::vector<long> id = fields<long>(lines, lines.need("a node tag"), "integer");
          if (id.size() != 1 || id[0] < 1) lines.fail("expected one positive node tag");
          ids.push_back(id[0]);
        }
        for (long i = 0; i < count; ++i) {
          const std::vector<double> f = fields<double>(lines, lines.need("node coordinates"), "number");
          if (f.size() < 3) lines.fail("expected 'x y z'");
          if (!std::isfinite(f[0]) || !std::isfinite(f[1]) || !std::isfinite(f[2])) lines.fail("non-finite coordinate");
          if (!index_of_id.emplace(ids[static_cast<size_t>(i)], static_cast<int>(points.size())).second)
            lines.fail("node " + std::to_string(ids[static_cast<size_t>(i)]) + " is given twice");
          points.emplace_back(scale * f[0], scale * f[1], scale * f[2]);
          c.ids.push_back(ids[static_cast<size_t>(i)]);
        }
      }
      if (static_cast<long>(points.size()) != h[1]) lines.fail("the blocks hold " + std::to_string(points.size()) + " nodes, the header says " + std::to_string(h[1]));
      expect(lines, "$EndNodes");
      have_nodes = true;
    } else if (line == "$Elements" && major == 4) {
      if (!have_nodes) lines.fail("$Elements before $Nodes");
      const std::vector<long> h = fields<long>(lines, lines.need("element header"), "integer");
      if (h.size() != 4) lines.fail("expected 'numEntityBlocks numElements minElementTag maxElementTag'");
      for (long b = 0; b < h[0]; ++b) {
        const std::vector<long> bh = fields<long>(lines, lines.need("an element block header"), "integer");
        if (bh.size() != 4) lines.fail("expected 'entityDim entityTag elementType numElementsInBlock'");
        const int dim = static_cast<int>(bh[0]), etag = static_cast<int>(bh[1]);
        const long type = bh[2];
        check_type(lines, type, allow_quadratic);
        const int count = nodes_of_type(type);
        const auto ph = entity_physicals.find({dim, etag});
        // Without an $Entities section (as meshio writes) the entity tag is the region tag.
        const int physical = ph != entity_physicals.end() && !ph->second.empty() ? ph->second.front()
                             : entity_physicals.empty()                            ? etag
                                                                                   : 0;
        for (long i = 0; i < bh[3]; ++i) {
          const std::vector<long> f = fields<long>(lines, lines.need("an element"), "integer");
          if (count == 0) continue;
          if (static_cast<long>(f.size()) != 1 + count)
            lines.fail("element type " + std::to_string(type) + " needs " + std::to_string(count) + " nodes");
          std::vector<int> nodes;
          for (int k = 0; k < count; ++k) {
            const auto found = index_of_id.find(f[static_cast<size_t>(1 + k)]);
            if (found == index_of_id.end())
              lines.fail("element refers to node " + std::to_string(f[static_cast<size_t>(1 + k)]) + ", which is not in $Nodes");
            nodes.push_back(found->second);
          }
          add_element(lines, c, type, nodes, ph != entity_physicals.end() ? ph->second : std::vector<int>{}, physical);
        }
      }
      expect(lines, "$EndElements");
      have_elements = true;
    } else if (line == "$Nodes") {
      if (major != 2) lines.fail("$Nodes before $MeshFormat");
      const long n = count_line(lines, "nodes");
      points.reserve(static_cast<size_t>(std::min(n, 1L << 20)));  // a bad count must not allocate
      for (long i = 0; i < n; ++i) {
        const std::vector<double> f = fields<double>(lines, lines.need("a node"), "number");
        if (f.size() != 4) lines.fail("expected 'id x y z'");
        const long id = whole(lines, f[0], "the node id", 1);
        if (!std::isfinite(f[1]) || !std::isfinite(f[2]) || !std::isfinite(f[3])) lines.fail("non-finite coordinate");
        if (!index_of_id.emplace(id, static_cast<int>(points.size())).second)
          lines.fail("node " + std::to_string(id) + " is given twice");
        points.emplace_back(scale * f[1], scale * f[2], scale * f[3]);
        c.ids.push_back(id);
      }
      expect(lines, "$EndNodes");
      have_nodes = true;
    } else if (line == "$Elements") {
      if (!have_nodes) lines.fail("$Elements before $Nodes");
      const long n = count_line(lines, "elements");
      for (long i = 0; i < n; ++i) {
        const std::vector<long> f = fields<long>(lines, lines.need("an element"), "integer");
        if (f.size() < 3) lines.fail("expected 'id type ntags tags... nodes...'");
        const long type = f[1], ntags = f[2];
        if (ntags < 0 || ntags > static_cast<long>(f.size()) - 3) lines.fail("bad tag count");
        check_type(lines, type, allow_quadratic);
        const int count = nodes_of_type(type);
        if (count == 0) continue;  // other lower-dimensional types are ignored
        if (static_cast<long>(f.size()) != 3 + ntags + count)
          lines.fail("element type " + std::to_string(type) + " needs " + std::to_string(count) + " nodes");
        const int physical = ntags > 0 ? static_cast<int>(whole(lines, static_cast<double>(f[3]), "the physical tag", -kIntMax, kIntMax)) : 0;
        std::vector<int> nodes;
        for (int k = 0; k < count; ++k) {
          const long id = f[static_cast<size_t>(3 + ntags + k)];
          const auto found = index_of_id.find(id);
          if (found == index_of_id.end()) lines.fail("element refers to node " + std::to_string(id) + ", which is not in $Nodes");
          nodes.push_back(found->second);
        }
        add_element(lines, c, type, nodes, ntags > 0 ? std::vector<int>{physical} : std::vector<int>{}, physical);
      }
      expect(lines, "$EndElements");
      have_elements = true;
    } else if (line[0] == '$') {
      // Unknown section ($NodeData, $Periodic, ...): skip to its end.
      const std::string end = "$End" + line.substr(1);
      std::string l;
      while (true) {
        if (!lines.next(l)) lines.fail("unexpected end of file inside " + printable(line));
        if (l == end) break;
      }
    } else {
      lines.fail("expected a section start ($...), got '" + printable(line, 40) + "'");
    }
  }
  if (!have_format) throw MeshFileError(origin + ": no $MeshFormat section (not a gmsh file?)");
  if (!have_elements || c.cells.empty())
    throw MeshFileError(origin + (allow_quadratic ? ": no tetrahedra (type 4 or 11) in the file" : ": no linear tetrahedra (type 4) in the file"));
  return c;
}

}  // namespace

namespace {

core::Positions columns(const std::vector<core::Vec3>& points) {
  core::Positions X(3, static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) X.col(static_cast<Eigen::Index>(i)) = points[i];
  return X;
}

// The corner mesh with the file's regions and node sets (restricted to corner nodes: at
// order 2 the mid-edge nodes of a physical group follow their corners, ElementMesh's
// fixed_dofs). `index` maps a file point to its corner index, -1 for an edge node.
core::TetMesh corner_mesh(const GmshContent& c, const std::vector<int>& index, std::vector<core::Vec3> corners) {
  std::vector<core::Tet> tets;
  tets.reserve(c.cells.size());
  for (const auto& cell : c.cells)
    tets.push_back({index[static_cast<size_t>(cell[0])], index[static_cast<size_t>(cell[1])],
                    index[static_cast<size_t>(cell[2])], index[static_cast<size_t>(cell[3])]});
  core::TetMesh mesh(columns(corners), std::move(tets), c.regions);
  for (const auto& [tag, nodes] : c.nodes_of_physical) {
    std::vector<int> set;
    for (int n : nodes)
      if (index[static_cast<size_t>(n)] >= 0) set.push_back(index[static_cast<size_t>(n)]);
    std::sort(set.begin(), set.end());
    const auto nm = c.physical_names.find(tag);
    mesh.set_node_set(nm != c.physical_names.end() ? nm->second : "physical " + std::to_string(tag), std::move(set));
  }
  return mesh;
}

// Order 2: the nodes in positions 4..9 of a tetrahedron are edge nodes, all others corners
// (so are nodes no element uses, as at order 1); corners keep their file order and come
// first, edge nodes follow in file order. A node both corner and edge node is refused;
// ElementMesh checks that the elements share their edge nodes consistently.
OrderedMesh build_ordered(const GmshContent& c, const std::string& origin) {
  std::vector<std::uint8_t> role(c.points.size(), 0);  // bit 0: corner, bit 1: edge node
  for (const auto& cell : c.cells)
    for (int k = 0; k < (c.order == 1 ? 4 : 10); ++k) role[static_cast<size_t>(cell[static_cast<size_t>(k)])] |= k < 4 ? 1 : 2;
  std::vector<int> index(c.points.size(), -1);
  std::vector<core::Vec3> corners, edges;
  for (size_t i = 0; i < c.points.size(); ++i) {
    if (role[i] == 3)
      throw MeshFileError(origin + ": node " + std::to_string(c.ids[i]) +
                          " is a corner of one tetrahedron and a mid-edge node of another");
    if (role[i] == 2) continue;
    index[i] = static_cast<int>(corners.size());
    corners.push_back(c.points[i]);
  }
  std::vector<int> edge_index(c.points.size(), -1);
  for (size_t i = 0; i < c.points.size(); ++i)
    if (role[i] == 2) {
      edge_index[i] = static_cast<int>(corners.size() + edges.size());
      edges.push_back(c.points[i]);
    }
  try {
    core::TetMesh mesh = corner_mesh(c, index, std::move(corners));
    if (c.order == 1) {
      core::hyperelastic::ElementMesh elements(mesh, 1);
      return {std::move(mesh), std::move(elements)};
    }
    std::vector<std::array<int, 10>> cells;
    cells.reserve(c.cells.size());
    for (const auto& cell : c.cells) {
      std::array<int, 10> n;
      for (size_t k = 0; k < 10; ++k) n[k] = k < 4 ? index[static_cast<size_t>(cell[k])] : edge_index[static_cast<size_t>(cell[k])];
      cells.push_back(n);
    }
    try {
      core::hyperelastic::ElementMesh elements(mesh, cells, columns(edges));
      return {std::move(mesh), std::move(elements)};
    } catch (const std::invalid_argument& e) {
      throw MeshFileError(origin + ": " + e.what() +
                          " (tetrahedra counted from 0 in file order; nodes from 0, corners in file order, then "
                          "mid-edge nodes in file order)");
    }
  } catch (const MeshFileError&) {
    throw;
  } catch (const std::invalid_argument& e) {
    throw MeshFileError(origin + ": " + e.what());
  }
}

}  // namespace

core::TetMesh read_gmsh(std::istream& in, const std::string& origin, double scale) {
  const GmshContent c = parse_gmsh(in, origin, scale, false);
  std::vector<int> index(c.points.size());
  std::iota(index.begin(), index.end(), 0);
  try {
    return corner_mesh(c, index, c.points);
  } catch (const std::invalid_argument& e) {
    throw MeshFileError(origin + ": " + e.what());
  }
}

OrderedMesh read_gmsh_any_order(std::istream& in, const std::string& origin, double scale) {
  return build_ordered(parse_gmsh(in, origin, scale, true), origin);
}

namespace {

// Next non-empty, non-comment line of a TetGen file (comments start with '#').
bool tetgen_line(Lines& lines, std::string& line) {
  while (lines.next(line)) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    if (line.find_first_not_of(" \t") != std::string::npos) return true;
  }
  return false;
}

// The numbers of the next line into `out` (`line` and `out` are reused: no allocation per line).
void tetgen_fields(Lines& lines, const std::string& what, std::string& line, std::vector<double>& out) {
  if (!tetgen_line(lines, line)) lines.fail("unexpected end of file, expected " + what);
  fields_into(lines, line, "number", out);
}

// Point ids to indices: arithmetic while the ids run consecutively from the first (as
// TetGen writes them), a hash map from the first id out of sequence on.
class PointIds {
 public:
  // False if `id` was given before.
  bool add(long id, int index) {
    if (index == 0) first_ = id;
    if (map_.empty() && id == first_ + index) return true;
    if (map_.empty())  // out of sequence: the ones before go into the map
      for (int i = 0; i < index; ++i) map_.emplace(first_ + i, i);
    return map_.emplace(id, index).second;
  }
  // The index of `id`, or -1.
  int find(long id, long count) const {
    if (map_.empty()) return id >= first_ && id - first_ < count ? static_cast<int>(id - first_) : -1;
    const auto it = map_.find(id);
    return it == map_.end() ? -1 : it->second;
  }

 private:
  long first_ = 0;
  std::unordered_map<long, int> map_;
};

}  // namespace

core::TetMesh read_tetgen(std::istream& node, const std::string& node_origin, std::istream& ele,
                          const std::string& ele_origin, double scale) {
  if (!(scale > 0 && std::isfinite(scale))) throw MeshFileError(node_origin + ": scale must be > 0");
  Lines nl(node, node_origin);
  std::string line;
  std::vector<double> h, f;
  tetgen_fields(nl, "'<points> <dim> <attributes> <markers>'", line, h);
  if (h.size() < 2 || h[1] != 3) nl.fail("expected '<points> 3 <attributes> <markers>' (three-dimensional)");
  const long n = whole(nl, h[0], "the point count");
  const long nattr = h.size() > 2 ? whole(nl, h[2], "the attribute count", 0, 1e6) : 0;
  const long nmark = h.size() > 3 ? whole(nl, h[3], "the marker count") : 0;
  if (n < 0 || nattr < 0 || nmark < 0 || nmark > 1) nl.fail("bad header counts");
  PointIds index_of_id;
  std::vector<core::Vec3> pts;
  pts.reserve(static_cast<size_t>(std::min(n, 1L << 20)));  // a header's count is not trusted
  for (long i = 0; i < n; ++i) {
    tetgen_fields(nl, "a point", line, f);
    if (static_cast<long>(f.size()) != 4 + nattr + nmark) nl.fail("expected 'id x y z' plus attributes and marker");
    if (!std::isfinite(f[1]) || !std::isfinite(f[2]) || !std::isfinite(f[3])) nl.fail("non-finite coordinate");
    const long id = whole(nl, f[0], "the point id");
    if (!index_of_id.add(id, static_cast<int>(i))) nl.fail("point " + std::to_string(id) + " is given twice");
    pts.push_back(scale * core::Vec3(f[1], f[2], f[3]));
  }
  core::Positions X(3, static_cast<Eigen::Index>(pts.size()));
  for (size_t i = 0; i < pts.size(); ++i) X.col(static_cast<Eigen::Index>(i)) = pts[i];
  Lines el(ele, ele_origin);
  std::vector<double> eh;
  tetgen_fields(el, "'<tetrahedra> <nodes per tet> <attributes>'", line, eh);
  if (eh.size() < 2 || eh[1] != 4) el.fail("expected '<tetrahedra> 4 <attributes>' (linear tetrahedra)");
  const long ne = whole(el, eh[0], "the tetrahedron count");
  const long eattr = eh.size() > 2 ? whole(el, eh[2], "the attribute count", 0, 1e6) : 0;
  if (ne < 0 || eattr < 0) el.fail("bad header counts");
  std::vector<core::Tet> tets;
  std::vector<int> regions;
  tets.reserve(static_cast<size_t>(std::min(ne, 1L << 20)));
  regions.reserve(tets.capacity());
  for (long i = 0; i < ne; ++i) {
    tetgen_fields(el, "a tetrahedron", line, f);
    if (static_cast<long>(f.size()) != 5 + eattr) el.fail("expected 'id n1 n2 n3 n4' plus attributes");
    core::Tet t{};
    for (int k = 0; k < 4; ++k) {
      const long id = whole(el, f[static_cast<size_t>(1 + k)], "a point id");
      const int index = index_of_id.find(id, static_cast<long>(pts.size()));
      if (index < 0) el.fail("tetrahedron refers to point " + std::to_string(id) + ", which is not in " + node_origin);
      t[static_cast<size_t>(k)] = index;
    }
    tets.push_back(t);
    regions.push_back(eattr > 0 ? static_cast<int>(whole(el, f[5], "the region attribute (non-negative)", 0, kIntMax)) : 0);
  }
  try {
    return core::TetMesh(std::move(X), std::move(tets), std::move(regions));
  } catch (const std::invalid_argument& e) {
    throw MeshFileError(ele_origin + ": " + e.what());
  }
}

namespace {

// Whitespace-separated tokens with their line numbers (legacy VTK is free-format).
class Tokens {
 public:
  Tokens(std::istream& in, std::string origin) : origin_(std::move(origin)) {
    std::string line;
    int n = 0;
    while (std::getline(in, line)) {
      ++n;
      lines_.push_back(line);
      if (n <= 2) continue;  // the version line and the title are free text
      std::istringstream s(line);
      std::string tok;
      while (s >> tok) toks_.emplace_back(tok, n);
    }
  }
  bool done() const { return pos_ >= toks_.size(); }
  size_t remaining() const { return toks_.size() - pos_; }
  const std::string& peek() const { return toks_[pos_].first; }
  std::string next(const std::string& what) {
    if (done()) fail("unexpected end of file, expected " + what);
    return toks_[pos_++].first;
  }
  template <class T>
  T number(const std::string& what) {
    const std::string tok = next(what);
    std::istringstream t(tok);
    T v{};
    if (!(t >> v) || !t.eof()) fail("'" + printable(tok) + "' is not a valid " + what);
    return v;
  }
  [[noreturn]] void fail(const std::string& what) const {
    const int line = toks_.empty() ? 0 : toks_[std::min(pos_ == 0 ? 0 : pos_ - 1, toks_.size() - 1)].second;
    throw MeshFileError(origin_ + ":" + std::to_string(line) + ": " + what);
  }
  const std::vector<std::string>& lines() const { return lines_; }

 private:
  std::string origin_;
  std::vector<std::string> lines_;
  std::vector<std::pair<std::string, int>> toks_;
  size_t pos_ = 0;
};

}  // namespace

core::TetMesh read_vtk(std::istream& in, const std::string& origin, double scale) {
  if (!(scale > 0 && std::isfinite(scale))) throw MeshFileError(origin + ": scale must be > 0");
  Tokens t(in, origin);
  if (t.lines().empty() || t.lines()[0].rfind("# vtk DataFile", 0) != 0)
    throw MeshFileError(origin + ":1: not a legacy VTK file (expected '# vtk DataFile Version ...')");
  if (t.next("ASCII or BINARY") != "ASCII") t.fail("only ASCII legacy VTK files are supported");
  if (t.next("DATASET") != "DATASET" || t.next("dataset type") != "UNSTRUCTURED_GRID")
    t.fail("expected DATASET UNSTRUCTURED_GRID");
  core::Positions X;
  std::vector<std::vector<long>> cells;
  std::vector<long> types;
  std::vector<long> tags;
  while (!t.done()) {
    const std::string key = t.next("a keyword");
    if (key == "POINTS") {
      const long n = t.number<long>("point count");
      t.next("data type");
      if (n < 0) t.fail("negative point count");
      if (static_cast<size_t>(n) > t.remaining() / 3) t.fail("the point count is larger than the file holds");
      X.resize(3, n);
      for (long i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
          const double v = t.number<double>("coordinate");
          if (!std::isfinite(v)) t.fail("non-finite coordinate");
          X(c, i) = scale * v;
        }
    } else if (key == "CELLS") {
      const long n = t.number<long>("cell count");
      const long size = t.number<long>("cell list size");
      if (n < 0 || size < 0 || static_cast<size_t>(n) > t.remaining() || static_cast<size_t>(size) > t.remaining())
        t.fail("the cell counts are larger than the file holds");
      if (!t.done() && t.peek() == "OFFSETS") {
        // VTK 5.x: n offsets, then the connectivity (size entries).
        t.next("OFFSETS");
        t.next("data type");
        std::vector<long> offsets;
        for (long i = 0; i < n; ++i) offsets.push_back(t.number<long>("offset"));
        if (t.next("CONNECTIVITY") != "CONNECTIVITY") t.fail("expected CONNECTIVITY");
        t.next("data type");
        std::vector<long> conn;
        for (long i = 0; i < size; ++i) {
          const long v = t.number<long>("point index");
          if (v < 0 || v >= X.cols()) t.fail("cell refers to point " + std::to_string(v) + ", out of range");
          conn.push_back(v);
        }
        for (long i = 0; i + 1 < n; ++i) {
          if (offsets[static_cast<size_t>(i)] < 0 || offsets[static_cast<size_t>(i + 1)] < offsets[static_cast<size_t>(i)] ||
              offsets[static_cast<size_t>(i + 1)] > size)
            t.fail("bad OFFSETS");
          cells.emplace_back(conn.begin() + offsets[static_cast<size_t>(i)], conn.begin() + offsets[static_cast<size_t>(i + 1)]);
        }
        continue;
      }
      for (long i = 0; i < n; ++i) {
        const long k = t.number<long>("cell size");
        if (k < 1 || k > 64) t.fail("bad cell size " + std::to_string(k));
        std::vector<long> c(static_cast<size_t>(k));
        for (auto& v : c) {
          v = t.number<long>("point index");
          if (v < 0 || v >= X.cols()) t.fail("cell refers to point " + std::to_string(v) + ", out of range");
        }
        cells.push_back(std::move(c));
      }
    } else if (key == "CELL_TYPES") {
      const long n = t.number<long>("cell type count");
      if (n != static_cast<long>(cells.size())) t.fail("CELL_TYPES count differs from CELLS");
      for (long i = 0; i < n; ++i) types.push_back(t.number<long>("cell type"));
    } else if (key == "CELL_DATA") {
      const long n = t.number<long>("cell data count");
      if (n != static_cast<long>(cells.size())) t.fail("CELL_DATA count differs from CELLS");
      // The first integer SCALARS array is the region tag; other arrays are skipped.
      if (!t.done() && t.peek() == "FIELD") {
        // FIELD name count, then per array: name components tuples type values.
        t.next("FIELD");
        t.next("field name");
        const long arrays = t.number<long>("array count");
        for (long a = 0; a < arrays; ++a) {
          t.next("array name");
          const long comps = t.number<long>("component count");
          const long tuples = t.number<long>("tuple count");
          // Counts bounded before multiplying (and by what the file can still hold).
          if (comps < 0 || tuples < 0 || comps > 1000000 || tuples > static_cast<long>(t.remaining()))
            t.fail("bad FIELD array size " + std::to_string(comps) + " x " + std::to_string(tuples));
          const std::string type = t.next("data type");
          // Only an integer array can hold region tags.
          const bool integer_type = type.find("int") != std::string::npos || type.find("long") != std::string::npos ||
                                    type.find("short") != std::string::npos || type.find("char") != std::string::npos;
          std::vector<long> values;
          for (long i = 0; i < comps * tuples; ++i) {
            const double v = t.number<double>("cell value");
            // Only a one-component array can be the region tags; others hold any number.
            values.push_back(tags.empty() && comps == 1 && integer_type ? whole(t, v, "the region tag (non-negative)", 0, kIntMax) : 0);
          }
          if (tags.empty() && comps == 1 && integer_type && tuples == n) tags = std::move(values);
        }
        continue;
      }
      while (!t.done() && t.peek() == "SCALARS") {
        t.next("SCALARS");
        t.next("array name");
        const std::string type = t.next("data type");
        const bool integer_type = type.find("int") != std::string::npos || type.find("long") != std::string::npos ||
                                  type.find("short") != std::string::npos || type.find("char") != std::string::npos;
        const bool take = tags.empty() && integer_type;  // region tags: the first integer array
        std::string tok = t.next("LOOKUP_TABLE or component count");
        if (tok != "LOOKUP_TABLE") tok = t.next("LOOKUP_TABLE");
        if (tok != "LOOKUP_TABLE") t.fail("expected LOOKUP_TABLE");
        t.next("lookup table name");
        std::vector<long> values;
        for (long i = 0; i < n; ++i) {
          const double v = t.number<double>("cell value");
          values.push_back(take ? whole(t, v, "the region tag (non-negative)", 0, kIntMax) : 0);
        }
        if (take) tags = std::move(values);
      }
    } else if (key == "POINT_DATA") {
      // Point arrays are not used: skip the rest of the file section by section.
      while (!t.done() && t.peek() != "CELL_DATA") t.next("");
    } else {
      t.fail("unexpected keyword '" + key + "'");
    }
  }
  if (types.size() != cells.size()) throw MeshFileError(origin + ": CELL_TYPES missing or incomplete");
  std::vector<core::Tet> tets;
  std::vector<int> regions;
  for (size_t i = 0; i < cells.size(); ++i) {
    if (types[i] == 24) throw MeshFileError(origin + ": cell " + std::to_string(i) + " is a quadratic tetrahedron (use first-order meshes)");
    if (types[i] != 10) continue;
    if (cells[i].size() != 4) throw MeshFileError(origin + ": cell " + std::to_string(i) + " of type 10 does not have 4 points");
    tets.push_back({static_cast<int>(cells[i][0]), static_cast<int>(cells[i][1]), static_cast<int>(cells[i][2]),
                    static_cast<int>(cells[i][3])});
    regions.push_back(tags.empty() ? 0 : static_cast<int>(tags[i]));
  }
  if (tets.empty()) throw MeshFileError(origin + ": no tetrahedra (cell type 10)");
  try {
    return core::TetMesh(std::move(X), std::move(tets), std::move(regions));
  } catch (const std::invalid_argument& e) {
    throw MeshFileError(origin + ": " + e.what());
  }
}

core::TetMesh read_mesh(const std::string& path, double scale) {
  const size_t dot = path.rfind('.');
  const std::string ext = dot == std::string::npos ? "" : path.substr(dot);
  if (ext == ".node" || ext == ".ele") {
    const std::string base = path.substr(0, dot);
    for (const std::string& f : {base + ".node", base + ".ele"})
      if (const std::string bad = input_file_problem(f); !bad.empty()) throw MeshFileError(f + ": cannot open the mesh file: " + bad);
    std::ifstream node(base + ".node"), ele(base + ".ele");
    if (!node) throw MeshFileError(base + ".node: cannot open the mesh file");
    if (!ele) throw MeshFileError(base + ".ele: cannot open the mesh file");
    return read_tetgen(node, base + ".node", ele, base + ".ele", scale);
  }
  if (ext == ".vtk" || ext == ".msh")
    if (const std::string bad = input_file_problem(path); !bad.empty()) throw MeshFileError(path + ": cannot open the mesh file: " + bad);
  if (ext == ".vtk") {
    std::ifstream f(path);
    if (!f) throw MeshFileError(path + ": cannot open the mesh file");
    return read_vtk(f, path, scale);
  }
  if (ext != ".msh") throw MeshFileError(path + ": unknown mesh format '" + ext + "' (supported: .msh, .node/.ele, .vtk)");
  std::ifstream f(path);
  if (!f) throw MeshFileError(path + ": cannot open the mesh file");
  return read_gmsh(f, path, scale);
}

OrderedMesh read_mesh_any_order(const std::string& path, double scale) {
  const size_t dot = path.rfind('.');
  if (dot == std::string::npos || path.substr(dot) != ".msh") {
    core::TetMesh mesh = read_mesh(path, scale);
    core::hyperelastic::ElementMesh elements(mesh, 1);
    return {std::move(mesh), std::move(elements)};
  }
  if (const std::string bad = input_file_problem(path); !bad.empty()) throw MeshFileError(path + ": cannot open the mesh file: " + bad);
  std::ifstream f(path);
  if (!f) throw MeshFileError(path + ": cannot open the mesh file");
  return read_gmsh_any_order(f, path, scale);
}

void write_gmsh22(const core::TetMesh& mesh, std::ostream& out) {
  out.precision(17);
  out << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
  int tag = 0;
  for (int r : mesh.regions()) tag = std::max(tag, r);
  std::vector<std::pair<int, std::string>> sets;
  for (const auto& kv : mesh.node_sets()) sets.emplace_back(++tag, kv.first);
  if (!sets.empty()) {
    out << "$PhysicalNames\n" << sets.size() << "\n";
    for (const auto& [t, name] : sets) out << "0 " << t << " \"" << name << "\"\n";
    out << "$EndPhysicalNames\n";
  }
  const auto& X = mesh.rest_positions();
  out << "$Nodes\n" << mesh.num_nodes() << "\n";
  for (int i = 0; i < mesh.num_nodes(); ++i) out << i + 1 << " " << X(0, i) << " " << X(1, i) << " " << X(2, i) << "\n";
  out << "$EndNodes\n";
  size_t points = 0;
  for (const auto& kv : mesh.node_sets()) points += kv.second.size();
  out << "$Elements\n" << static_cast<size_t>(mesh.num_elements()) + points << "\n";
  long id = 1;
  for (size_t s = 0; s < sets.size(); ++s)
    for (int n : mesh.node_set(sets[s].second)) out << id++ << " 15 2 " << sets[s].first << " " << sets[s].first << " " << n + 1 << "\n";
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const core::Tet& t = mesh.tets()[static_cast<size_t>(e)];
    const int r = mesh.regions()[static_cast<size_t>(e)];
    out << id++ << " 4 2 " << r << " " << r << " " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << " " << t[3] + 1 << "\n";
  }
  out << "$EndElements\n";
}

}  // namespace fiberfem::io
