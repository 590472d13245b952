// Prints the lumped circulation's trajectory (all four chambers as elastances, the paper's
// defaults, Regazzoni's initial state) as CSV for regazzoni_reference_test.py, which
// compares it with the PyPI package `circulation`, an independent implementation.
// Usage: circulation_trajectory STEP_S BEATS
#include "core/circulation/circulation.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace cc = fiberfem::core::circulation;

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s STEP_S BEATS\n", argv[0]);
    return 2;
  }
  const double h = std::atof(argv[1]);
  const int beats = std::atoi(argv[2]);
  const cc::Parameters p;
  cc::State s = cc::State::regazzoni_initial();
  const long n = std::lround(beats * p.period_s / h);
  std::printf("t,V_LA,V_LV,V_RA,V_RV,p_AR_SYS,p_VEN_SYS,p_AR_PUL,p_VEN_PUL,p_LV,total\n");
  for (long i = 1; i <= n; ++i) {
    s = cc::step(p, s, h);
    const cc::Observables o = cc::observe(p, s);
    std::printf("%.6f", s.time_s);
    for (double v : s.volume_m3) std::printf(",%.9g", v / cc::kM3PerMl);
    for (double q : s.pressure_pa) std::printf(",%.9g", q / cc::kPaPerMmHg);
    std::printf(",%.9g,%.17g\n", o.chamber_pa[cc::lv] / cc::kPaPerMmHg, cc::total_volume(p, s) / cc::kM3PerMl);
  }
  return 0;
}
