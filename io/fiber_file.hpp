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
/// number of each. @throws FiberFileError naming the line.
std::vector<core::Vec3> read_fiber_vectors(std::istream& in, const std::string& origin, std::vector<int>* line_of = nullptr);

/// Polylines: points "x y z" one per line, a blank line (or "---") ends a polyline; each
/// polyline needs two distinct consecutive points at least. @throws FiberFileError.
std::vector<std::vector<core::Vec3>> read_polylines(std::istream& in, const std::string& origin);

}  // namespace fiberfem::io
