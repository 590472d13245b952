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

/// A random rotation from a seeded generator.
inline core::Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

}  // namespace fiberfem::testing
