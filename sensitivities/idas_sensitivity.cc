#include "sensitivities/idas_sensitivity.h"

#include <idas/idas.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_klu.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <exception>
#include <memory>
#include <stdexcept>
#include <utility>

#include "dae/format.h"
#include "dae/ida_internal.h"
#include "dae/sundials_owners.h"
#include "dae/sparse.h"

namespace mbdae::sens {

bool IdasSensitivityOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = "IdasSensitivityOptions: " + why;
    return false;
  };
  std::string why;
  if (!ida.IsValid(&why)) return fail(why);
  if (!std::isfinite(t_end)) return fail("t_end must be finite");
  for (size_t i = 0; i < output_times.size(); ++i) {
    if (!std::isfinite(output_times[i])) return fail("output times must be finite");
    if (i > 0 && !(output_times[i] > output_times[i - 1]))
      return fail("output times must be strictly increasing");
  }
  if (!output_times.empty() && output_times.back() > t_end)
    return fail("output times must not exceed t_end");
  if (checkpoint_steps < 1) return fail("checkpoint_steps must be >= 1");
  return true;
}

namespace {

using Dense = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;

using dae::sundials::ContextPtr;
using dae::sundials::IdaMemPtr;
using dae::sundials::LinearSolverPtr;
using dae::sundials::MatrixPtr;
using dae::sundials::VectorPtr;

// An array of N_Vectors (N_VCloneVectorArray) with its owner.
class VectorArray {
 public:
  VectorArray() = default;
  VectorArray(int count, N_Vector like) : count_(count) {
    if (count > 0) {
      v_ = N_VCloneVectorArray(count, like);
      if (!v_) throw std::runtime_error("IDAS: N_VCloneVectorArray failed");
      for (int k = 0; k < count; ++k) N_VConst(0.0, v_[k]);
    }
  }
  VectorArray(const VectorArray&) = delete;
  VectorArray& operator=(const VectorArray&) = delete;
  VectorArray& operator=(VectorArray&& o) noexcept {
    std::swap(v_, o.v_);
    std::swap(count_, o.count_);
    return *this;
  }
  ~VectorArray() {
    if (v_) N_VDestroyVectorArray(v_, count_);
  }
  N_Vector* get() { return v_; }
  double* data(int k) { return N_VGetArrayPointer(v_[k]); }

 private:
  N_Vector* v_ = nullptr;
  int count_ = 0;
};

std::string Num(double x) { return FormatG(x, 17); }

// The gradient of one objective (unit weight) at a point, dense.
struct PointGradient {
  std::vector<double> dq, dv, da, dlambda, dp;
  void Resize(int nq, int nc, int np) {
    dq.assign(nq, 0.0);
    dv.assign(nq, 0.0);
    da.assign(nq, 0.0);
    dlambda.assign(nc, 0.0);
    dp.assign(np, 0.0);
  }
  void Zero() {
    for (auto* v : {&dq, &dv, &da, &dlambda, &dp}) std::fill(v->begin(), v->end(), 0.0);
  }
  ObjectiveGradient View() {
    ObjectiveGradient g;
    g.dq = dq.data();
    g.dv = dv.data();
    g.da = da.data();
    g.dlambda = dlambda.data();
    g.dp = dp.data();
    return g;
  }
};

class IdasSensitivitySolver;

// user_data of one backward problem.
struct Backward {
  IdasSensitivitySolver* owner = nullptr;
  int objective = 0;
  int which = -1;
  MatrixPtr matrix;
  LinearSolverPtr solver;
  VectorPtr yB, ypB, qB;
  Vec alpha, beta;  // terminal multipliers
  std::vector<double> phi_p;
};

class IdasSensitivitySolver {
 public:
  IdasSensitivitySolver(dae::MechanicalSystem& system, const IdasSensitivityOptions& options,
                        ObjectiveFunction& objective)
      : sys_(system), opt_(options), obj_(objective), ggl_(system) {
    nq_ = ggl_.nq();
    nc_ = ggl_.nc();
    n_ = ggl_.size();
    np_ = system.num_parameters();
    no_ = objective.num_objectives();
    const dae::CscPattern& p = ggl_.jacobian_pattern();
    col_start_.assign(p.col_start.begin(), p.col_start.end());
    row_index_.assign(p.row_index.begin(), p.row_index.end());
    jac_.assign(p.nnz(), 0.0);
    // The pattern of the transpose and where each entry goes.
    {
      std::vector<int> count(n_ + 1, 0);
      for (int k = 0; k < p.nnz(); ++k) ++count[p.row_index[k] + 1];
      for (int r = 0; r < n_; ++r) count[r + 1] += count[r];
      tcol_start_.assign(count.begin(), count.end());
      trow_index_.assign(p.nnz(), 0);
      tperm_.assign(p.nnz(), 0);
      std::vector<int> next(count.begin(), count.end() - 1);
      for (int c = 0; c < n_; ++c)
        for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) {
          const int dst = next[p.row_index[k]]++;
          trow_index_[dst] = c;
          tperm_[k] = dst;
        }
    }
    mass_.assign(sys_.pattern(dae::Matrix::kMass).nnz(), 0.0);
    SetupMassRate(p);
    madq_.assign(sys_.pattern(dae::Matrix::kMassTimesAccDq).nnz(), 0.0);
    fp_.assign(static_cast<size_t>(n_) * np_, 0.0);
    weights_.assign(no_, 0.0);
    grads_.resize(no_);
    for (auto& g : grads_) g.Resize(nq_, nc_, np_);
  }

  bool Run(bool adjoint, const dae::State& x0, const InitialStateDerivatives& dx0,
           IdasSensitivityResult* result, std::string* error) {
    try {
      if (!Check(x0, dx0, adjoint, error)) return false;
      Setup(x0);
      const bool ok = adjoint ? RunAdjoint(x0, dx0, result) : RunForward(x0, dx0, result);
      if (!ok && error) *error = error_;
      return ok;
    } catch (const std::exception& e) {
      if (error) *error = e.what();
      return false;
    }
  }

 private:
  bool Check(const dae::State& x0, const InitialStateDerivatives& dx0, bool adjoint,
             std::string* error) {
    std::string why;
    auto fail = [&](const std::string& m) {
      if (error) *error = (adjoint ? "IDAS adjoint: " : "IDAS forward: ") + m;
      return false;
    };
    if (!opt_.IsValid(&why)) return fail(why);
    if (!(opt_.t_end > x0.t)) return fail("t_end " + Num(opt_.t_end) + " must exceed the initial time " + Num(x0.t));
    if (!opt_.output_times.empty() && !(opt_.output_times.front() > x0.t))
      return fail("output times must be after the initial time");
    if (static_cast<int>(x0.q.size()) != nq_ || static_cast<int>(x0.v.size()) != nq_ ||
        static_cast<int>(x0.a.size()) != nq_ || static_cast<int>(x0.lambda.size()) != nc_)
      return fail("the initial state does not have the system's sizes");
    if (np_ < 1) return fail("the system has no parameters (num_parameters() = 0)");
    if (no_ < 1) return fail("no objectives");
    const size_t nq_np = static_cast<size_t>(nq_) * np_, nc_np = static_cast<size_t>(nc_) * np_;
    if (dx0.np != np_ || dx0.dq.size() != nq_np || dx0.dv.size() != nq_np ||
        dx0.da.size() != nq_np || dx0.dlambda.size() != nc_np)
      return fail("the initial state derivatives must be nq x np (q, v, a) and nc x np (lambda) "
                  "with np = " + std::to_string(np_));
    if (adjoint && (obj_.depends_on_acceleration() || obj_.depends_on_multipliers()))
      return fail(
          "objectives that depend on accelerations or multipliers (reactions) are not supported "
          "by the IDAS adjoint of the index-2 form (a terminal or integrand dependence on a or "
          "lambda has no consistent adjoint terminal condition); use the forward method");
    return true;
  }

  void ThrowIf(int flag, const char* what) {
    if (flag < 0)
      throw std::runtime_error(std::string("IDAS: ") + what + " failed with " +
                               dae::internal::IdaFlagName(flag) +
                               (ida_error_.empty() ? std::string() : " (" + ida_error_ + ")"));
  }

  void Setup(const dae::State& x0) {
    SUNContext ctx = nullptr;
    if (SUNContext_Create(nullptr, &ctx) != 0) throw std::runtime_error("IDAS: SUNContext_Create failed");
    ctx_.reset(ctx);
    y_.reset(N_VNew_Serial(n_, ctx));
    yp_.reset(N_VNew_Serial(n_, ctx));
    id_.reset(N_VNew_Serial(n_, ctx));
    atol_.reset(N_VNew_Serial(n_, ctx));
    yq_.reset(N_VNew_Serial(no_, ctx));
    if (!y_ || !yp_ || !id_ || !atol_ || !yq_) throw std::runtime_error("IDAS: N_VNew_Serial failed");
    double* y = N_VGetArrayPointer(y_.get());
    double* yp = N_VGetArrayPointer(yp_.get());
    double* id = N_VGetArrayPointer(id_.get());
    double* atol = N_VGetArrayPointer(atol_.get());
    // As the IDA integrator (dae/ida.cc): lambda, mu out of the error test.
    const double alg = opt_.ida.algebraic_atol > 0 ? opt_.ida.algebraic_atol : 1e100;
    for (int i = 0; i < n_; ++i) {
      y[i] = yp[i] = 0;
      id[i] = i < 2 * nq_ ? 1.0 : 0.0;
      atol[i] = i < 2 * nq_ ? opt_.ida.atol : alg;
    }
    for (int i = 0; i < nq_; ++i) {
      y[i] = x0.q[i];
      y[nq_ + i] = x0.v[i];
      yp[i] = x0.v[i];
      yp[nq_ + i] = x0.a[i];
    }
    for (int r = 0; r < nc_; ++r) y[2 * nq_ + r] = x0.lambda[r];
    N_VConst(0.0, yq_.get());

    mem_.reset(IDACreate(ctx));
    if (!mem_) throw std::runtime_error("IDAS: IDACreate failed");
    void* mem = mem_.get();
    ThrowIf(IDASetErrHandlerFn(mem, &ErrorHandler, this), "IDASetErrHandlerFn");
    ThrowIf(IDAInit(mem, &Res, x0.t, y_.get(), yp_.get()), "IDAInit");
    ThrowIf(IDASetUserData(mem, this), "IDASetUserData");
    ThrowIf(IDASVtolerances(mem, opt_.ida.rtol, atol_.get()), "IDASVtolerances");
    matrix_.reset(NewMatrix());
    solver_.reset(SUNLinSol_KLU(y_.get(), matrix_.get(), ctx));
    if (!solver_) throw std::runtime_error("IDAS: SUNLinSol_KLU failed");
    ThrowIf(IDASetLinearSolver(mem, solver_.get(), matrix_.get()), "IDASetLinearSolver");
    ThrowIf(IDASetJacFn(mem, &Jac), "IDASetJacFn");
    ThrowIf(IDASetId(mem, id_.get()), "IDASetId");
    ThrowIf(IDASetSuppressAlg(mem, SUNTRUE), "IDASetSuppressAlg");
    ThrowIf(IDASetMaxNumSteps(mem, opt_.ida.max_num_steps), "IDASetMaxNumSteps");
    ThrowIf(IDASetMaxOrd(mem, opt_.ida.max_order), "IDASetMaxOrd");
    if (opt_.ida.max_step > 0) ThrowIf(IDASetMaxStep(mem, opt_.ida.max_step), "IDASetMaxStep");
    if (opt_.ida.min_step > 0) ThrowIf(IDASetMinStep(mem, opt_.ida.min_step), "IDASetMinStep");
    if (opt_.ida.initial_step > 0) ThrowIf(IDASetInitStep(mem, opt_.ida.initial_step), "IDASetInitStep");
    // The integral parts of the objectives (their values), as the IDA integrator's
    // quadrature.
    ThrowIf(IDAQuadInit(mem, &QuadRhs, yq_.get()), "IDAQuadInit");
    ThrowIf(IDAQuadSStolerances(mem, opt_.ida.rtol, opt_.ida.atol), "IDAQuadSStolerances");
    ThrowIf(IDASetQuadErrCon(mem, SUNTRUE), "IDASetQuadErrCon");
  }

  SUNMatrix NewMatrix() {
    const sunindextype nnz = std::max<sunindextype>(1, static_cast<sunindextype>(jac_.size()));
    SUNMatrix m = SUNSparseMatrix(n_, n_, nnz, CSC_MAT, ctx_.get());
    if (!m) throw std::runtime_error("IDAS: SUNSparseMatrix failed");
    return m;
  }

  std::vector<double> OutputTimes() const {
    std::vector<double> times = opt_.output_times;
    if (times.empty() || times.back() < opt_.t_end) times.push_back(opt_.t_end);
    return times;
  }

  // Runs the forward problem through every output time (IDASolveF when adjoint).
  bool Advance(bool adjoint, IdasSensitivityResult* result) {
    void* mem = mem_.get();
    double t = 0;
    // The forward run stops exactly at every output time as a simulation does. The
    // adjoint's replay of a checkpoint interval (IDAAdataStore) applies only the last
    // stop time: intermediate stops would make the replay take other steps than the
    // run and overrun IDAS's storage of the interval; and intermediate IDASolveF calls
    // that return interpolated values have been measured to corrupt the quadratures
    // (an integral 2.5e-3 off with outputs every 1e-3 s, inside IDA's steps). The adjoint
    // needs no intermediate outputs: it goes straight to t_end.
    const std::vector<double> outputs = adjoint ? std::vector<double>{opt_.t_end} : OutputTimes();
    for (double t_out : outputs) {
      if (!adjoint || t_out == opt_.t_end) IDASetStopTime(mem, t_out);
      int flag;
      if (adjoint) {
        int ncheck = 0;
        flag = IDASolveF(mem, t_out, &t, y_.get(), yp_.get(), IDA_NORMAL, &ncheck);
        result->checkpoints = ncheck;
      } else {
        flag = IDASolve(mem, t_out, &t, y_.get(), yp_.get(), IDA_NORMAL);
      }
      if (flag < 0) return Fail("the forward run failed at t = " + Num(t) + " with " + dae::internal::IdaFlagName(flag));
    }
    t_final_ = t;
    IDAGetNumSteps(mem, &result->steps);
    long etf = 0, etfS = 0;
    IDAGetNumErrTestFails(mem, &etf);
    if (!adjoint) IDAGetSensNumErrTestFails(mem, &etfS);
    result->error_test_failures = etf + etfS;
    return true;
  }

  bool Fail(const std::string& why) {
    error_ = why;
    if (!callback_error_.empty()) error_ += "; " + callback_error_;
    if (!ida_error_.empty()) error_ += " (" + ida_error_ + ")";
    return false;
  }

  ObjectivePoint Point(double t, const double* y, const double* yp) const {
    ObjectivePoint x;
    x.t = t;
    x.q = y;
    x.v = y + nq_;
    x.a = yp + nq_;
    x.lambda = y + 2 * nq_;
    return x;
  }

  // grads_[i] = gradient of g_i (integrand) or phi_i (terminal) at the point, for the
  // objectives i in [first, last).
  int Gradients(bool terminal, const ObjectivePoint& x, int first, int last) {
    for (int i = first; i < last; ++i) {
      grads_[i].Zero();
      if (terminal ? !obj_.has_terminal(i) : !obj_.has_integral(i)) continue;
      std::fill(weights_.begin(), weights_.end(), 0.0);
      weights_[i] = 1.0;
      ObjectiveGradient out = grads_[i].View();
      const int code = terminal ? obj_.TerminalGradient(x, weights_.data(), &out)
                                : obj_.IntegrandGradient(x, weights_.data(), &out);
      if (code != 0) {
        callback_error_ = std::string("objective ") + (terminal ? "terminal" : "integrand") +
                          " gradient failed at t = " + Num(x.t) + ": " + obj_.last_error();
        return code;
      }
    }
    return 0;
  }

  // out += M(q) x.
  int MassTimes(double t, const double* q, const double* x, double* out) {
    dae::EvalInput in;
    in.t = t;
    in.q = q;
    dae::EvalOutput o;
    o[dae::Matrix::kMass] = mass_.data();
    const int code = sys_.Evaluate(in, o);
    if (code != 0) return code;
    dae::MultiplyAdd(sys_.pattern(dae::Matrix::kMass), mass_.data(), 1.0, x, out);
    return 0;
  }

  // The backward Jacobian's dM/dt block (rows and columns v), column by column through
  // d(M a)/dq v with a = e_j, and columns that share no row of M in one evaluation
  // (greedy colouring of the columns of M; 4 evaluations for Euler-parameter bodies,
  // none for a constant M). mdot_slot_[k]: where entry k of M's pattern, (i, j), goes in
  // the transposed GGL pattern, i.e. at F_y's entry (nq + j, nq + i).
  void SetupMassRate(const dae::CscPattern& fy) {
    mdot_colors_.clear();
    mdot_slot_.clear();
    if (sys_.pattern(dae::Matrix::kMassTimesAccDq).nnz() == 0) return;
    const dae::CscPattern& pm = sys_.pattern(dae::Matrix::kMass);
    std::vector<std::vector<char>> used;  // rows taken, per colour
    for (int j = 0; j < pm.cols; ++j) {
      size_t c = 0;
      for (; c < used.size(); ++c) {
        bool free = true;
        for (int k = pm.col_start[j]; k < pm.col_start[j + 1] && free; ++k) free = !used[c][pm.row_index[k]];
        if (free) break;
      }
      if (c == used.size()) {
        used.emplace_back(pm.rows, 0);
        mdot_colors_.emplace_back();
      }
      for (int k = pm.col_start[j]; k < pm.col_start[j + 1]; ++k) used[c][pm.row_index[k]] = 1;
      mdot_colors_[c].push_back(j);
    }
    mdot_slot_.assign(pm.nnz(), -1);
    for (int j = 0; j < pm.cols; ++j)
      for (int k = pm.col_start[j]; k < pm.col_start[j + 1]; ++k) {
        const int col = nq_ + pm.row_index[k], row = nq_ + j;
        for (int f = fy.col_start[col]; f < fy.col_start[col + 1]; ++f)
          if (fy.row_index[f] == row) mdot_slot_[k] = tperm_[f];
        if (mdot_slot_[k] < 0)
          throw std::runtime_error("IDAS adjoint: the GGL Jacobian pattern lacks an entry of the mass matrix");
      }
    mdot_a_.assign(nq_, 0.0);
    mdot_w_.assign(nq_, 0.0);
  }

  // data (the backward Jacobian in the transposed pattern) += dM/dt in rows and columns v.
  int AddMassRate(double t, const double* q, const double* v, double* data) {
    if (mdot_colors_.empty()) return 0;
    const dae::CscPattern& pm = sys_.pattern(dae::Matrix::kMass);
    const dae::CscPattern& pk = sys_.pattern(dae::Matrix::kMassTimesAccDq);
    for (const std::vector<int>& cols : mdot_colors_) {
      for (int j : cols) mdot_a_[j] = 1.0;
      dae::EvalInput in;
      in.t = t;
      in.q = q;
      in.v = v;
      in.a = mdot_a_.data();
      dae::EvalOutput o;
      o[dae::Matrix::kMassTimesAccDq] = madq_.data();
      const int code = sys_.Evaluate(in, o);
      for (int j : cols) mdot_a_[j] = 0.0;
      if (code != 0) return code;
      std::fill(mdot_w_.begin(), mdot_w_.end(), 0.0);
      dae::MultiplyAdd(pk, madq_.data(), 1.0, v, mdot_w_.data());  // sum over the colour of columns of dM/dt
      for (int j : cols)
        for (int k = pm.col_start[j]; k < pm.col_start[j + 1]; ++k) data[mdot_slot_[k]] += mdot_w_[pm.row_index[k]];
    }
    return 0;
  }

  // out += (dM/dt) x = d(M x)/dq q', with q' = v.
  int MassRateTimes(double t, const double* q, const double* v, const double* x, double* out) {
    if (sys_.pattern(dae::Matrix::kMassTimesAccDq).nnz() == 0) return 0;
    dae::EvalInput in;
    in.t = t;
    in.q = q;
    in.v = v;
    in.a = x;
    dae::EvalOutput o;
    o[dae::Matrix::kMassTimesAccDq] = madq_.data();
    const int code = sys_.Evaluate(in, o);
    if (code != 0) return code;
    dae::MultiplyAdd(sys_.pattern(dae::Matrix::kMassTimesAccDq), madq_.data(), 1.0, v, out);
    return 0;
  }

  Dense DenseOf(const dae::CscPattern& p, const std::vector<double>& val) const {
    Dense d = Dense::Zero(p.rows, p.cols);
    for (int c = 0; c < p.cols; ++c)
      for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) d(p.row_index[k], c) += val[k];
    return d;
  }

  // ---------------------------------------------------------------- forward
  bool RunForward(const dae::State& /*x0*/, const InitialStateDerivatives& dx0,
                  IdasSensitivityResult* result) {
    void* mem = mem_.get();
    VectorArray yS(np_, y_.get()), ypS(np_, y_.get()), qS(np_, yq_.get());
    for (int k = 0; k < np_; ++k) {
      double* s = yS.data(k);
      double* sp = ypS.data(k);
      for (int i = 0; i < nq_; ++i) {
        s[i] = dx0.dq[static_cast<size_t>(k) * nq_ + i];
        s[nq_ + i] = dx0.dv[static_cast<size_t>(k) * nq_ + i];
        sp[i] = s[nq_ + i];  // s_q' = s_v (mu = 0 and its sensitivity 0)
        sp[nq_ + i] = dx0.da[static_cast<size_t>(k) * nq_ + i];
      }
      for (int r = 0; r < nc_; ++r) s[2 * nq_ + r] = dx0.dlambda[static_cast<size_t>(k) * nc_ + r];
    }
    ThrowIf(IDASensInit(mem, np_, IDA_STAGGERED, &SensRes, yS.get(), ypS.get()), "IDASensInit");
    VectorArray atolS(np_, y_.get());
    for (int k = 0; k < np_; ++k) N_VScale(1.0, atol_.get(), atolS.get()[k]);
    ThrowIf(IDASensSVtolerances(mem, opt_.ida.rtol, atolS.get()), "IDASensSVtolerances");
    ThrowIf(IDASetSensErrCon(mem, SUNTRUE), "IDASetSensErrCon");
    ThrowIf(IDAQuadSensInit(mem, &QuadSensRhs, qS.get()), "IDAQuadSensInit");
    std::vector<double> atolQS(np_, opt_.ida.atol);
    ThrowIf(IDAQuadSensSStolerances(mem, opt_.ida.rtol, atolQS.data()), "IDAQuadSensSStolerances");
    ThrowIf(IDASetQuadSensErrCon(mem, SUNTRUE), "IDASetQuadSensErrCon");

    if (!Advance(false, result)) return false;
    double t = t_final_;
    ThrowIf(IDAGetQuad(mem, &t, yq_.get()), "IDAGetQuad");
    ThrowIf(IDAGetSens(mem, &t, yS.get()), "IDAGetSens");
    ThrowIf(IDAGetSensDky(mem, t_final_, 1, ypS.get()), "IDAGetSensDky");
    ThrowIf(IDAGetQuadSens(mem, &t, qS.get()), "IDAGetQuadSens");

    const double* y = N_VGetArrayPointer(y_.get());
    const double* yp = N_VGetArrayPointer(yp_.get());
    const ObjectivePoint xT = Point(t_final_, y, yp);
    std::vector<double> phi(no_, 0.0);
    if (obj_.Terminal(xT, phi.data()) != 0)
      return Fail(std::string("the terminal objective failed: ") + obj_.last_error());
    if (Gradients(true, xT, 0, no_) != 0) return Fail("terminal gradient");
    const double* yq = N_VGetArrayPointer(yq_.get());
    result->values.assign(no_, 0.0);
    result->gradient.assign(static_cast<size_t>(no_) * np_, 0.0);
    for (int i = 0; i < no_; ++i) {
      result->values[i] = yq[i] + phi[i];
      const PointGradient& g = grads_[i];
      for (int k = 0; k < np_; ++k) {
        const double* s = yS.data(k);
        const double* sp = ypS.data(k);
        double d = qS.data(k)[i] + g.dp[k];
        for (int j = 0; j < nq_; ++j) d += g.dq[j] * s[j] + g.dv[j] * s[nq_ + j] + g.da[j] * sp[nq_ + j];
        for (int r = 0; r < nc_; ++r) d += g.dlambda[r] * s[2 * nq_ + r];
        result->gradient[static_cast<size_t>(i) * np_ + k] = d;
      }
    }
    return true;
  }

  // ---------------------------------------------------------------- adjoint
  bool RunAdjoint(const dae::State& x0, const InitialStateDerivatives& dx0,
                  IdasSensitivityResult* result) {
    void* mem = mem_.get();
    ThrowIf(IDAAdjInit(mem, opt_.checkpoint_steps,
                       opt_.hermite_interpolation ? IDA_HERMITE : IDA_POLYNOMIAL),
            "IDAAdjInit");
    fresh_factorizations_ = true;
    if (!Advance(true, result)) return false;
    const double T = t_final_;
    double t = T;
    ThrowIf(IDAGetQuad(mem, &t, yq_.get()), "IDAGetQuad");
    const std::vector<double> y(N_VGetArrayPointer(y_.get()), N_VGetArrayPointer(y_.get()) + n_);
    const std::vector<double> yp(N_VGetArrayPointer(yp_.get()), N_VGetArrayPointer(yp_.get()) + n_);
    const ObjectivePoint xT = Point(T, y.data(), yp.data());
    std::vector<double> phi(no_, 0.0);
    if (obj_.Terminal(xT, phi.data()) != 0)
      return Fail(std::string("the terminal objective failed: ") + obj_.last_error());
    result->values.assign(no_, 0.0);
    for (int i = 0; i < no_; ++i) result->values[i] = N_VGetArrayPointer(yq_.get())[i] + phi[i];

    // Dense pieces at T: F_y, C_q, V_q, M, F_p.
    if (ggl_.Jacobian(T, 0.0, y.data(), yp.data(), jac_.data()) != 0)
      return Fail("the Jacobian at t_end failed");
    const Dense Fy = DenseOf(ggl_.jacobian_pattern(), jac_);
    const Dense Cq = Fy.block(2 * nq_, 0, nc_, nq_);
    const Dense Vq = Fy.block(2 * nq_ + nc_, 0, nc_, nq_);
    {
      std::vector<double> dummy(nq_, 0.0);
      if (MassTimes(T, y.data(), dummy.data(), dummy.data()) != 0) return Fail("mass matrix at t_end");
    }
    const Dense M = DenseOf(sys_.pattern(dae::Matrix::kMass), mass_);
    // M itself is singular for every body with Euler parameters (4 G^T J G e = 0) and for
    // massless bodies; only the saddle-point matrix K = [M C_q^T; C_q 0] is regular (M
    // positive definite on the null space of C_q, which the normalisation rows 2 e^T
    // provide). Every "M^-1" of the adjoint's terminal values is a solve with K.
    Dense K = Dense::Zero(nq_ + nc_, nq_ + nc_);
    K.topLeftCorner(nq_, nq_) = M;
    K.topRightCorner(nq_, nc_) = Cq.transpose();
    K.bottomLeftCorner(nc_, nq_) = Cq;
    const Eigen::PartialPivLU<Dense> Klu(K);
    const double k_rcond = Klu.rcond();
    if (!(k_rcond > 1e-15))
      return Fail("the matrix [M C_q^T; C_q 0] at t_end is singular (reciprocal condition " + Num(k_rcond) +
                  "): the constraints must be independent and M positive definite where C_q v = 0");
    // (x, y) with M x + C_q^T y = a, C_q x = b.
    auto kkt = [&](const Vec& a, const Vec& bb) {
      Vec rhs(nq_ + nc_);
      rhs << a, bb;
      return Vec(Klu.solve(rhs));
    };
    const Eigen::CompleteOrthogonalDecomposition<Dense> CCt(Cq * Cq.transpose());
    std::vector<double> fpT(fp_.size());
    if (ggl_.ParameterJacobian(T, y.data(), yp.data(), fpT.data()) != 0)
      return Fail("the parameter derivatives at t_end failed");
    const Eigen::Map<const Dense> FpT(fpT.data(), n_, np_);

    if (Gradients(true, xT, 0, no_) != 0) return Fail("terminal gradient");
    std::vector<PointGradient> terminal = grads_;
    if (Gradients(false, xT, 0, no_) != 0) return Fail("integrand gradient");

    backward_.clear();
    for (int i = 0; i < no_; ++i) {
      auto b = std::make_unique<Backward>();
      b->owner = this;
      b->objective = i;
      const PointGradient& tg = terminal[i];
      const Eigen::Map<const Vec> phi_q(tg.dq.data(), nq_), phi_v(tg.dv.data(), nq_);
      // M chi2 + C_q^T beta = phi_v^T, C_q chi2 = 0.
      const Vec chi2_beta = kkt(phi_v, Vec::Zero(nc_));
      const Vec chi2 = chi2_beta.head(nq_);
      b->beta = chi2_beta.tail(nc_);
      b->alpha = CCt.solve(Cq * (phi_q - Vq.transpose() * b->beta));
      const Vec chi1 = phi_q - Cq.transpose() * b->alpha - Vq.transpose() * b->beta;
      b->phi_p = tg.dp;
      // Consistent chi3, chi4 and chi' at T. With r = F_y^T (chi1, chi2, 0, 0) the
      // adjoint's q and v rows are
      //   chi1' = base1 + C_q^T chi3 + V_q^T chi4,   M chi2' = base2 + C_q^T chi4,
      // (base1 = r_q - g_q, base2 = r_v - dM/dt chi2 - g_v), and the derivatives of the
      // constraints ((C_q)' = V_q along the solution) C_q chi1' = -V_q chi1,
      // C_q chi2' = -V_q chi2. The second pair is a saddle-point system in (chi2', -chi4);
      // then chi3 from the first.
      Vec chi = Vec::Zero(n_);
      chi.head(nq_) = chi1;
      chi.segment(nq_, nq_) = chi2;
      const Vec r = Fy.transpose() * chi;
      const PointGradient& gg = grads_[i];
      const Eigen::Map<const Vec> g_q(gg.dq.data(), nq_), g_v(gg.dv.data(), nq_);
      Vec mdot = Vec::Zero(nq_);
      if (MassRateTimes(T, y.data(), y.data() + nq_, chi2.data(), mdot.data()) != 0)
        return Fail("dM/dt at t_end");
      const Vec base1 = r.head(nq_) - g_q;
      const Vec base2 = r.segment(nq_, nq_) - mdot - g_v;
      const Vec chi2p_chi4 = kkt(base2, -Vq * chi2);
      const Vec chi4 = -chi2p_chi4.tail(nc_);
      const Vec chi3 = CCt.solve(-Vq * chi1 - Cq * (base1 + Vq.transpose() * chi4));
      chi.segment(2 * nq_, nc_) = chi3;
      chi.tail(nc_) = chi4;
      Vec chip = Vec::Zero(n_);
      chip.head(nq_) = base1 + Cq.transpose() * chi3 + Vq.transpose() * chi4;
      chip.segment(nq_, nq_) = chi2p_chi4.head(nq_);
      if (!chi.allFinite() || !chip.allFinite())
        return Fail("the adjoint terminal values of objective " + obj_.names()[i] + " are not finite");

      b->yB.reset(N_VNew_Serial(n_, ctx_.get()));
      b->ypB.reset(N_VNew_Serial(n_, ctx_.get()));
      b->qB.reset(N_VNew_Serial(np_, ctx_.get()));
      if (!b->yB || !b->ypB || !b->qB) throw std::runtime_error("IDAS: N_VNew_Serial failed");
      std::copy(chi.data(), chi.data() + n_, N_VGetArrayPointer(b->yB.get()));
      std::copy(chip.data(), chip.data() + n_, N_VGetArrayPointer(b->ypB.get()));
      N_VConst(0.0, b->qB.get());

      ThrowIf(IDACreateB(mem, &b->which), "IDACreateB");
      const int w = b->which;
      ThrowIf(IDAInitB(mem, w, &ResB, T, b->yB.get(), b->ypB.get()), "IDAInitB");
      ThrowIf(IDASetUserDataB(mem, w, b.get()), "IDASetUserDataB");
      ThrowIf(IDASVtolerancesB(mem, w, opt_.ida.rtol, atol_.get()), "IDASVtolerancesB");
      ThrowIf(IDASetIdB(mem, w, id_.get()), "IDASetIdB");
      ThrowIf(IDASetSuppressAlgB(mem, w, SUNTRUE), "IDASetSuppressAlgB");
      ThrowIf(IDASetMaxNumStepsB(mem, w, opt_.ida.max_num_steps), "IDASetMaxNumStepsB");
      ThrowIf(IDASetMaxOrdB(mem, w, opt_.ida.max_order), "IDASetMaxOrdB");
      if (opt_.ida.max_step > 0) ThrowIf(IDASetMaxStepB(mem, w, opt_.ida.max_step), "IDASetMaxStepB");
      b->matrix.reset(NewMatrix());
      b->solver.reset(SUNLinSol_KLU(b->yB.get(), b->matrix.get(), ctx_.get()));
      if (!b->solver) throw std::runtime_error("IDAS: SUNLinSol_KLU failed");
      ThrowIf(IDASetLinearSolverB(mem, w, b->solver.get(), b->matrix.get()), "IDASetLinearSolverB");
      ThrowIf(IDASetJacFnB(mem, w, &JacB), "IDASetJacFnB");
      ThrowIf(IDAQuadInitB(mem, w, &QuadRhsB, b->qB.get()), "IDAQuadInitB");
      ThrowIf(IDAQuadSStolerancesB(mem, w, opt_.ida.rtol, opt_.ida.atol), "IDAQuadSStolerancesB");
      ThrowIf(IDASetQuadErrConB(mem, w, SUNTRUE), "IDASetQuadErrConB");
      backward_.push_back(std::move(b));
    }

    callback_error_.clear();
    const int flag = IDASolveB(mem, x0.t, IDA_NORMAL);
    if (flag < 0) return Fail(std::string("the backward run failed with ") + dae::internal::IdaFlagName(flag));

    // Sensitivities of the initial state enter through (F_y'^T chi)^T s at t0.
    std::vector<double> mdv(static_cast<size_t>(nq_) * np_, 0.0);
    for (int k = 0; k < np_; ++k)
      if (MassTimes(x0.t, x0.q.data(), &dx0.dv[static_cast<size_t>(k) * nq_], &mdv[static_cast<size_t>(k) * nq_]) != 0)
        return Fail("mass matrix at t0");
    result->gradient.assign(static_cast<size_t>(no_) * np_, 0.0);
    result->backward_steps = 0;
    for (auto& b : backward_) {
      const int i = b->objective;
      double tb = 0;
      ThrowIf(IDAGetB(mem, b->which, &tb, b->yB.get(), b->ypB.get()), "IDAGetB");
      ThrowIf(IDAGetQuadB(mem, b->which, &tb, b->qB.get()), "IDAGetQuadB");
      long nsteps = 0;
      IDAGetNumSteps(IDAGetAdjIDABmem(mem, b->which), &nsteps);
      result->backward_steps += nsteps;
      const double* chi = N_VGetArrayPointer(b->yB.get());
      const double* qB = N_VGetArrayPointer(b->qB.get());
      for (int k = 0; k < np_; ++k) {
        double d = kQuadratureSign * qB[k] + b->phi_p[k];
        for (int r = 0; r < nc_; ++r)
          d -= b->alpha[r] * FpT(2 * nq_ + r, k) + b->beta[r] * FpT(2 * nq_ + nc_ + r, k);
        for (int j = 0; j < nq_; ++j)
          d += chi[j] * dx0.dq[static_cast<size_t>(k) * nq_ + j] +
               chi[nq_ + j] * mdv[static_cast<size_t>(k) * nq_ + j];
        result->gradient[static_cast<size_t>(i) * np_ + k] = d;
      }
    }
    return true;
  }

  // IDAS integrates the backward quadrature from T down to t0: this sign turns its
  // result into int_{t0}^{T} of the integrand.
  static constexpr double kQuadratureSign = -1.0;

  // ---------------------------------------------------------------- callbacks
  template <typename F>
  int Guard(const char* what, F&& f) {
    try {
      return f();
    } catch (const std::exception& e) {
      callback_error_ = std::string("exception in the ") + what + ": " + e.what();
    } catch (...) {
      callback_error_ = std::string("unknown exception in the ") + what;
    }
    return -1;
  }

  int SystemCode(int code, double t) {
    if (code != 0) {
      const char* why = sys_.last_error();
      callback_error_ = std::string(code > 0 ? "recoverable" : "unrecoverable") +
                        " system error at t = " + Num(t) + (why && *why ? std::string(": ") + why : "");
    }
    return code;
  }

  static int Res(double t, N_Vector y, N_Vector yp, N_Vector F, void* ud) {
    auto* self = static_cast<IdasSensitivitySolver*>(ud);
    return self->Guard("residual", [&] {
      return self->SystemCode(self->ggl_.Residual(t, N_VGetArrayPointer(y), N_VGetArrayPointer(yp),
                                                  N_VGetArrayPointer(F)), t);
    });
  }

  static int Jac(double t, double cj, N_Vector y, N_Vector yp, N_Vector, SUNMatrix J, void* ud,
                 N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<IdasSensitivitySolver*>(ud);
    return self->Guard("Jacobian", [&] {
      std::copy(self->col_start_.begin(), self->col_start_.end(), SUNSparseMatrix_IndexPointers(J));
      std::copy(self->row_index_.begin(), self->row_index_.end(), SUNSparseMatrix_IndexValues(J));
      // Adjoint: IDAS replays each checkpoint interval (IDAAdataStore) and stores its steps
      // in an array sized by the checkpoint interval, without a bound check; the replay
      // must take exactly the steps of the run. KLU's refactorisation reuses the pivots of
      // the last full factorisation, which in the replay is another one than in the run
      // (the intervals are replayed last to first), so the iterates differed in the last
      // bits, a replay ended a step later than its interval and wrote past IDAS's array
      // (a segfault in IDASolveB, e.g. the gradient demo at rtol 1e-11). A full
      // factorisation at every Jacobian makes each step a function of the checkpointed
      // data only.
      if (self->fresh_factorizations_) SUNLinSolInitialize(self->solver_.get());
      return self->SystemCode(self->ggl_.Jacobian(t, cj, N_VGetArrayPointer(y), N_VGetArrayPointer(yp),
                                                  SUNSparseMatrix_Data(J)), t);
    });
  }

  static int QuadRhs(double t, N_Vector y, N_Vector yp, N_Vector rq, void* ud) {
    auto* self = static_cast<IdasSensitivitySolver*>(ud);
    return self->Guard("objective integrand", [&] {
      const int code = self->obj_.Integrand(
          self->Point(t, N_VGetArrayPointer(y), N_VGetArrayPointer(yp)), N_VGetArrayPointer(rq));
      if (code != 0) {
        self->callback_error_ = "objective integrand failed at t = " + Num(t) + ": " + self->obj_.last_error();
        return -1;
      }
      return 0;
    });
  }

  // resS_k = F_y s_k + F_y' s_k' + dF/dp_k.
  static int SensRes(int ns, double t, N_Vector y, N_Vector yp, N_Vector, N_Vector* yS,
                     N_Vector* ypS, N_Vector* resS, void* ud, N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<IdasSensitivitySolver*>(ud);
    return self->Guard("sensitivity residual", [&] {
      const int nq = self->nq_, n = self->n_;
      const double* yy = N_VGetArrayPointer(y);
      const double* yyp = N_VGetArrayPointer(yp);
      int code = self->ggl_.Jacobian(t, 0.0, yy, yyp, self->jac_.data());
      if (code == 0) code = self->ggl_.ParameterJacobian(t, yy, yyp, self->fp_.data());
      if (code != 0) return self->SystemCode(code, t);
      const dae::CscPattern& p = self->ggl_.jacobian_pattern();
      for (int k = 0; k < ns; ++k) {
        double* r = N_VGetArrayPointer(resS[k]);
        const double* s = N_VGetArrayPointer(yS[k]);
        const double* sp = N_VGetArrayPointer(ypS[k]);
        std::copy(&self->fp_[static_cast<size_t>(k) * n], &self->fp_[static_cast<size_t>(k + 1) * n], r);
        dae::MultiplyAdd(p, self->jac_.data(), 1.0, s, r);
        for (int i = 0; i < nq; ++i) r[i] += sp[i];
        code = self->MassTimes(t, yy, sp + nq, r + nq);
        if (code != 0) return self->SystemCode(code, t);
      }
      return 0;
    });
  }

  static int QuadSensRhs(int ns, double t, N_Vector y, N_Vector yp, N_Vector* yS, N_Vector* ypS,
                         N_Vector, N_Vector* rhsQS, void* ud, N_Vector, N_Vector, N_Vector) {
    auto* self = static_cast<IdasSensitivitySolver*>(ud);
    return self->Guard("quadrature sensitivity", [&] {
      const int nq = self->nq_, nc = self->nc_;
      const ObjectivePoint x = self->Point(t, N_VGetArrayPointer(y), N_VGetArrayPointer(yp));
      if (self->Gradients(false, x, 0, self->no_) != 0) return -1;
      for (int k = 0; k < ns; ++k) {
        const double* s = N_VGetArrayPointer(yS[k]);
        const double* sp = N_VGetArrayPointer(ypS[k]);
        double* out = N_VGetArrayPointer(rhsQS[k]);
        for (int i = 0; i < self->no_; ++i) {
          const PointGradient& g = self->grads_[i];
          double d = g.dp[k];
          for (int j = 0; j < nq; ++j) d += g.dq[j] * s[j] + g.dv[j] * s[nq + j] + g.da[j] * sp[nq + j];
          for (int r = 0; r < nc; ++r) d += g.dlambda[r] * s[2 * nq + r];
          out[i] = d;
        }
      }
      return 0;
    });
  }

  // The adjoint residual (F_y'^T chi)' - F_y^T chi + g_y^T, F_y'^T chi = (chi1, M chi2, 0, 0).
  static int ResB(double t, N_Vector y, N_Vector yp, N_Vector yB, N_Vector ypB, N_Vector rB, void* udB) {
    auto* b = static_cast<Backward*>(udB);
    IdasSensitivitySolver* self = b->owner;
    return self->Guard("adjoint residual", [&] {
      const int nq = self->nq_, n = self->n_;
      const double* yy = N_VGetArrayPointer(y);
      const double* yyp = N_VGetArrayPointer(yp);
      const double* chi = N_VGetArrayPointer(yB);
      const double* chip = N_VGetArrayPointer(ypB);
      double* r = N_VGetArrayPointer(rB);
      int code = self->ggl_.Jacobian(t, 0.0, yy, yyp, self->jac_.data());
      if (code != 0) return self->SystemCode(code, t);
      std::fill(r, r + n, 0.0);
      dae::MultiplyTransposeAdd(self->ggl_.jacobian_pattern(), self->jac_.data(), -1.0, chi, r);
      for (int i = 0; i < nq; ++i) r[i] += chip[i];
      code = self->MassTimes(t, yy, chip + nq, r + nq);
      if (code == 0) code = self->MassRateTimes(t, yy, yy + nq, chi + nq, r + nq);
      if (code != 0) return self->SystemCode(code, t);
      const int i = b->objective;
      if (self->obj_.has_integral(i)) {
        if (self->Gradients(false, self->Point(t, yy, yyp), i, i + 1) != 0) return -1;
        const PointGradient& g = self->grads_[i];
        for (int j = 0; j < nq; ++j) {
          r[j] += g.dq[j];
          r[nq + j] += g.dv[j];
        }
      }
      return 0;
    });
  }

  // d resB/d chi + cjB d resB/d chi' = -(F_y - cjB F_y')^T + dM/dt in the block (v, v).
  static int JacB(double t, double cjB, N_Vector y, N_Vector yp, N_Vector, N_Vector, N_Vector,
                  SUNMatrix J, void* udB, N_Vector, N_Vector, N_Vector) {
    auto* b = static_cast<Backward*>(udB);
    IdasSensitivitySolver* self = b->owner;
    return self->Guard("adjoint Jacobian", [&] {
      const int code = self->ggl_.Jacobian(t, -cjB, N_VGetArrayPointer(y), N_VGetArrayPointer(yp),
                                           self->jac_.data());
      if (code != 0) return self->SystemCode(code, t);
      std::copy(self->tcol_start_.begin(), self->tcol_start_.end(), SUNSparseMatrix_IndexPointers(J));
      std::copy(self->trow_index_.begin(), self->trow_index_.end(), SUNSparseMatrix_IndexValues(J));
      double* data = SUNSparseMatrix_Data(J);
      for (size_t k = 0; k < self->jac_.size(); ++k) data[self->tperm_[k]] = -self->jac_[k];
      const double* yy = N_VGetArrayPointer(y);
      return self->SystemCode(self->AddMassRate(t, yy, yy + self->nq_, data), t);
    });
  }

  // g_p - chi^T F_p.
  static int QuadRhsB(double t, N_Vector y, N_Vector yp, N_Vector yB, N_Vector, N_Vector rq, void* udB) {
    auto* b = static_cast<Backward*>(udB);
    IdasSensitivitySolver* self = b->owner;
    return self->Guard("adjoint quadrature", [&] {
      const int n = self->n_, np = self->np_;
      const double* yy = N_VGetArrayPointer(y);
      const double* yyp = N_VGetArrayPointer(yp);
      const double* chi = N_VGetArrayPointer(yB);
      double* out = N_VGetArrayPointer(rq);
      const int code = self->ggl_.ParameterJacobian(t, yy, yyp, self->fp_.data());
      if (code != 0) return self->SystemCode(code, t);
      const int i = b->objective;
      if (self->obj_.has_integral(i) &&
          self->Gradients(false, self->Point(t, yy, yyp), i, i + 1) != 0)
        return -1;
      for (int k = 0; k < np; ++k) {
        double d = self->obj_.has_integral(i) ? self->grads_[i].dp[k] : 0.0;
        const double* col = &self->fp_[static_cast<size_t>(k) * n];
        for (int r = 0; r < n; ++r) d -= chi[r] * col[r];
        out[k] = d;
      }
      return 0;
    });
  }

  static void ErrorHandler(int, const char* module, const char* function, char* msg, void* ud) {
    auto* self = static_cast<IdasSensitivitySolver*>(ud);
    try {
      self->ida_error_ = std::string(module ? module : "") + "." + (function ? function : "") +
                         ": " + (msg ? msg : "");
    } catch (...) {
    }
  }

  dae::MechanicalSystem& sys_;
  const IdasSensitivityOptions& opt_;
  ObjectiveFunction& obj_;
  dae::internal::GglResidual ggl_;
  int nq_ = 0, nc_ = 0, n_ = 0, np_ = 0, no_ = 0;
  std::vector<sunindextype> col_start_, row_index_, tcol_start_, trow_index_;
  std::vector<int> tperm_;
  std::vector<double> jac_, mass_, madq_, fp_, weights_;
  std::vector<PointGradient> grads_;
  std::vector<std::vector<int>> mdot_colors_;
  std::vector<int> mdot_slot_;
  std::vector<double> mdot_a_, mdot_w_;
  double t_final_ = 0;
  bool fresh_factorizations_ = false;
  std::string error_, callback_error_, ida_error_;
  // Destroyed in reverse order: IDAS memory first, the context last.
  ContextPtr ctx_;
  VectorPtr y_, yp_, id_, atol_, yq_;
  MatrixPtr matrix_;
  LinearSolverPtr solver_;
  std::vector<std::unique_ptr<Backward>> backward_;
  IdaMemPtr mem_;
};

bool RunTimed(bool adjoint, dae::MechanicalSystem& system, const IdasSensitivityOptions& options,
              ObjectiveFunction& objective, const dae::State& x0, const InitialStateDerivatives& dx0,
              IdasSensitivityResult* result, std::string* error) {
  const auto wall0 = std::chrono::steady_clock::now();
  const std::clock_t cpu0 = std::clock();
  *result = IdasSensitivityResult{};
  bool ok = false;
  {
    IdasSensitivitySolver solver(system, options, objective);
    ok = solver.Run(adjoint, x0, dx0, result, error);
  }
  result->wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  result->cpu_time = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  return ok;
}

}  // namespace

bool IdasForwardGradient(dae::MechanicalSystem& system, const IdasSensitivityOptions& options,
                         ObjectiveFunction& objective, const dae::State& x0,
                         const InitialStateDerivatives& dx0, IdasSensitivityResult* result,
                         std::string* error) {
  return RunTimed(false, system, options, objective, x0, dx0, result, error);
}

bool IdasAdjointGradient(dae::MechanicalSystem& system, const IdasSensitivityOptions& options,
                         ObjectiveFunction& objective, const dae::State& x0,
                         const InitialStateDerivatives& dx0, IdasSensitivityResult* result,
                         std::string* error) {
  return RunTimed(true, system, options, objective, x0, dx0, result, error);
}

}  // namespace mbdae::sens
