// vega_beam: Vega FEM 4.0 runs a tetrahedral cantilever from rest, the Vega side of
// docs/vega-comparison.md. Built by scripts/vega/CMakeLists.txt against a Vega checkout.
//
//   vega_beam MESH.node|MESH.ele|MESH.veg [--steps N] [--scale M] [--tip X Y Z] ...
//
// What runs is Vega's own code, as its examples use it: TetMesh (Vega's TetGen or .veg
// reader) with one E/nu material, Vega's consistent mass matrix, CorotationalLinearFEM
// through CorotationalLinearFEMForceModel with the exact tangent (warp 2; --warp 1 is the
// warped stiffness R K R^T of Mueller and Gross 2004), ImplicitBackwardEulerSparse with
// one Newton iteration per step (the linearised step) and its Jacobi-preconditioned CG
// (tolerance 1e-6 and the zero initial guess are fixed inside Vega's integrator). The only addition is a count of CG iterations: Vega discards
// the count its solver returns, so the integrator's solver is replaced by a CGSolver that
// counts the products with its search direction (one per iteration) and is otherwise the
// same object Vega builds.
//
// Prints one `key value` line per figure (read by scripts/vega/compare.sh).
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "CGSolver.h"
#include "corotationalLinearFEM.h"
#include "corotationalLinearFEMForceModel.h"
#include "generateMassMatrix.h"
#include "implicitBackwardEulerSparse.h"
#include "tetMesh.h"

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// The run's settings; defaults are docs/vega-comparison.md's.
struct Options {
  std::string mesh;                          ///< TetGen .node/.ele (either name) or Vega .veg
  int steps = 60;                            ///< time steps from rest, > 0
  double scale_m = 1.0;                      ///< metres per mesh unit, > 0
  double youngs_pa = 1e5;                    ///< Young's modulus E, Pa
  double poisson = 0.45;                     ///< Poisson ratio nu
  double density_kg_m3 = 1000.0;             ///< rho
  double dt_s = 1.0 / 60.0;                  ///< backward Euler step h
  double stiffness_damping_s = 0.01;         ///< Rayleigh beta (D = alpha M + beta K)
  double mass_damping_1_s = 0.0;             ///< Rayleigh alpha
  double gravity_z_m_s2 = -9.81;             ///< gravity along z
  double fixed_x = 0.0;                      ///< mesh units: nodes on this plane are held
  std::array<double, 3> tip = {10, 0.5, 0.5};  ///< mesh units: the nearest node is reported
  int warp = 2;                              ///< Vega's tangent: 2 exact, 1 warped R K R^T, 0 linear
};

[[noreturn]] void usage_error(const std::string& message) {
  std::fprintf(stderr,
               "vega_beam: %s\nusage: vega_beam MESH.node|MESH.ele|MESH.veg [--steps N] [--scale M] "
               "[--tip X Y Z] [--fixed-x X] [--E PA] [--nu NU] [--density KG_M3] [--dt S] "
               "[--stiffness-damping S] [--mass-damping 1_S] [--gravity-z M_S2] [--warp 0|1|2]\n",
               message.c_str());
  std::exit(2);
}

double number_after(int& i, int argc, char** argv) {
  if (i + 1 >= argc) usage_error(std::string(argv[i]) + " needs a value");
  char* end = nullptr;
  const double value = std::strtod(argv[++i], &end);
  if (end == argv[i] || *end != '\0') usage_error(std::string("not a number: ") + argv[i]);
  return value;
}

Options parse_options(int argc, char** argv) {
  Options o;
  const std::vector<std::pair<const char*, double*>> numbers = {
      {"--scale", &o.scale_m},          {"--E", &o.youngs_pa},
      {"--nu", &o.poisson},             {"--density", &o.density_kg_m3},
      {"--dt", &o.dt_s},                {"--stiffness-damping", &o.stiffness_damping_s},
      {"--mass-damping", &o.mass_damping_1_s}, {"--gravity-z", &o.gravity_z_m_s2},
      {"--fixed-x", &o.fixed_x}};
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto named = std::find_if(numbers.begin(), numbers.end(),
                                    [&](const auto& n) { return arg == n.first; });
    if (named != numbers.end()) {
      *named->second = number_after(i, argc, argv);
    } else if (arg == "--steps") {
      o.steps = static_cast<int>(number_after(i, argc, argv));
    } else if (arg == "--warp") {
      o.warp = static_cast<int>(number_after(i, argc, argv));
    } else if (arg == "--tip") {
      for (double& c : o.tip) c = number_after(i, argc, argv);
    } else if (arg.rfind("--", 0) == 0 || !o.mesh.empty()) {
      usage_error("unknown argument " + arg);
    } else {
      o.mesh = arg;
    }
  }
  if (o.mesh.empty()) usage_error("no mesh file given");
  if (o.steps <= 0 || o.scale_m <= 0 || o.dt_s <= 0) usage_error("--steps, --scale and --dt must be > 0");
  if (o.warp < 0 || o.warp > 2) usage_error("--warp must be 0, 1 or 2");
  return o;
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

/// Vega's readers: TetGen files by base name (1-based ids), .veg by file name. The
/// material the file may carry is replaced by the run's E, nu, rho; coordinates are
/// scaled to metres.
std::unique_ptr<TetMesh> load_mesh(const Options& o) {
  std::unique_ptr<TetMesh> mesh;
  try {
    if (ends_with(o.mesh, ".veg")) {
      mesh = std::make_unique<TetMesh>(o.mesh.c_str(), TetMesh::ASCII, 0);
    } else if (ends_with(o.mesh, ".node") || ends_with(o.mesh, ".ele")) {
      const std::string base = o.mesh.substr(0, o.mesh.rfind('.'));
      mesh = std::make_unique<TetMesh>(base.c_str(), 0, 0);
    } else {
      usage_error("the mesh must be a .node, .ele or .veg file: " + o.mesh);
    }
  } catch (...) {  // Vega's readers throw an int naming the failed check
    std::fprintf(stderr, "vega_beam: Vega could not read %s\n", o.mesh.c_str());
    std::exit(1);
  }
  mesh->setSingleMaterial(o.youngs_pa, o.poisson, o.density_kg_m3);
  double origin[3] = {0, 0, 0};
  double scale[9] = {o.scale_m, 0, 0, 0, o.scale_m, 0, 0, 0, o.scale_m};
  mesh->applyLinearTransformation(origin, scale);
  return mesh;
}

/// The x, y, z degrees of freedom of every node on the plane x = fixed_x, ascending (as
/// Vega's integrators require).
std::vector<int> fixed_dofs(const TetMesh& mesh, const Options& o) {
  std::vector<int> dofs;
  const double plane_m = o.fixed_x * o.scale_m;
  for (int v = 0; v < mesh.getNumVertices(); ++v) {
    if (std::abs(mesh.getVertex(v)[0] - plane_m) > 1e-9 * o.scale_m) continue;
    for (int c = 0; c < 3; ++c) dofs.push_back(3 * v + c);
  }
  return dofs;
}

int nearest_node(const TetMesh& mesh, const Options& o) {
  int best = 0;
  double best_d2 = INFINITY;
  for (int v = 0; v < mesh.getNumVertices(); ++v) {
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += std::pow(mesh.getVertex(v)[c] - o.tip[c] * o.scale_m, 2);
    if (d2 < best_d2) best_d2 = d2, best = v;
  }
  return best;
}

/// Vega's CGSolver on the same matrix, counting iterations: the solver multiplies its
/// search direction d once per iteration, and its iterate x for the initial and the
/// periodically recomputed residual, through the multiplicator hook it owns.
class CountingCGSolver : public CGSolver {
 public:
  explicit CountingCGSolver(SparseMatrix* a) : CGSolver(a) {
    multiplicator = &CountingCGSolver::multiply;
    multiplicatorData = this;
  }
  long iterations() const { return iterations_; }

 private:
  static void multiply(const void* data, const double* x, double* ax) {
    const auto* self = static_cast<const CountingCGSolver*>(data);
    if (x == self->d) ++self->iterations_;
    self->A->MultiplyVector(x, ax);
  }
  mutable long iterations_ = 0;
};

/// ImplicitBackwardEulerSparse whose Jacobi-PCG counts its iterations.
class CountingBackwardEuler : public ImplicitBackwardEulerSparse {
 public:
  CountingBackwardEuler(int dofs, const Options& o, SparseMatrix* mass, ForceModel* model,
                        std::vector<int>& fixed)
      : ImplicitBackwardEulerSparse(dofs, o.dt_s, mass, model, static_cast<int>(fixed.size()), fixed.data(),
                                    o.mass_damping_1_s, o.stiffness_damping_s, /*maxIterations=*/1) {
    delete jacobiPreconditionedCGSolver;
    counting_ = new CountingCGSolver(systemMatrix);
    jacobiPreconditionedCGSolver = counting_;
  }
  ~CountingBackwardEuler() override { delete counting_; }  // Vega's destructor leaves its solver
  long cg_iterations() const { return counting_->iterations(); }

 private:
  CountingCGSolver* counting_ = nullptr;
};

/// Gravity as Vega's examples apply it: f_ext = M g, with g along z at every node.
std::vector<double> gravity_forces(const SparseMatrix& mass, int dofs, const Options& o) {
  std::vector<double> g(dofs, 0.0), f(dofs, 0.0);
  for (int i = 2; i < dofs; i += 3) g[i] = o.gravity_z_m_s2;
  mass.MultiplyVector(g.data(), f.data());
  return f;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct StepFigures {
  std::vector<double> step_s, assembly_s, solve_s, cg_iterations;
  double window_s = 0;
};

StepFigures run_steps(CountingBackwardEuler& integrator, int steps) {
  StepFigures out;
  const Clock::time_point window = Clock::now();
  for (int k = 0; k < steps; ++k) {
    const long cg_before = integrator.cg_iterations();
    const Clock::time_point start = Clock::now();
    if (integrator.DoTimestep() != 0) {
      std::fprintf(stderr, "vega_beam: Vega's step %d failed\n", k + 1);
      std::exit(1);
    }
    out.step_s.push_back(seconds_since(start));
    out.assembly_s.push_back(integrator.GetForceAssemblyTime());
    out.solve_s.push_back(integrator.GetSystemSolveTime());
    out.cg_iterations.push_back(static_cast<double>(integrator.cg_iterations() - cg_before));
  }
  out.window_s = seconds_since(window);
  return out;
}

double mean(const std::vector<double>& v) {
  double sum = 0;
  for (double x : v) sum += x;
  return v.empty() ? 0 : sum / static_cast<double>(v.size());
}

void print_figures(const TetMesh& mesh, size_t fixed_dofs_count, double setup_s, const StepFigures& f,
                   int tip, const double* q) {
  std::printf("nodes %d\ntets %d\nfixed_nodes %zu\n", mesh.getNumVertices(), mesh.getNumElements(),
              fixed_dofs_count / 3);
  std::printf("setup_s %.6f\nsteps %zu\n", setup_s, f.step_s.size());
  std::printf("median_step_s %.6e\nsteps_per_s %.4f\n", median(f.step_s),
              static_cast<double>(f.step_s.size()) / f.window_s);
  std::printf("mean_assembly_s %.6e\nmean_solve_s %.6e\n", mean(f.assembly_s), mean(f.solve_s));
  std::printf("cg_iterations_mean %.2f\ncg_iterations_max %.0f\n", mean(f.cg_iterations),
              *std::max_element(f.cg_iterations.begin(), f.cg_iterations.end()));
  const Vec3d& rest = mesh.getVertex(tip);
  std::printf("tip_node %d\ntip_rest_m %.9g %.9g %.9g\n", tip + 1, rest[0], rest[1], rest[2]);
  std::printf("tip_displacement_m %.9g %.9g %.9g\n", q[3 * tip], q[3 * tip + 1], q[3 * tip + 2]);
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse_options(argc, argv);
  const Clock::time_point setup = Clock::now();
  std::unique_ptr<TetMesh> mesh = load_mesh(o);
  std::vector<int> fixed = fixed_dofs(*mesh, o);
  if (fixed.empty()) usage_error("no node lies on the plane x = --fixed-x");
  const int dofs = 3 * mesh->getNumVertices();

  SparseMatrix* mass_raw = nullptr;
  GenerateMassMatrix::computeMassMatrix(mesh.get(), &mass_raw, true);  // consistent, as Vega's examples
  std::unique_ptr<SparseMatrix> mass(mass_raw);
  CorotationalLinearFEM fem(mesh.get());
  CorotationalLinearFEMForceModel model(&fem, o.warp);
  CountingBackwardEuler integrator(dofs, o, mass.get(), &model, fixed);
  std::vector<double> gravity = gravity_forces(*mass, dofs, o);
  integrator.SetExternalForces(gravity.data());
  const double setup_s = seconds_since(setup);

  const StepFigures figures = run_steps(integrator, o.steps);
  print_figures(*mesh, fixed.size(), setup_s, figures, nearest_node(*mesh, o), integrator.Getq());
  return 0;
}
