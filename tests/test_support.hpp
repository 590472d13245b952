#pragma once
// Shared helpers for the GoogleTest suites.

#include "core/builtin_scenes.hpp"
#include "core/lv_ellipsoid.hpp"
#include "core/types.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <map>
#include <random>
#include <vector>
#include <stdexcept>
#include <string>

namespace fiberfem::testing {

/// Runs `f` and checks it throws std::invalid_argument (or a subclass) whose message
/// contains every one of `fragments`.
template <class F>
void expect_invalid(F&& f, std::initializer_list<std::string> fragments) {
  try {
    f();
    ADD_FAILURE() << "expected std::invalid_argument mentioning " << *fragments.begin();
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    for (const auto& frag : fragments)
      EXPECT_NE(msg.find(frag), std::string::npos) << "message '" << msg << "' lacks '" << frag << "'";
  }
}

/// The compliance of PHYSICS.md section 2 (fiber along local z, Voigt xx, yy, zz, xy, yz,
/// zx, engineering shear), written out independently of core/material.cpp: the tests'
/// oracle for the material.
inline core::Mat6 engineering_compliance(const core::EngineeringConstants& c) {
  core::Mat6 S = core::Mat6::Zero();
  S(0, 0) = S(1, 1) = 1 / c.E_T;
  S(0, 1) = S(1, 0) = -c.nu_T / c.E_T;
  S(0, 2) = S(2, 0) = S(1, 2) = S(2, 1) = -c.nu_LT / c.E_L;
  S(2, 2) = 1 / c.E_L;
  S(3, 3) = 2 * (1 + c.nu_T) / c.E_T;
  S(4, 4) = S(5, 5) = 1 / c.G_L;
  return S;
}

/// `s` with the first occurrence of `from` replaced by `to` (for mutating test inputs);
/// a missing `from` fails the test that asked.
inline std::string replace_once(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

/// How many elements use each triangular face (sorted node triple): 2 for an interior
/// face of a conforming mesh, 1 on the boundary. Counted from the connectivity alone,
/// independently of TetMesh's own boundary.
inline std::map<std::array<int, 3>, int> face_uses(const std::vector<core::Tet>& tets) {
  std::map<std::array<int, 3>, int> uses;
  for (const core::Tet& t : tets)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f{};
      int k = 0;
      for (int a = 0; a < 4; ++a)
        if (a != skip) f[static_cast<size_t>(k++)] = t[static_cast<size_t>(a)];
      std::sort(f.begin(), f.end());
      uses[f] += 1;
    }
  return uses;
}

/// Volume of the ellipsoid x^2/rs^2 + y^2/rs^2 + z^2/rl^2 <= 1 below the plane z = b: the
/// cross-section at height z is a disk of area pi rs^2 (1 - z^2/rl^2), so
/// V = pi rs^2 int_{-rl}^{b} (1 - z^2/rl^2) dz = pi rs^2 ((b + rl) - (b^3 + rl^3) / (3 rl^2)).
inline double truncated_ellipsoid_volume(double rs, double rl, double b) {
  const double pi = 3.14159265358979323846;
  return pi * rs * rs * ((b + rl) - (b * b * b + rl * rl * rl) / (3 * rl * rl));
}

/// The benchmark ellipsoid's default geometry at the given resolution.
inline core::LvEllipsoidSpec lv_spec(int circumferential, int longitudinal, int transmural) {
  core::LvEllipsoidSpec s;
  s.circumferential = circumferential;
  s.longitudinal = longitudinal;
  s.transmural = transmural;
  return s;
}

/// A random rotation from a seeded generator.
inline core::Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

}  // namespace fiberfem::testing
