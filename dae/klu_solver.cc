#include "dae/klu_solver.h"

#include <klu.h>

#include <cassert>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace mbdae::dae {

namespace {
// Refactorisation reuses the pivot order of the last full factorisation. When the
// values have drifted far enough that those pivots are poor, the reciprocal pivot
// growth (klu_rgrowth, 1 is ideal, small is bad) or the condition estimate drops
// sharply; below these limits we factor again with fresh pivoting.
constexpr double kMinPivotGrowth = 1e-8;
constexpr double kRcondDropFactor = 1e-6;  // relative to the last full factorisation
}  // namespace

struct KluSolver::Impl {
  int n = 0;
  // Copies of the pattern: klu_factor/klu_refactor take Ap/Ai on every call.
  std::vector<int> col_start, row_index;
  klu_common common;
  klu_symbolic* symbolic = nullptr;
  klu_numeric* numeric = nullptr;
  double rcond = 0;
  double rcond_full = 0;  // rcond after the last full factorisation
  long factorizations = 0;
  int growth_check_interval = 1;
  long refactors_since_check = 0;

  ~Impl() {
    if (numeric) klu_free_numeric(&numeric, &common);
    if (symbolic) klu_free_symbolic(&symbolic, &common);
  }

  void FreeNumeric() {
    if (numeric) klu_free_numeric(&numeric, &common);
    numeric = nullptr;
  }

  bool Full(double* values, std::string* error) {
    FreeNumeric();
    numeric = klu_factor(col_start.data(), row_index.data(), values, symbolic, &common);
    ++factorizations;
    if (!numeric || common.status != KLU_OK) {
      if (error) {
        *error = common.status == KLU_SINGULAR
                     ? "KLU: matrix is singular (zero pivot in column " +
                           std::to_string(common.singular_col) + ")"
                     : "KLU: factorisation failed with status " + std::to_string(common.status);
      }
      FreeNumeric();
      rcond = 0;
      return false;
    }
    klu_rcond(symbolic, numeric, &common);
    rcond = common.rcond;
    rcond_full = rcond;
    if (!(rcond > 0) || !std::isfinite(rcond)) {
      if (error) *error = "KLU: matrix is numerically singular (rcond = " + std::to_string(rcond) + ")";
      FreeNumeric();
      return false;
    }
    return true;
  }
};

KluSolver::KluSolver(const CscPattern& pattern) : KluSolver(pattern, 1) {}

KluSolver::KluSolver(const CscPattern& pattern, int growth_check_interval)
    : impl_(std::make_unique<Impl>()) {
  if (growth_check_interval < 1)
    throw std::invalid_argument("KluSolver: growth_check_interval must be >= 1, got " +
                                std::to_string(growth_check_interval));
  impl_->growth_check_interval = growth_check_interval;
  std::string err;
  if (!pattern.IsValid(&err)) throw std::invalid_argument("KluSolver: invalid pattern: " + err);
  if (pattern.rows != pattern.cols)
    throw std::invalid_argument("KluSolver: matrix is " + std::to_string(pattern.rows) + " x " +
                                std::to_string(pattern.cols) + ", not square");
  Impl& d = *impl_;
  d.n = pattern.rows;
  d.col_start = pattern.col_start;
  d.row_index = pattern.row_index;
  klu_defaults(&d.common);
  // Stop at the first zero pivot: a singular Newton matrix is a failure to report.
  d.common.halt_if_singular = 1;
  d.symbolic = klu_analyze(d.n, d.col_start.data(), d.row_index.data(), &d.common);
  if (!d.symbolic)
    throw std::runtime_error("KluSolver: klu_analyze failed with status " +
                             std::to_string(d.common.status));
}

KluSolver::~KluSolver() = default;

bool KluSolver::Factor(const double* values, std::string* error) {
  Impl& d = *impl_;
  // KLU takes non-const pointers but does not modify the values.
  double* vals = const_cast<double*>(values);
  if (d.n == 0) {
    d.rcond = 1;
    ++d.factorizations;
    return true;
  }
  if (!d.numeric) return d.Full(vals, error);
  const int ok = klu_refactor(d.col_start.data(), d.row_index.data(), vals, d.symbolic, d.numeric,
                              &d.common);
  ++d.factorizations;
  if (ok && d.common.status == KLU_OK) {
    double growth = 1;
    if (++d.refactors_since_check >= d.growth_check_interval) {
      d.refactors_since_check = 0;
      klu_rgrowth(d.col_start.data(), d.row_index.data(), vals, d.symbolic, d.numeric, &d.common);
      growth = d.common.rgrowth;
    }
    klu_rcond(d.symbolic, d.numeric, &d.common);
    d.rcond = d.common.rcond;
    if (growth > kMinPivotGrowth && d.rcond > kRcondDropFactor * d.rcond_full &&
        std::isfinite(d.rcond))
      return true;
  }
  // Pivots unusable for these values: factor from scratch with new pivoting.
  return d.Full(vals, error);
}

void KluSolver::Solve(double* b) const {
  Impl& d = *impl_;
  if (d.n == 0) return;
  assert(d.numeric && "KluSolver::Solve before a successful Factor");
  klu_solve(d.symbolic, d.numeric, d.n, 1, b, &d.common);
}

void KluSolver::SolveTransposed(double* b) const {
  Impl& d = *impl_;
  if (d.n == 0) return;
  assert(d.numeric && "KluSolver::SolveTransposed before a successful Factor");
  klu_tsolve(d.symbolic, d.numeric, d.n, 1, b, &d.common);
}

double KluSolver::rcond() const { return impl_->rcond; }

long KluSolver::factorizations() const { return impl_->factorizations; }

}  // namespace mbdae::dae
