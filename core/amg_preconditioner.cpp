#include "core/amg_preconditioner.hpp"

#ifdef FIBERFEM_HAVE_AMGCL
#include <amgcl/adapter/block_matrix.hpp>
#include <amgcl/adapter/crs_tuple.hpp>
#include <amgcl/amg.hpp>
#include <amgcl/backend/builtin.hpp>
#include <amgcl/coarsening/as_scalar.hpp>
#include <amgcl/coarsening/rigid_body_modes.hpp>
#include <amgcl/coarsening/smoothed_aggregation.hpp>
#include <amgcl/relaxation/damped_jacobi.hpp>
#include <amgcl/value_type/static_matrix.hpp>
#endif

#include <cstdlib>
#include <exception>
#include <sstream>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

namespace fiberfem::core {

#ifdef FIBERFEM_HAVE_AMGCL
namespace {
// Blocks of doubles for the input matrix, of floats for the hierarchy: a V-cycle reads
// half the bytes, and as a preconditioner of a lagged matrix its round-off (1e-7) is far
// below the lag's (as the Cholesky factor's single-precision copy). Measured on the
// 245,760-tet beam's step matrix (docs/performance.md): 6.1 ms per PCG iteration in float
// against 7.5 in double, the same iterations. Damped Jacobi smoothing: the cheapest
// iteration of those measured (Chebyshev of degree 3 saves one or two iterations at 1.7
// times the cost; SPAI-0 triples them). The coarsening aggregates on the scalar matrix
// with the node blocks' rigid-body modes as near-null space (as_scalar: AMGCL's way for
// block values with a given null space); every connection counts as strong (eps_strong
// 0): the anisotropic fiber stiffness should not split aggregates.
using DoubleBlock = amgcl::static_matrix<double, 3, 3>;
using FloatBlock = amgcl::static_matrix<float, 3, 3>;
using Vec3Block = amgcl::static_matrix<double, 3, 1>;
// apply() views an Eigen vector of 3n doubles as n of these.
static_assert(sizeof(Vec3Block) == 3 * sizeof(double) && alignof(Vec3Block) <= alignof(double) &&
                  std::is_standard_layout_v<Vec3Block>,
              "amgcl::static_matrix<double, 3, 1> is not three packed doubles");
using Backend = amgcl::backend::builtin<FloatBlock>;
using Amg = amgcl::amg<Backend, amgcl::coarsening::as_scalar<amgcl::coarsening::smoothed_aggregation>::type,
                       amgcl::relaxation::damped_jacobi>;
}  // namespace

struct AmgHierarchy::Impl {
  std::unique_ptr<Amg> amg;
  std::ptrdiff_t blocks = 0;
};

bool has_amg() { return true; }

bool AmgHierarchy::build(const Eigen::SparseMatrix<double, Eigen::RowMajor, int>& A, const Eigen::VectorXd& positions) {
  impl_->amg.reset();
  const std::ptrdiff_t n = A.rows();
  if (n == 0 || n % 3 != 0 || A.cols() != n || positions.size() != n || !A.isCompressed()) return false;
  try {
    std::vector<std::ptrdiff_t> ptr(A.outerIndexPtr(), A.outerIndexPtr() + n + 1), col(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
    std::vector<double> val(A.valuePtr(), A.valuePtr() + A.nonZeros());
    auto scalar = std::tie(n, ptr, col, val);
    Amg::params prm;
    prm.coarsening.aggr.eps_strong = 0;
    std::vector<double> coordinates(positions.data(), positions.data() + n);
    prm.coarsening.nullspace.cols = amgcl::coarsening::rigid_body_modes(3, coordinates, prm.coarsening.nullspace.B);
    impl_->amg = std::make_unique<Amg>(amgcl::adapter::block_matrix<DoubleBlock>(scalar), prm);
    impl_->blocks = n / 3;
    return true;
  } catch (const std::exception&) {
    impl_->amg.reset();
    return false;
  }
}

void AmgHierarchy::apply(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  x.resize(b.size());
  auto* bb = reinterpret_cast<const Vec3Block*>(b.data());
  auto* xb = reinterpret_cast<Vec3Block*>(x.data());
  auto rhs = amgcl::make_iterator_range(bb, bb + impl_->blocks);
  auto sol = amgcl::make_iterator_range(xb, xb + impl_->blocks);
  impl_->amg->apply(rhs, sol);
}

namespace {
// AMGCL keeps its levels private; its summary (operator<<) names both figures.
double summary_value(const Amg& amg, const std::string& label) {
  std::ostringstream os;
  os << amg;
  const std::string text = os.str();
  const size_t at = text.find(label);
  return at == std::string::npos ? 0.0 : std::strtod(text.c_str() + at + label.size(), nullptr);
}
}  // namespace

int AmgHierarchy::levels() const { return impl_->amg ? static_cast<int>(summary_value(*impl_->amg, "Number of levels:")) : 0; }

double AmgHierarchy::operator_complexity() const {
  return impl_->amg ? summary_value(*impl_->amg, "Operator complexity:") : 0.0;
}
#else
struct AmgHierarchy::Impl {};
bool has_amg() { return false; }
bool AmgHierarchy::build(const Eigen::SparseMatrix<double, Eigen::RowMajor, int>&, const Eigen::VectorXd&) { return false; }
void AmgHierarchy::apply(const Eigen::VectorXd& b, Eigen::VectorXd& x) const { x = b; }
int AmgHierarchy::levels() const { return 0; }
double AmgHierarchy::operator_complexity() const { return 0; }
#endif

AmgHierarchy::AmgHierarchy() : impl_(std::make_unique<Impl>()) {}
AmgHierarchy::~AmgHierarchy() = default;
AmgHierarchy::AmgHierarchy(AmgHierarchy&&) noexcept = default;
AmgHierarchy& AmgHierarchy::operator=(AmgHierarchy&&) noexcept = default;
bool AmgHierarchy::ok() const {
#ifdef FIBERFEM_HAVE_AMGCL
  return impl_ && impl_->amg != nullptr;  // (a moved-from hierarchy has no impl_)
#else
  return false;
#endif
}

}  // namespace fiberfem::core
