#include "io/fiber_file.hpp"

#include "io/input_file.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace fiberfem::io {
namespace {

// Strips a '#' comment and surrounding blanks.
std::string content(const std::string& line) {
  std::string s = line.substr(0, line.find('#'));
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  const size_t b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

std::string at(const std::string& origin, int line) { return origin + ":" + std::to_string(line) + ": "; }

// The numbers of a line, as many as it has (up to 7, enough to refuse a bad count).
// strtod, not a stream: "nan" and "inf" read as numbers and are refused as such.
std::vector<double> parse_numbers(const std::string& text, const std::string& origin, int line, const char* expected) {
  std::istringstream ss(text);
  std::vector<double> v;
  std::string word;
  while (ss >> word && v.size() < 7) {
    char* end = nullptr;
    const double x = std::strtod(word.c_str(), &end);
    if (!end || *end != '\0') throw FiberFileError(at(origin, line) + "expected " + expected + ", got '" + printable(text) + "'");
    v.push_back(x);
  }
  for (double x : v)
    if (!std::isfinite(x)) throw FiberFileError(at(origin, line) + "non-finite value in '" + printable(text) + "'");
  return v;
}

core::Vec3 parse_triple(const std::string& text, const std::string& origin, int line) {
  const std::vector<double> v = parse_numbers(text, origin, line, "three numbers 'x y z'");
  if (v.size() != 3) throw FiberFileError(at(origin, line) + "expected three numbers 'x y z', got '" + printable(text) + "'");
  return {v[0], v[1], v[2]};
}

}  // namespace

std::vector<core::Vec3> read_fiber_vectors(std::istream& in, const std::string& origin, std::vector<int>* line_of) {
  std::vector<core::Vec3> out;
  std::string raw;
  int line = 0;
  while (std::getline(in, raw)) {
    ++line;
    const std::string text = content(raw);
    if (text.empty()) continue;
    const core::Vec3 v = parse_triple(text, origin, line);
    if (v.norm() < 1e-12)
      throw FiberFileError(origin + ":" + std::to_string(line) + ": zero vector (vector " + std::to_string(out.size()) +
                           ") is not a fiber direction");
    out.push_back(v);
    if (line_of) line_of->push_back(line);
    if (out.size() > 100000000) throw FiberFileError(origin + ": more than 1e8 vectors");
  }
  if (out.empty()) throw FiberFileError(origin + ": no vectors");
  return out;
}

FiberVectors read_fiber_file(std::istream& in, const std::string& origin) {
  const char* expected = "three numbers 'fx fy fz' or six 'fx fy fz sx sy sz'";
  FiberVectors out;
  std::string raw;
  int line = 0;
  size_t width = 0;  // numbers per line, set by the first
  int first_line = 0;
  while (std::getline(in, raw)) {
    ++line;
    const std::string text = content(raw);
    if (text.empty()) continue;
    const std::vector<double> v = parse_numbers(text, origin, line, expected);
    if (v.size() != 3 && v.size() != 6) throw FiberFileError(at(origin, line) + "expected " + expected + ", got '" + printable(text) + "'");
    if (width == 0) width = v.size(), first_line = line;
    if (v.size() != width)
      throw FiberFileError(at(origin, line) + std::to_string(v.size()) + " numbers, but line " + std::to_string(first_line) +
                           " has " + std::to_string(width) + ": every line gives a fiber, or every line a fiber and a sheet");
    const core::Vec3 f(v[0], v[1], v[2]);
    if (f.norm() < 1e-12)
      throw FiberFileError(at(origin, line) + "zero vector (vector " + std::to_string(out.fibers.size()) + ") is not a fiber direction");
    if (width == 6) {
      const core::Vec3 sh(v[3], v[4], v[5]);
      if (sh.cross(f).norm() <= 1e-6 * sh.norm() * f.norm())
        throw FiberFileError(at(origin, line) + "the sheet (vector " + std::to_string(out.fibers.size()) +
                             ") is zero or parallel to its fiber");
      out.sheets.push_back(sh);
    }
    out.fibers.push_back(f);
    out.line_of.push_back(line);
    if (out.fibers.size() > 100000000) throw FiberFileError(origin + ": more than 1e8 vectors");
  }
  if (out.fibers.empty()) throw FiberFileError(origin + ": no vectors");
  return out;
}

std::vector<std::vector<core::Vec3>> read_polylines(std::istream& in, const std::string& origin) {
  std::vector<std::vector<core::Vec3>> lines(1);
  std::vector<int> first_line(1, 1);
  std::string raw;
  int line = 0;
  while (std::getline(in, raw)) {
    ++line;
    const std::string stripped = content(raw);
    const bool blank = raw.find_first_not_of(" \t\r") == std::string::npos;
    if (blank || stripped == "---") {
      if (!lines.back().empty()) {
        lines.emplace_back();
        first_line.push_back(line + 1);
      }
      continue;
    }
    if (stripped.empty()) continue;  // a comment line
    if (lines.back().empty()) first_line.back() = line;
    lines.back().push_back(parse_triple(stripped, origin, line));
  }
  if (lines.back().empty()) {
    lines.pop_back();
    first_line.pop_back();
  }
  if (lines.empty()) throw FiberFileError(origin + ": no polylines");
  for (size_t k = 0; k < lines.size(); ++k) {
    bool moves = false;
    for (size_t i = 1; i < lines[k].size(); ++i) moves = moves || (lines[k][i] - lines[k][i - 1]).norm() > 0;
    if (!moves)
      throw FiberFileError(origin + ":" + std::to_string(first_line[k]) + ": polyline " + std::to_string(k) +
                           " needs two distinct points");
  }
  return lines;
}

}  // namespace fiberfem::io
