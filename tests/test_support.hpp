#pragma once
// Shared helpers for the GoogleTest suites.

#include "core/builtin_scenes.hpp"
#include "core/types.hpp"

#include <gtest/gtest.h>

#include <random>
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

/// A random rotation from a seeded generator.
inline core::Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

}  // namespace fiberfem::testing
