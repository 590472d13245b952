#include "core/circulation/circulation.hpp"

#include <Eigen/LU>

#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::core::circulation {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kNodes = 8;     // pressure nodes: the four chambers, then the four compartments
constexpr int kUnknowns = 12; // chamber volumes, compartment pressures, compartment flows

// The loop as a graph of pressure nodes: valve v joins kValveEnds[v] (up, down),
// compartment k's flow leaves node 4 + k for kCompartmentDown[k].
constexpr int kValveEnds[4][2] = {{la, lv}, {lv, kNodes / 2 + ar_sys}, {ra, rv}, {rv, kNodes / 2 + ar_pul}};
constexpr int kCompartmentDown[4] = {kNodes / 2 + ven_sys, ra, kNodes / 2 + ven_pul, la};

using Vec12 = Eigen::Matrix<double, kUnknowns, 1>;
using Mat12 = Eigen::Matrix<double, kUnknowns, kUnknowns>;

Vec12 pack(const State& s) {
  Vec12 y;
  for (int i = 0; i < 4; ++i) {
    y(i) = s.volume_m3[static_cast<size_t>(i)];
    y(4 + i) = s.pressure_pa[static_cast<size_t>(i)];
    y(8 + i) = s.flow_m3_s[static_cast<size_t>(i)];
  }
  return y;
}

void unpack(const Vec12& y, State& s) {
  for (int i = 0; i < 4; ++i) {
    s.volume_m3[static_cast<size_t>(i)] = y(i);
    s.pressure_pa[static_cast<size_t>(i)] = y(4 + i);
    s.flow_m3_s[static_cast<size_t>(i)] = y(8 + i);
  }
}

// Pressure of every node and its derivative in the node's own unknown (volume or pressure).
struct NodePressures {
  std::array<double, kNodes> value{};
  std::array<double, kNodes> slope{};
};

// t: time since the beats' origin; previous_period: State::previous_period_s.
NodePressures node_pressures(const Parameters& p, const Vec12& y, double t, const std::array<double, 2>& external,
                             double previous_period) {
  NodePressures n;
  for (int c = 0; c < 4; ++c) {
    const Chamber& ch = p.chambers[static_cast<size_t>(c)];
    switch (ch.kind) {
      case ChamberKind::elastance: {
        const double e = ch.elastance.elastance(t, p.period_s, previous_period);
        n.value[static_cast<size_t>(c)] = e * (y(c) - ch.elastance.rest_volume_m3);
        n.slope[static_cast<size_t>(c)] = e;
        break;
      }
      case ChamberKind::prescribed:
        n.value[static_cast<size_t>(c)] = ch.pressure_pa;
        break;
      case ChamberKind::external:
        n.value[static_cast<size_t>(c)] = external[c == lv ? 0 : 1];
        break;
    }
  }
  for (int k = 0; k < 4; ++k) {
    n.value[static_cast<size_t>(4 + k)] = y(4 + k);
    n.slope[static_cast<size_t>(4 + k)] = 1.0;
  }
  return n;
}

double node_volume_slope(const Parameters& p, int i) {
  return i < 4 ? 1.0 : p.compartments[static_cast<size_t>(i - 4)].compliance_m3_pa;
}

// Backward-Euler residual G(y) (rows 0-7: volume balance of each node, m^3; rows 8-11:
// momentum of each compartment, Pa s), its Jacobian in y, and its derivative in the
// pressure of each node (dG_dpi, column per node) for the external chambers' sensitivity.
struct Linearisation {
  Vec12 residual;
  Mat12 jacobian;
  Eigen::Matrix<double, kUnknowns, kNodes> dG_dpi;
};

Linearisation linearise(const Parameters& p, const State& s0, const Vec12& y, double h, double t,
                        const std::array<double, 2>& external) {
  const Vec12 y0 = pack(s0);
  const NodePressures pi = node_pressures(p, y, t, external, s0.previous_period_s);
  Linearisation L;
  L.residual.setZero();
  L.jacobian.setZero();
  L.dG_dpi.setZero();
  for (int i = 0; i < kNodes; ++i) {
    const double dvol = node_volume_slope(p, i);
    L.residual(i) = dvol * (y(i) - y0(i));
    L.jacobian(i, i) += dvol;
  }
  for (int v = 0; v < 4; ++v) {
    const int u = kValveEnds[v][0], d = kValveEnds[v][1];
    double slope = 0;
    const double q = p.valves[static_cast<size_t>(v)].flow(pi.value[static_cast<size_t>(u)] - pi.value[static_cast<size_t>(d)], &slope);
    L.residual(u) += h * q;
    L.residual(d) -= h * q;
    L.dG_dpi(u, u) += h * slope;
    L.dG_dpi(u, d) -= h * slope;
    L.dG_dpi(d, u) -= h * slope;
    L.dG_dpi(d, d) += h * slope;
  }
  for (int k = 0; k < 4; ++k) {
    const int u = 4 + k, d = kCompartmentDown[k], row = 8 + k;
    const Compartment& c = p.compartments[static_cast<size_t>(k)];
    const double q = y(row);
    L.residual(u) += h * q;
    L.residual(d) -= h * q;
    L.jacobian(u, row) += h;
    L.jacobian(d, row) -= h;
    L.residual(row) = c.inertance_pa_s2_m3 * (q - y0(row)) -
                      h * (pi.value[static_cast<size_t>(u)] - pi.value[static_cast<size_t>(d)] - c.resistance_pa_s_m3 * q);
    L.jacobian(row, row) += c.inertance_pa_s2_m3 + h * c.resistance_pa_s_m3;
    L.dG_dpi(row, u) -= h;
    L.dG_dpi(row, d) += h;
  }
  for (int i = 0; i < kNodes; ++i) L.jacobian.col(i) += pi.slope[static_cast<size_t>(i)] * L.dG_dpi.col(i);
  return L;
}

// Scales of the unknowns (1 mL, 1 mmHg, 1 mL/s) and of the residual rows, so that Newton's
// pivoting and stopping test see numbers of order one.
Vec12 unknown_scale() {
  Vec12 d;
  d << kM3PerMl, kM3PerMl, kM3PerMl, kM3PerMl, kPaPerMmHg, kPaPerMmHg, kPaPerMmHg, kPaPerMmHg, kM3PerMl, kM3PerMl, kM3PerMl,
      kM3PerMl;
  return d;
}

Vec12 row_scale(double h) {
  Vec12 r;
  r.head<8>().setConstant(1.0 / kM3PerMl);
  r.tail<4>().setConstant(1.0 / (h * kPaPerMmHg));
  return r;
}

}  // namespace

double Elastance::activation(double t_s, double period_s, double previous_period_s) const {
  const auto wrap = [](double x, double period) { return x - period * std::floor(x / period); };
  // Time since the last time `start` (in the beat) came round. In the first beat after a
  // change of period, a start still ahead in it last came round in the beat before, which
  // lasted previous_period_s.
  const auto phase = [&](double start) {
    if (!(previous_period_s > 0)) return wrap(t_s - start, period_s);
    const double x = t_s - wrap(start, period_s);
    if (x >= 0) return wrap(x, period_s);
    return wrap(x + previous_period_s, previous_period_s);
  };
  double e = 0;
  const double rise = phase(onset_s);
  if (rise < contraction_s) e += 0.5 * (1 - std::cos(kPi * rise / contraction_s));
  const double fall = phase(onset_s + contraction_s);
  if (fall < relaxation_s) e += 0.5 * (1 + std::cos(kPi * fall / relaxation_s));
  return std::min(1.0, std::max(0.0, e));
}

double Valve::flow(double dp_pa, double* dflow) const {
  // Regazzoni et al.'s switch: log10 R = log10 R_min + (log10 R_max - log10 R_min) H(x),
  // x = (p_down - p_up) in mmHg, H(x) = atan(100 pi x) / pi + 1/2.
  const double lo = std::log10(r_min_pa_s_m3), span = std::log10(r_max_pa_s_m3) - lo;
  const double k = 100.0 * kPi / kPaPerMmHg * scale_pressure_inverse;
  const double x = -dp_pa;
  const double H = std::atan(k * x) / kPi + 0.5;
  const double R = std::pow(10.0, lo + span * H);
  const double q = dp_pa / R;
  if (dflow) {
    const double dH_ddp = -(k / kPi) / (1 + (k * x) * (k * x));
    const double dR_ddp = R * std::log(10.0) * span * dH_ddp;
    *dflow = 1.0 / R - dp_pa * dR_ddp / (R * R);
  }
  return q;
}

Parameters::Parameters() {
  const double mmHg_ml = kPaPerMmHg / kM3PerMl;
  auto elastance = [&](double ea, double eb, double v0, double onset, double tc, double tr) {
    Chamber c;
    c.elastance = {ea * mmHg_ml, eb * mmHg_ml, v0 * kM3PerMl, onset, tc, tr};
    return c;
  };
  chambers[la] = elastance(0.07, 0.09, 4.0, 0.8, 0.17, 0.17);
  chambers[lv] = elastance(2.75, 0.08, 5.0, 0.0, 0.34, 0.17);
  chambers[ra] = elastance(0.06, 0.07, 4.0, 0.8, 0.17, 0.17);
  chambers[rv] = elastance(0.55, 0.05, 10.0, 0.0, 0.34, 0.17);
  compartments[ar_sys] = {0.8 * mmHg_ml, 1.2 / mmHg_ml, 5e-3 * mmHg_ml};
  compartments[ven_sys] = {0.26 * mmHg_ml, 60.0 / mmHg_ml, 5e-4 * mmHg_ml};
  compartments[ar_pul] = {0.1625 * mmHg_ml, 10.0 / mmHg_ml, 5e-4 * mmHg_ml};
  compartments[ven_pul] = {0.1625 * mmHg_ml, 16.0 / mmHg_ml, 5e-4 * mmHg_ml};
}

void Parameters::scale(double pressure, double volume) {
  if (!(pressure > 0) || !(volume > 0) || !std::isfinite(pressure) || !std::isfinite(volume))
    throw std::invalid_argument("circulation scale: factors must be finite and > 0");
  const double stiff = pressure / volume;
  for (Chamber& c : chambers) {
    c.elastance.active_pa_m3 *= stiff;
    c.elastance.passive_pa_m3 *= stiff;
    c.elastance.rest_volume_m3 *= volume;
    c.pressure_pa *= pressure;
  }
  for (Valve& v : valves) {
    v.r_min_pa_s_m3 *= stiff;
    v.r_max_pa_s_m3 *= stiff;
    v.scale_pressure_inverse /= pressure;
  }
  for (Compartment& c : compartments) {
    c.resistance_pa_s_m3 *= stiff;
    c.inertance_pa_s2_m3 *= stiff;
    c.compliance_m3_pa /= stiff;
  }
}

void Parameters::validate() const {
  static const char* chamber_names[4] = {"left_atrium", "left_ventricle", "right_atrium", "right_ventricle"};
  static const char* valve_names[4] = {"mitral", "aortic", "tricuspid", "pulmonary"};
  static const char* compartment_names[4] = {"systemic.arteries", "systemic.veins", "pulmonary.arteries", "pulmonary.veins"};
  auto fail = [](const std::string& what) { throw std::invalid_argument("circulation: " + what); };
  if (!(period_s > 0) || !std::isfinite(period_s)) fail("period must be > 0 s, got " + std::to_string(period_s));
  for (int c = 0; c < 4; ++c) {
    const Chamber& ch = chambers[static_cast<size_t>(c)];
    const std::string name = chamber_names[c];
    if (ch.kind == ChamberKind::prescribed && !std::isfinite(ch.pressure_pa)) fail(name + ".pressure must be finite");
    if (ch.kind != ChamberKind::elastance) continue;
    const Elastance& e = ch.elastance;
    if (!(e.passive_pa_m3 > 0) || !std::isfinite(e.passive_pa_m3)) fail(name + ".passive_elastance must be > 0");
    if (!(e.active_pa_m3 >= 0) || !std::isfinite(e.active_pa_m3)) fail(name + ".active_elastance must be >= 0");
    if (!(e.contraction_s > 0) || !(e.relaxation_s > 0)) fail(name + ".contraction and .relaxation must be > 0 s");
    if (!std::isfinite(e.rest_volume_m3) || !std::isfinite(e.onset_s)) fail(name + ".rest_volume and .onset must be finite");
  }
  for (int v = 0; v < 4; ++v) {
    const Valve& va = valves[static_cast<size_t>(v)];
    const std::string name = std::string("valves.") + valve_names[v];
    if (!(va.r_min_pa_s_m3 > 0) || !std::isfinite(va.r_max_pa_s_m3))
      fail(name + ".R_min must be > 0 and R_max finite");
    if (!(va.r_min_pa_s_m3 < va.r_max_pa_s_m3))
      fail(name + ": R_min (" + std::to_string(va.r_min_pa_s_m3) + " Pa s/m^3) must be below R_max (" +
           std::to_string(va.r_max_pa_s_m3) + "): the valve would never open");
  }
  for (int k = 0; k < 4; ++k) {
    const Compartment& c = compartments[static_cast<size_t>(k)];
    const std::string name = compartment_names[k];
    if (!(c.resistance_pa_s_m3 > 0) || !std::isfinite(c.resistance_pa_s_m3)) fail(name + ".resistance must be > 0");
    if (!(c.compliance_m3_pa > 0) || !std::isfinite(c.compliance_m3_pa))
      fail(name + ".compliance must be > 0, got " + std::to_string(c.compliance_m3_pa) + " m^3/Pa");
    if (!(c.inertance_pa_s2_m3 >= 0) || !std::isfinite(c.inertance_pa_s2_m3)) fail(name + ".inertance must be >= 0");
  }
}

State State::regazzoni_initial() {
  State s;
  s.volume_m3 = {65 * kM3PerMl, 120 * kM3PerMl, 65 * kM3PerMl, 145 * kM3PerMl};
  s.pressure_pa = {80 * kPaPerMmHg, 30 * kPaPerMmHg, 35 * kPaPerMmHg, 24 * kPaPerMmHg};
  return s;
}

Observables observe(const Parameters& p, const State& s) {
  const NodePressures pi = node_pressures(p, pack(s), s.time_s - s.beat_origin_s, s.external_pa, s.previous_period_s);
  Observables o;
  for (int c = 0; c < 4; ++c) o.chamber_pa[static_cast<size_t>(c)] = pi.value[static_cast<size_t>(c)];
  for (int v = 0; v < 4; ++v)
    o.valve_m3_s[static_cast<size_t>(v)] = p.valves[static_cast<size_t>(v)].flow(
        pi.value[static_cast<size_t>(kValveEnds[v][0])] - pi.value[static_cast<size_t>(kValveEnds[v][1])]);
  return o;
}

double total_volume(const Parameters& p, const State& s) {
  double v = 0;
  for (int c = 0; c < 4; ++c) v += s.volume_m3[static_cast<size_t>(c)];
  for (int k = 0; k < 4; ++k) v += p.compartments[static_cast<size_t>(k)].compliance_m3_pa * s.pressure_pa[static_cast<size_t>(k)];
  return v;
}

void keep_beat_phase(State& s, double old_period_s) {
  const double since = s.time_s - s.beat_origin_s;
  if (since < old_period_s) {  // still in the first beat since the origin: its start and the one before stay
    if (!(s.previous_period_s > 0)) s.previous_period_s = old_period_s;
    return;
  }
  s.beat_origin_s = s.time_s - (since - old_period_s * std::floor(since / old_period_s));
  s.previous_period_s = old_period_s;
}

State step(const Parameters& p, const State& s, double h, const std::array<double, 2>& external_pa,
           Eigen::Matrix2d* dvolume_dexternal) {
  const double t = s.time_s + h;
  const double t_beat = t - s.beat_origin_s;  // what the chambers' activations read
  const Vec12 D = unknown_scale(), rows = row_scale(h);
  // Newton from the old state: its total volume is the old one, and every update (whole
  // or damped) keeps it, as the volume rows of the Jacobian sum to the volume weights.
  Vec12 y = pack(s);
  Linearisation L = linearise(p, s, y, h, t_beat, external_pa);
  double norm = (rows.asDiagonal() * L.residual).lpNorm<Eigen::Infinity>();
  bool converged = false;
  for (int it = 0; it < 60 && !converged; ++it) {
    const Mat12 J = rows.asDiagonal() * L.jacobian * D.asDiagonal();
    const Vec12 dz = J.partialPivLu().solve(-(rows.asDiagonal() * L.residual));
    // Backtracking on the scaled residual: the valves' switch is steep.
    double alpha = 1;
    for (int k = 0; k < 30; ++k, alpha *= 0.5) {
      const Vec12 trial = y + alpha * D.cwiseProduct(dz);
      Linearisation Lt = linearise(p, s, trial, h, t_beat, external_pa);
      const double nt = (rows.asDiagonal() * Lt.residual).lpNorm<Eigen::Infinity>();
      if (nt < norm || k == 29 || (alpha * dz).lpNorm<Eigen::Infinity>() < 1e-11) {
        y = trial;
        L = std::move(Lt);
        norm = nt;
        break;
      }
    }
    converged = (alpha * dz).lpNorm<Eigen::Infinity>() < 1e-10 || norm < 1e-12;
  }
  if (!converged || !y.allFinite())
    throw std::runtime_error("circulation: the backward-Euler step did not converge (residual " + std::to_string(norm) + ")");
  State out = s;
  out.time_s = t;
  out.external_pa = external_pa;
  unpack(y, out);
  if (dvolume_dexternal) {
    // J dy/dp = -dG/dp; the external pressures enter G through their nodes' pressure.
    const auto lu = L.jacobian.partialPivLu();
    for (int k = 0; k < 2; ++k) {
      const Vec12 dy = lu.solve(-L.dG_dpi.col(k == 0 ? lv : rv));
      (*dvolume_dexternal)(0, k) = dy(lv);
      (*dvolume_dexternal)(1, k) = dy(rv);
    }
  }
  return out;
}

}  // namespace fiberfem::core::circulation
