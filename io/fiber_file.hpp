#pragma once
/// @file Fiber files and stroke files (docs/fiber-format.md): plain text, one vector or
/// point per line.

#include "core/types.hpp"

#include <istream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::io {

/// A malformed fiber or stroke file: the message starts with "<file>:<line>: ".
class FiberFileError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Vectors, one "x y z" per line; '#' starts a comment; blank lines are skipped. Every
/// vector must be finite and non-zero (a fiber direction); `line_of` receives the line
/// number of each. @throws FiberFileError naming the line (also for a line with a sheet).
std::vector<core::Vec3> read_fiber_vectors(std::istream& in, const std::string& origin, std::vector<int>* line_of = nullptr);

/// A fiber file's vectors: a fiber per line, and a sheet per line when the lines give one.
struct FiberVectors {
  std::vector<core::Vec3> fibers;
  std::vector<core::Vec3> sheets;  ///< Empty, or one per fiber.
  std::vector<int> line_of;        ///< The line of each vector.
};

/// As read_fiber_vectors, where every line is "fx fy fz" or every line is
/// "fx fy fz sx sy sz" (a fiber and a sheet direction; the sheet finite and not parallel to
/// its fiber). @throws FiberFileError naming the line.
FiberVectors read_fiber_file(std::istream& in, const std::string& origin);

/// Polylines: points "x y z" one per line, a blank line (or "---") ends a polyline; each
/// polyline needs two distinct consecutive points at least. @throws FiberFileError.
std::vector<std::vector<core::Vec3>> read_polylines(std::istream& in, const std::string& origin);

}  // namespace fiberfem::io
