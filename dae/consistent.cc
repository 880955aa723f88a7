// Consistent initial values by minimum-norm Gauss-Newton steps, and redundant
// constraints by a rank-revealing sparse QR of C_q^T.
//
// The QR is SuiteSparseQR (T. A. Davis, ACM TOMS 38 (2011) 8) with the fixed column
// ordering and Heath's rank detection (M. T. Heath, SIAM J. Sci. Stat. Comput. 3
// (1982) 223-237): the columns of C_q^T, i.e. the constraint equations, are eliminated
// in the order given; an equation whose remaining norm (its would-be |R_ii|) is below
// the threshold is dependent on the equations before it and is set aside. So of a group
// of dependent equations the LAST ones are flagged redundant and the first listed
// joints keep their multipliers.
//
// With C_q^T E = Q R, R = [R11 R12] (R11 r x r upper triangular, r the rank, E the
// permutation that puts the independent equations first), the minimum-norm solution of
// C_q x = b is x = Q1 z with R11^T z = (E^T b)(1:r): it lies in the row space of C_q
// and satisfies the independent equations, hence all of them when b is consistent.
#include "dae/consistent.h"

#include <SuiteSparseQR.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "dae/format.h"
#include "dae/klu_solver.h"
#include "dae/tree_kkt.h"

namespace mbdae::dae {

bool ConsistencyOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = "ConsistencyOptions: " + why;
    return false;
  };
  if (!(position_tolerance > 0) || !std::isfinite(position_tolerance))
    return fail("position_tolerance must be positive and finite");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!(rank_tolerance > 0 && rank_tolerance < 1)) return fail("rank_tolerance must be in (0, 1)");
  return true;
}

namespace {

using Long = SuiteSparse_long;

// RAII for the CHOLMOD workspace and the objects SPQR returns.
class CholmodCommon {
 public:
  CholmodCommon() { cholmod_l_start(&cc_); }
  ~CholmodCommon() { cholmod_l_finish(&cc_); }
  CholmodCommon(const CholmodCommon&) = delete;
  CholmodCommon& operator=(const CholmodCommon&) = delete;
  cholmod_common* get() { return &cc_; }

 private:
  cholmod_common cc_;
};

// C_q^T E = Q R of one C_q, and minimum-norm solves with it.
class TransposedQr {
 public:
  // cq: values of C_q (nc x nq) in the pattern `p`; `rank_tolerance` relative to the
  // largest row norm of C_q.
  // `order` (a permutation of the equations, or empty for the natural order) is the
  // elimination order: of dependent equations the later ones in it are set aside.
  TransposedQr(const CscPattern& p, const double* cq, double rank_tolerance,
               const std::vector<int>& order)
      : nc_(p.rows), nq_(p.cols) {
    assert(nc_ > 0);
    if (!order.empty()) {
      std::vector<char> seen(nc_, 0);
      bool ok = static_cast<int>(order.size()) == nc_;
      for (int k = 0; ok && k < nc_; ++k) {
        ok = order[k] >= 0 && order[k] < nc_ && !seen[order[k]];
        if (ok) seen[order[k]] = 1;
      }
      if (!ok)
        throw std::invalid_argument("consistent: elimination_order is not a permutation of the " +
                                    std::to_string(nc_) + " constraint equations");
    }
    std::vector<int> pos(nc_), eq(nc_);
    for (int j = 0; j < nc_; ++j) eq[j] = order.empty() ? j : order[j];
    for (int j = 0; j < nc_; ++j) pos[eq[j]] = j;
    cholmod_common* cc = common_.get();
    // C_q^T is nq x nc; its CSC arrays are the CSR arrays of C_q.
    cholmod_sparse* At = cholmod_l_allocate_sparse(nq_, nc_, std::max(1, p.nnz()), /*sorted=*/1,
                                                   /*packed=*/1, /*stype=*/0, CHOLMOD_REAL, cc);
    if (!At) throw std::runtime_error("consistent: cholmod_l_allocate_sparse failed");
    auto* Ap = static_cast<Long*>(At->p);
    auto* Ai = static_cast<Long*>(At->i);
    auto* Ax = static_cast<double*>(At->x);
    std::fill(Ap, Ap + nc_ + 1, 0);
    for (int k = 0; k < p.nnz(); ++k) ++Ap[pos[p.row_index[k]] + 1];
    for (int r = 0; r < nc_; ++r) Ap[r + 1] += Ap[r];
    std::vector<Long> next(Ap, Ap + nc_);
    std::vector<double> row_norm2(nc_, 0.0);
    for (int c = 0; c < nq_; ++c) {
      for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) {
        const int r = p.row_index[k];
        const Long dst = next[pos[r]]++;
        Ai[dst] = c;  // columns visited in increasing order: rows of C_q^T sorted
        Ax[dst] = cq[k];
        row_norm2[r] += cq[k] * cq[k];
      }
    }
    double max_norm = 0;
    for (double s : row_norm2) max_norm = std::max(max_norm, std::sqrt(s));
    // An all-zero C_q: every equation is dependent (rank 0).
    const double tol = max_norm > 0 ? rank_tolerance * max_norm : 1.0;

    Long* E = nullptr;
    rank_ = SuiteSparseQR<double>(SPQR_ORDERING_FIXED, tol, /*econ=*/0, At, &R_, &E, &H_,
                                  &HPinv_, &HTau_, cc);
    cholmod_l_free_sparse(&At, cc);
    if (rank_ < 0 || !R_) {
      Free();
      throw std::runtime_error("consistent: SuiteSparseQR failed (status " +
                               std::to_string(cc->status) + ")");
    }
    // R is "squeezed" (rows = the r independent columns in elimination order): column j
    // of R is independent when its last entry lies on the next pivot row, dependent
    // when all its entries lie above it.
    const auto* Rp = static_cast<const Long*>(R_->p);
    const auto* Ri = static_cast<const Long*>(R_->i);
    Long pivot = 0;
    for (int j = 0; j < nc_; ++j) {
      const int equation = eq[E ? static_cast<int>(E[j]) : j];
      const bool live = Rp[j + 1] > Rp[j] && Ri[Rp[j + 1] - 1] == pivot && pivot < rank_;
      if (live) {
        live_.push_back({j, equation});
        ++pivot;
      } else {
        dependent_.push_back(equation);
      }
    }
    if (E) cholmod_l_free(nc_, sizeof(Long), E, cc);
    std::sort(dependent_.begin(), dependent_.end());
    if (pivot != rank_) {
      Free();
      throw std::runtime_error("consistent: unexpected structure of the SuiteSparseQR factor");
    }
  }
  ~TransposedQr() { Free(); }
  TransposedQr(const TransposedQr&) = delete;
  TransposedQr& operator=(const TransposedQr&) = delete;

  int rank() const { return static_cast<int>(rank_); }

  // The equations set aside as dependent, sorted.
  const std::vector<int>& Dependent() const { return dependent_; }

  // x (nq) = the minimum-norm solution of the independent equations of C_q x = b (nc).
  void MinNormSolve(const double* b, double* x) {
    cholmod_common* cc = common_.get();
    const int r = rank();
    // Forward substitution R11^T z = b(independent): the k-th independent column j of
    // R holds R(0..k, j), its diagonal on row k.
    std::vector<double> z(r, 0.0);
    const auto* Rp = static_cast<const Long*>(R_->p);
    const auto* Ri = static_cast<const Long*>(R_->i);
    const auto* Rx = static_cast<const double*>(R_->x);
    for (int k = 0; k < r; ++k) {
      const auto [j, equation] = live_[k];
      double s = b[equation];
      double diag = 0;
      for (Long e = Rp[j]; e < Rp[j + 1]; ++e) {
        const Long i = Ri[e];
        if (i < k) s -= Rx[e] * z[i];
        else if (i == k) diag = Rx[e];
      }
      assert(diag != 0);
      z[k] = s / diag;
    }
    cholmod_dense* Z = cholmod_l_zeros(nq_, 1, CHOLMOD_REAL, cc);
    if (!Z) throw std::runtime_error("consistent: cholmod_l_zeros failed");
    std::copy(z.begin(), z.end(), static_cast<double*>(Z->x));
    cholmod_dense* X = SuiteSparseQR_qmult<double>(SPQR_QX, H_, HTau_, HPinv_, Z, cc);
    cholmod_l_free_dense(&Z, cc);
    if (!X) throw std::runtime_error("consistent: SuiteSparseQR_qmult failed");
    std::copy(static_cast<double*>(X->x), static_cast<double*>(X->x) + nq_, x);
    cholmod_l_free_dense(&X, cc);
  }

 private:
  void Free() {
    cholmod_common* cc = common_.get();
    if (R_) cholmod_l_free_sparse(&R_, cc);
    if (H_) cholmod_l_free_sparse(&H_, cc);
    if (HTau_) cholmod_l_free_dense(&HTau_, cc);
    if (HPinv_) cholmod_l_free(nq_, sizeof(Long), HPinv_, cc);
    HPinv_ = nullptr;
  }

  int nc_, nq_;
  CholmodCommon common_;
  Long rank_ = 0;
  cholmod_sparse* R_ = nullptr;
  cholmod_sparse* H_ = nullptr;
  Long* HPinv_ = nullptr;
  cholmod_dense* HTau_ = nullptr;
  std::vector<std::pair<int, int>> live_;  // (column of R, equation) of the k-th pivot
  std::vector<int> dependent_;
};

double MaxAbs(const std::vector<double>& x) {
  double m = 0;
  for (double v : x) m = std::max(m, std::abs(v));
  return m;
}

std::string Num(double x) { return FormatG(x, 3); }

// The system with only some of its constraint equations.
class KeptConstraints final : public MechanicalSystem {
 public:
  KeptConstraints(MechanicalSystem& base, std::vector<int> kept)
      : base_(base), kept_(std::move(kept)) {
    const int nc = base_.num_constraints();
    for (size_t k = 0; k < kept_.size(); ++k) {
      if (kept_[k] < 0 || kept_[k] >= nc)
        throw std::invalid_argument("KeepConstraints: equation " + std::to_string(kept_[k]) +
                                    " is out of range [0, " + std::to_string(nc) + ")");
      if (k > 0 && kept_[k] <= kept_[k - 1])
        throw std::invalid_argument("KeepConstraints: the kept equations must be sorted and "
                                    "distinct (" + std::to_string(kept_[k - 1]) + " before " +
                                    std::to_string(kept_[k]) + ")");
    }
    all_kept_ = static_cast<int>(kept_.size()) == nc;  // sorted and distinct: 0 .. nc - 1
    std::vector<int> new_row(nc, -1);
    for (size_t k = 0; k < kept_.size(); ++k) new_row[kept_[k]] = static_cast<int>(k);
    Filter(base_.pattern(Matrix::kConstraintDq), new_row, &cq_, &cq_map_);
    Filter(base_.pattern(Matrix::kConstraintVelDq), new_row, &veldq_, &veldq_map_);
    for (ParameterMatrix m : kRowsAreConstraints) {
      const int i = static_cast<int>(m);
      Filter(base_.parameter_pattern(m), new_row, &param_[i], &param_map_[i]);
      param_full_[i].assign(base_.parameter_pattern(m).nnz(), 0.0);
    }
    c_.assign(nc, 0.0);
    ct_.assign(nc, 0.0);
    gamma_.assign(nc, 0.0);
    ctt_.assign(nc, 0.0);
    w_.assign(nc, 0.0);
    cq_full_.assign(base_.pattern(Matrix::kConstraintDq).nnz(), 0.0);
    veldq_full_.assign(base_.pattern(Matrix::kConstraintVelDq).nnz(), 0.0);
  }

  int num_coordinates() const override { return base_.num_coordinates(); }
  int num_constraints() const override { return static_cast<int>(kept_.size()); }
  const CscPattern& pattern(Matrix m) const override {
    if (m == Matrix::kConstraintDq) return cq_;
    if (m == Matrix::kConstraintVelDq) return veldq_;
    return base_.pattern(m);
  }
  const std::vector<int>& quaternion_offsets() const override {
    return base_.quaternion_offsets();
  }
  const char* last_error() const override { return base_.last_error(); }
  // The base system's C_q^T w with the dropped equations' weights zero: their terms add
  // zeros, so the sums equal those over the kept rows to the last bit.
  bool provides_constraint_transpose_w() const override {
    return base_.provides_constraint_transpose_w();
  }
  int num_parameters() const override { return base_.num_parameters(); }
  const CscPattern& parameter_pattern(ParameterMatrix m) const override {
    for (ParameterMatrix r : kRowsAreConstraints)
      if (m == r) return param_[static_cast<int>(m)];
    return base_.parameter_pattern(m);
  }

  int Evaluate(const EvalInput& in, EvalOutput& out) override {
    // Nothing set aside (the usual case): the same rows in the same order, so the base
    // system writes the outputs itself, without the copies below.
    if (all_kept_) return base_.Evaluate(in, out);
    EvalInput bin = in;
    if (in.w) {
      // Weights of the dropped equations are zero.
      for (size_t k = 0; k < kept_.size(); ++k) w_[kept_[k]] = in.w[k];
      bin.w = w_.data();
    }
    EvalOutput bout = out;
    if (out.constraint) bout.constraint = c_.data();
    if (out.constraint_dt) bout.constraint_dt = ct_.data();
    if (out.acc_rhs) bout.acc_rhs = gamma_.data();
    if (out.constraint_dtt) bout.constraint_dtt = ctt_.data();
    if (out[Matrix::kConstraintDq]) bout[Matrix::kConstraintDq] = cq_full_.data();
    if (out[Matrix::kConstraintVelDq]) bout[Matrix::kConstraintVelDq] = veldq_full_.data();
    for (ParameterMatrix m : kRowsAreConstraints)
      if (out[m]) bout[m] = param_full_[static_cast<int>(m)].data();
    const int code = base_.Evaluate(bin, bout);
    if (code != 0) return code;
    for (size_t k = 0; k < kept_.size(); ++k) {
      const int r = kept_[k];
      if (out.constraint) out.constraint[k] = c_[r];
      if (out.constraint_dt) out.constraint_dt[k] = ct_[r];
      if (out.acc_rhs) out.acc_rhs[k] = gamma_[r];
      if (out.constraint_dtt) out.constraint_dtt[k] = ctt_[r];
    }
    if (double* dst = out[Matrix::kConstraintDq])
      for (size_t k = 0; k < cq_map_.size(); ++k) dst[k] = cq_full_[cq_map_[k]];
    if (double* dst = out[Matrix::kConstraintVelDq])
      for (size_t k = 0; k < veldq_map_.size(); ++k) dst[k] = veldq_full_[veldq_map_[k]];
    for (ParameterMatrix m : kRowsAreConstraints) {
      const int i = static_cast<int>(m);
      if (double* dst = out[m])
        for (size_t k = 0; k < param_map_[i].size(); ++k) dst[k] = param_full_[i][param_map_[i][k]];
    }
    return 0;
  }

 private:
  // Rows of `p` renumbered by new_row (dropped when -1); map[k]: the entry of p that
  // entry k of the result comes from.
  static void Filter(const CscPattern& p, const std::vector<int>& new_row, CscPattern* out,
                     std::vector<int>* map) {
    out->rows = 0;
    for (int r : new_row) out->rows += r >= 0;
    out->cols = p.cols;
    out->col_start.assign(p.cols + 1, 0);
    out->row_index.clear();
    map->clear();
    for (int c = 0; c < p.cols; ++c) {
      for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) {
        const int r = new_row[p.row_index[k]];
        if (r < 0) continue;
        out->row_index.push_back(r);  // increasing since kept is sorted
        map->push_back(k);
      }
      out->col_start[c + 1] = static_cast<int>(out->row_index.size());
    }
  }

  // The parameter matrices whose rows are constraint equations.
  static constexpr ParameterMatrix kRowsAreConstraints[3] = {
      ParameterMatrix::kConstraintDp, ParameterMatrix::kConstraintVelDp,
      ParameterMatrix::kAccRhsDp};

  MechanicalSystem& base_;
  std::vector<int> kept_;
  bool all_kept_ = false;  // kept_ is every equation
  CscPattern param_[kNumParameterMatrices];
  std::vector<int> param_map_[kNumParameterMatrices];
  std::vector<double> param_full_[kNumParameterMatrices];
  CscPattern cq_, veldq_;
  std::vector<int> cq_map_, veldq_map_;
  std::vector<double> c_, ct_, gamma_, ctt_, w_, cq_full_, veldq_full_;
};

}  // namespace

std::vector<int> FindRedundantConstraints(MechanicalSystem& system, double t, const double* q,
                                          double rank_tolerance,
                                          const std::vector<int>& elimination_order) {
  const int nc = system.num_constraints();
  if (nc == 0) return {};
  if (!(rank_tolerance > 0 && rank_tolerance < 1))
    throw std::invalid_argument("FindRedundantConstraints: rank_tolerance must be in (0, 1), got " +
                                Num(rank_tolerance));
  const CscPattern& p = system.pattern(Matrix::kConstraintDq);
  std::vector<double> cq(p.nnz());
  EvalInput in;
  in.t = t;
  in.q = q;
  EvalOutput out;
  out[Matrix::kConstraintDq] = cq.data();
  const int code = system.Evaluate(in, out);
  if (code != 0)
    throw std::runtime_error(std::string("FindRedundantConstraints: the system cannot evaluate "
                                         "C_q: ") + system.last_error());
  TransposedQr qr(p, cq.data(), rank_tolerance, elimination_order);
  return qr.Dependent();
}

std::unique_ptr<MechanicalSystem> KeepConstraints(MechanicalSystem& base, std::vector<int> kept) {
  return std::make_unique<KeptConstraints>(base, std::move(kept));
}

ConsistencyReport MakeConsistent(MechanicalSystem& system, State& x,
                                 const ConsistencyOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  const int nq = system.num_coordinates(), nc = system.num_constraints();
  if (static_cast<int>(x.q.size()) != nq || static_cast<int>(x.v.size()) != nq)
    throw std::invalid_argument("MakeConsistent: the state has " + std::to_string(x.q.size()) +
                                " positions and " + std::to_string(x.v.size()) +
                                " velocities, the system has " + std::to_string(nq) +
                                " coordinates");
  x.a.assign(nq, 0.0);
  x.lambda.assign(nc, 0.0);

  ConsistencyReport report;
  const std::vector<double> q0 = x.q, v0 = x.v;
  const CscPattern& pcq = system.pattern(Matrix::kConstraintDq);
  std::vector<double> c(nc), ct(nc), cq(pcq.nnz()), dq(nq), rhs(nc);

  auto evaluate = [&](bool with_jacobian) {
    EvalInput in;
    in.t = x.t;
    in.q = x.q.data();
    in.v = x.v.data();
    EvalOutput out;
    out.constraint = c.data();
    out.constraint_dt = ct.data();
    if (with_jacobian) out[Matrix::kConstraintDq] = cq.data();
    const int code = system.Evaluate(in, out);
    if (code != 0) {
      report.ok = false;
      report.message = std::string("MakeConsistent: the system cannot be evaluated at t = ") +
                       Num(x.t) + ": " + system.last_error();
    }
    return code == 0;
  };
  auto velocity_residual = [&]() {
    std::copy(ct.begin(), ct.end(), rhs.begin());
    MultiplyAdd(pcq, cq.data(), 1.0, x.v.data(), rhs.data());
    return MaxAbs(rhs);
  };
  auto list_violated = [&](const std::vector<double>& res, double tol) {
    report.violated.clear();
    for (int r = 0; r < nc; ++r)
      if (!(std::abs(res[r]) <= tol)) report.violated.push_back(r);
  };
  auto changes = [&]() {
    for (int i = 0; i < nq; ++i) {
      report.max_position_change = std::max(report.max_position_change, std::abs(x.q[i] - q0[i]));
      report.max_velocity_change = std::max(report.max_velocity_change, std::abs(x.v[i] - v0[i]));
    }
  };

  std::vector<int> kept;
  if (nc > 0) {
    // 1. Positions: Gauss-Newton with minimum-norm steps dq = -C_q^+ C.
    if (!evaluate(true)) return report;
    report.initial_position_violation = MaxAbs(c);
    report.initial_velocity_violation = velocity_residual();
    double violation = report.initial_position_violation;
    bool converged = violation <= options.position_tolerance;
    while (!converged && report.iterations < options.max_iterations) {
      TransposedQr qr(pcq, cq.data(), options.rank_tolerance, options.elimination_order);
      for (int r = 0; r < nc; ++r) rhs[r] = -c[r];
      qr.MinNormSolve(rhs.data(), dq.data());
      double step = 0, size = 0;
      for (int i = 0; i < nq; ++i) {
        x.q[i] += dq[i];
        step = std::max(step, std::abs(dq[i]));
        size = std::max(size, std::abs(x.q[i]));
      }
      ++report.iterations;
      if (!evaluate(true)) return report;
      violation = MaxAbs(c);
      converged = violation <= options.position_tolerance;
      // Stalled: the independent equations hold, the others cannot be met.
      if (!converged && step <= 4 * std::numeric_limits<double>::epsilon() * std::max(1.0, size))
        break;
    }
    if (!converged) {
      list_violated(c, options.position_tolerance);
      changes();
      std::ostringstream os;
      os << "MakeConsistent: the positions do not satisfy the constraints after "
         << report.iterations << " Gauss-Newton iterations: max |C| = " << Num(violation)
         << " > " << Num(options.position_tolerance) << " in equation(s)";
      for (int r : report.violated) os << ' ' << r;
      report.message = os.str();
      return report;
    }

    // 2. Redundancy at the projected positions, and the velocities: v -= C_q^+ (C_q v + C_t).
    TransposedQr qr(pcq, cq.data(), options.rank_tolerance, options.elimination_order);
    report.redundant = qr.Dependent();
    double cq_max = 0;
    for (double e : cq) cq_max = std::max(cq_max, std::abs(e));
    for (int pass = 0; pass < 3; ++pass) {
      const double vel = velocity_residual();
      const double tol_v =
          options.position_tolerance * std::max(1.0, cq_max * MaxAbs(x.v) + MaxAbs(ct));
      if (vel <= tol_v) break;
      for (double& e : rhs) e = -e;
      qr.MinNormSolve(rhs.data(), dq.data());
      for (int i = 0; i < nq; ++i) x.v[i] += dq[i];
    }
    const double tol_v =
        options.position_tolerance * std::max(1.0, cq_max * MaxAbs(x.v) + MaxAbs(ct));
    const double vel = velocity_residual();
    changes();
    if (!(vel <= tol_v)) {
      list_violated(rhs, tol_v);
      std::ostringstream os;
      os << "MakeConsistent: the velocities cannot satisfy C_q v + C_t = 0: max residual "
         << Num(vel) << " > " << Num(tol_v) << " in equation(s)";
      for (int r : report.violated) os << ' ' << r;
      report.message = os.str();
      return report;
    }
    for (int r = 0, k = 0; r < nc; ++r) {
      if (k < static_cast<int>(report.redundant.size()) && report.redundant[k] == r) ++k;
      else kept.push_back(r);
    }
  }

  // 3. Accelerations and multipliers of the independent equations:
  //    [M C_q^T; C_q 0] [a; lambda] = [Q; gamma].
  auto reduced = KeepConstraints(system, kept);
  const int nk = static_cast<int>(kept.size());
  std::vector<double> lambda(nk, 0.0);
  AccelerationSolver acceleration(*reduced);
  if (const int rc = acceleration.Solve(x.t, x.q.data(), x.v.data(), x.a.data(), lambda.data()); rc != 0) {
    x.a.assign(nq, 0.0);
    report.message = rc == 1 ? "MakeConsistent: the acceleration-level system [M C_q^T; C_q 0] is "
                               "singular at the consistent positions: " + acceleration.last_error()
                             : std::string("MakeConsistent: the system cannot be evaluated at t = ") +
                                   Num(x.t) + ": " + system.last_error();
    return report;
  }
  for (int k = 0; k < nk; ++k) x.lambda[kept[k]] = lambda[k];
  report.ok = true;
  return report;
}

}  // namespace mbdae::dae

namespace mbdae::dae {

struct AccelerationSolver::Impl {
  MechanicalSystem& system;
  int nq = 0, nc = 0;
  BlockAssembler kkt;
  int b_m = 0, b_ct = 0, b_c = 0;
  std::vector<double> mass, cq, values, sol, gamma;
  std::unique_ptr<KluSolver> klu;
  std::unique_ptr<TreeKktSolver> tree;
  std::string error, tree_refusal = "not requested";
  bool used_tree = false;
  TreePivotRule tree_rule;
  long klu_fallbacks = 0;

  Impl(MechanicalSystem& s, int growth_check_interval, bool tree_elimination)
      : system(s), nq(s.num_coordinates()), nc(s.num_constraints()) {
    if (tree_elimination) {
      tree = TreeKktSolver::Analyze(system.pattern(Matrix::kMass),
                                    system.pattern(Matrix::kConstraintDq), kMaxTreeNode,
                                    &tree_refusal);
      if (tree) tree_refusal.clear();
    }
    const CscPattern& pm = system.pattern(Matrix::kMass);
    const CscPattern& pc = system.pattern(Matrix::kConstraintDq);
    b_m = kkt.AddBlock(pm, 0, 0);
    b_ct = kkt.AddBlock(pc, 0, nq, /*transpose=*/true);
    b_c = kkt.AddBlock(pc, nq, 0);
    kkt.Finalize(nq + nc, nq + nc);
    mass.assign(pm.nnz(), 0.0);
    cq.assign(pc.nnz(), 0.0);
    values.assign(kkt.pattern().nnz(), 0.0);
    sol.assign(nq + nc, 0.0);
    gamma.assign(nc, 0.0);
    klu = std::make_unique<KluSolver>(kkt.pattern(), growth_check_interval);
  }
};

AccelerationSolver::AccelerationSolver(MechanicalSystem& system, int growth_check_interval,
                                       bool tree_elimination)
    : impl_(std::make_unique<Impl>(system, growth_check_interval, tree_elimination)) {}
AccelerationSolver::~AccelerationSolver() = default;
const std::string& AccelerationSolver::last_error() const { return impl_->error; }
bool AccelerationSolver::used_tree() const { return impl_->used_tree; }
const std::string& AccelerationSolver::tree_refusal() const { return impl_->tree_refusal; }
long AccelerationSolver::klu_fallbacks() const { return impl_->klu_fallbacks; }

void AccelerationSolver::MultiplyConstraintJacobian(const double* x, double* y) const {
  std::fill(y, y + impl_->nc, 0.0);
  MultiplyAdd(impl_->system.pattern(Matrix::kConstraintDq), impl_->cq.data(), 1.0, x, y);
}

void AccelerationSolver::SolveAgain(double* rhs) const {
  if (impl_->used_tree)
    impl_->tree->Solve(rhs);
  else
    impl_->klu->Solve(rhs);
}

int AccelerationSolver::Solve(double t, const double* q, const double* v, double* a,
                              double* lambda) {
  Impl& m = *impl_;
  std::fill(m.sol.begin(), m.sol.end(), 0.0);
  EvalInput in;
  in.t = t;
  in.q = q;
  in.v = v;
  EvalOutput out;
  out.force = m.sol.data();
  out.acc_rhs = m.gamma.data();
  out[Matrix::kMass] = m.mass.data();
  out[Matrix::kConstraintDq] = m.cq.data();
  if (const int rc = m.system.Evaluate(in, out); rc != 0) {
    m.error = std::string("the system cannot be evaluated at t = ") + Num(t) + ": " +
              m.system.last_error();
    return rc;
  }
  std::copy(m.gamma.begin(), m.gamma.end(), m.sol.begin() + m.nq);
  if (m.tree) {
    // The rule of the class comment: the tree's pivots, else KLU.
    if (m.tree->Factor(m.mass.data(), m.cq.data())) {
      if (m.tree_rule.Accept(m.tree->rcond())) {
        m.tree->Solve(m.sol.data());
        m.used_tree = true;
        std::copy(m.sol.begin(), m.sol.begin() + m.nq, a);
        std::copy(m.sol.begin() + m.nq, m.sol.end(), lambda);
        return 0;
      }
    }
    ++m.klu_fallbacks;
    if (!m.tree_rule.seen_usable()) {
      // The first factorisation failed: a loop closed through the ground (bodies tied to
      // the ground at two places are not a tree, though Analyze sees none) or a singular
      // start. KLU from here on.
      m.tree.reset();
      m.tree_refusal = "the tree elimination failed at the first state (a loop closed "
                       "through the ground, or a singular position)";
    }
  }
  m.used_tree = false;
  std::fill(m.values.begin(), m.values.end(), 0.0);
  m.kkt.Accumulate(m.b_m, m.mass.data(), 1.0, m.values.data());
  m.kkt.Accumulate(m.b_ct, m.cq.data(), 1.0, m.values.data());
  m.kkt.Accumulate(m.b_c, m.cq.data(), 1.0, m.values.data());
  if (!m.klu->Factor(m.values.data(), &m.error)) return 1;
  m.klu->Solve(m.sol.data());
  std::copy(m.sol.begin(), m.sol.begin() + m.nq, a);
  std::copy(m.sol.begin() + m.nq, m.sol.end(), lambda);
  return 0;
}

}  // namespace mbdae::dae
