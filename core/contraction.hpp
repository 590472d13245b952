#pragma once
/// @file Fiber-directed contraction (PHYSICS.md section 6): a periodic twitch of active
/// tension per region, optionally delayed per element by a pacing site and a conduction
/// speed, applied as an active stress along the deformed fiber (the default) or, as in
/// the paper, as nodal forces along the rest fibers.

#include "core/types.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace fiberfem::core {

/// Shape of one beat, normalised to a peak of 1.
enum class TwitchShape {
  biexponential,  ///< (exp(-t/tau1) - exp(-t/tau2)) / beta (REFERENCES.md), peak 1 at t*.
  sine,           ///< sin^2(pi t / systole) for t < systole, 0 after.
};
const char* to_string(TwitchShape s);

struct Twitch {
  TwitchShape shape = TwitchShape::biexponential;
  double tau1_s = 0.05;      ///< biexponential: rise time constant, s (> 0, < tau2). Default 0.05.
  double tau2_s = 0.11;      ///< biexponential: decay time constant, s. Default 0.11.
  double systole_s = 0.3;    ///< sine: duration of the active part, s (> 0). Default 0.3.
  /// Normalised tension at time `t` since the beat started (0 for t < 0).
  double value(double t) const;
  /// Time of the peak, s.
  double peak_time() const;
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

enum class ContractionMode {
  active_stress,  ///< -T_a R g^e: along the deformed fiber (default).
  nodal_forces,   ///< -T_a g^e: along the rest fiber, the paper's periodic external forces.
};
const char* to_string(ContractionMode m);

/// A normalised periodic beat sampled once (the twitch plus the previous beat's tail),
/// read by linear interpolation: a step's tensions then cost a lookup per element instead
/// of two exponentials. 4,096 samples per period: relative error below 1e-5 for the
/// default biexponential at 72 beats/min (tests/core/contraction_test.cpp).
struct TwitchTable {
  double period_s = 1.0;
  std::vector<double> samples;  ///< samples.size() - 1 intervals over one period; last = first.
  /// Normalised tension at time `t` since the first activation (0 for t < 0).
  double value(double t) const {
    if (!(t >= 0) || samples.empty()) return 0.0;
    const double n = static_cast<double>(samples.size() - 1);
    double x = t / period_s;
    x = (x - std::floor(x)) * n;
    const size_t k = std::min(static_cast<size_t>(x), samples.size() - 2);
    const double w = x - static_cast<double>(k);
    // The first beat has no previous tail: subtract it back (tail = the twitch one period on).
    const double v = (1 - w) * samples[k] + w * samples[k + 1];
    return t < period_s ? v - first_beat_tail(t) : v;
  }
  std::vector<double> tail;  ///< the previous beat's contribution over one period (same grid)
  double first_beat_tail(double t) const {
    const double n = static_cast<double>(tail.size() - 1);
    const double x = t / period_s * n;
    const size_t k = std::min(static_cast<size_t>(x), tail.size() - 2);
    const double w = x - static_cast<double>(k);
    return (1 - w) * tail[k] + w * tail[k + 1];
  }
};

/// When and how hard each element contracts. Disabled when every peak tension is zero.
struct Contraction {
  ContractionMode mode = ContractionMode::active_stress;
  double period_s = 60.0 / 72.0;          ///< Beat period, s (> 0). Default 72 beats/min.
  Twitch twitch{};
  std::vector<double> region_peak_pa;     ///< Peak tension per region id, Pa (>= 0); empty: off.
  std::vector<double> element_delay_s;    ///< Activation delay per element, s (>= 0); empty: none.

  bool enabled() const;
  /// Activation of each element: its tension over its region's peak, 1 (0 where the peak
  /// is 0); zeros for an empty `tension_pa` (contraction off).
  /// @throws std::invalid_argument when tension_pa is neither empty nor one per element.
  std::vector<double> activation(const std::vector<int>& regions, const std::vector<double>& tension_pa) const;
  /// Tension of an element of region `region` with delay `delay_s` at time `t_s`, Pa.
  double tension(int region, double delay_s, double t_s) const;
  /// The normalised beat (tension / peak as a function of time since activation), sampled.
  TwitchTable tabulate(int samples = 4096) const;
  /// The time a contraction that replaces `before` at time t_s counts its beats from, so
  /// that the beat under way keeps its phase (a rate change does not jump the twitch):
  /// one whole new period (or more) before the current beat's start, so the tail of a
  /// previous beat is counted; `before`'s origin while still in its first beat.
  static double continued_origin(const Contraction& before, double before_origin_s, const Contraction& after, double t_s);
  /// Also refuses a twitch that has not decayed to 1e-4 of its peak two periods after it
  /// starts (each beat carries only the previous beat's tail).
  /// @param num_regions, num_elements sizes to check against.
  /// @throws std::invalid_argument naming the field and index.
  void validate(int num_regions, int num_elements) const;
};

/// Activation delays for a pacing site: distance from `site_m` to each element centroid
/// over `speed_m_s` (straight-line distance: a conduction that is uniform and unobstructed).
/// @throws std::invalid_argument for a non-positive or non-finite speed or site.
std::vector<double> pacing_delays(const Positions& rest, const std::vector<Tet>& tets, const Vec3& site_m, double speed_m_s);

}  // namespace fiberfem::core
