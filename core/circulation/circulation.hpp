#pragma once
/// @file The lumped closed-loop circulation of Regazzoni et al. 2022 (J. Comput. Phys.
/// 457:111083; docs/circulation.md): four chambers, four valves, systemic and pulmonary
/// arteries and veins as R-C-L compartments. SI units throughout (Pa, m^3, s); the
/// parameter defaults are the paper's, given there in mmHg, mL and s.

#include <Eigen/Core>

#include <array>

namespace fiberfem::core::circulation {

inline constexpr double kPaPerMmHg = 133.322387415;  ///< 1 mmHg in Pa.
inline constexpr double kM3PerMl = 1e-6;             ///< 1 mL in m^3.

/// A chamber's time-varying elastance p = E(t) (V - V0), E = E_passive + E_active e(t),
/// e(t) a cosine rise over `contraction_s` from `onset_s` (in the beat) and a cosine fall
/// over `relaxation_s` after it (Regazzoni et al. 2022, eq. 3).
struct Elastance {
  double active_pa_m3 = 0;     ///< E_active, Pa/m^3.
  double passive_pa_m3 = 0;    ///< E_passive, Pa/m^3 (> 0).
  double rest_volume_m3 = 0;   ///< V0, m^3.
  double onset_s = 0;          ///< Start of contraction in the beat, s.
  double contraction_s = 0.3;  ///< Duration of the rise, s (> 0).
  double relaxation_s = 0.15;  ///< Duration of the fall, s (> 0).
  /// The activation e in [0, 1] at time t (since the beats' origin) of a run beating with
  /// `period_s`; `previous_period_s` > 0: the beat before the origin lasted that long (the
  /// period changed in the beat that began at the origin), 0: it lasted `period_s`.
  double activation(double t_s, double period_s, double previous_period_s = 0) const;
  double elastance(double t_s, double period_s, double previous_period_s = 0) const {
    return passive_pa_m3 + active_pa_m3 * activation(t_s, period_s, previous_period_s);
  }
};

/// How a chamber's pressure is given.
enum class ChamberKind {
  elastance,  ///< p = E(t) (V - V0) (Elastance).
  prescribed, ///< A constant pressure (a reservoir; its volume still counts the flows).
  external,   ///< Given for each step from outside (a 3D ventricle).
};

struct Chamber {
  ChamberKind kind = ChamberKind::elastance;
  Elastance elastance;
  double pressure_pa = 0;  ///< With ChamberKind::prescribed, Pa.
};

/// A valve as a smooth non-ideal diode: Q = (p_up - p_down) / R, with log10 R blending
/// from log10 R_min (open, p_up > p_down) to log10 R_max (shut) through a smooth step of
/// width about 0.01 mmHg (the paper's arctangent switch).
struct Valve {
  double r_min_pa_s_m3 = 0.0075 * kPaPerMmHg / kM3PerMl;   ///< Open, Pa s/m^3 (> 0).
  double r_max_pa_s_m3 = 75006.2 * kPaPerMmHg / kM3PerMl;  ///< Shut, Pa s/m^3 (> r_min).
  /// 1 / the pressure factor of Parameters::scale (the switch narrows with the pressures).
  double scale_pressure_inverse = 1.0;
  /// Flow from up to down for the pressure difference dp = p_up - p_down, m^3/s, and its
  /// derivative in dp.
  double flow(double dp_pa, double* dflow = nullptr) const;
};

/// An R-C-L compartment: C dp/dt = Q_in - Q, L dQ/dt = p - p_down - R Q.
struct Compartment {
  double resistance_pa_s_m3 = 0;   ///< R, Pa s/m^3 (> 0).
  double compliance_m3_pa = 0;     ///< C, m^3/Pa (> 0).
  double inertance_pa_s2_m3 = 0;   ///< L, Pa s^2/m^3 (>= 0; 0: no inertia).
};

enum ChamberId { la = 0, lv = 1, ra = 2, rv = 3 };
enum ValveId { mitral = 0, aortic = 1, tricuspid = 2, pulmonic = 3 };
enum CompartmentId { ar_sys = 0, ven_sys = 1, ar_pul = 2, ven_pul = 3 };

/// Every parameter of the model. Defaults: Regazzoni et al. 2022's (75 beats/min).
struct Parameters {
  Parameters();
  double period_s = 0.8;                  ///< Beat period, s (> 0).
  std::array<Chamber, 4> chambers;        ///< By ChamberId.
  std::array<Valve, 4> valves;            ///< By ValveId.
  std::array<Compartment, 4> compartments;///< By CompartmentId.
  /// Multiplies every pressure by `pressure` and every volume by `volume` (elastances,
  /// resistances and inertances by pressure/volume, compliances by volume/pressure, so
  /// that every time constant is kept): the same model for a smaller heart or a softer
  /// material. Factors > 0.
  void scale(double pressure, double volume);
  /// @throws std::invalid_argument naming the parameter ("compartments.ar_sys.compliance", ...).
  void validate() const;
};

/// The state: chamber volumes, compartment pressures and flows.
struct State {
  double time_s = 0;
  std::array<double, 4> volume_m3{};     ///< By ChamberId.
  std::array<double, 4> pressure_pa{};   ///< By CompartmentId.
  std::array<double, 4> flow_m3_s{};     ///< By CompartmentId (out of it, downstream).
  /// Pressures of the external chambers during the step that led here (lv, rv), Pa.
  std::array<double, 2> external_pa{};
  /// Where the beats are counted from, s: the chambers' activations read the time since
  /// then (0 unless the beat period was changed during the run: keep_beat_phase).
  double beat_origin_s = 0;
  /// How long the beat before the origin lasted, s (0: one period, as when none changed).
  double previous_period_s = 0;
  /// Regazzoni et al. 2022's initial state (65/120/65/145 mL; 80/30/35/24 mmHg; no flow).
  static State regazzoni_initial();
};

/// Before the beat period changes from `old_period_s` at the state's time: moves the beats'
/// origin to the start of the beat under way and remembers how long the beat before it
/// lasted, so that the beat under way keeps the time since it began and every chamber's
/// activation goes on from where it is: exactly when each chamber's onset and onset +
/// contraction, taken modulo the period, are the same under both periods (below both, say),
/// and when the beat under way has not passed the new period yet. The next beat starts one new
/// period after the one under way began: the rule of core::Simulator::set_contraction, so
/// a loop and a contraction that beat together before the change still do after it.
void keep_beat_phase(State& s, double old_period_s);

/// What a state implies: chamber pressures and valve flows at its time.
struct Observables {
  std::array<double, 4> chamber_pa{};  ///< By ChamberId.
  std::array<double, 4> valve_m3_s{};  ///< By ValveId.
};
Observables observe(const Parameters& p, const State& s);

/// Blood in the loop: chamber volumes plus C p of every compartment, m^3 (the unstressed
/// volumes, a constant, left out). Conserved by `step` to round-off.
double total_volume(const Parameters& p, const State& s);

/// One backward-Euler step of size h (Newton on the 12 unknowns, exact Jacobian; every
/// Newton update conserves total_volume exactly, so the volume does not depend on the
/// tolerance). `external_pa`: the pressures of the lv and rv chambers when they are
/// ChamberKind::external. Optional `dvolume_dexternal`: d V_(lv, rv) / d external_pa at
/// the solution, m^3/Pa (for the coupling's Newton).
/// @throws std::runtime_error when Newton fails (not for valid parameters and h <= 0.1 s).
State step(const Parameters& p, const State& s, double h_s, const std::array<double, 2>& external_pa = {},
           Eigen::Matrix2d* dvolume_dexternal = nullptr);

}  // namespace fiberfem::core::circulation
