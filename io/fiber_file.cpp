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

core::Vec3 parse_triple(const std::string& text, const std::string& origin, int line) {
  // strtod, not a stream: "nan" and "inf" read as numbers and are refused as such.
  std::istringstream ss(text);
  core::Vec3 v;
  std::string word;
  int n = 0;
  bool numbers = true;
  while (ss >> word) {
    char* end = nullptr;
    const double x = std::strtod(word.c_str(), &end);
    if (n < 3 && end && *end == '\0') v[n] = x;
    else numbers = false;
    ++n;
  }
  if (!numbers || n != 3)
    throw FiberFileError(origin + ":" + std::to_string(line) + ": expected three numbers 'x y z', got '" + printable(text) + "'");
  if (!v.allFinite()) throw FiberFileError(origin + ":" + std::to_string(line) + ": non-finite value in '" + printable(text) + "'");
  return v;
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
