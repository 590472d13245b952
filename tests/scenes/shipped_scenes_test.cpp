// The scenes that ship in configs/scenes/, each run by the real `fiberfem run` with a JSON
// report, checked against an analytic or published reference (the tolerance of each is
// argued where it is asserted).

#include "core/builtin_scenes.hpp"
#include "process_support.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

namespace {

using fiberfem::testing::read_json;
using fiberfem::testing::run_process;
using fiberfem::testing::TempDir;
using nlohmann::json;

std::string scene(const std::string& name) { return std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/" + name; }

// Runs a scene with extra arguments and returns its report (failing the test if the run did).
json run_scene(const std::string& file, std::vector<std::string> extra = {}) {
  TempDir dir;
  std::vector<std::string> args{FIBERFEM_BIN, "run", scene(file), "--report", dir.file("report.json")};
  args.insert(args.end(), extra.begin(), extra.end());
  const auto r = run_process(args);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  json report = read_json(dir.file("report.json"));
  EXPECT_EQ(report.value("status", ""), "completed") << r.output;
  return report;
}

json probe(const json& report, const std::string& name) {
  for (const json& p : report["probes"])
    if (p["name"] == name) return p;
  ADD_FAILURE() << "no probe " << name;
  return json::object();
}

double uz(const json& report, const std::string& name) { return probe(report, name)["displacement_m"][2].get<double>(); }

// Timoshenko tip deflection (downwards, positive) of the 10 x 1 x 1 cm cantilevers under a
// 1.5 Pa end traction.
double beam_theory(double E, double G) {
  const double area = 0.01 * 0.01;
  return fiberfem::core::cantilever_tip_deflection(0.1, 0.01, 0.01, E, G, 0, 1.5 * area);
}

// Linear tetrahedra converge to the beam from the stiff side, slowly in bending. The test
// runs the shipped mesh (40 x 4 x 4 cells) and one twice as fine, and checks
//  - the error shrinks at least by 1.8 (first order or better; linear elements give O(h)
//    in energy, O(h^2) displacements asymptotically);
//  - Richardson extrapolation of the two with order 2 lands within 3% of beam theory: the
//    beam theory itself differs from 3D elasticity by about 1% at length/height 10 (the
//    clamped end also stops the Poisson contraction), and the pair is not yet asymptotic
//    (measured ratios 2.0 to 2.4, not 4), so extrapolation with order 2 under-corrects;
//  - fibers across make the beam softer by the ratio beam theory gives, within 5%.
struct Cantilever {
  double coarse, fine;
  double extrapolated() const { return fine + (fine - coarse) / 3.0; }
};

// Memoised: two tests use the fibers-along beam.
Cantilever run_cantilever(const std::string& file) {
  static std::map<std::string, Cantilever> done;
  if (const auto it = done.find(file); it != done.end()) return it->second;
  Cantilever c{};
  c.coarse = -uz(run_scene(file), "tip");
  c.fine = -uz(run_scene(file, {"--cells", "80", "8", "8"}), "tip");
  return done[file] = c;
}

TEST(ShippedScenes, CantileverFibersAlongMatchesBeamTheory) {
  const Cantilever c = run_cantilever("cantilever-along.yaml");
  const double beam = beam_theory(60e3, 8e3);  // E_L, G_L
  RecordProperty("coarse_mm", std::to_string(1e3 * c.coarse));
  RecordProperty("fine_mm", std::to_string(1e3 * c.fine));
  RecordProperty("beam_mm", std::to_string(1e3 * beam));
  EXPECT_LT(c.coarse, c.fine);
  EXPECT_LT(c.fine, beam);
  EXPECT_GT((beam - c.coarse) / (beam - c.fine), 1.8);
  EXPECT_NEAR(c.extrapolated() / beam, 1.0, 0.03) << "coarse " << c.coarse << " fine " << c.fine << " beam " << beam;
}

TEST(ShippedScenes, CantileverFibersAcrossMatchesBeamTheory) {
  const Cantilever across = run_cantilever("cantilever-across.yaml");
  const Cantilever along = run_cantilever("cantilever-along.yaml");
  // Bending along x now uses the transverse modulus and the transverse shear modulus.
  const double E_T = 20e3, G_T = E_T / (2 * (1 + 0.45));
  const double beam = beam_theory(E_T, G_T);
  EXPECT_LT(across.coarse, across.fine);
  EXPECT_LT(across.fine, beam);
  EXPECT_GT((beam - across.coarse) / (beam - across.fine), 1.8);
  EXPECT_NEAR(across.extrapolated() / beam, 1.0, 0.03) << "coarse " << across.coarse << " fine " << across.fine;
  EXPECT_NEAR((across.extrapolated() / along.extrapolated()) / (beam / beam_theory(60e3, 8e3)), 1.0, 0.05);
}

// A column on a frictionless floor under its own weight (uniaxial stress rho g (H - z)):
// the sag of the top centre is rho g H^2 / (2 E_L) and the strain energy
// rho^2 g^2 A H^3 / (6 E_L). Tolerance 1%: the exact displacement is quadratic along z,
// which linear elements on 20 layers represent to O(h^2) = 0.25% (nodally exact in 1D);
// the floor holds the base flat where elasticity would bow it by nu rho g r^2 / (2 E_L),
// 0.5% of the sag at the corners, less at the centre. The run is dynamic: it must also
// have settled (kinetic energy 1e-9 of the elastic) within its one second.
TEST(ShippedScenes, BoxUnderGravitySagsAsElasticityPredicts) {
  const json r = run_scene("box-gravity.yaml");
  const double rho = 1000, g = 9.81, H = 0.05, A = 1e-4, E_L = 60e3;
  EXPECT_NEAR(-uz(r, "top") / (rho * g * H * H / (2 * E_L)), 1.0, 0.01);
  // Mid-height: rho g (H z - z^2 / 2) / E_L at z = H / 2.
  EXPECT_NEAR(-uz(r, "mid") / (rho * g * (H * H / 2 - H * H / 8) / E_L), 1.0, 0.01);
  const double energy = r["energies"]["final"]["elastic_j"].get<double>();
  EXPECT_NEAR(energy / (rho * rho * g * g * A * H * H * H / (6 * E_L)), 1.0, 0.01);
  EXPECT_LT(r["energies"]["final"]["kinetic_j"].get<double>(), 1e-9 * energy);
  EXPECT_EQ(r["steps"]["completed"], 60);
}

// Land et al. 2015 problem 1 (REFERENCES.md). Published (nonlinear Guccione, follower
// pressure, converged meshes): deformed z of the point (10, 0.5, 1) mm is 4.17 mm, codes
// from 4.15 to 4.19. Here the small-strain limit of that material, nearly incompressible,
// on linear tetrahedra, which lock in bending: the value is far below 4.17 at the shipped
// 40 x 4 x 4 cells (an independent implementation: 2.54 mm at 40 x 4 x 4, 3.45 mm at
// 80 x 8 x 8) and rises towards it with refinement. The test pins what must hold whatever
// the locking: the beam bends up (the pressure pushes along the inward normal +z), the
// point's z rises with refinement, stays below the top of the published band, and the
// locking is what it is for this incompressibility (the fine mesh gains at least 25%).
TEST(ShippedScenes, LandBeamConvergesTowardsThePublishedDeflectionFromBelow) {
  const double coarse = 1e-3 + uz(run_scene("land-beam.yaml"), "end");
  const double fine = 1e-3 + uz(run_scene("land-beam.yaml", {"--cells", "80", "8", "8"}), "end");
  RecordProperty("coarse_z_mm", std::to_string(1e3 * coarse));
  RecordProperty("fine_z_mm", std::to_string(1e3 * fine));
  EXPECT_GT(coarse, 1.5e-3) << "the beam must bend up, several millimetres";
  EXPECT_GT(fine, 1.25 * coarse);
  EXPECT_LT(fine, 4.19e-3);
}

// The beating ventricle (configs/scenes/lv-beat.yaml): no closed-form answer, so the test
// checks what any contracting ventricle must do, each can fail independently: at peak
// systole (t = 0.1 s: the twitch peaks 0.076 s after each element's activation, which
// reaches the equator about 0.03 s after the apex) the endocardium at the equator moves
// inwards and the apex towards the base, the wall thickens at the apex (the endocardial
// apex moves further than the epicardial one), and the base-to-apex helix twists the
// equator (a displacement along e_c); a beat later it is back at rest (the twitch has
// decayed to 2e-3 of its peak by 0.8 s and the mass damping removes the motion).
TEST(ShippedScenes, LvBeatContractsAndRelaxes) {
  const json peak = run_scene("lv-beat.yaml", {"--until", "0.1"});
  const json p_eq = probe(peak, "equator_endo")["displacement_m"], p_ae = probe(peak, "apex_endo")["displacement_m"],
             p_ap = probe(peak, "apex_epi")["displacement_m"];
  EXPECT_LT(p_eq[0].get<double>(), -0.05 * 0.007) << "the equator moves inwards by 5% of the radius at least";
  EXPECT_GT(p_ae[2].get<double>(), 1e-4) << "the apex moves towards the base";
  EXPECT_GT(p_ae[2].get<double>(), p_ap[2].get<double>()) << "the wall thickens at the apex";
  EXPECT_GT(std::abs(p_eq[1].get<double>()), 0.1 * std::abs(p_eq[0].get<double>())) << "the equator twists";
  // The cavity: at rest the endocardial polyhedron of the truncated ellipsoid
  // (pi rs^2 ((b + rl) - (b^3 + rl^3) / (3 rl^2)) = 2.492 mL, less 2.2% for the faceting at
  // this resolution, tests/core/cavity_test.cpp); two complete, identical beats (a
  // periodic steady state from the first beat: the twitch has decayed before the next);
  // an ejection fraction in the physiological 0.3 to 0.7 the scene is tuned for.
  const json full = run_scene("lv-beat.yaml");
  ASSERT_EQ(full["cavities"].size(), 1u);
  const json& lv = full["cavities"][0];
  const double exact = fiberfem::testing::truncated_ellipsoid_volume(0.007, 0.017, 0.005);
  EXPECT_NEAR(lv["rest_m3"].get<double>() / exact, 1.0 - 0.0215, 0.005);
  ASSERT_EQ(lv["beats"].size(), 2u);
  EXPECT_TRUE(lv["beats"][0]["complete"].get<bool>());
  EXPECT_TRUE(lv["beats"][1]["complete"].get<bool>());
  // Beat 0 starts from rest: its end-diastolic volume is the rest volume.
  EXPECT_EQ(lv["beats"][0]["end_diastolic_m3"].get<double>(), lv["rest_m3"].get<double>());
  const double ef0 = lv["beats"][0]["ejection_fraction"].get<double>(), ef1 = lv["beats"][1]["ejection_fraction"].get<double>();
  EXPECT_NEAR(ef0, ef1, 0.01);
  EXPECT_GT(ef1, 0.3);
  EXPECT_LT(ef1, 0.7);
  // The apex excursion per beat: the same in both beats, and at least what the probe showed
  // at t = 0.1 s (the per-beat maximum is taken over every step).
  const json apex = probe(full, "apex_endo");
  ASSERT_EQ(apex["beats"].size(), 2u);
  const double a0 = apex["beats"][0]["max_displacement_norm_m"].get<double>(), a1 = apex["beats"][1]["max_displacement_norm_m"].get<double>();
  EXPECT_NEAR(a0 / a1, 1.0, 0.01);
  EXPECT_GE(a0 * (1 + 1e-12), std::hypot(p_ae[0].get<double>(), p_ae[1].get<double>(), p_ae[2].get<double>()));
  const json rest = run_scene("lv-beat.yaml", {"--until", "0.8"});
  EXPECT_LT(std::abs(probe(rest, "equator_endo")["displacement_m"][0].get<double>()), 0.05 * std::abs(p_eq[0].get<double>()));
}

// The default heart (configs/scenes/heart.yaml on meshes/biventricle.msh): the LV cavity
// at rest is the truncated endocardial ellipsoid of scripts/make_biventricle.py
// (rs 0.015, rl 0.038, base z = 0.012: 26.11 mL) less the faceting of a 4 mm mesh (the
// inscribed polyhedron: about 1%, bound 3%); both ventricles eject within the
// physiological 0.3 to 0.7 the scene is tuned for, in two identical beats.
TEST(ShippedScenes, HeartBeatsWithPhysiologicalEjectionFractions) {
  const json r = run_scene("heart.yaml");
  ASSERT_EQ(r["cavities"].size(), 2u);
  const double lv_exact = fiberfem::testing::truncated_ellipsoid_volume(0.015, 0.038, 0.012);
  for (const json& c : r["cavities"]) {
    if (c["name"] == "lv") {
      EXPECT_LT(c["rest_m3"].get<double>(), lv_exact);
      EXPECT_GT(c["rest_m3"].get<double>(), 0.97 * lv_exact);
    }
    ASSERT_EQ(c["beats"].size(), 2u) << c["name"];
    EXPECT_TRUE(c["beats"][1]["complete"].get<bool>());
    const double ef0 = c["beats"][0]["ejection_fraction"].get<double>(), ef1 = c["beats"][1]["ejection_fraction"].get<double>();
    EXPECT_NEAR(ef0, ef1, 0.01) << c["name"];
    EXPECT_GT(ef1, 0.3) << c["name"];
    EXPECT_LT(ef1, 0.7) << c["name"];
  }
}

// The default heart with the closed-loop circulation (configs/scenes/heart-circulation-
// realtime.yaml, docs/circulation.md) over five beats: blood is conserved to round-off, the
// loop settles (the last beat's LV stroke volume within 1% of the one before) and closes
// (the two ventricles' stroke volumes within 2%), and the LV ejects a physiological
// fraction against the scaled aortic pressure (peak LV above the aortic diastolic).
TEST(ShippedScenes, HeartWithCirculationSettlesIntoAClosedLoop) {
  const json r = run_scene("heart-circulation-realtime.yaml", {"--until", "4.1667", "--set", "solver.threads=1"});
  const json& c = r["circulation"];
  EXPECT_LT(c["max_blood_volume_drift_m3"].get<double>(), 1e-12 * c["blood_volume_m3"].get<double>());
  const json& beats = c["beats"];
  ASSERT_GE(beats.size(), 5u);
  const json &last = beats[4], &before = beats[3];
  ASSERT_TRUE(last["complete"].get<bool>());
  const double sv = last["lv"]["stroke_volume_m3"].get<double>(), sv_rv = last["rv"]["stroke_volume_m3"].get<double>();
  EXPECT_LT(std::abs(sv - before["lv"]["stroke_volume_m3"].get<double>()), 0.01 * sv);
  EXPECT_LT(std::abs(sv - sv_rv), 0.02 * sv);
  const double ef = last["lv"]["ejection_fraction"].get<double>();
  EXPECT_GT(ef, 0.3);
  EXPECT_LT(ef, 0.7);
  EXPECT_GT(last["lv"]["peak_pressure_pa"].get<double>(), last["systemic_arterial_min_pa"].get<double>());
  EXPECT_GT(last["systemic_arterial_max_pa"].get<double>(), 1.3 * last["systemic_arterial_min_pa"].get<double>());
}

// The paper's palm tree (Figs. 1 to 3) in four variants (configs/scenes/palm-*.yaml on
// meshes/palm.msh). The paper's qualitative findings, each a comparison that can fail:
// the stiffer trunk of the heterogeneous tree sways and sags less than the soft isotropic
// one, and the fiber model (stiffer along the trunk and the leaf veins) sags least and
// stretches its leaves least; a dragging force pulls its leaf along the force. Speeds are
// reported in docs/scenes.md (benchmarks, not assertions). Leaf stretch: the change of the
// distance between a probe near the leaf's root and one near its tip.
TEST(ShippedScenes, PalmTreeVariantsFollowThePapersFindings) {
  struct Result {
    double trunk, droop, stretch, tip_y;
  };
  auto run = [&](const std::string& file) {
    const json r = run_scene(file);
    const json b = probe(r, "leaf_base"), t = probe(r, "leaf_tip"), top = probe(r, "trunk_top");
    auto length = [&](const char* key) {
      double d2 = 0;
      for (int k = 0; k < 3; ++k) {
        const double d = t[key][k].get<double>() - b[key][k].get<double>();
        d2 += d * d;
      }
      return std::sqrt(d2);
    };
    const json& u = top["displacement_m"];
    return Result{std::hypot(u[0].get<double>(), u[1].get<double>(), u[2].get<double>()), -t["displacement_m"][2].get<double>(),
                  length("final_m") / length("rest_m") - 1.0, t["displacement_m"][1].get<double>()};
  };
  const Result iso = run("palm-isotropic.yaml"), het = run("palm-heterogeneous.yaml"), fib = run("palm-fibers.yaml"),
               drag = run("palm-drag.yaml");
  std::printf("palm: trunk top |u| iso %.3e het %.3e fib %.3e m; leaf tip droop %.3e %.3e %.3e m; "
              "leaf stretch %.2e %.2e %.2e; drag tip y %.3e (fibers alone %.3e)\n",
              iso.trunk, het.trunk, fib.trunk, iso.droop, het.droop, fib.droop, iso.stretch, het.stretch, fib.stretch,
              drag.tip_y, fib.tip_y);
  EXPECT_LT(het.trunk, 0.5 * iso.trunk);
  EXPECT_LT(fib.trunk, 0.5 * het.trunk);
  EXPECT_GT(iso.droop, 0.0);
  EXPECT_LT(fib.droop, 0.5 * het.droop);
  EXPECT_LT(fib.droop, 0.5 * iso.droop);
  EXPECT_LT(std::abs(fib.stretch), 0.5 * std::abs(het.stretch));
  EXPECT_LT(std::abs(fib.stretch), 0.5 * std::abs(iso.stretch));
  EXPECT_GT(drag.tip_y - fib.tip_y, 1e-3) << "the leaf follows the 0.5 N drag along +y";
}

// Land problem 2 with the linearised material (configs/scenes/land-ventricle-p2.yaml): no
// pass/fail against the published 10 kPa shape (the linear material cannot carry it: a
// limit point between 2 and 3 kPa, docs/scenes.md), so the test checks what must hold:
// the run settles (kinetic energy negligible) at both 1 and 2 kPa, the cavity and the
// apex descent grow with the pressure, and the follower pressure inflates more than a dead
// one of the same size (the wall's area grows, and so does the load on it).
TEST(ShippedScenes, LandVentricleProblem2InflatesAndSettles) {
  auto run = [&](const std::string& pressure, const std::string& follower) {
    return run_scene("land-ventricle-p2.yaml",
                     {"--set", "loads.tractions[0].pressure=" + pressure, "--set", "loads.tractions[0].follower=" + follower});
  };
  const json p1 = run("1.0e3", "true"), p2 = run("2.0e3", "true"), dead = run("2.0e3", "false");
  for (const json* r : {&p1, &p2, &dead})
    EXPECT_LT((*r)["energies"]["final"]["kinetic_j"].get<double>(), 1e-12 * (*r)["energies"]["final"]["elastic_j"].get<double>());
  auto volume = [](const json& r) { return r["cavities"][0]["max_m3"].get<double>(); };
  auto apex = [](const json& r) { return probe(r, "apex_endo")["final_m"][2].get<double>(); };
  EXPECT_GT(volume(p1), p1["cavities"][0]["rest_m3"].get<double>());
  EXPECT_GT(volume(p2), volume(p1));
  EXPECT_LT(apex(p2), apex(p1));
  EXPECT_LT(apex(p1), -0.017);
  EXPECT_GT(volume(p2), volume(dead));
  std::printf("Land problem 2, linearised: inner apex z %.2f mm at 1 kPa, %.2f mm at 2 kPa (dead load %.2f); "
              "cavity %.3f / %.3f mL\n",
              1e3 * apex(p1), 1e3 * apex(p2), 1e3 * apex(dead), 1e6 * volume(p1), 1e6 * volume(p2));
}

// Problem 3, linearised and with both loads scaled by 0.2 (the linear material has no
// equilibrium at the full loads): contraction wins over inflation, the apex rises as in the
// published nonlinear solutions (inner apex from -17 mm at rest to -12.3 .. -12.5 mm), the
// cavity shrinks, and the state at 2 s is quasi-static.
TEST(ShippedScenes, LandVentricleProblem3ContractsAndTheApexRises) {
  const json r = run_scene("land-ventricle-p3.yaml", {});
  const double inner = probe(r, "apex_endo")["final_m"][2].get<double>();
  const double outer = probe(r, "apex_epi")["final_m"][2].get<double>();
  EXPECT_GT(inner, -0.017 + 0.002);  // rises by millimetres ...
  EXPECT_LT(inner, -0.017 + 0.008);  // ... not by centimetres
  EXPECT_GT(outer, -0.020 + 0.002);
  EXPECT_LT(r["cavities"][0]["min_m3"].get<double>(), r["cavities"][0]["rest_m3"].get<double>());
  EXPECT_LT(r["energies"]["final"]["kinetic_j"].get<double>(), 1e-3 * r["energies"]["final"]["elastic_j"].get<double>());
  std::printf("Land problem 3, linearised, loads x0.2: inner apex z %.2f mm, outer %.2f mm (published at full load: -12.3 to -12.5, "
              "about -15.5)\n", 1e3 * inner, 1e3 * outer);
}

// The accurate tier on Land et al. 2015 at the benchmark's full loads (incompressible
// Guccione, P2/P1 Taylor-Hood tetrahedra, follower pressure): each shipped scene against
// the published consensus. The shipped meshes are the coarsest of the convergence tables
// in docs/accurate-tier.md; the tolerances are those tables' errors at that level, with
// margin, and each test also checks the side it converges from where the table shows one.
TEST(ShippedScenes, LandBeamGuccioneMeetsThePublishedTipAtFullLoad) {
  const json r = run_scene("land-beam-guccione.yaml");
  EXPECT_EQ(r["static"]["tier"], "accurate");
  const double z = probe(r, "end")["final_m"][2].get<double>();
  // Within 0.5% of the converged 4.1688 mm (30 cells: -0.33%; -0.64% at 20, -0.09% at 80).
  EXPECT_NEAR(z, 4.1688e-3, 0.005 * 4.1688e-3);
  EXPECT_LT(z, 4.1688e-3);  // from below, as tetrahedra do
  std::printf("Land problem 1, Guccione, full load: tip z %.4f mm (published 4.17)\n", 1e3 * z);
}

namespace {

// The apex probes of a shipped Land ventricle scene against the published inner / outer
// apex z (m), each within `fraction` of its value; returns the inner apex z.
double expect_apex_near_published(const std::string& scene, const char* problem, double inner_m, double outer_m,
                                  double fraction) {
  const json r = run_scene(scene);
  const double inner = probe(r, "apex_endo")["final_m"][2].get<double>();
  const double outer = probe(r, "apex_epi")["final_m"][2].get<double>();
  EXPECT_NEAR(inner, inner_m, fraction * std::abs(inner_m));
  EXPECT_NEAR(outer, outer_m, fraction * std::abs(outer_m));
  std::printf("Land problem %s, Guccione, full load: apex z %.3f / %.3f mm (published %.3f / %.3f)\n", problem,
              1e3 * inner, 1e3 * outer, 1e3 * inner_m, 1e3 * outer_m);
  return inner;
}

}  // namespace

// Problem 2 on its graded mesh: both apex probes within 0.5% of the converged -26.613 /
// -28.282 mm (measured +0.04% / -0.06%).
TEST(ShippedScenes, LandVentricleProblem2GuccioneMeetsThePublishedApexAtFullLoad) {
  expect_apex_near_published("land-ventricle-p2-guccione.yaml", "2", -26.613e-3, -28.282e-3, 0.005);
}

// Problem 3 on its graded six-layer mesh: both apex probes within 0.5% of the published
// -12.35 / -15.45 mm (measured -0.46% / +0.28%), the inner apex from above (less deep), as
// every graded mesh of the table approaches it.
TEST(ShippedScenes, LandVentricleProblem3GuccioneMeetsThePublishedApexAtFullLoad) {
  EXPECT_GT(expect_apex_near_published("land-ventricle-p3-guccione.yaml", "3", -12.35e-3, -15.45e-3, 0.005), -12.35e-3);
}

// In time, the accurate tier's backward-Euler steps with mass damping settle on the static
// solution of the same scene (found by the independent load-stepping solve).
TEST(ShippedScenes, LandBeamGuccioneInTimeSettlesOnItsStaticSolution) {
  const std::vector<std::string> coarse{"--set", "mesh.cells=[10, 1, 1]"};
  std::vector<std::string> dynamic = coarse;
  for (const char* o : {"solver.mode=dynamic", "solver.dt=0.01", "solver.until=1.2", "regions[0].damping={mass: 100.0}"})
    dynamic.insert(dynamic.end(), {"--set", o});
  const json s = run_scene("land-beam-guccione.yaml", coarse);
  const json d = run_scene("land-beam-guccione.yaml", dynamic);
  EXPECT_EQ(d["dynamic"]["tier"], "accurate");
  EXPECT_EQ(d["dynamic"]["steps"], 120);
  const double zs = uz(s, "end"), zd = uz(d, "end");
  EXPECT_GT(zs, 1e-3);
  EXPECT_NEAR(zd, zs, 5e-3 * zs);
  std::printf("Land beam, accurate tier: static tip uz %.4f mm, after 1.2 s of damped motion %.4f mm\n", 1e3 * zs, 1e3 * zd);
  // --compare-static compares with the real-time tier's static solve: refused by name.
  std::vector<std::string> args{FIBERFEM_BIN, "run", scene("land-beam-guccione.yaml"), "--compare-static"};
  args.insert(args.end(), dynamic.begin(), dynamic.end());
  const auto r = run_process(args);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("accurate tier"), std::string::npos) << r.output;
}

// A beat on the accurate tier reports its cavity per beat as the real-time tier does, and
// at small strain the two tiers, independent engines on the same linear tetrahedra (the
// accurate tier's neo-Hookean law and Newton, the real-time tier's linearised material and
// corotated step), eject the same fraction: lv-beat.yaml with a weak contraction.
TEST(ShippedScenes, ABeatOnTheAccurateTierEjectsAsTheRealTimeTierAtSmallStrain) {
  const std::vector<std::string> small{"--set", "mesh.refine=0.5", "--set", "solver.until=0.85", "--set",
                                       "contraction.peak_tension=300.0", "--set",
                                       "regions[0].material={law: neo_hookean, E: 40000.0, nu: 0.3, density: 1060.0}"};
  std::vector<std::string> fast = small;
  fast.insert(fast.end(), {"--set", "solver.tier=real_time"});
  const json a = run_scene("lv-beat.yaml", small);
  const json r = run_scene("lv-beat.yaml", fast);
  ASSERT_EQ(a["dynamic"]["tier"], "accurate");
  ASSERT_TRUE(a["cavities"].is_array() && r["cavities"].is_array());
  const json& beat_a = a["cavities"][0]["beats"][0];
  const json& beat_r = r["cavities"][0]["beats"][0];
  ASSERT_TRUE(beat_a["complete"].get<bool>() && beat_r["complete"].get<bool>());
  const double ef_a = beat_a["ejection_fraction"], ef_r = beat_r["ejection_fraction"];
  EXPECT_GT(ef_a, 1e-3);  // a beat to compare
  EXPECT_LT(ef_a, 0.05);  // small strain
  // Within 5%: the tiers' helix fibers differ slightly (per point on the ellipsoid against
  // per element from the Laplace coordinate), the rest is linearisation.
  EXPECT_NEAR(ef_a / ef_r, 1.0, 0.05) << ef_a << " " << ef_r;
  std::printf("small-strain beat: ejection fraction %.5f (accurate tier) and %.5f (real-time tier)\n", ef_a, ef_r);
}

// A step the accurate tier cannot take whole (Newton from the predictor leaves the soft
// Guccione law's admissible states under a strong contraction at a large step) is retried
// in substeps instead of ending the run, and the run lands where a run at a quarter of the
// step does (within 0.5% at the apex: both have relaxed to nearly the same state). At
// 100 kPa three steps fail whole; at 60 kPa one did, and whether it does turns on the
// tangent's round-off (the order of the assembly's sums).
TEST(ShippedScenes, AnAccurateStepThatFailsWholeIsTakenInSubsteps) {
  const std::vector<std::string> hard{"--set", "mesh.refine=0.5", "--set", "solver.until=0.4", "--set",
                                      "contraction.peak_tension=100e3", "--set",
                                      "regions[0].material={law: guccione, C: 880.0, b_f: 18.48, b_t: 3.58, b_fs: 1.627, density: 1060.0}"};
  std::vector<std::string> coarse = hard, fine = hard;
  coarse.insert(coarse.end(), {"--set", "solver.dt=0.0333"});
  fine.insert(fine.end(), {"--set", "solver.dt=0.008333"});
  const json c = run_scene("lv-beat.yaml", coarse);
  const json f = run_scene("lv-beat.yaml", fine);
  EXPECT_GE(c["dynamic"]["recovered_with_substeps"].get<int>(), 1);
  const double uc = uz(c, "apex_epi"), uf = uz(f, "apex_epi");
  EXPECT_NEAR(uc / uf, 1.0, 5e-3) << uc << " " << uf;
}

// The closed-loop circulation on the accurate tier: lv-beat.yaml's cavity as the left
// ventricle of the loop (the right one lumped), at small strain (weak contraction, the
// loop's pressures scaled down) so that the two tiers, independent engines and couplings
// (the accurate tier's converged Newton steps iterated on the pressure, the real-time
// tier's affine step), must give the same beat: stroke volume and peak pressure within 5%.
// The accurate run keeps the blood volume, and while both of the left ventricle's valves
// are shut its volume stays within 0.1%.
TEST(ShippedScenes, TheAccurateTierBeatsAgainstTheCirculationAsTheRealTimeTierAtSmallStrain) {
  const std::vector<std::string> small{
      "--set", "mesh.refine=0.5", "--set", "solver.until=1.67", "--set", "contraction.peak_tension=500.0", "--set",
      "regions[0].material={law: neo_hookean, E: 40000.0, nu: 0.3, density: 1060.0}", "--set",
      "circulation={ventricles: {left: lv}, scale: {pressure: 0.00125, volume: 0.015}}"};
  std::vector<std::string> fast = small;
  fast.insert(fast.end(), {"--set", "solver.tier=real_time"});
  const json a = run_scene("lv-beat.yaml", small);
  const json r = run_scene("lv-beat.yaml", fast);
  ASSERT_EQ(a["dynamic"]["tier"], "accurate");
  const json& ca = a["circulation"];
  const json& cr = r["circulation"];
  ASSERT_TRUE(ca.is_object() && cr.is_object());
  const json& beat_a = ca["beats"][1]["lv"];
  const json& beat_r = cr["beats"][1]["lv"];
  const double sv_a = beat_a["stroke_volume_m3"], sv_r = beat_r["stroke_volume_m3"];
  const double peak_a = beat_a["peak_pressure_pa"], peak_r = beat_r["peak_pressure_pa"];
  EXPECT_GT(sv_a, 0.005 * beat_a["end_diastolic_volume_m3"].get<double>());  // it ejects
  EXPECT_LT(beat_a["ejection_fraction"].get<double>(), 0.05);                 // small strain
  EXPECT_NEAR(sv_a / sv_r, 1.0, 0.05) << sv_a << " " << sv_r;
  EXPECT_NEAR(peak_a / peak_r, 1.0, 0.05) << peak_a << " " << peak_r;
  EXPECT_LT(ca["max_blood_volume_drift_m3"].get<double>(), 1e-12 * ca["blood_volume_m3"].get<double>());
  // Isovolumic phases: steps whose mitral and aortic flows are both below 1e-4 of the
  // largest aortic flow (the valves' shut resistance lets through about 1e-5 of it); at
  // this step a phase lasts a step or two.
  const json& st = ca["steps"];
  const std::vector<double> mitral = st["mitral_flow_m3_s"], aortic = st["aortic_flow_m3_s"], volume = st["lv_volume_m3"];
  double most = 0;
  for (double q : aortic) most = std::max(most, std::abs(q));
  int shut = 0;
  double drift = 0;
  for (size_t k = 1; k < volume.size(); ++k) {
    if (std::abs(mitral[k]) > 1e-4 * most || std::abs(aortic[k]) > 1e-4 * most) continue;
    ++shut;
    drift = std::max(drift, std::abs(volume[k] - volume[k - 1]) / volume[k - 1]);
  }
  EXPECT_GE(shut, 2) << "no isovolumic phase to check";
  EXPECT_LT(drift, 1e-3);
  std::printf("circulation, small strain: LV stroke volume %.4e / %.4e m^3, peak %.3f / %.3f Pa (accurate / real-time); "
              "%d isovolumic steps, largest volume change %.2e\n",
              sv_a, sv_r, peak_a, peak_r, shut, drift);
}

// The physiological heart (configs/scenes/heart-circulation.yaml, docs/circulation.md): the
// accurate tier's ventricles coupled to the loop at human pressures. Its periodic state takes
// minutes (a measurement in the docs); here its first 80 ms, from the unloaded rest, in 5 ms
// steps (at the scene's 1/60 s the first step fails whole and is taken in substeps, which
// costs more): both ventricles fill through their open inflow valves, then the contraction
// shuts them and the left ventricle's pressure rises at constant volume (the isovolumic
// contraction) until it passes the aortic pressure and the aortic valve opens. Blood is
// conserved to round-off, every pressure stays finite and positive, and an outflow valve
// passes blood only while its ventricle's pressure is above its artery's.
TEST(ShippedScenes, ThePhysiologicalHeartFillsContractsIsovolumicallyAndEjects) {
  const json r = run_scene("heart-circulation.yaml", {"--steps", "16", "--set", "solver.dt=0.005", "--threads", "1"});
  ASSERT_EQ(r["dynamic"]["tier"], "accurate");
  const json& c = r["circulation"];
  EXPECT_EQ(c["coupled_cavities"], json({{"lv", "lv"}, {"rv", "rv"}}));
  EXPECT_LT(c["max_blood_volume_drift_m3"].get<double>(), 1e-12 * c["blood_volume_m3"].get<double>());
  const json& st = c["steps"];
  for (const auto& [name, values] : st.items()) {
    if (name.size() < 3 || name.substr(name.size() - 3) != "_pa") continue;
    for (double p : values) {
      EXPECT_TRUE(std::isfinite(p)) << name;
      EXPECT_GT(p, 0.0) << name;
    }
  }
  const std::vector<double> mitral = st["mitral_flow_m3_s"], aortic = st["aortic_flow_m3_s"], tricuspid = st["tricuspid_flow_m3_s"],
                            pulmonary = st["pulmonary_valve_flow_m3_s"], volume = st["lv_volume_m3"], p_lv = st["lv_pressure_pa"],
                            p_rv = st["rv_pressure_pa"], p_ao = st["systemic_arterial_pressure_pa"],
                            p_pa = st["pulmonary_arterial_pressure_pa"];
  ASSERT_EQ(volume.size(), 16u);
  double most = 0;
  for (size_t k = 0; k < volume.size(); ++k) most = std::max({most, std::abs(mitral[k]), std::abs(aortic[k])});
  const double open = 1e-4 * most;  // a shut valve leaks about 1e-6 of the open flows here
  // Filling first: the inflow valves open, the outflow valves shut, the cavities grow.
  EXPECT_GT(mitral[0], open);
  EXPECT_GT(tricuspid[0], open);
  EXPECT_GT(volume[0], r["cavities"][0]["rest_m3"].get<double>());
  int isovolumic = 0, ejecting = 0;
  for (size_t k = 0; k < volume.size(); ++k) {
    if (aortic[k] > open) {
      ++ejecting;
      EXPECT_GT(p_lv[k], p_ao[k]) << "step " << k;
    } else {
      EXPECT_LT(p_lv[k], p_ao[k] + 0.01 * 133.3) << "step " << k;
    }
    if (pulmonary[k] > open) {
      EXPECT_GT(p_rv[k], p_pa[k]) << "step " << k;
    }
    // Isovolumic: both valves shut at the step's start (the last step's end) and end.
    auto shut = [&](size_t i) { return std::abs(mitral[i]) < open && std::abs(aortic[i]) < open; };
    if (k > 0 && shut(k - 1) && shut(k)) {
      ++isovolumic;
      EXPECT_LT(std::abs(volume[k] - volume[k - 1]), 1e-3 * volume[k - 1]) << "step " << k;
      EXPECT_GT(p_lv[k], p_lv[k - 1]) << "step " << k;
    }
  }
  EXPECT_GE(isovolumic, 3) << "no isovolumic contraction";
  EXPECT_GE(ejecting, 1) << "the left ventricle did not eject";
  EXPECT_GT(aortic.back(), open);
}

}  // namespace
