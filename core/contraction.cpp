#include "core/contraction.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fiberfem::core {
namespace {
constexpr double kPi = 3.14159265358979323846;
}

const char* to_string(TwitchShape s) { return s == TwitchShape::sine ? "sine" : "biexponential"; }
const char* to_string(ContractionMode m) { return m == ContractionMode::nodal_forces ? "nodal_forces" : "active_stress"; }

void Twitch::validate() const {
  if (shape == TwitchShape::biexponential) {
    if (!(tau1_s > 0 && std::isfinite(tau1_s))) throw std::invalid_argument("twitch: tau1_s must be > 0");
    if (!(tau2_s > tau1_s && std::isfinite(tau2_s)))
      throw std::invalid_argument("twitch: tau2_s must be > tau1_s (" + std::to_string(tau1_s) + ")");
  } else if (!(systole_s > 0 && std::isfinite(systole_s))) {
    throw std::invalid_argument("twitch: systole_s must be > 0");
  }
}

double Twitch::peak_time() const {
  if (shape == TwitchShape::sine) return 0.5 * systole_s;
  return tau1_s * tau2_s * std::log(tau2_s / tau1_s) / (tau2_s - tau1_s);
}

double Twitch::value(double t) const {
  if (!(t > 0)) return 0.0;
  if (shape == TwitchShape::sine) {
    if (t >= systole_s) return 0.0;
    const double s = std::sin(kPi * t / systole_s);
    return s * s;
  }
  // beta = r^(1/(1-r)) - r^(r/(1-r)), r = tau1/tau2: the peak value, so the peak is 1.
  const double r = tau1_s / tau2_s;
  const double beta = std::pow(r, 1.0 / (1.0 - r)) - std::pow(r, r / (1.0 - r));
  return (std::exp(-t / tau1_s) - std::exp(-t / tau2_s)) / beta;
}

std::vector<double> Contraction::activation(const std::vector<int>& regions, const std::vector<double>& tension_pa) const {
  std::vector<double> a(regions.size(), 0.0);
  if (tension_pa.empty()) return a;
  if (tension_pa.size() != regions.size())
    throw std::invalid_argument("activation: " + std::to_string(tension_pa.size()) + " tensions for " +
                                std::to_string(regions.size()) + " elements");
  for (size_t e = 0; e < regions.size(); ++e) {
    const size_t r = static_cast<size_t>(regions[e]);
    const double peak = r < region_peak_pa.size() ? region_peak_pa[r] : 0.0;
    a[e] = peak > 0 ? tension_pa[e] / peak : 0.0;
  }
  return a;
}

bool Contraction::enabled() const {
  return std::any_of(region_peak_pa.begin(), region_peak_pa.end(), [](double p) { return p > 0; });
}

double Contraction::tension(int region, double delay_s, double t_s) const {
  const double peak = region_peak_pa[static_cast<size_t>(region)];
  if (peak == 0.0) return 0.0;
  const double local = t_s - delay_s;
  if (local < 0) return 0.0;
  // Within the beat; the twitch of the previous beat is added for a shape that has not
  // decayed by the end of the period (the biexponential's tail).
  const double phase = std::fmod(local, period_s);
  double v = twitch.value(phase);
  if (local >= period_s) v += twitch.value(phase + period_s);
  return peak * v;
}

double Contraction::continued_origin(const Contraction& before, double before_origin_s, const Contraction& after, double t_s) {
  const double since = t_s - before_origin_s;
  if (since < before.period_s) return before_origin_s;  // still in the first beat
  const double phase = since - std::floor(since / before.period_s) * before.period_s;
  return t_s - phase - after.period_s;
}

TwitchTable Contraction::tabulate(int samples) const {
  TwitchTable t;
  t.period_s = period_s;
  t.samples.resize(static_cast<size_t>(samples) + 1);
  t.tail.resize(static_cast<size_t>(samples) + 1);
  for (int k = 0; k <= samples; ++k) {
    const double phase = period_s * k / samples;
    t.tail[static_cast<size_t>(k)] = twitch.value(phase + period_s);
    t.samples[static_cast<size_t>(k)] = twitch.value(phase) + t.tail[static_cast<size_t>(k)];
  }
  // Periodic: the value at the period's end is the next beat's start.
  t.samples.back() = t.samples.front();
  t.tail.back() = twitch.value(2 * period_s);
  return t;
}

void Contraction::validate(int num_regions, int num_elements) const {
  if (!(period_s > 0 && std::isfinite(period_s))) throw std::invalid_argument("contraction: period_s must be > 0");
  twitch.validate();
  // A beat adds to the next one (its tail), not to the one after: the twitch must have
  // decayed within two periods.
  if (twitch.value(2 * period_s) > 1e-4)
    throw std::invalid_argument("contraction: the twitch is still " + std::to_string(twitch.value(2 * period_s)) +
                                " of its peak two periods (" + std::to_string(2 * period_s) +
                                " s) after it starts: lengthen period_s or shorten tau2_s");
  if (!region_peak_pa.empty() && static_cast<int>(region_peak_pa.size()) != num_regions)
    throw std::invalid_argument("contraction: region_peak_pa has " + std::to_string(region_peak_pa.size()) +
                                " entries for " + std::to_string(num_regions) + " regions");
  for (size_t r = 0; r < region_peak_pa.size(); ++r)
    if (!(region_peak_pa[r] >= 0 && std::isfinite(region_peak_pa[r])))
      throw std::invalid_argument("contraction: region_peak_pa[" + std::to_string(r) + "] must be >= 0 and finite");
  if (!element_delay_s.empty() && static_cast<int>(element_delay_s.size()) != num_elements)
    throw std::invalid_argument("contraction: element_delay_s has " + std::to_string(element_delay_s.size()) +
                                " entries for " + std::to_string(num_elements) + " elements");
  for (size_t e = 0; e < element_delay_s.size(); ++e)
    if (!(element_delay_s[e] >= 0 && std::isfinite(element_delay_s[e])))
      throw std::invalid_argument("contraction: element_delay_s[" + std::to_string(e) + "] must be >= 0 and finite");
}

std::vector<double> pacing_delays(const Positions& rest, const std::vector<Tet>& tets, const Vec3& site_m, double speed_m_s) {
  if (!(speed_m_s > 0 && std::isfinite(speed_m_s)))
    throw std::invalid_argument("pacing: speed must be > 0 m/s, got " + std::to_string(speed_m_s));
  if (!site_m.allFinite()) throw std::invalid_argument("pacing: the site must be finite");
  std::vector<double> delay(tets.size());
  for (size_t e = 0; e < tets.size(); ++e) {
    Vec3 c = Vec3::Zero();
    for (int n : tets[e]) c += 0.25 * rest.col(n);
    delay[e] = (c - site_m).norm() / speed_m_s;
  }
  return delay;
}

}  // namespace fiberfem::core
