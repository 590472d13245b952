// bench_accuracy: the speed-against-accuracy study (docs/speed-accuracy.md).
// A program, not a timed test.
//
// For each scene (cantilever, large-rotation cantilever, Land beam, Land ventricle, the
// default beating heart) it runs a converged reference (finest mesh level, smallest step,
// PCG at 1e-10; cached on disk), two convergence checks of that reference (one level
// coarser, twice the step), and then the sweeps, each against the reference: time step,
// mesh level, PCG tolerance and iteration cap, warm start, direct solver and block-Jacobi
// preconditioner, SVD against polar rotations, corotation off, the scene's features, and a
// grid of step x level x tolerance for the Pareto front. Every run is the shipped scene
// file with overrides (the same path as `fiberfem run --set`).
//
// Error measures (against the reference, sampled every 1/30 s of simulated time):
//   probe_err: max over time of |u_probe - u_ref| over max over time of |u_ref| (the
//     scene's first probe: the tip, the benchmark point, the apex);
//   l2_err: relative L2 error of the displacements of all nodes over all samples (the
//     reference interpolated at the run's rest nodes when the meshes differ);
//   final_err: |u_probe - u_ref| at the end over |u_ref| at the end (settled scenes);
//   volume_err: max over time of |V - V_ref| / V_ref(0) of the first cavity;
//   ef_err: ejection fraction (over the last beat) minus the reference's, percentage points;
//   phase_err: time of the signal's extremum (least cavity volume in the last beat, or the
//     probe's first peak; none for the settling scenes) minus the reference's, ms
//     (parabolic refinement between samples).
// Cost measures: wall seconds per simulated second (one engine thread unless --threads)
// and steps per second.
//
//   bench_accuracy [--scene NAME]... [--quick] [--out-dir build/study]
//                  [--heart-meshes DIR] [--markdown FILE] [--threads 1] [--stability]

#include "core/box_generator.hpp"
#include "core/builtin_scenes.hpp"
#include "core/cavity.hpp"
#include "core/simulator.hpp"
#include "core/static_solver.hpp"
#include "io/scene.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace core = fiberfem::core;
namespace io = fiberfem::io;
namespace fs = std::filesystem;

namespace {

constexpr double kSample = 1.0 / 30.0;  // s of simulated time between samples
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------- what a run records

struct Trace {
  core::Positions rest;                 // 3 x N
  std::vector<Eigen::VectorXd> u;       // displacement per sample, 3N
  std::vector<double> t;                // sample times, s
  std::vector<core::Vec3> probe;        // first probe's displacement per sample
  std::vector<double> volume;           // first cavity's volume per sample (empty: none)
  double wall_s = 0;
  long steps = 0;
  int failed = 0, recovered = 0;
  bool finite = true;
  int tets = 0;
};

// FNV-1a, stable across builds (cache keys).
std::uint64_t fnv1a(const std::string& s) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

template <class T>
void put(std::ostream& o, const T& v) { o.write(reinterpret_cast<const char*>(&v), sizeof v); }
template <class T>
void get(std::istream& i, T& v) { i.read(reinterpret_cast<char*>(&v), sizeof v); }

// Reference cache file: "FFREF1", then counts and doubles (native endianness; a cache, not
// an exchange format: a file that does not read back is recomputed).
void save_trace(const std::string& path, const Trace& tr) {
  std::ofstream o(path, std::ios::binary);
  o.write("FFREF1", 6);
  const std::int64_t n = tr.rest.cols(), s = static_cast<std::int64_t>(tr.u.size()),
                     nv = static_cast<std::int64_t>(tr.volume.size());
  put(o, n), put(o, s), put(o, nv), put(o, tr.wall_s), put(o, tr.steps), put(o, tr.tets);
  o.write(reinterpret_cast<const char*>(tr.rest.data()), static_cast<std::streamsize>(sizeof(double) * 3 * n));
  for (std::int64_t k = 0; k < s; ++k) {
    put(o, tr.t[k]);
    o.write(reinterpret_cast<const char*>(tr.u[k].data()), static_cast<std::streamsize>(sizeof(double) * 3 * n));
    o.write(reinterpret_cast<const char*>(tr.probe[k].data()), sizeof(double) * 3);
  }
  for (double v : tr.volume) put(o, v);
}

bool load_trace(const std::string& path, Trace& tr) {
  std::ifstream i(path, std::ios::binary);
  if (!i) return false;
  char magic[6];
  i.read(magic, 6);
  if (!i || std::string(magic, 6) != "FFREF1") return false;
  std::int64_t n = 0, s = 0, nv = 0;
  get(i, n), get(i, s), get(i, nv), get(i, tr.wall_s), get(i, tr.steps), get(i, tr.tets);
  if (!i || n <= 0 || s <= 0 || n > 100000000 || s > 1000000) return false;
  tr.rest.resize(3, n);
  i.read(reinterpret_cast<char*>(tr.rest.data()), static_cast<std::streamsize>(sizeof(double) * 3 * n));
  tr.u.assign(static_cast<size_t>(s), Eigen::VectorXd(3 * n));
  tr.t.resize(static_cast<size_t>(s));
  tr.probe.resize(static_cast<size_t>(s));
  for (std::int64_t k = 0; k < s; ++k) {
    get(i, tr.t[k]);
    i.read(reinterpret_cast<char*>(tr.u[k].data()), static_cast<std::streamsize>(sizeof(double) * 3 * n));
    i.read(reinterpret_cast<char*>(tr.probe[k].data()), sizeof(double) * 3);
  }
  tr.volume.resize(static_cast<size_t>(nv));
  for (double& v : tr.volume) get(i, v);
  return static_cast<bool>(i);
}

// Runs a scene (with overrides) for `until` s, sampling every kSample. The step must
// divide kSample (1/30, 1/60, ... s).
Trace run_scene(const std::string& file, const std::vector<std::string>& overrides, double until, int threads) {
  std::vector<std::string> ov = overrides;
  ov.push_back("solver.threads=" + std::to_string(threads));
  const io::Scene sc = io::load_scene(file, ov);
  core::Simulator sim(sc.model, sc.settings);
  const double dt = sc.settings.dt_s;
  const long per_sample = std::lround(kSample / dt);
  if (per_sample < 1 || std::abs(per_sample * dt - kSample) > 1e-9 * kSample)
    throw std::invalid_argument("solver.dt " + std::to_string(dt) + " s does not divide the sampling interval 1/30 s");
  const long samples = std::lround(until / kSample);
  Trace tr;
  tr.rest = sc.model.mesh.rest_positions();
  tr.tets = sc.model.mesh.num_elements();
  const Eigen::Map<const Eigen::VectorXd> X(tr.rest.data(), tr.rest.size());
  auto sample = [&] {
    const auto x = sim.positions();
    Eigen::VectorXd u = Eigen::Map<const Eigen::VectorXd>(x.data(), x.size()) - X;
    tr.finite = tr.finite && u.allFinite();
    tr.u.push_back(std::move(u));
    tr.t.push_back(sim.time_s());
    const core::Positions xp = x;
    tr.probe.push_back(sc.probes.empty() ? core::Vec3::Zero() : sc.probes[0].displacement(sc.model.mesh, xp));
    if (!sc.cavities.empty()) tr.volume.push_back(core::cavity_volume(sc.cavities[0].surface, x));
  };
  sample();
  for (long k = 0; k < samples; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    for (long j = 0; j < per_sample; ++j) {
      const core::StepReport r = sim.step();
      ++tr.steps;
      if (r.status == core::StepStatus::failed) ++tr.failed;
      if (r.status == core::StepStatus::recovered) ++tr.recovered;
    }
    tr.wall_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    sample();
    if (!tr.finite) break;  // a blown-up run says so; no point going on
  }
  return tr;
}

// ---------------------------------------------------------------- comparison

// For each rest node of `from`, the element of the reference mesh around it and its
// barycentric weights (the least negative weight when a curved surface's node lies just
// outside the reference's facets).
struct Interp {
  std::vector<std::array<int, 4>> nodes;
  std::vector<Eigen::Vector4d> w;
};

Interp locate(const core::Positions& from, const core::TetMesh& ref) {
  const auto& X = ref.rest_positions();
  const int ne = ref.num_elements();
  std::vector<core::Mat3> Dinv(static_cast<size_t>(ne));
  std::vector<core::Vec3> lo(static_cast<size_t>(ne)), hi(static_cast<size_t>(ne));
  for (int e = 0; e < ne; ++e) {
    const core::Tet& t = ref.tets()[static_cast<size_t>(e)];
    core::Mat3 D;
    for (int j = 0; j < 3; ++j) D.col(j) = X.col(t[static_cast<size_t>(j + 1)]) - X.col(t[0]);
    Dinv[static_cast<size_t>(e)] = D.inverse();
    lo[static_cast<size_t>(e)] = hi[static_cast<size_t>(e)] = X.col(t[0]);
    for (int j = 1; j < 4; ++j) {
      lo[static_cast<size_t>(e)] = lo[static_cast<size_t>(e)].cwiseMin(X.col(t[static_cast<size_t>(j)]));
      hi[static_cast<size_t>(e)] = hi[static_cast<size_t>(e)].cwiseMax(X.col(t[static_cast<size_t>(j)]));
    }
  }
  const auto [blo, bhi] = ref.bounding_box();
  const double slack = 0.05 * (bhi - blo).norm();
  Interp in;
  for (int n = 0; n < from.cols(); ++n) {
    const core::Vec3 p = from.col(n);
    double best = -HUGE_VAL;
    int be = -1;
    Eigen::Vector4d bw;
    for (double pad : {1e-12 * slack, slack, HUGE_VAL}) {
      for (int e = 0; e < ne; ++e) {
        if (((p - lo[static_cast<size_t>(e)]).array() < -pad).any() || ((hi[static_cast<size_t>(e)] - p).array() < -pad).any())
          continue;
        const core::Tet& t = ref.tets()[static_cast<size_t>(e)];
        const core::Vec3 l = Dinv[static_cast<size_t>(e)] * (p - X.col(t[0]));
        const Eigen::Vector4d w(1 - l.sum(), l.x(), l.y(), l.z());
        if (w.minCoeff() > best) best = w.minCoeff(), be = e, bw = w;
      }
      if (best > -1e-9) break;
    }
    const core::Tet& t = ref.tets()[static_cast<size_t>(be)];
    in.nodes.push_back({t[0], t[1], t[2], t[3]});
    in.w.push_back(bw);
  }
  return in;
}

struct Errors {
  double probe = kNaN, probe_mm = kNaN, l2 = kNaN, final_ = kNaN, volume = kNaN, ef_pp = kNaN, phase_ms = kNaN;
};

// Time of the largest value of s over [t0, t1], refined by a parabola through three samples.
double peak_time(const std::vector<double>& t, const std::vector<double>& s, double t0, double t1) {
  int best = -1;
  for (size_t k = 0; k < s.size(); ++k)
    if (t[k] >= t0 - 1e-9 && t[k] <= t1 + 1e-9 && (best < 0 || s[k] > s[static_cast<size_t>(best)])) best = static_cast<int>(k);
  if (best < 0) return kNaN;
  const size_t b = static_cast<size_t>(best);
  if (b == 0 || b + 1 >= s.size()) return t[b];
  const double a = s[b - 1], c = s[b + 1], m = s[b];
  const double den = a - 2 * m + c;
  const double off = den < 0 ? 0.5 * (a - c) / den : 0.0;
  return t[b] + std::clamp(off, -1.0, 1.0) * (t[b + 1] - t[b]);
}

struct SceneDef;



// ---------------------------------------------------------------- the scenes

struct Level {
  std::string name;                    // shown in tables
  std::vector<std::string> overrides;  // what selects it
};

struct SceneDef {
  std::string key, file, probe_label;
  double until = 2.0;
  std::vector<std::string> base;       // overrides every run of the scene gets
  std::vector<Level> levels;           // coarse to fine
  int base_level = 1;                  // the shipped scene's level
  std::string base_dt = "1/60";
  bool beating = false;                // phase and EF from the cavity over the last beat
  double period_s = 0;                 // beat period (beating)
  bool settled = false;                // the final state is static (final_err meaningful)
  std::vector<std::pair<std::string, std::vector<std::string>>> features;  // name, overrides
  bool rotation_sweep = true;
};

double parse_dt(const std::string& s) {
  const size_t slash = s.find('/');
  return slash == std::string::npos ? std::stod(s) : std::stod(s.substr(0, slash)) / std::stod(s.substr(slash + 1));
}
std::string dt_override(const std::string& dt) {
  std::ostringstream o;
  o << std::setprecision(17) << "solver.dt=" << parse_dt(dt);
  return o.str();
}

Errors compare(const Trace& run, const Trace& ref, const Interp* interp, const SceneDef& def) {
  Errors e;
  const size_t ns = std::min(run.u.size(), ref.u.size());
  if (!run.finite || run.u.size() != ref.u.size()) {
    e.probe = e.l2 = e.final_ = HUGE_VAL;
    return e;
  }
  double num = 0, den = 0, pmax = 0, pref = 0, vmax = 0;
  for (size_t k = 0; k < ns; ++k) {
    Eigen::VectorXd ur;
    if (interp) {
      ur.resize(run.u[k].size());
      for (size_t n = 0; n < interp->nodes.size(); ++n) {
        core::Vec3 v = core::Vec3::Zero();
        for (int j = 0; j < 4; ++j) v += interp->w[n](j) * ref.u[k].segment<3>(3 * interp->nodes[n][static_cast<size_t>(j)]);
        ur.segment<3>(static_cast<Eigen::Index>(3 * n)) = v;
      }
    } else {
      ur = ref.u[k];
    }
    num += (run.u[k] - ur).squaredNorm();
    den += ur.squaredNorm();
    pmax = std::max(pmax, (run.probe[k] - ref.probe[k]).norm());
    pref = std::max(pref, ref.probe[k].norm());
    if (!run.volume.empty() && !ref.volume.empty())
      vmax = std::max(vmax, std::abs(run.volume[k] - ref.volume[k]) / ref.volume[0]);
  }
  e.l2 = den > 0 ? std::sqrt(num / den) : kNaN;
  e.probe = pref > 0 ? pmax / pref : kNaN;
  e.probe_mm = pmax * 1e3;
  e.final_ = (run.probe.back() - ref.probe.back()).norm() / std::max(ref.probe.back().norm(), 1e-300);
  if (!run.volume.empty() && !ref.volume.empty()) {
    e.volume = vmax;
    if (def.beating) {
      const double t1 = ref.t.back(), t0 = t1 - def.period_s;
      auto ef = [&](const Trace& tr) {
        double lo = HUGE_VAL, hi = 0;
        for (size_t k = 0; k < tr.volume.size(); ++k)
          if (tr.t[k] >= t0 - 1e-9) lo = std::min(lo, tr.volume[k]), hi = std::max(hi, tr.volume[k]);
        return (hi - lo) / hi;
      };
      e.ef_pp = 100 * (ef(run) - ef(ref));
      std::vector<double> a(run.volume.size()), b(ref.volume.size());
      for (size_t k = 0; k < a.size(); ++k) a[k] = -run.volume[k];
      for (size_t k = 0; k < b.size(); ++k) b[k] = -ref.volume[k];
      e.phase_ms = 1e3 * (peak_time(run.t, a, t0, t1) - peak_time(ref.t, b, t0, t1));
    }
  }
  if (!def.beating && !def.settled) {
    // The probe's first peak (an oscillating scene; a settling one has no phase): the first local maximum of |u| above half its largest value.
    auto first_peak = [](const Trace& tr) {
      std::vector<double> s(tr.probe.size());
      double big = 0;
      for (size_t k = 0; k < s.size(); ++k) s[k] = tr.probe[k].norm(), big = std::max(big, s[k]);
      for (size_t k = 1; k + 1 < s.size(); ++k)
        if (s[k] >= 0.5 * big && s[k] >= s[k - 1] && s[k] > s[k + 1]) return peak_time(tr.t, s, tr.t[k - 1], tr.t[k + 1]);
      return kNaN;
    };
    e.phase_ms = 1e3 * (first_peak(run) - first_peak(ref));
  }
  return e;
}

std::vector<SceneDef> scene_defs(const std::string& src, const std::string& heart_meshes, bool quick) {
  const std::string dir = src + "/configs/scenes/";
  std::vector<SceneDef> d;
  auto box = [](int a, int b, int c) {
    return Level{std::to_string(a) + "x" + std::to_string(b) + "x" + std::to_string(c),
                 {"mesh.cells=[" + std::to_string(a) + ", " + std::to_string(b) + ", " + std::to_string(c) + "]"}};
  };
  auto lv = [](int c, int l, int t) {
    return Level{"lv " + std::to_string(c) + "/" + std::to_string(l) + "/" + std::to_string(t),
                 {"mesh.resolution={circumferential: " + std::to_string(c) + ", longitudinal: " + std::to_string(l) +
                  ", transmural: " + std::to_string(t) + "}"}};
  };
  {  // Small end load, undamped: oscillates about the static deflection (analytic 0.964 mm).
    SceneDef s;
    s.base_level = 2;
    s.key = "cantilever";
    s.file = dir + "cantilever-along.yaml";
    s.probe_label = "tip";
    s.until = quick ? 1.0 : 2.0;
    s.base = {"solver.mode=dynamic"};
    s.levels = {box(20, 2, 2), box(30, 3, 3), box(40, 4, 4), box(60, 6, 6)};
    d.push_back(s);
  }
  {  // Under its own weight: droops far beyond small rotations (corotation matters).
    SceneDef s;
    s.key = "cantilever-gravity";
    s.file = dir + "demo-cantilever.yaml";
    s.probe_label = "tip";
    s.until = quick ? 1.0 : 2.0;
    s.levels = {box(10, 1, 1), box(20, 2, 2), box(40, 4, 4), box(60, 6, 6)};
    s.features = {{"no damping", {"regions[0].damping.mass=0"}}};
    d.push_back(s);
  }
  {  // Land problem 1, run dynamically with mass damping until settled.
    SceneDef s;
    s.base_level = 2;
    s.key = "land-beam";
    s.file = dir + "land-beam.yaml";
    s.probe_label = "end";
    s.until = 1.0;
    s.base = {"solver.mode=dynamic", "regions[0].damping={mass: 20.0}"};
    s.levels = {box(20, 2, 2), box(30, 3, 3), box(40, 4, 4), box(60, 6, 6)};
    s.settled = true;
    d.push_back(s);
  }
  {  // Land problem 2 (linearised, 2 kPa), ramped over 1 s, settling.
    SceneDef s;
    s.key = "land-ventricle";
    s.file = dir + "land-ventricle-p2.yaml";
    s.probe_label = "apex_endo";
    s.until = quick ? 1.0 : 2.0;
    s.levels = {lv(12, 5, 2), lv(24, 10, 3), lv(36, 14, 3), lv(48, 20, 4)};
    s.base_dt = "1/60";
    s.settled = true;
    s.features = {{"less damping (mass 10)", {"regions[0].damping.mass=10"}}};
    d.push_back(s);
  }
  {  // The default beating heart, two beats.
    SceneDef s;
    s.key = "heart";
    s.file = dir + "heart.yaml";
    s.probe_label = "lv_apex";
    s.until = quick ? 0.8333333333333334 : 1.6666666666666667;
    s.beating = true;
    s.period_s = 60.0 / 72.0;
    s.base = {"solver.until=2"};
    const std::string shipped = src + "/meshes/biventricle.msh";
    s.levels.clear();
    for (const char* size : {"0.008", "0.006", "0.004", "0.003"}) {
      std::string f = std::string(size) == "0.004" ? shipped : heart_meshes + "/biventricle-" + size + ".msh";
      if (fs::exists(f)) s.levels.push_back(Level{"h " + std::string(size), {"mesh.file=" + f}});
    }
    s.base_level = 0;
    for (size_t i = 0; i < s.levels.size(); ++i)
      if (s.levels[i].name == "h 0.004") s.base_level = static_cast<int>(i);
    s.features = {{"no damping", {"regions[0].damping.mass=0"}},
                  {"contraction as nodal forces", {"contraction.mode=nodal_forces"}},
                  {"no pacing (all at once)", {"contraction.pacing.speed=1000"}}};
    d.push_back(s);
  }
  if (quick)
    for (SceneDef& s : d)
      if (s.levels.size() > 2) {
        s.levels.resize(2);
        s.base_level = 0;
      }
  return d;
}

// ---------------------------------------------------------------- one row of results

struct Knobs {
  std::string dt = "1/60";
  int level = 0;
  double tolerance = 1e-6;
  int max_iterations = 500;
  std::string method = "pcg", preconditioner = "cholesky", rotation = "polar";
  bool warm_start = true, corotation = true;
  std::string feature = "-";
  std::vector<std::string> feature_overrides;
  std::string preset;  // a `fidelity` preset: the scene with that key and nothing else changed

  std::vector<std::string> overrides(const SceneDef& s) const {
    std::vector<std::string> o = s.base;
    if (!preset.empty()) {
      // The preset's key, and its step and tolerance again: the shipped scenes give
      // solver.dt (and some solver.tolerance) explicitly, which would override the preset.
      // The mesh refinement comes from the key alone.
      const std::map<std::string, std::pair<std::string, std::string>> v{
          {"interactive", {"1/30", "0.001"}}, {"balanced", {"1/60", "1e-06"}}, {"accurate", {"1/120", "1e-06"}}};
      o.push_back("fidelity=" + preset);
      o.push_back(dt_override(v.at(preset).first));
      o.push_back("solver.tolerance=" + v.at(preset).second);
      return o;
    }
    const auto& lv = s.levels[static_cast<size_t>(level)].overrides;
    o.insert(o.end(), lv.begin(), lv.end());
    std::ostringstream tol;
    tol << std::setprecision(3) << tolerance;
    o.push_back(dt_override(dt));
    o.push_back("solver.tolerance=" + tol.str());
    o.push_back("solver.max_iterations=" + std::to_string(max_iterations));
    o.push_back("solver.method=" + method);
    o.push_back("solver.preconditioner=" + preconditioner);
    o.push_back("solver.rotation=" + rotation);
    o.push_back(std::string("solver.warm_start=") + (warm_start ? "true" : "false"));
    o.push_back(std::string("solver.corotation=") + (corotation ? "true" : "false"));
    o.insert(o.end(), feature_overrides.begin(), feature_overrides.end());
    return o;
  }
};

struct Row {
  std::string scene, sweep;
  Knobs k;
  std::string level_name;
  int tets = 0;
  Errors e;
  double wall_per_sim = 0, steps_per_s = 0;
  long steps = 0;
  int failed = 0, recovered = 0;
  bool stable = true;
  bool pareto = false;
};

std::string fmt(double v, int prec = 3) {
  if (std::isnan(v)) return "";
  if (std::isinf(v)) return "inf";
  std::ostringstream o;
  o << std::setprecision(prec) << v;
  return o.str();
}

std::string knob_text(const Row& r) {
  std::ostringstream o;
  if (!r.k.preset.empty()) return "fidelity: " + r.k.preset + " (" + r.level_name + ")";
  o << "dt " << r.k.dt << ", " << r.level_name << ", ";
  if (r.k.method == "direct")
    o << "direct";
  else
    o << "pcg " << fmt(r.k.tolerance, 2) << (r.k.max_iterations != 500 ? " cap " + std::to_string(r.k.max_iterations) : "")
      << (r.k.preconditioner != "cholesky" ? " " + r.k.preconditioner : "") << (r.k.warm_start ? "" : " cold");
  if (r.k.rotation != "polar") o << ", " << r.k.rotation;
  if (!r.k.corotation) o << ", corotation off";
  if (r.k.feature != "-") o << ", " << r.k.feature;
  return o.str();
}

// Pareto front of (cost, l2 error) per scene: no other row is both cheaper and more accurate.
void mark_pareto(std::vector<Row>& rows) {
  for (Row& r : rows) {
    if (r.sweep == "reference-check" || !r.stable || !std::isfinite(r.e.l2)) continue;
    bool dominated = false;
    for (const Row& o : rows)
      if (&o != &r && o.scene == r.scene && o.sweep != "reference-check" && o.stable && std::isfinite(o.e.l2) &&
          o.wall_per_sim <= r.wall_per_sim && o.e.l2 <= r.e.l2 && (o.wall_per_sim < r.wall_per_sim || o.e.l2 < r.e.l2))
        dominated = true;
    r.pareto = !dominated;
  }
}

void write_csv(const std::string& path, const std::vector<Row>& rows) {
  std::ofstream o(path);
  o << "scene,sweep,dt_s,dt,level,tets,method,preconditioner,tolerance,max_iterations,warm_start,rotation,corotation,"
       "feature,probe_err_rel,probe_err_mm,l2_err_rel,final_err_rel,volume_err_rel,ef_err_pp,phase_err_ms,"
       "wall_s_per_sim_s,steps_per_s,steps,failed_steps,recovered_steps,stable,pareto\n";
  for (const Row& r : rows)
    o << r.scene << ',' << r.sweep << ',' << std::setprecision(10) << parse_dt(r.k.dt) << ',' << r.k.dt << ','
      << r.level_name << ',' << r.tets << ',' << r.k.method << ',' << r.k.preconditioner << ','
      << std::setprecision(3) << r.k.tolerance << ',' << r.k.max_iterations << ',' << r.k.warm_start << ','
      << r.k.rotation << ',' << r.k.corotation << ",\"" << r.k.feature << "\"," << fmt(r.e.probe, 4) << ','
      << fmt(r.e.probe_mm, 4) << ',' << fmt(r.e.l2, 4) << ',' << fmt(r.e.final_, 4) << ',' << fmt(r.e.volume, 4) << ','
      << fmt(r.e.ef_pp, 4) << ',' << fmt(r.e.phase_ms, 4) << ',' << fmt(r.wall_per_sim, 4) << ','
      << fmt(r.steps_per_s, 4) << ',' << r.steps << ',' << r.failed << ',' << r.recovered << ',' << r.stable << ','
      << r.pareto << '\n';
}

// ---------------------------------------------------------------- the study

struct Study {
  std::string out_dir;
  int threads = 1;
  bool quick = false;
  std::vector<Row> rows;
  std::map<std::string, std::string> notes;  // reference facts per scene for the markdown
  std::map<std::string, Trace> refs;  // by scene (independent checks)
  std::string checks;

  Row measure(const SceneDef& s, const std::string& sweep, const Knobs& k, const Trace& ref, const core::TetMesh& ref_mesh,
              std::map<int, Interp>& interps) {
    Row r;
    r.scene = s.key, r.sweep = sweep, r.k = k, r.level_name = s.levels[static_cast<size_t>(k.level)].name;
    Trace tr;
    try {
      tr = run_scene(s.file, k.overrides(s), s.until, threads);
    } catch (const std::exception& ex) {
      std::cerr << s.key << " " << knob_text(r) << ": " << ex.what() << "\n";
      r.stable = false;
      rows.push_back(r);
      return r;
    }
    const Interp* in = nullptr;
    if (tr.rest.cols() != ref.rest.cols() || !tr.rest.isApprox(ref.rest)) {
      const int n = static_cast<int>(tr.rest.cols());
      if (!interps.count(n)) interps[n] = locate(tr.rest, ref_mesh);
      in = &interps[n];
    }
    r.tets = tr.tets;
    if (!k.preset.empty()) r.level_name = std::to_string(tr.tets) + " tets";
    r.e = compare(tr, ref, in, s);
    const double sim = tr.t.back();
    r.wall_per_sim = tr.wall_s / sim;
    r.steps_per_s = tr.steps / tr.wall_s;
    r.steps = tr.steps;
    r.failed = tr.failed;
    r.recovered = tr.recovered;
    r.stable = tr.finite && tr.failed == 0 && static_cast<int>(tr.u.size()) == static_cast<int>(ref.u.size());
    std::printf("%-18s %-16s %-60s l2 %-9s probe %-9s phase %-8s ms  %7.3f s/s  %7.1f steps/s%s\n", s.key.c_str(),
                sweep.c_str(), knob_text(r).c_str(), fmt(r.e.l2).c_str(), fmt(r.e.probe).c_str(), fmt(r.e.phase_ms).c_str(),
                r.wall_per_sim, r.steps_per_s, r.stable ? "" : "  UNSTABLE");
    std::fflush(stdout);
    rows.push_back(r);
    return r;
  }

  void run(const SceneDef& s) {
    const int finest = static_cast<int>(s.levels.size()) - 1;
    Knobs refk;
    refk.level = finest;
    refk.dt = "1/240";
    refk.tolerance = 1e-10;
    refk.max_iterations = 5000;
    const std::vector<std::string> ref_ov = refk.overrides(s);
    std::string keytext = s.file + "|" + std::to_string(s.until);
    {
      std::ifstream f(s.file);
      keytext += std::string(std::istreambuf_iterator<char>(f), {});
    }
    for (const auto& o : ref_ov) keytext += "|" + o;
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(fnv1a(keytext)));
    const std::string cache = out_dir + "/ref-" + s.key + "-" + hex + ".bin";
    Trace ref;
    if (load_trace(cache, ref) && static_cast<long>(ref.u.size()) == std::lround(s.until / kSample) + 1) {
      std::printf("%s: reference from %s\n", s.key.c_str(), cache.c_str());
    } else {
      std::printf("%s: computing the reference (%s, dt %s, PCG 1e-10)...\n", s.key.c_str(), s.levels[static_cast<size_t>(finest)].name.c_str(),
                  refk.dt.c_str());
      std::fflush(stdout);
      ref = run_scene(s.file, ref_ov, s.until, threads);
      if (!ref.finite || ref.failed) throw std::runtime_error(s.key + ": the reference run failed");
      save_trace(cache, ref);
    }
    const core::TetMesh ref_mesh = io::load_scene(s.file, ref_ov).model.mesh;
    if (s.key == "cantilever") refs[s.key] = ref;
    std::map<int, Interp> interps;
    std::ostringstream note;
    note << "| " << s.key << " | " << s.levels[static_cast<size_t>(finest)].name << " (" << ref.tets << " tets) | "
          << refk.dt << " | " << fmt(ref.probe.back().norm() * 1e3, 4) << " | "
          << (ref.volume.empty() ? "" : fmt(ref.volume.front() * 1e6, 4) + " -> " + fmt(ref.volume.back() * 1e6, 4)) << " | "
          << fmt(ref.wall_s, 3) << " |\n";
    notes[s.key] = note.str();

    // Convergence of the reference: twice its step, one level coarser.
    {
      Knobs k = refk;
      k.dt = "1/120";
      measure(s, "reference-check", k, ref, ref_mesh, interps);
      if (finest > 0) {
        k = refk;
        k.level = finest - 1;
        measure(s, "reference-check", k, ref, ref_mesh, interps);
      }
    }
    Knobs base;
    base.level = s.base_level;
    base.dt = s.base_dt;
    measure(s, "base", base, ref, ref_mesh, interps);
    const std::vector<std::string> dts = quick ? std::vector<std::string>{"1/30", "1/120"}
                                               : std::vector<std::string>{"1/30", "1/60", "1/120", "1/240"};
    for (const std::string& dt : dts) {
      if (dt == base.dt || (dt == "1/240" && base.level == finest)) continue;
      Knobs k = base;
      k.dt = dt;
      measure(s, "dt", k, ref, ref_mesh, interps);
    }
    for (int l = 0; l <= finest; ++l) {
      if (l == base.level) continue;
      Knobs k = base;
      k.level = l;
      measure(s, "level", k, ref, ref_mesh, interps);
    }
    for (double tol : quick ? std::vector<double>{1e-2, 1e-10} : std::vector<double>{1e-2, 1e-3, 1e-4, 1e-8, 1e-10}) {
      Knobs k = base;
      k.tolerance = tol;
      measure(s, "tolerance", k, ref, ref_mesh, interps);
    }
    for (int cap : quick ? std::vector<int>{2} : std::vector<int>{1, 2, 5, 20}) {
      Knobs k = base;
      k.tolerance = 1e-8;
      k.max_iterations = cap;
      measure(s, "iteration cap", k, ref, ref_mesh, interps);
    }
    {
      Knobs k = base;
      k.warm_start = false;
      measure(s, "warm start", k, ref, ref_mesh, interps);
      k = base;
      k.method = "direct";
      measure(s, "solver", k, ref, ref_mesh, interps);
      k = base;
      k.preconditioner = "block_jacobi";
      measure(s, "solver", k, ref, ref_mesh, interps);
      k = base;
      k.rotation = "svd";
      measure(s, "rotation", k, ref, ref_mesh, interps);
      k = base;
      k.corotation = false;
      measure(s, "corotation", k, ref, ref_mesh, interps);
    }
    // The presets, through the scene key itself (docs/scenes.md `fidelity`).
    for (const char* preset : {"interactive", "balanced", "accurate"}) {
      Knobs k = base;
      k.preset = preset;
      k.feature = std::string("fidelity: ") + preset;  // the CSV's label of the row
      measure(s, "preset", k, ref, ref_mesh, interps);
    }
    for (const auto& [name, ov] : s.features) {
      Knobs k = base;
      k.feature = name;
      k.feature_overrides = ov;
      measure(s, "feature", k, ref, ref_mesh, interps);
    }
    if (!quick) {
      // The grid for the Pareto front: step x level x tolerance (base points are above).
      for (const std::string dt : {"1/30", "1/60", "1/120"})
        for (int l = 0; l < finest; ++l)  // the finest level is the reference's
          for (double tol : {1e-3, 1e-6}) {
            Knobs k = base;
            k.dt = dt, k.level = l, k.tolerance = tol;
            const bool one_at_a_time = (dt == base.dt && tol == base.tolerance) || (l == base.level && tol == base.tolerance) ||
                                       (l == base.level && dt == base.dt);
            if (one_at_a_time) continue;
            measure(s, "grid", k, ref, ref_mesh, interps);
          }
    }
  }
};

// Independent checks: static solves of the beams at every level against beam theory
// (cantilever, Timoshenko) and the published Land et al. 2015 value (land-beam), and the
// cantilever reference's first period against Euler-Bernoulli.
std::string independent_checks(const std::vector<SceneDef>& defs, const std::map<std::string, Trace>& refs) {
  std::ostringstream o;
  o << "| scene | level | tets | static probe | independent value | ratio |\n|---|---|---:|---:|---:|---:|\n";
  for (const SceneDef& s : defs) {
    if (s.key != "cantilever" && s.key != "land-beam") continue;
    for (const Level& l : s.levels) {
      std::vector<std::string> ov = s.base;
      ov.insert(ov.end(), l.overrides.begin(), l.overrides.end());
      ov.push_back("solver.mode=static");
      const io::Scene sc = io::load_scene(s.file, ov);
      core::Positions x;
      core::StaticSettings ss;
      ss.load_steps = 4;
      const core::StaticReport r = core::solve_static(sc.model, x, ss);
      const core::Vec3 u = sc.probes[0].displacement(sc.model.mesh, x);
      if (s.key == "cantilever") {
        // 1.5 Pa on the 1 x 1 cm end face: P = 1.5e-4 N; E = E_L, G = G_L.
        const double w = core::cantilever_tip_deflection(0.1, 0.01, 0.01, 60e3, 8e3, 0, 1.5e-4);
        o << "| cantilever | " << l.name << " | " << sc.model.mesh.num_elements() << " | tip deflection "
          << fmt(-u.z() * 1e3, 4) << " mm" << (r.converged ? "" : " (not converged)") << " | Timoshenko " << fmt(w * 1e3, 4)
          << " mm | " << fmt(-u.z() / w, 3) << " |\n";
      } else {
        const double z = 1e-3 + u.z();
        o << "| land-beam | " << l.name << " | " << sc.model.mesh.num_elements() << " | deformed z of (10, 0.5, 1) mm "
          << fmt(z * 1e3, 4) << " mm" << (r.converged ? "" : " (not converged)") << " | Land et al. 4.17 mm | "
          << fmt(z / 4.17e-3, 3) << " |\n";
      }
    }
  }
  if (refs.count("cantilever")) {
    // First period of the reference's tip: time between its first two maxima of |u|.
    const Trace& t = refs.at("cantilever");
    std::vector<double> sig(t.probe.size());
    for (size_t k = 0; k < sig.size(); ++k) sig[k] = t.probe[k].norm();
    std::vector<double> peaks;
    for (size_t k = 1; k + 1 < sig.size() && peaks.size() < 2; ++k)
      if (sig[k] >= sig[k - 1] && sig[k] > sig[k + 1] && sig[k] > 0.5 * *std::max_element(sig.begin(), sig.end()))
        peaks.push_back(peak_time(t.t, sig, t.t[k - 1], t.t[k + 1]));
    // Euler-Bernoulli: w1 = 1.8751^2 sqrt(E I / (rho A L^4)).
    const double EI = 60e3 * 0.01 * 1e-6 / 12, rhoA = 1000 * 1e-4, L = 0.1;
    const double T_eb = 2 * M_PI / (1.8751 * 1.8751 * std::sqrt(EI / (rhoA * L * L * L * L)));
    if (peaks.size() == 2)
      o << "| cantilever | reference | " << t.tets << " | first period " << fmt(peaks[1] - peaks[0], 4)
        << " s | Euler-Bernoulli " << fmt(T_eb, 4) << " s (no shear: a lower bound) | " << fmt((peaks[1] - peaks[0]) / T_eb, 3)
        << " |\n";
  }
  return o.str();
}

std::string slurp(const std::string& path) {
  std::ifstream f(path);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

// One scene's rows as a Markdown section (reference, table) into OUT_DIR/results-SCENE.md
// and its CSV rows into OUT_DIR/results-SCENE.csv; then results.csv and the Markdown file
// are put together from every scene's files present, so a run of a subset (--scene)
// updates its scenes and keeps the others.
void write_results(const std::string& out_dir, const std::string& markdown, const Study& st, const std::string& scene,
                   const std::vector<SceneDef>& defs, const std::string& command) {
  std::vector<Row> mine;
  for (const Row& r : st.rows)
    if (r.scene == scene) mine.push_back(r);
  write_csv(out_dir + "/results-" + scene + ".csv", mine);
  {
    std::ofstream o(out_dir + "/results-" + scene + ".md");
    o << "## " << scene << "\n\nMade by `" << command << "`.\n\n";
    o << "| reference: finest level | step s | final probe displacement mm | cavity volume ml (start -> end) | wall s |\n"
         "|---|---|---:|---|---:|\n"
      << (st.notes.count(scene) ? st.notes.at(scene).substr(st.notes.at(scene).find('|', 1)) : std::string("|\n")) << "\n";
    if (st.checks.find("| " + scene + " |") != std::string::npos) {
      o << "Independent checks (static solves against beam theory or the published value; the reference's period):\n\n";
      std::istringstream lines(st.checks);
      std::string line;
      for (int i = 0; std::getline(lines, line); ++i)
        if (i < 2 || line.rfind("| " + scene + " |", 0) == 0) o << line << "\n";
      o << "\n";
    }
    o << "| sweep | settings | tets | L2 err | probe err | probe err mm | final err | volume err | EF err pp | phase ms "
         "| wall s / sim s | steps/s | recovered | P |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
    for (const Row& r : mine)
      o << "| " << r.sweep << " | " << knob_text(r) << (r.stable ? "" : " **UNSTABLE**") << " | " << r.tets << " | "
        << fmt(r.e.l2) << " | " << fmt(r.e.probe) << " | " << fmt(r.e.probe_mm) << " | " << fmt(r.e.final_) << " | "
        << fmt(r.e.volume) << " | " << fmt(r.e.ef_pp) << " | " << fmt(r.e.phase_ms) << " | " << fmt(r.wall_per_sim)
        << " | " << fmt(r.steps_per_s, 4) << " | " << r.recovered << " | " << (r.pareto ? "P" : "") << " |\n";
    o << "\n";
  }
  std::ofstream csv(out_dir + "/results.csv");
  std::ofstream md(markdown);
  md << "<!-- Generated by bench_accuracy; do not edit by hand. -->\n";
  md << "# Speed against accuracy: measured tables\n\n";
  md << "Errors against each scene's converged reference (method: docs/speed-accuracy.md); cost = wall seconds per "
        "simulated second on one engine thread (< 1 is faster than real time). P = on the Pareto front of (cost, L2 "
        "error). One section per scene, each with the command that made it.\n\n";
  bool header = false;
  for (const SceneDef& d : defs) {
    const std::string c = slurp(out_dir + "/results-" + d.key + ".csv");
    if (c.empty()) continue;
    const size_t nl = c.find('\n');
    if (!header) csv << c.substr(0, nl + 1), header = true;
    csv << c.substr(nl + 1);
    md << slurp(out_dir + "/results-" + d.key + ".md");
  }
}

}  // namespace

int stability_main(const std::string& out_md, int threads);

int main(int argc, char** argv) {
  CLI::App app{"bench_accuracy: the speed-against-accuracy study (docs/speed-accuracy.md)"};
  std::vector<std::string> only;
  bool quick = false, stability = false;
  std::string out_dir = "build/study", heart_meshes, markdown, stability_md;
  int threads = 1;
  app.add_option("--scene", only, "Run only these scenes (cantilever, cantilever-gravity, land-beam, land-ventricle, heart)");
  app.add_flag("--quick", quick, "Two levels, two steps, a short run: a smoke test of the program");
  app.add_option("--out-dir", out_dir, "Where results.csv and the cached references go")->capture_default_str();
  app.add_option("--heart-meshes", heart_meshes, "Folder with biventricle-0.008/0.006/0.003.msh (the prepare steps of configs/sweeps/speed-accuracy/heart.yaml make them in build/study/meshes); default OUT_DIR/meshes");
  app.add_option("--markdown", markdown, "Also write the tables here (default OUT_DIR/results.md)");
  app.add_option("--threads", threads, "Engine threads")->capture_default_str();
  app.add_flag("--stability", stability, "Run the stability map instead (docs/speed-accuracy.md)");
  app.add_option("--stability-markdown", stability_md, "With --stability: write the table here (default OUT_DIR/stability.md)");
  CLI11_PARSE(app, argc, argv);
  fs::create_directories(out_dir);
  if (stability) return stability_main(stability_md.empty() ? out_dir + "/stability.md" : stability_md, threads);
  if (heart_meshes.empty()) heart_meshes = out_dir + "/meshes";
  heart_meshes = fs::absolute(heart_meshes).string();
  if (markdown.empty()) markdown = out_dir + "/results.md";
  std::string command = "bench_accuracy";
  for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];

  Study st;
  st.out_dir = out_dir;
  st.threads = threads;
  st.quick = quick;
  std::vector<std::string> done;
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<SceneDef> defs = scene_defs(FIBERFEM_SOURCE_DIR, heart_meshes, quick);
  for (const SceneDef& s : defs) {
    if (!only.empty() && std::find(only.begin(), only.end(), s.key) == only.end()) continue;
    st.run(s);
    done.push_back(s.key);
    if (s.key == "land-beam" || s.key == "cantilever") {
      std::vector<SceneDef> sel;
      for (const SceneDef& d : defs)
        if (std::find(done.begin(), done.end(), d.key) != done.end()) sel.push_back(d);
      st.checks = independent_checks(sel, st.refs);
    }
    mark_pareto(st.rows);
    write_results(out_dir, markdown, st, s.key, defs, command);
  }
  if (done.empty()) {
    std::cerr << "bench_accuracy: no scene selected\n";
    return 2;
  }
  std::printf("study done in %.0f s: %s/results.csv, %s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), out_dir.c_str(), markdown.c_str());
  return 0;
}
