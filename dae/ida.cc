#include "dae/ida.h"

#include <idas/idas.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_linearsolver.h>
#include <sunlinsol/sunlinsol_klu.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "dae/block_tree_lu.h"
#include "dae/ida_internal.h"
#include "dae/sundials_owners.h"

namespace mbdae::dae {

bool IdaOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = "IdaOptions: " + why;
    return false;
  };
  if (!(rtol > 0) || !std::isfinite(rtol)) return fail("rtol must be positive and finite");
  if (!(atol > 0) || !std::isfinite(atol)) return fail("atol must be positive and finite");
  if (!(max_step >= 0) || !std::isfinite(max_step)) return fail("max_step must be >= 0 (0: no limit)");
  if (!(min_step >= 0) || !std::isfinite(min_step)) return fail("min_step must be >= 0 (0: no limit)");
  if (max_step > 0 && min_step > max_step) return fail("min_step must not exceed max_step");
  if (!(initial_step >= 0) || !std::isfinite(initial_step))
    return fail("initial_step must be >= 0 (0: IDA chooses)");
  if (!(algebraic_atol >= 0) || !std::isfinite(algebraic_atol))
    return fail("algebraic_atol must be >= 0 (0: left out of the Newton test)");
  if (max_order < 1 || max_order > 5) return fail("max_order must be in [1, 5]");
  if (max_num_steps < 1) return fail("max_num_steps must be >= 1");
  if (max_steps < 0) return fail("max_steps must be >= 0 (0: no limit)");
  if (!(min_relative_step >= 0) || !(min_relative_step < 1e-3))
    return fail("min_relative_step must be in [0, 1e-3) (0: no limit)");
  if (!(roundoff_factor >= 0) || !std::isfinite(roundoff_factor))
    return fail("roundoff_factor must be >= 0 and finite (0: no rounding-level rules)");
  if (max_restarts < 0) return fail("max_restarts must be >= 0 (0: no restarts)");
  if (std::isnan(stop_time)) return fail("stop_time must not be NaN");
  return true;
}

namespace internal {

std::string IdaFlagName(int flag) {
  char* name = IDAGetReturnFlagName(flag);
  std::string out = name ? name : "IDA flag " + std::to_string(flag);
  std::free(name);
  return out;
}

GglResidual::GglResidual(MechanicalSystem& system)
    : system_(system), nq_(system.num_coordinates()), nc_(system.num_constraints()) {
  const int nq = nq_, nc = nc_;
  auto P = [&](Matrix m) -> const CscPattern& { return system_.pattern(m); };
  std::vector<std::pair<int, int>> diag_q, minus_i_v;
  for (int i = 0; i < nq; ++i) {
    diag_q.push_back({i, i});
    minus_i_v.push_back({i, nq + i});
  }
  const int lam = 2 * nq, mu = 2 * nq + nc;  // column offsets of lambda and mu
  // Row block 1: q' - v + C_q^T mu.
  b_cj_q_ = assembler_.AddEntries(diag_q);
  b_minus_i_v_ = assembler_.AddEntries(minus_i_v);
  b_tdq_mu_ = assembler_.AddBlock(P(Matrix::kConstraintTDq), 0, 0);
  b_cqt_mu_ = assembler_.AddBlock(P(Matrix::kConstraintDq), 0, mu, /*transpose=*/true);
  // Row block 2: M v' + C_q^T lambda - Q.
  b_madq_ = assembler_.AddBlock(P(Matrix::kMassTimesAccDq), nq, 0);
  b_tdq_lambda_ = assembler_.AddBlock(P(Matrix::kConstraintTDq), nq, 0);
  b_fdq_ = assembler_.AddBlock(P(Matrix::kForceDq), nq, 0);
  b_fdv_ = assembler_.AddBlock(P(Matrix::kForceDv), nq, nq);
  b_mass_ = assembler_.AddBlock(P(Matrix::kMass), nq, nq);
  b_cqt_lambda_ = assembler_.AddBlock(P(Matrix::kConstraintDq), nq, lam, /*transpose=*/true);
  // Row block 3: C(q, t).
  b_cq3_ = assembler_.AddBlock(P(Matrix::kConstraintDq), 2 * nq, 0);
  // Row block 4: C_q v + C_t.
  b_veldq_ = assembler_.AddBlock(P(Matrix::kConstraintVelDq), 2 * nq + nc, 0);
  b_cq4_ = assembler_.AddBlock(P(Matrix::kConstraintDq), 2 * nq + nc, nq);
  assembler_.Finalize(size(), size());

  ones_.assign(nq, 1.0);
  force_.assign(nq, 0.0);
  constraint_.assign(nc, 0.0);
  constraint_dt_.assign(nc, 0.0);
  for (int m = 0; m < kNumMatrices; ++m) val_[m].assign(P(static_cast<Matrix>(m)).nnz(), 0.0);
  tdq_mu_.assign(P(Matrix::kConstraintTDq).nnz(), 0.0);
  fixed_.assign(size(), 0.0);
  scaled_.assign(2 * nq, 0.0);
}

int GglResidual::Residual(double t, const double* y, const double* yp, double* F) {
  const int nq = nq_, nc = nc_;
  const double* q = y;
  const double* v = y + nq;
  const double* lambda = y + 2 * nq;
  const double* mu = y + 2 * nq + nc;
  const double* qp = yp;
  const double* vp = yp + nq;

  EvalInput in;
  in.t = t;
  in.q = q;
  in.v = v;
  EvalOutput out;
  out.force = force_.data();
  out.constraint = constraint_.data();
  out.constraint_dt = constraint_dt_.data();
  out[Matrix::kMass] = val_[static_cast<int>(Matrix::kMass)].data();
  out[Matrix::kConstraintDq] = val_[static_cast<int>(Matrix::kConstraintDq)].data();
  const int code = system_.Evaluate(in, out);
  if (code != 0) return code;

  const CscPattern& pm = system_.pattern(Matrix::kMass);
  const CscPattern& pc = system_.pattern(Matrix::kConstraintDq);
  const double* mass = val_[static_cast<int>(Matrix::kMass)].data();
  const double* cq = val_[static_cast<int>(Matrix::kConstraintDq)].data();

  double* F1 = F;
  double* F2 = F + nq;
  double* F3 = F + 2 * nq;
  double* F4 = F + 2 * nq + nc;
  for (int i = 0; i < nq; ++i) {
    F1[i] = qp[i] - v[i];
    F2[i] = -force_[i];
  }
  MultiplyTransposeAdd(pc, cq, 1.0, mu, F1);
  MultiplyAdd(pm, mass, 1.0, vp, F2);
  MultiplyTransposeAdd(pc, cq, 1.0, lambda, F2);
  for (int r = 0; r < nc; ++r) {
    F3[r] = constraint_[r];
    F4[r] = constraint_dt_[r];
  }
  MultiplyAdd(pc, cq, 1.0, v, F4);

  // Magnitudes of the terms of every row (their rounding error is about machine epsilon
  // times these): fixed_ the terms that do not scale with cj, scaled_ the magnitude
  // that one unit in the last place of q or v takes through q' and v'
  // (= cj (y - y_predicted) + ...); RoundingLevel combines them.
  std::fill(fixed_.begin(), fixed_.end(), 0.0);
  std::fill(scaled_.begin(), scaled_.end(), 0.0);
  double* f1 = fixed_.data();
  double* f2 = f1 + nq;
  double* f3 = f2 + nq;
  double* f4 = f3 + nc;
  double* s1 = scaled_.data();
  double* s2 = s1 + nq;
  for (int i = 0; i < nq; ++i) {
    f1[i] = std::max(std::abs(qp[i]), std::abs(v[i]));
    f2[i] = std::abs(force_[i]);
    s1[i] = std::abs(q[i]);
  }
  for (int r = 0; r < nc; ++r) f4[r] = std::abs(constraint_dt_[r]);
  for (int c = 0; c < nq; ++c) {
    for (int k = pm.col_start[c]; k < pm.col_start[c + 1]; ++k) {
      f2[pm.row_index[k]] += std::abs(mass[k] * vp[c]);
      s2[pm.row_index[k]] += std::abs(mass[k] * v[c]);
    }
    for (int k = pc.col_start[c]; k < pc.col_start[c + 1]; ++k) {
      const int r = pc.row_index[k];
      const double a = std::abs(cq[k]);
      f1[c] = std::max(f1[c], a * std::abs(mu[r]));
      f2[c] += a * std::abs(lambda[r]);
      f3[r] += a * std::abs(q[c]);
      f4[r] += a * std::abs(v[c]);
    }
  }
  return 0;
}

int GglResidual::Jacobian(double t, double cj, const double* y, const double* yp,
                          double* values) {
  const int nq = nq_, nc = nc_;
  const double* q = y;
  const double* v = y + nq;
  const double* lambda = y + 2 * nq;
  const double* mu = y + 2 * nq + nc;
  const double* vp = yp + nq;

  auto V = [&](Matrix m) { return val_[static_cast<int>(m)].data(); };
  EvalInput in;
  in.t = t;
  in.q = q;
  in.v = v;
  in.a = vp;
  in.w = mu;
  {
    // d(C_q^T mu)/dq needs its own evaluation (the weights differ from row block 2).
    EvalOutput out;
    out[Matrix::kConstraintTDq] = tdq_mu_.data();
    const int code = system_.Evaluate(in, out);
    if (code != 0) return code;
  }
  in.w = lambda;
  EvalOutput out;
  for (int m = 0; m < kNumMatrices; ++m) out.matrix[m] = val_[m].data();
  const int code = system_.Evaluate(in, out);
  if (code != 0) return code;

  std::fill(values, values + assembler_.pattern().nnz(), 0.0);
  assembler_.Accumulate(b_cj_q_, ones_.data(), cj, values);
  assembler_.Accumulate(b_minus_i_v_, ones_.data(), -1.0, values);
  assembler_.Accumulate(b_tdq_mu_, tdq_mu_.data(), 1.0, values);
  assembler_.Accumulate(b_cqt_mu_, V(Matrix::kConstraintDq), 1.0, values);
  assembler_.Accumulate(b_madq_, V(Matrix::kMassTimesAccDq), 1.0, values);
  assembler_.Accumulate(b_tdq_lambda_, V(Matrix::kConstraintTDq), 1.0, values);
  assembler_.Accumulate(b_fdq_, V(Matrix::kForceDq), -1.0, values);
  assembler_.Accumulate(b_fdv_, V(Matrix::kForceDv), -1.0, values);
  assembler_.Accumulate(b_mass_, V(Matrix::kMass), cj, values);
  assembler_.Accumulate(b_cqt_lambda_, V(Matrix::kConstraintDq), 1.0, values);
  assembler_.Accumulate(b_cq3_, V(Matrix::kConstraintDq), 1.0, values);
  assembler_.Accumulate(b_veldq_, V(Matrix::kConstraintVelDq), 1.0, values);
  assembler_.Accumulate(b_cq4_, V(Matrix::kConstraintDq), 1.0, values);
  return 0;
}

int GglResidual::ParameterJacobian(double t, const double* y, const double* yp, double* dense) {
  const int nq = nq_, nc = nc_, n = size();
  const int np = system_.num_parameters();
  std::fill(dense, dense + static_cast<size_t>(n) * np, 0.0);
  if (np == 0) return 0;
  auto P = [&](ParameterMatrix m) -> const CscPattern& { return system_.parameter_pattern(m); };
  if (ptdp_mu_.empty()) {
    for (int m = 0; m < kNumParameterMatrices; ++m)
      pval_[m].assign(P(static_cast<ParameterMatrix>(m)).nnz(), 0.0);
    ptdp_mu_.assign(P(ParameterMatrix::kConstraintTDp).nnz(), 0.0);
  }
  EvalInput in;
  in.t = t;
  in.q = y;
  in.v = y + nq;
  in.a = yp + nq;
  in.w = y + 2 * nq + nc;  // mu
  {
    EvalOutput out;
    out[ParameterMatrix::kConstraintTDp] = ptdp_mu_.data();
    const int code = system_.Evaluate(in, out);
    if (code != 0) return code;
  }
  in.w = y + 2 * nq;  // lambda
  EvalOutput out;
  for (int m = 0; m < kNumParameterMatrices; ++m) out.parameter_matrix[m] = pval_[m].data();
  const int code = system_.Evaluate(in, out);
  if (code != 0) return code;
  // Adds scale * block into the dense matrix at row offset r0.
  auto add = [&](const CscPattern& p, const double* val, double scale, int r0) {
    for (int c = 0; c < p.cols; ++c)
      for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k)
        dense[static_cast<size_t>(c) * n + r0 + p.row_index[k]] += scale * val[k];
  };
  auto V = [&](ParameterMatrix m) { return pval_[static_cast<int>(m)].data(); };
  add(P(ParameterMatrix::kConstraintTDp), ptdp_mu_.data(), 1.0, 0);
  add(P(ParameterMatrix::kMassTimesAccDp), V(ParameterMatrix::kMassTimesAccDp), 1.0, nq);
  add(P(ParameterMatrix::kConstraintTDp), V(ParameterMatrix::kConstraintTDp), 1.0, nq);
  add(P(ParameterMatrix::kForceDp), V(ParameterMatrix::kForceDp), -1.0, nq);
  add(P(ParameterMatrix::kConstraintDp), V(ParameterMatrix::kConstraintDp), 1.0, 2 * nq);
  add(P(ParameterMatrix::kConstraintVelDp), V(ParameterMatrix::kConstraintVelDp), 1.0, 2 * nq + nc);
  return 0;
}

void GglResidual::RoundingLevel(double cj, double* level) const {
  constexpr double eps = std::numeric_limits<double>::epsilon();
  const int n = size(), nd = 2 * nq_;
  for (int i = 0; i < n; ++i)
    level[i] = eps * (i < nd ? std::max(fixed_[i], std::abs(cj) * scaled_[i]) : fixed_[i]);
}

GglRounding::GglRounding(const GglResidual& ggl, double factor)
    : ggl_(ggl), factor_(factor), resolution_(ggl.size(), 0.0), work_(ggl.size(), 0.0),
      level_(ggl.size(), 0.0) {}

void GglRounding::Update(double cj, const std::function<void(double*)>& solve) {
  cj_ = cj;
  Clear();
  if (!(factor_ > 0)) return;
  const int n = ggl_.size();
  ggl_.RoundingLevel(cj, level_.data());
  unsigned state = 12345u;  // the same right sides at every Update
  for (int pass = 0; pass < 4; ++pass) {
    for (int i = 0; i < n; ++i) {
      state = state * 1664525u + 1013904223u;  // the LCG of Numerical Recipes
      // Random signs; in passes 2 and 3 also a random size in [0.5, 1): with sizes all
      // equal, the rows of a mode that involves few rows with equal rounding levels (one
      // loop of a chain of loops) can cancel exactly, and that mode's resolution would
      // come out at zero.
      const double size =
          pass < 2 ? 1.0 : 0.5 + 0.5 * static_cast<double>((state >> 8) & 0xffffu) / 65536.0;
      work_[i] = (state & 0x80000000u ? 1.0 : -1.0) * size * factor_ * level_[i];
    }
    solve(work_.data());
    for (int i = 0; i < n; ++i) resolution_[i] = std::max(resolution_[i], std::abs(work_[i]));
  }
}

bool GglRounding::ZeroIfRounding(double* b) {
  if (!(factor_ > 0)) return false;
  const int n = ggl_.size();
  ggl_.RoundingLevel(cj_, level_.data());
  for (int i = 0; i < n; ++i)
    if (!(std::abs(b[i]) <= factor_ * level_[i])) return false;
  std::fill(b, b + n, 0.0);
  ++stops_;
  return true;
}

}  // namespace internal

namespace {

using sundials::ContextPtr;
using sundials::IdaMemPtr;
using sundials::LinearSolverPtr;
using sundials::MatrixPtr;
using sundials::VectorPtr;

class IdaIntegrator final : public Integrator {
 public:
  IdaIntegrator(MechanicalSystem& system, const IdaOptions& options)
      : options_(options), ggl_(system) {
    std::string error;
    if (!options_.IsValid(&error)) throw std::invalid_argument(error);
    static_assert(sizeof(sunindextype) == 8 || sizeof(sunindextype) == 4, "sunindextype");
    const CscPattern& p = ggl_.jacobian_pattern();
    col_start_.assign(p.col_start.begin(), p.col_start.end());
    row_index_.assign(p.row_index.begin(), p.row_index.end());
    values_.assign(p.nnz(), 0.0);
    state_.Resize(ggl_.nq(), ggl_.nc());
    dense_ = options_.dense_output;
    if (dense_) out_.Resize(ggl_.nq(), ggl_.nc());
    rounding_ = std::make_unique<internal::GglRounding>(ggl_, options_.roundoff_factor);
    if (options_.linear_solver == LinearSolverKind::kTree) {
      MechanicalSystem& sys = ggl_.system();
      const int nq = ggl_.nq(), nc = ggl_.nc();
      tree_ = BlockTreeLu::ForMechanicalSystem(p, sys.pattern(Matrix::kMass),
                                               sys.pattern(Matrix::kConstraintDq), kMaxTreeNode,
                                               &tree_refusal_, {0, nq}, {2 * nq, 2 * nq + nc});
    }
  }

  void Initialize(const State& x0) override {
    const int nq = ggl_.nq(), nc = ggl_.nc(), n = ggl_.size();
    if (static_cast<int>(x0.q.size()) != nq || static_cast<int>(x0.v.size()) != nq ||
        static_cast<int>(x0.a.size()) != nq || static_cast<int>(x0.lambda.size()) != nc) {
      throw std::invalid_argument("IDA Initialize: the initial state has sizes (q " +
                                  std::to_string(x0.q.size()) + ", v " +
                                  std::to_string(x0.v.size()) + ", a " +
                                  std::to_string(x0.a.size()) + ", lambda " +
                                  std::to_string(x0.lambda.size()) + "), the system needs (" +
                                  std::to_string(nq) + ", " + std::to_string(nq) + ", " +
                                  std::to_string(nq) + ", " + std::to_string(nc) + ")");
    }
    // Tear down a previous run: counters start again from zero.
    mem_.reset();
    solver_.reset();
    matrix_.reset();
    id_.reset();
    atol_.reset();
    yq_.reset();
    dense_yq_.reset();
    dense_yp_.reset();
    dense_y_.reset();
    yp_.reset();
    y_.reset();
    context_.reset();
    summary_ = Summary{};
    counted_ = Summary{};
    summary_.linear_solver = LinearSolverReport();
    history_.clear();
    history_first_ = history_count_ = 0;
    if (options_.max_restarts > 0 && quad_spec_.size == 0)
      history_.assign(kHistory, Snapshot{0.0, std::vector<double>(n), std::vector<double>(n)});
    restarts_in_a_row_ = 0;
    restarts_ = 0;
    restart_clear_ = -std::numeric_limits<double>::infinity();
    tiny_steps_ = 0;
    callback_error_.clear();
    ida_error_.clear();

    SUNContext ctx = nullptr;
    if (SUNContext_Create(nullptr, &ctx) != 0) throw std::runtime_error("IDA: SUNContext_Create failed");
    context_.reset(ctx);
    y_.reset(N_VNew_Serial(n, ctx));
    yp_.reset(N_VNew_Serial(n, ctx));
    id_.reset(N_VNew_Serial(n, ctx));
    if (!y_ || !yp_ || !id_) throw std::runtime_error("IDA: N_VNew_Serial failed");
    if (dense_) {
      dense_y_.reset(N_VNew_Serial(n, ctx));
      dense_yp_.reset(N_VNew_Serial(n, ctx));
      if (!dense_y_ || !dense_yp_) throw std::runtime_error("IDA: N_VNew_Serial failed");
      if (quad_spec_.size > 0) {
        dense_yq_.reset(N_VNew_Serial(quad_spec_.size, ctx));
        if (!dense_yq_) throw std::runtime_error("IDA: N_VNew_Serial failed");
      }
    }
    double* y = N_VGetArrayPointer(y_.get());
    double* yp = N_VGetArrayPointer(yp_.get());
    double* id = N_VGetArrayPointer(id_.get());
    for (int i = 0; i < nq; ++i) {
      y[i] = x0.q[i];
      y[nq + i] = x0.v[i];
      yp[i] = x0.v[i];  // q' = v since mu = 0
      yp[nq + i] = x0.a[i];
      id[i] = id[nq + i] = 1.0;
    }
    for (int r = 0; r < nc; ++r) {
      y[2 * nq + r] = x0.lambda[r];
      y[2 * nq + nc + r] = 0.0;  // mu
      yp[2 * nq + r] = yp[2 * nq + nc + r] = 0.0;
      id[2 * nq + r] = id[2 * nq + nc + r] = 0.0;
    }

    const sunindextype nnz = std::max<sunindextype>(1, static_cast<sunindextype>(values_.size()));
    matrix_.reset(SUNSparseMatrix(n, n, nnz, CSC_MAT, ctx));
    if (!matrix_) throw std::runtime_error("IDA: SUNSparseMatrix failed");
    solver_.reset(MakeLinearSolver(ctx));
    if (!solver_) throw std::runtime_error("IDA: SUNLinSolNewEmpty failed");

    mem_.reset(IDACreate(ctx));
    if (!mem_) throw std::runtime_error("IDA: IDACreate failed");
    void* mem = mem_.get();
    Check(IDASetErrHandlerFn(mem, &IdaIntegrator::ErrorHandler, this), "IDASetErrHandlerFn");
    Check(IDAInit(mem, &IdaIntegrator::ResidualCallback, x0.t, y_.get(), yp_.get()), "IDAInit");
    Check(IDASetUserData(mem, this), "IDASetUserData");
    // lambda and mu are out of the error test; their absolute tolerance only enters the
    // Newton convergence test. With small tolerances they would stall it: at small
    // steps the iteration matrix of the index-2 form has a condition number of order
    // 1/h^2 and their increments carry that round-off. By default they are left out of
    // the convergence test too (weight ~ 0): q and v, which they drive, are tested.
    atol_.reset(N_VNew_Serial(n, ctx));
    if (!atol_) throw std::runtime_error("IDA: N_VNew_Serial failed");
    {
      double* atol = N_VGetArrayPointer(atol_.get());
      const double alg = options_.algebraic_atol > 0 ? options_.algebraic_atol : 1e100;
      for (int i = 0; i < n; ++i) atol[i] = i < 2 * nq ? options_.atol : alg;
    }
    rounding_->Clear();
    near_singular_ = false;
    Check(IDAWFtolerances(mem, &IdaIntegrator::EwtCallback), "IDAWFtolerances");
    Check(IDASetLinearSolver(mem, solver_.get(), matrix_.get()), "IDASetLinearSolver");
    Check(IDASetJacFn(mem, &IdaIntegrator::JacobianCallback), "IDASetJacFn");
    Check(IDASetId(mem, id_.get()), "IDASetId");
    Check(IDASetSuppressAlg(mem, SUNTRUE), "IDASetSuppressAlg");
    Check(IDASetMaxNumSteps(mem, options_.max_num_steps), "IDASetMaxNumSteps");
    Check(IDASetMaxOrd(mem, options_.max_order), "IDASetMaxOrd");
    if (options_.max_step > 0) Check(IDASetMaxStep(mem, options_.max_step), "IDASetMaxStep");
    if (options_.min_step > 0) Check(IDASetMinStep(mem, options_.min_step), "IDASetMinStep");
    if (options_.initial_step > 0) Check(IDASetInitStep(mem, options_.initial_step), "IDASetInitStep");

    // Quadrature variables: integrals of g(t, q, v, a = v', lambda) from x0.t, in the
    // error test with the tolerances of q and v.
    std::fill(quad_.begin(), quad_.end(), 0.0);
    if (quad_spec_.size > 0) {
      yq_.reset(N_VNew_Serial(quad_spec_.size, ctx));
      if (!yq_) throw std::runtime_error("IDA: N_VNew_Serial failed");
      N_VConst(0.0, yq_.get());
      Check(IDAQuadInit(mem, &IdaIntegrator::QuadratureCallback, yq_.get()), "IDAQuadInit");
      Check(IDAQuadSStolerances(mem, options_.rtol, options_.atol), "IDAQuadSStolerances");
      Check(IDASetQuadErrCon(mem, SUNTRUE), "IDASetQuadErrCon");
    }

    state_ = x0;
    if (dense_) out_ = x0;
    summary_.status = Summary::Status::kRunning;
    summary_.t_reached = x0.t;
    if (observer_) observer_(state_, 0.0);
  }

  bool AdvanceTo(double t_target) override {
    if (!mem_) {
      summary_.status = Summary::Status::kFailed;
      summary_.message = "IDA: AdvanceTo called before Initialize";
      return false;
    }
    if (summary_.status == Summary::Status::kFailed) return false;
    const double t_now = dense_ ? out_.t : state_.t;
    if (!(t_target > t_now)) {
      summary_.status = Summary::Status::kFailed;
      summary_.message = "IDA: AdvanceTo(" + ToString(t_target) +
                         ") must go beyond the current time " + ToString(t_now);
      return false;
    }
    if (dense_ && t_target > options_.stop_time)
      return Fail("IDA: AdvanceTo(" + ToString(t_target) + ") is beyond the stop time " +
                  ToString(options_.stop_time) + " (dense output)");
    void* mem = mem_.get();
    callback_error_.clear();
    ida_error_.clear();
    // Stop exactly at the target: the reported state is a solution of the DAE, not an
    // interpolant, and the integration never steps beyond a requested time. One step per
    // IDASolve call, so that the step budget, the smallest step and the observer see
    // every step. With dense output the steps land on the stop time only, and the state
    // at the target is interpolated (IDAGetDky).
    const double t_land = dense_ ? options_.stop_time : t_target;
    if (std::isfinite(t_land)) IDASetStopTime(mem, t_land);
    double t_ret = state_.t;
    int flag = IDA_SUCCESS;
    // Dense output: a target within the last step needs no step.
    for (long steps_this_call = 0; !dense_ || state_.t < t_target;) {
      if (options_.max_steps > 0 && summary_.steps_accepted >= options_.max_steps)
        return Fail("IDA: the step budget of " + std::to_string(options_.max_steps) +
                    " steps is used up at t = " + ToString(state_.t) +
                    " with h = " + ToString(summary_.h_last) + ", before t = " + ToString(t_target));
      if (steps_this_call++ >= options_.max_num_steps) {
        return Fail("IDA failed at t = " + ToString(state_.t) + " with IDA_TOO_MUCH_WORK (more than " +
                    std::to_string(options_.max_num_steps) + " steps towards t = " + ToString(t_target) + ")");
      }
      flag = IDASolve(mem, t_target, &t_ret, y_.get(), yp_.get(), IDA_ONE_STEP);
      UpdateCounters();
      // After a step and after a failure IDA leaves (t_ret, y, y') at the last point
      // reached.
      CopyState(t_ret);
      const double h = std::abs(summary_.h_last);
      tiny_steps_ = flag >= 0 && h < options_.min_relative_step * std::max(1.0, std::abs(t_ret))
                        ? tiny_steps_ + 1
                        : 0;
      if ((flag < 0 || tiny_steps_ >= kTinyStepsToFail) && Restart(t_ret, t_land)) continue;
      if (flag < 0) break;
      Remember(t_ret);
      if (tiny_steps_ >= kTinyStepsToFail)
        return Fail("IDA: the step size fell to h = " + ToString(h) + " at t = " + ToString(t_ret) +
                    ", below " + ShortNumber(options_.min_relative_step) + " max(1, |t|) for " +
                    std::to_string(kTinyStepsToFail) +
                    " steps in a row: the time no longer advances (a singular configuration or a "
                    "discontinuity the corrector cannot pass, or a stiffness the tolerances do not "
                    "resolve)");
      if (observer_) observer_(state_, summary_.h_last);
      if (flag == IDA_TSTOP_RETURN || t_ret >= t_target) break;
    }
    if (quad_spec_.size > 0 && flag >= 0) {
      double t_quad = t_ret;
      const int qflag = dense_ ? IDAGetQuadDky(mem, t_target, 0, dense_yq_.get())
                               : IDAGetQuad(mem, &t_quad, yq_.get());
      if (qflag != IDA_SUCCESS)
        return Fail(std::string("IDA: IDAGetQuad") + (dense_ ? "Dky" : "") + " failed with " + FlagName(qflag));
      const double* yq = N_VGetArrayPointer(dense_ ? dense_yq_.get() : yq_.get());
      std::copy(yq, yq + quad_spec_.size, quad_.begin());
    }
    if (flag < 0) {
      std::ostringstream os;
      os << "IDA failed at t = " << ToString(t_ret) << " with " << FlagName(flag);
      if (!callback_error_.empty()) os << "; last system error: " << callback_error_;
      if (!ida_error_.empty()) os << " (" << ida_error_ << ")";
      return Fail(os.str());
    }
    if (dense_ && !Interpolate(t_target)) return false;
    summary_.status = Summary::Status::kRunning;
    summary_.message.clear();
    return true;
  }

  // Dense output: out_ at t from IDA's interpolating polynomial of its last step.
  bool Interpolate(double t) {
    void* mem = mem_.get();
    int flag = IDAGetDky(mem, t, 0, dense_y_.get());
    if (flag == IDA_SUCCESS) flag = IDAGetDky(mem, t, 1, dense_yp_.get());
    if (flag != IDA_SUCCESS)
      return Fail("IDA: IDAGetDky at t = " + ToString(t) + " failed with " + FlagName(flag));
    const int nq = ggl_.nq(), nc = ggl_.nc();
    const double* y = N_VGetArrayPointer(dense_y_.get());
    const double* yp = N_VGetArrayPointer(dense_yp_.get());
    out_.t = t;
    for (int i = 0; i < nq; ++i) {
      out_.q[i] = y[i];
      out_.v[i] = y[nq + i];
      out_.a[i] = yp[nq + i];
    }
    for (int r = 0; r < nc; ++r) out_.lambda[r] = y[2 * nq + r];
    return true;
  }

  // Keeps the last kHistory accepted steps (t, y, y') in a ring (sized at Initialize:
  // no allocation while stepping), for Restart.
  void Remember(double t) {
    if (history_.empty()) return;
    if (t > restart_clear_) restarts_in_a_row_ = 0;
    Snapshot& snap = history_[(history_first_ + history_count_) % kHistory];
    if (history_count_ < kHistory) {
      ++history_count_;
    } else {
      history_first_ = (history_first_ + 1) % kHistory;
    }
    const double* y = N_VGetArrayPointer(y_.get());
    const double* yp = N_VGetArrayPointer(yp_.get());
    snap.t = t;
    std::copy(y, y + ggl_.size(), snap.y.begin());
    std::copy(yp, yp + ggl_.size(), snap.yp.begin());
  }

  // After a failure (IDA's, or collapsing steps) at t_fail: IDA starts again (IDAReInit,
  // order 1) from the oldest of the last kHistory accepted steps, so that its steps fall
  // elsewhere. Near a singular position a run fails when one of its steps lands so close
  // that the rounding, amplified by the nearly singular matrix, exceeds the tolerances;
  // another sequence of steps passes. At most IdaOptions::max_restarts in a row (the
  // count clears once the run is beyond t_fail by the distance it went back); not with
  // quadratures. Returns false when it does not restart.
  bool Restart(double t_fail, double t_target) {
    if (restarts_in_a_row_ >= options_.max_restarts || history_count_ == 0 || quad_spec_.size > 0)
      return false;
    const Snapshot& s = history_[history_first_];
    if (!(s.t < t_fail)) return false;
    void* mem = mem_.get();
    std::copy(s.y.begin(), s.y.end(), N_VGetArrayPointer(y_.get()));
    std::copy(s.yp.begin(), s.yp.end(), N_VGetArrayPointer(yp_.get()));
    // IDA's counters start again from zero: keep what they counted so far.
    counted_ = summary_;
    if (IDAReInit(mem, s.t, y_.get(), yp_.get()) != IDA_SUCCESS) return false;
    if (std::isfinite(t_target) && IDASetStopTime(mem, t_target) != IDA_SUCCESS) return false;
    // A first step that differs at every restart of a row (the mean step of the history
    // times 0.3, 0.5, 0.7), so that the new sequence of steps differs from the failed one.
    const double h0 = (t_fail - s.t) / static_cast<double>(history_count_) *
                      (0.3 + 0.2 * restarts_in_a_row_);
    if (IDASetInitStep(mem, h0) != IDA_SUCCESS) return false;
    ++restarts_in_a_row_;
    ++restarts_;
    restart_clear_ = t_fail + (t_fail - s.t);
    tiny_steps_ = 0;
    const double t0 = s.t;
    history_count_ = 0;
    CopyState(t0);
    callback_error_.clear();
    ida_error_.clear();
    return true;
  }

  void SetStepObserver(StepObserver observer) override { observer_ = std::move(observer); }

  void SetQuadrature(Quadrature quadrature) override {
    if (quadrature.size < 0 || (quadrature.size > 0 && !quadrature.integrand))
      throw std::invalid_argument("IDA::SetQuadrature: a positive size needs an integrand");
    quad_spec_ = std::move(quadrature);
    quad_.assign(quad_spec_.size, 0.0);
    // Takes effect at the next Initialize.
    mem_.reset();
    summary_.status = Summary::Status::kNotStarted;
  }
  const std::vector<double>& quadrature() const override { return quad_; }

  const State& state() const override { return dense_ ? out_ : state_; }
  const Summary& summary() const override { return summary_; }
  std::string name() const override {
    char buf[128];
    std::snprintf(buf, sizeof buf, "IDA (BDF, stabilised index-2 form), rtol = %g, atol = %g%s",
                  options_.rtol, options_.atol, dense_ ? ", dense output" : "");
    return buf;
  }

 private:
  static std::string ToString(double x) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.17g", x);
    return buf;
  }
  static std::string ShortNumber(double x) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
  }

  static std::string FlagName(int flag) { return internal::IdaFlagName(flag); }

  static void Check(int flag, const char* what) {
    if (flag != IDA_SUCCESS)
      throw std::runtime_error(std::string("IDA: ") + what + " failed with " + FlagName(flag));
  }

  bool Fail(const std::string& why) {
    summary_.status = Summary::Status::kFailed;
    summary_.message = why;
    if (dense_) out_ = state_;  // the last state reached is the last step's
    return false;
  }

  void UpdateCounters() {
    void* mem = mem_.get();
    long steps = 0, etf = 0, ncf = 0, nni = 0, nje = 0, nsetups = 0, nre = 0, nrels = 0;
    double h = 0;
    IDAGetNumSteps(mem, &steps);
    IDAGetNumErrTestFails(mem, &etf);
    IDAGetNumNonlinSolvConvFails(mem, &ncf);
    IDAGetNumNonlinSolvIters(mem, &nni);
    IDAGetNumJacEvals(mem, &nje);
    IDAGetNumLinSolvSetups(mem, &nsetups);
    IDAGetNumResEvals(mem, &nre);
    IDAGetNumLinResEvals(mem, &nrels);
    IDAGetLastStep(mem, &h);
    // counted_: what IDA counted before its last restart (Restart).
    summary_.steps_accepted = counted_.steps_accepted + steps;
    summary_.steps_rejected = counted_.steps_rejected + etf + ncf;
    summary_.newton_iterations = counted_.newton_iterations + nni;
    summary_.jacobian_evaluations = counted_.jacobian_evaluations + nje;
    // Every linear solver setup evaluates the Jacobian and refactors it with KLU.
    summary_.factorizations = counted_.factorizations + nsetups;
    summary_.residual_evaluations = counted_.residual_evaluations + nre + nrels;
    summary_.h_last = h;
  }

  void CopyState(double t) {
    const int nq = ggl_.nq(), nc = ggl_.nc();
    const double* y = N_VGetArrayPointer(y_.get());
    const double* yp = N_VGetArrayPointer(yp_.get());
    state_.t = t;
    for (int i = 0; i < nq; ++i) {
      state_.q[i] = y[i];
      state_.v[i] = y[nq + i];
      state_.a[i] = yp[nq + i];
    }
    for (int r = 0; r < nc; ++r) state_.lambda[r] = y[2 * nq + r];
    summary_.t_reached = t;
  }

  // C callbacks: nothing may escape as an exception.
  static int ResidualCallback(double t, N_Vector y, N_Vector yp, N_Vector F, void* user_data) {
    auto* self = static_cast<IdaIntegrator*>(user_data);
    try {
      const int code = self->ggl_.Residual(t, N_VGetArrayPointer(y), N_VGetArrayPointer(yp),
                                           N_VGetArrayPointer(F));
      if (code != 0) self->NoteSystemError(code, t);
      return code;
    } catch (const std::exception& e) {
      self->callback_error_ = std::string("exception in the residual: ") + e.what();
    } catch (...) {
      self->callback_error_ = "unknown exception in the residual";
    }
    return -1;
  }

  static int JacobianCallback(double t, double cj, N_Vector y, N_Vector yp, N_Vector /*r*/,
                              SUNMatrix J, void* user_data, N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<IdaIntegrator*>(user_data);
    try {
      // SUNMatZero clears the structure too: write it every time.
      sunindextype* cols = SUNSparseMatrix_IndexPointers(J);
      sunindextype* rows = SUNSparseMatrix_IndexValues(J);
      double* data = SUNSparseMatrix_Data(J);
      assert(SUNSparseMatrix_NNZ(J) >= static_cast<sunindextype>(self->values_.size()));
      std::copy(self->col_start_.begin(), self->col_start_.end(), cols);
      std::copy(self->row_index_.begin(), self->row_index_.end(), rows);
      self->cj_ = cj;
      const int code =
          self->ggl_.Jacobian(t, cj, N_VGetArrayPointer(y), N_VGetArrayPointer(yp), data);
      if (code != 0) self->NoteSystemError(code, t);
      return code;
    } catch (const std::exception& e) {
      self->callback_error_ = std::string("exception in the Jacobian: ") + e.what();
    } catch (...) {
      self->callback_error_ = "unknown exception in the Jacobian";
    }
    return -1;
  }

  // IDA's linear solver: SUNDIALS' KLU (inner_solver_, as IDA used before) with the
  // rules of internal::GglRounding, behind SUNDIALS' generic interface (a matrix-based,
  // "direct" solver on the SUNSparseMatrix that JacobianCallback fills).
  SUNLinearSolver MakeLinearSolver(SUNContext ctx) {
    inner_solver_.reset(SUNLinSol_KLU(y_.get(), matrix_.get(), ctx));
    work_b_.reset(N_VNew_Serial(ggl_.size(), ctx));
    work_x_.reset(N_VNew_Serial(ggl_.size(), ctx));
    if (!inner_solver_ || !work_b_ || !work_x_) return nullptr;
    SUNLinearSolver s = SUNLinSolNewEmpty(ctx);
    if (!s) return nullptr;
    s->content = this;
    s->ops->gettype = [](SUNLinearSolver) { return SUNLINEARSOLVER_DIRECT; };
    s->ops->getid = [](SUNLinearSolver) { return SUNLINEARSOLVER_CUSTOM; };
    s->ops->initialize = [](SUNLinearSolver ls) {
      return SUNLinSolInitialize(static_cast<IdaIntegrator*>(ls->content)->inner_solver_.get());
    };
    s->ops->setup = &IdaIntegrator::LinearSetupCallback;
    s->ops->solve = &IdaIntegrator::LinearSolveCallback;
    s->ops->lastflag = [](SUNLinearSolver ls) -> sunindextype {
      return SUNLinSolLastFlag(static_cast<IdaIntegrator*>(ls->content)->inner_solver_.get());
    };
    s->ops->free = [](SUNLinearSolver ls) {
      ls->content = nullptr;  // the integrator owns what it points to
      SUNLinSolFreeEmpty(ls);
      return 0;
    };
    return s;
  }

  // The tree's factorisation of A when it was set up and passes the check below, else
  // false: KLU then, and for the rest of the run. There is no pivoting across the tree's
  // nodes, and its pivot ratio says nothing here (the index-2 iteration matrix has pivots
  // of cj M next to ones of order 1 / cj^2: 4e-18 at IDA's first step of 2e-7 s on a
  // chain of rods, where the factors are accurate), so every factorisation is checked by
  // the normwise backward error of one solve, |A x - b|_inf / (|A|_inf |x|_inf + |b|_inf)
  // <= kTreeBackwardError (a loop closed through the ground, which the forest of bodies
  // does not see, fails it; a zero pivot fails the factorisation itself).
  bool TreeSetup(SUNMatrix A) {
    use_tree_ = false;
    if (!tree_) return false;
    const double* values = SUNSparseMatrix_Data(A);
    if (tree_->Factor(values) && tree_->BackwardError(values) <= kTreeBackwardError)
      return use_tree_ = true;
    ++summary_.klu_fallbacks;
    tree_.reset();
    tree_refusal_ = "a factorisation failed its check at t = " + ToString(state_.t);
    summary_.linear_solver = LinearSolverReport();
    return false;
  }

  std::string LinearSolverReport() const {
    if (tree_) return "tree";
    if (options_.linear_solver == LinearSolverKind::kTree) return "klu (no tree: " + tree_refusal_ + ")";
    return "klu";
  }

  // Solves with the last setup's factorisation in place (x: ggl_.size() entries).
  void SolveInPlace(double* x) {
    if (use_tree_) {
      tree_->Solve(x);
      return;
    }
    const int size = ggl_.size();
    std::copy(x, x + size, N_VGetArrayPointer(work_b_.get()));
    SUNLinSolSolve(inner_solver_.get(), matrix_.get(), work_x_.get(), work_b_.get(), 0.0);
    const double* xx = N_VGetArrayPointer(work_x_.get());
    std::copy(xx, xx + size, x);
  }

  static int LinearSetupCallback(SUNLinearSolver s, SUNMatrix A) {
    auto* self = static_cast<IdaIntegrator*>(s->content);
    self->near_singular_ = false;
    if (!self->TreeSetup(A)) {
      const int flag = SUNLinSolSetup(self->inner_solver_.get(), A);
      if (flag != SUNLS_SUCCESS) return flag;
    }
    try {
      // One captured pointer: fits std::function's local storage (no allocation).
      self->rounding_->Update(self->cj_, [self](double* x) { self->SolveInPlace(x); });
      // Near a singular position: the resolution of q or v exceeds kNearSingular times
      // the tolerances (rtol |y| + atol at the last accepted step). Only there the rules
      // apply; elsewhere IDA runs as without them.
      const int nq = self->ggl_.nq();
      const double* atol = N_VGetArrayPointer(self->atol_.get());
      const std::vector<double>& r = self->rounding_->resolution();
      for (int i = 0; i < 2 * nq && !self->near_singular_; ++i) {
        const double y = i < nq ? self->state_.q[i] : self->state_.v[i - nq];
        self->near_singular_ = r[i] > kNearSingular * (self->options_.rtol * std::abs(y) + atol[i]);
      }
    } catch (...) {
      self->rounding_->Clear();
      self->near_singular_ = false;
    }
    return SUNLS_SUCCESS;
  }

  static int LinearSolveCallback(SUNLinearSolver s, SUNMatrix A, N_Vector x, N_Vector b, double tol) {
    auto* self = static_cast<IdaIntegrator*>(s->content);
    if (self->near_singular_) {
      N_VScale(1.0, b, x);
      if (self->rounding_->ZeroIfRounding(N_VGetArrayPointer(x))) return SUNLS_SUCCESS;
    }
    if (self->use_tree_) {
      N_VScale(1.0, b, x);
      self->tree_->Solve(N_VGetArrayPointer(x));
      return SUNLS_SUCCESS;
    }
    return SUNLinSolSolve(self->inner_solver_.get(), A, x, b, tol);
  }

  // Error weights (IDAWFtolerances): 1 / (rtol |y_i| + atol_i + r_i), r the resolution
  // of a Newton solution (GglRounding::resolution) at the last matrix setup: neither
  // the error test nor the Newton convergence test asks for accuracy below what the
  // arithmetic resolves (near a singular position, where r grows like 1/s^2).
  static int EwtCallback(N_Vector y, N_Vector ewt, void* user_data) {
    auto* self = static_cast<IdaIntegrator*>(user_data);
    const double* yy = N_VGetArrayPointer(y);
    double* w = N_VGetArrayPointer(ewt);
    const double* atol = N_VGetArrayPointer(self->atol_.get());
    const std::vector<double>& r = self->rounding_->resolution();
    const int n = self->ggl_.size();
    for (int i = 0; i < n; ++i) {
      const double tol = self->options_.rtol * std::abs(yy[i]) + atol[i] +
                         (self->near_singular_ ? r[i] : 0.0);
      if (!(tol > 0) || !std::isfinite(tol)) return -1;
      w[i] = 1.0 / tol;
    }
    return 0;
  }


  static int QuadratureCallback(double t, N_Vector y, N_Vector yp, N_Vector rhs, void* user_data) {
    auto* self = static_cast<IdaIntegrator*>(user_data);
    try {
      const int nq = self->ggl_.nq();
      const double* yy = N_VGetArrayPointer(y);
      const double* yyp = N_VGetArrayPointer(yp);
      const int code = self->quad_spec_.integrand(t, yy, yy + nq, yyp + nq, yy + 2 * nq,
                                                  N_VGetArrayPointer(rhs));
      if (code != 0) {
        self->callback_error_ = "quadrature integrand failed at t = " + ToString(t);
        return -1;
      }
      return 0;
    } catch (const std::exception& e) {
      self->callback_error_ = std::string("exception in the quadrature integrand: ") + e.what();
    } catch (...) {
      self->callback_error_ = "unknown exception in the quadrature integrand";
    }
    return -1;
  }

  static void ErrorHandler(int /*code*/, const char* module, const char* function, char* msg,
                           void* user_data) {
    auto* self = static_cast<IdaIntegrator*>(user_data);
    try {
      self->ida_error_ = std::string(module ? module : "") + "." + (function ? function : "") +
                         ": " + (msg ? msg : "");
    } catch (...) {
    }
  }

  void NoteSystemError(int code, double t) {
    const char* reason = ggl_.system().last_error();
    callback_error_ = std::string(code > 0 ? "recoverable" : "unrecoverable") +
                      " system error at t = " + ToString(t) +
                      (reason && *reason ? std::string(": ") + reason : std::string());
  }

  IdaOptions options_;
  internal::GglResidual ggl_;
  // The rounding rules of IDA's linear solver (MakeLinearSolver), applied where the
  // resolution exceeds kNearSingular times the tolerances (near_singular_, at the last
  // matrix setup).
  std::unique_ptr<internal::GglRounding> rounding_;
  static constexpr double kNearSingular = 10;
  bool near_singular_ = false;  // at the last matrix setup (LinearSetupCallback)
  double cj_ = 0;  // of the last Jacobian evaluation
  std::vector<sunindextype> col_start_, row_index_;
  std::vector<double> values_;
  State state_;
  // Dense output (IdaOptions::dense_output): the reported (interpolated) state.
  bool dense_ = false;
  State out_;
  Summary summary_;
  Quadrature quad_spec_;
  std::vector<double> quad_;
  StepObserver observer_;
  // Steps in a row below the smallest relative step. A few are normal: IDA's first step
  // can be far smaller (0.5 / ||y'|| in the error weights) and doubles at every step.
  static constexpr int kTinyStepsToFail = 20;
  // Restart: the accepted steps kept, the restarts since the run last got beyond the
  // failure (restart_clear_), and the counters of IDA before its last restart.
  struct Snapshot {
    double t = 0;
    std::vector<double> y, yp;
  };
  static constexpr size_t kHistory = 10;
  std::vector<Snapshot> history_;  // a ring: history_first_, history_count_
  size_t history_first_ = 0, history_count_ = 0;
  int restarts_in_a_row_ = 0;
  long restarts_ = 0;  // in the whole run
  double restart_clear_ = 0;
  Summary counted_;
  int tiny_steps_ = 0;
  std::string callback_error_, ida_error_;
  // Destroyed in reverse order: IDA memory first, the context last.
  ContextPtr context_;
  VectorPtr y_, yp_, id_, atol_, yq_;
  VectorPtr dense_y_, dense_yp_, dense_yq_;  // IDAGetDky's outputs (dense output)
  MatrixPtr matrix_;
  LinearSolverPtr inner_solver_, solver_;
  // IdaOptions::linear_solver kTree: the block tree elimination (null when refused or
  // after a factorisation failed its check), whether the last setup used it, and the
  // reason it is not used (Summary::linear_solver, klu_fallbacks: set where they change).
  std::unique_ptr<BlockTreeLu> tree_;
  bool use_tree_ = false;
  std::string tree_refusal_;
  static constexpr int kMaxTreeNode = 48;
  static constexpr double kTreeBackwardError = 1e-12;
  VectorPtr work_b_, work_x_;
  IdaMemPtr mem_;
};

}  // namespace

std::unique_ptr<Integrator> MakeIdaIntegrator(MechanicalSystem& system, const IdaOptions& options) {
  return std::make_unique<IdaIntegrator>(system, options);
}

}  // namespace mbdae::dae
