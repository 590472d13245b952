#pragma once
// A simulator's steps recorded for exact comparison (tests that compare runs with ==).

#include "core/simulator.hpp"

#include <gtest/gtest.h>

#include <set>
#include <vector>

namespace fiberfem::testing {

/// What each step left: state, solver work, time, energy, threads.
struct StepTrace {
  std::vector<Eigen::VectorXd> x, v;
  std::vector<int> iterations, factorizations;
  std::vector<double> times, elastic;
  std::set<int> threads;  ///< thread counts the steps ran on
};

/// Steps `sim` `steps` times, appending to `t`; a failed step fails the test.
inline void record_steps(core::Simulator& sim, int steps, StepTrace& t) {
  for (int i = 0; i < steps; ++i) {
    const core::StepReport r = sim.step();
    ASSERT_NE(r.status, core::StepStatus::failed) << r.message;
    t.x.emplace_back(Eigen::Map<const Eigen::VectorXd>(sim.positions().data(), sim.positions().size()));
    t.v.emplace_back(Eigen::Map<const Eigen::VectorXd>(sim.velocities().data(), sim.velocities().size()));
    t.iterations.push_back(r.solver_iterations);
    t.factorizations.push_back(r.solver_factorizations);
    t.times.push_back(sim.time_s());
    t.elastic.push_back(r.elastic_energy_j);
    t.threads.insert(r.threads);
  }
}

}  // namespace fiberfem::testing
