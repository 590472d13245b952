#include "core/spencer_element.hpp"

namespace fiberfem::core {

// Spencer's constants from the local Voigt constants (file comment of the header): match
// C_ijkl with f = e3 entry by entry (C1111 = lambda + 2 mu_T, C1122 = lambda,
// C1133 = lambda + alpha, C2323 = mu_T + gamma, C3333 = lambda + 2 mu_T + 2 alpha +
// 4 gamma + beta). An isotropic material gets exact zeros: no fiber terms at all.
SpencerConstants SpencerConstants::of(const Material& m) {
  const Mat6& C = m.stiffness();
  SpencerConstants s;
  s.lambda = C(0, 1);
  s.mu_t = C(3, 3);
  if (m.is_isotropic()) return s;
  s.alpha = C(0, 2) - C(0, 1);
  s.gamma = C(4, 4) - C(3, 3);
  s.beta = C(2, 2) - C(0, 0) - 2.0 * s.alpha - 4.0 * s.gamma;
  return s;
}

}  // namespace fiberfem::core
