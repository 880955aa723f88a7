// Discrete adjoint and direct differentiation of HHT runs (see hht_sensitivity.h and
// docs/sensitivities.md, "HHT").
//
// Step k takes the state s_{k-1} = (q, v, a, lambda, abar, wbar) to s_k. Its unknowns
// u = (a_k, lambda_k) solve R(q_k, v_k, u, t_k, p) = 0 (the scaled residual of
// dae/hht.cc, both forms), where q_k, v_k = Phi(s_{k-1}, a_k) are Newmark's formulas
// (on abar in the equilibrium form) and, for Euler-parameter groups of the modified
// scheme, the rotation map of dae/hht.cc (its fixed point in e_{k+1} resolved by the
// implicit function theorem). With Rt(s_{k-1}, u) = R(Phi(s_{k-1}, u), u):
//   adjoint:  Rt_u^T mu = Phi_u^T sigma_k,
//             sigma_{k-1} = w_{k-1} grad g + Phi_s^T (sigma_k - [R_q^T mu; R_v^T mu]),
//             dG/dp -= R_p^T mu;
//   forward:  Rt_u du = -(R_q dq_exp + R_v dv_exp + R_p),  ds_k = ds_exp + Phi_u du.
// Rt_u is the HHT Newton matrix: exact for the classical scheme, and for the modified
// scheme with its rotation blocks (the groups' dq/da and dv/da from the same group
// Jacobians, dae/hht.h HhtNewtonMatrix); the solves still refine iteratively with the
// exact products, which a pass confirms (the first-order matrix needed about 3 passes a
// solve).
#include "sensitivities/hht_sensitivity.h"

#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "dae/format.h"
#include "dae/hht_rotation.h"
#include "dae/klu_solver.h"
#include "sensitivities/system_matrices.h"

namespace mbdae::sens {

namespace {

using dae::Matrix;
using dae::ParameterMatrix;

struct Scheme {
  double alpha = 0, beta = 0, gamma = 0;
  double s = 1;     // 1 / (1 + alpha)
  double mix = 1;   // dq/dabar factor: 1 + alpha (equilibrium) or 1
  double c1 = 1;    // scale of K_Ma in dR_q/dq: s
  double c2 = 1;    // scale of K_C - Q_q, -Q_v: s (equilibrium) or 1 (negrut)
  double cl = 1;    // scale of C_q^T in dR_q/dlambda
  bool eq = true, modified = false;
};

// The rotation update of one Euler-parameter group (dae/hht_rotation.h), x = (e_n, e'_n,
// a_n, wbar_n, a_{n+1}, e_iter) (4+4+4+3+4+4 = 23) giving y = (e_{n+1}, e'_{n+1},
// wbar_{n+1}) (4+4+3 = 11).
using L = dae::HhtRotationLayout;
constexpr int kGx = L::kEIter;  // inputs other than e_iter

using GroupJac = Eigen::Matrix<double, L::kOutputs, kGx>;

// Total derivative of y with respect to the first 19 inputs, with e_iter = e_{n+1}.
GroupJac GroupJacobian(const dae::HhtRotationScheme& sc, double h, double r, const double* xin) {
  using Deriv = Eigen::Matrix<double, L::kInputs, 1>;
  using AD = Eigen::AutoDiffScalar<Deriv>;
  AD x[L::kInputs], y[L::kOutputs];
  for (int i = 0; i < L::kInputs; ++i) x[i] = AD(xin[i], L::kInputs, i);
  dae::HhtRotationMap(sc, h, r, x, y);
  Eigen::Matrix<double, L::kOutputs, L::kInputs> J;
  for (int i = 0; i < L::kOutputs; ++i) J.row(i) = y[i].derivatives().transpose();
  const Eigen::Matrix<double, L::kOutputs, 4> Jit = J.middleCols<4>(L::kEIter);
  const Eigen::Matrix4d A = Eigen::Matrix4d::Identity() - Jit.middleRows<4>(L::kE1);
  const Eigen::Matrix<double, 4, kGx> de =
      A.partialPivLu().solve(J.block<4, kGx>(L::kE1, 0));
  return J.leftCols<kGx>() + Jit * de;
}

// The linearisation of the run, step by step, and the two sweeps.
class Sweeps {
 public:
  Sweeps(dae::MechanicalSystem& system, const dae::HhtOptions& options,
         ObjectiveFunction& objective, const HhtTrajectory& traj)
      : sys_(system), obj_(objective), traj_(traj), win_(system, options, traj),
        newton_(system, options, /*rotation_blocks=*/options.modified), sm_(system), sm_prev_(system) {
    nq_ = system.num_coordinates();
    nc_ = system.num_constraints();
    np_ = system.num_parameters();
    no_ = objective.num_objectives();
    sc_.alpha = options.alpha;
    sc_.beta = (1 - sc_.alpha) * (1 - sc_.alpha) / 4;
    sc_.gamma = 0.5 - sc_.alpha;
    sc_.s = 1 / (1 + sc_.alpha);
    sc_.eq = options.form == dae::HhtOptions::Form::kEquilibrium;
    sc_.mix = sc_.eq ? 1 + sc_.alpha : 1.0;
    sc_.c1 = sc_.s;
    sc_.c2 = sc_.eq ? sc_.s : 1.0;
    sc_.cl = sc_.eq ? sc_.s : 1.0;
    sc_.modified = options.modified;
    rotation_scheme_ = dae::HhtRotationScheme::Of(sc_.alpha, sc_.eq);
    if (sc_.modified) groups_ = system.quaternion_offsets();
    quat_.assign(nq_, false);
    for (int g : groups_)
      for (int k = 0; k < 4; ++k) quat_[g + k] = true;
    jac_.assign(newton_.pattern().nnz(), 0.0);
    klu_ = std::make_unique<dae::KluSolver>(newton_.pattern());
    T_.resize(groups_.size());
    rotation_.assign(32 * groups_.size(), 0.0);
    // What the steps' partial derivatives use (not C_q v + C_t and gamma and their
    // parameter derivatives).
    for (Matrix m : {Matrix::kMass, Matrix::kMassTimesAccDq, Matrix::kForceDq, Matrix::kForceDv,
                     Matrix::kConstraintDq, Matrix::kConstraintTDq})
      all_.matrices[static_cast<int>(m)] = true;
    for (ParameterMatrix m : {ParameterMatrix::kMassTimesAccDp, ParameterMatrix::kForceDp,
                              ParameterMatrix::kConstraintTDp, ParameterMatrix::kConstraintDp})
      all_.parameters[static_cast<int>(m)] = true;
    prev_.matrices[static_cast<int>(Matrix::kForceDq)] = true;
    prev_.matrices[static_cast<int>(Matrix::kForceDv)] = true;
    prev_.matrices[static_cast<int>(Matrix::kConstraintDq)] = true;
    prev_.matrices[static_cast<int>(Matrix::kConstraintTDq)] = true;
    prev_.parameters[static_cast<int>(ParameterMatrix::kForceDp)] = true;
    prev_.parameters[static_cast<int>(ParameterMatrix::kConstraintTDp)] = true;
    const int n = nq_ + nc_;
    for (auto* v : {&b_, &mu_, &res_, &tmp_}) v->assign(n, 0.0);
    for (auto* v : {&rq_, &rv_}) v->assign(nq_, 0.0);
    wbar_.assign(3 * groups_.size(), 0.0);
    for (auto* v : {&obj_vals_, &obj_wts_}) v->assign(no_, 0.0);
  }

  bool Adjoint(const InitialStateDerivatives& dx0, HhtSensitivityResult* out, std::string* error);
  bool Forward(const InitialStateDerivatives& dx0, HhtSensitivityResult* out, std::string* error);

 private:
  int N() const { return traj_.size() - 1; }
  // Counters and memory into the result.
  void Finish(HhtSensitivityResult* out) const {
    out->linear_solves = solves_;
    out->factorizations = factorizations_;
    out->recomputed_steps = win_.recomputed_steps();
    out->recompute_deviation = win_.max_deviation();
    out->peak_trajectory_bytes =
        std::max(traj_.peak_memory(), traj_.memory() + win_.peak_bytes());
  }
  double StepT1(int k) const { return traj_.t(k - 1) + traj_.h(k); }
  double Ratio(int k) const {
    return sc_.eq && k >= 2 && traj_.h(k - 1) > 0 ? traj_.h(k) / traj_.h(k - 1) : 1.0;
  }
  // Trapezoidal weight of state n.
  double Weight(int n) const {
    double w = 0;
    if (n >= 1) w += 0.5 * traj_.h(n);
    if (n + 1 <= N()) w += 0.5 * traj_.h(n + 1);
    return w;
  }
  // wbar_n of every group, as the integrator carried it: from the checkpoint when
  // state n starts a recomputed segment, else 2 G(e_n) a_n (n = 0 or the negrut form)
  // or 2 ((1 + alpha) G(e_n) a_n - alpha G(e_{n-1}) a_{n-1}).
  void Wbar(int n, double* wbar) const {
    if (n == win_first_ && win_.first_wbar()) {
      std::copy(win_.first_wbar(), win_.first_wbar() + 3 * groups_.size(), wbar);
      return;
    }
    const double* a = win_.a(n);
    for (size_t grp = 0; grp < groups_.size(); ++grp) {
      const int g = groups_[grp];
      double w[3], wp[3];
      dae::HhtRotationG(win_.q(n) + g, a + g, w);
      if (n == 0 || !sc_.eq) {
        for (int k = 0; k < 3; ++k) wbar[3 * grp + k] = 2 * w[k];
      } else {
        dae::HhtRotationG(win_.q(n - 1) + g, win_.a(n - 1) + g, wp);
        for (int k = 0; k < 3; ++k) wbar[3 * grp + k] = 2 * ((1 + sc_.alpha) * w[k] - sc_.alpha * wp[k]);
      }
    }
  }
  // Loads segment i of the window.
  bool LoadSegment(int i, std::string* error) {
    if (!win_.Load(i, error)) return false;
    win_first_ = win_.first(i);
    return true;
  }

  // Evaluates everything step k needs (matrices at s_k, the Newton matrix, the group
  // Jacobians; for the negrut form the matrices of F at s_{k-1}).
  bool Linearise(int k, std::string* error) {
    const double t1 = StepT1(k), h = traj_.h(k);
    std::string err;
    if (sm_.Evaluate(all_, t1, win_.q(k), win_.v(k), win_.a(k), win_.lambda(k), &err) != 0) {
      *error = "evaluation at t = " + Num(t1) + " failed: " + err;
      return false;
    }
    if (!sc_.eq) {
      const double tp = k == 1 ? traj_.t(0) : traj_.t(k - 2) + traj_.h(k - 1);
      if (sm_prev_.Evaluate(prev_, tp, win_.q(k - 1), win_.v(k - 1), win_.a(k - 1),
                            win_.lambda(k - 1), &err) != 0) {
        *error = "evaluation at t = " + Num(tp) + " failed: " + err;
        return false;
      }
    }
    if (!groups_.empty()) {
      Wbar(k - 1, wbar_.data());
      const double r = Ratio(k);
      for (size_t grp = 0; grp < groups_.size(); ++grp) {
        const int g = groups_[grp];
        double x[L::kInputs];
        for (int i = 0; i < 4; ++i) {
          x[L::kE0 + i] = win_.q(k - 1)[g + i];
          x[L::kEd0 + i] = win_.v(k - 1)[g + i];
          x[L::kA0 + i] = win_.a(k - 1)[g + i];
          x[L::kA1 + i] = win_.a(k)[g + i];
          x[L::kEIter + i] = win_.q(k)[g + i];
        }
        for (int i = 0; i < 3; ++i) x[L::kWbar0 + i] = wbar_[3 * grp + i];
        T_[grp] = GroupJacobian(rotation_scheme_, h, r, x);
        // The Newton matrix's rotation blocks (dae/hht.h, HhtNewtonMatrix::Assemble):
        // with them it is Rt_u itself.
        double de[16], ded[16];
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 4; ++j) {
            de[4 * i + j] = T_[grp](L::kE1 + i, L::kA1 + j);
            ded[4 * i + j] = T_[grp](L::kEd1 + i, L::kA1 + j);
          }
        dae::HhtRotationBlock(rotation_scheme_, h, de, ded,
                              &rotation_[32 * grp]);
      }
    }
    newton_.AssembleFrom(h, sm_.all_values(), jac_.data(),
                         groups_.empty() ? nullptr : rotation_.data());
    ++factorizations_;
    if (!klu_->Factor(jac_.data(), &err)) {
      *error = "the Newton matrix of the step to t = " + Num(t1) + " is singular: " + err;
      return false;
    }
    return true;
  }

  // rq = R_q^T mu, rv = R_v^T mu (partials of the scaled residual in q_k, v_k).
  void RqvT(double h, const double* mu, double* rq, double* rv) const {
    std::fill(rq, rq + nq_, 0.0);
    std::fill(rv, rv + nq_, 0.0);
    sm_.MulT(Matrix::kMassTimesAccDq, sc_.c1, mu, rq);
    sm_.MulT(Matrix::kConstraintTDq, sc_.c2, mu, rq);
    sm_.MulT(Matrix::kForceDq, -sc_.c2, mu, rq);
    sm_.MulT(Matrix::kConstraintDq, 1 / (sc_.mix * sc_.beta * h * h), mu + nq_, rq);
    sm_.MulT(Matrix::kForceDv, -sc_.c2, mu, rv);
  }
  // y = R_q dq + R_v dv (nq + nc).
  void Rqv(double h, const double* dq, const double* dv, double* y) const {
    std::fill(y, y + nq_ + nc_, 0.0);
    sm_.Mul(Matrix::kMassTimesAccDq, sc_.c1, dq, y);
    sm_.Mul(Matrix::kConstraintTDq, sc_.c2, dq, y);
    sm_.Mul(Matrix::kForceDq, -sc_.c2, dq, y);
    sm_.Mul(Matrix::kForceDv, -sc_.c2, dv, y);
    sm_.Mul(Matrix::kConstraintDq, 1 / (sc_.mix * sc_.beta * h * h), dq, y + nq_);
  }
  // The a_k-columns of Phi applied to a vector (forward) and their transposes.
  void PhiA(double h, const double* da, double* dq, double* dv) const {
    for (int i = 0; i < nq_; ++i) {
      dq[i] = sc_.mix * sc_.beta * h * h * da[i];
      dv[i] = sc_.mix * sc_.gamma * h * da[i];
    }
    for (size_t grp = 0; grp < groups_.size(); ++grp) {
      const int g = groups_[grp];
      const Eigen::Map<const Eigen::Vector4d> x(da + g);
      Eigen::Map<Eigen::Vector4d>(dq + g) = T_[grp].block<4, 4>(L::kE1, L::kA1) * x;
      Eigen::Map<Eigen::Vector4d>(dv + g) = T_[grp].block<4, 4>(L::kEd1, L::kA1) * x;
    }
  }
  void PhiAT(double h, const double* sq, const double* sv, double* da) const {
    for (int i = 0; i < nq_; ++i)
      if (!quat_[i]) da[i] += sc_.mix * (sc_.beta * h * h * sq[i] + sc_.gamma * h * sv[i]);
    for (size_t grp = 0; grp < groups_.size(); ++grp) {
      const int g = groups_[grp];
      Eigen::Map<Eigen::Vector4d>(da + g) +=
          T_[grp].block<4, 4>(L::kE1, L::kA1).transpose() * Eigen::Map<const Eigen::Vector4d>(sq + g) +
          T_[grp].block<4, 4>(L::kEd1, L::kA1).transpose() * Eigen::Map<const Eigen::Vector4d>(sv + g);
    }
  }
  // y = Rt_u^T mu (transposed = true) or Rt_u x (false), exact.
  void ApplyRt(double h, bool transposed, const double* x, double* y) {
    if (transposed) {
      RqvT(h, x, rq_.data(), rv_.data());
      std::fill(y, y + nq_ + nc_, 0.0);
      PhiAT(h, rq_.data(), rv_.data(), y);
      sm_.MulT(Matrix::kMass, sc_.s, x, y);
      sm_.Mul(Matrix::kConstraintDq, sc_.cl, x, y + nq_);
    } else {
      PhiA(h, x, rq_.data(), rv_.data());
      Rqv(h, rq_.data(), rv_.data(), y);
      sm_.Mul(Matrix::kMass, sc_.s, x, y);
      sm_.MulT(Matrix::kConstraintDq, sc_.cl, x + nq_, y);
    }
  }
  // Solves Rt_u^T x = b (or Rt_u x = b) in place: the factorised Newton matrix and
  // iterative refinement with the exact products (one pass for the classical scheme).
  bool Solve(double h, bool transposed, double* b, std::string* error) {
    const int n = nq_ + nc_;
    std::copy(b, b + n, b_.begin());
    double bnorm = 0;
    for (int i = 0; i < n; ++i) bnorm = std::max(bnorm, std::abs(b_[i]));
    std::copy(b_.begin(), b_.end(), mu_.begin());
    transposed ? klu_->SolveTransposed(mu_.data()) : klu_->Solve(mu_.data());
    ++solves_;
    if (!groups_.empty()) {
      double last = HUGE_VAL;
      for (int it = 0;; ++it) {
        ApplyRt(h, transposed, mu_.data(), tmp_.data());
        double rnorm = 0;
        for (int i = 0; i < n; ++i) {
          res_[i] = b_[i] - tmp_[i];
          rnorm = std::max(rnorm, std::abs(res_[i]));
        }
        if (rnorm <= 1e-14 * bnorm || (it > 3 && rnorm >= 0.5 * last)) break;
        if (it >= 50) {
          *error = "the refinement of a step's linear system did not converge (residual " +
                   Num(rnorm / std::max(bnorm, 1e-300)) + " relative)";
          return false;
        }
        last = rnorm;
        transposed ? klu_->SolveTransposed(res_.data()) : klu_->Solve(res_.data());
        ++solves_;
        for (int i = 0; i < n; ++i) mu_[i] += res_[i];
      }
    }
    std::copy(mu_.begin(), mu_.end(), b);
    return true;
  }

  static std::string Num(double x) { return FormatG(x, 6); }
  // The objectives' parts at state n: adds w_n g (+ phi when terminal) to values, and
  // for each objective j with a part there, lets it add the gradient of w_n g_j
  // (+ phi_j) into the buffers of target(j) (an ObjectiveGradient), then calls done(j).
  template <class Target, class Done>
  bool ObjectiveTerms(int n, bool terminal, double* values, Target target, Done done,
                      std::string* error) {
    const ObjectivePoint x = Point(n);
    const double w = Weight(n);
    if (w > 0) {
      if (obj_.Integrand(x, obj_vals_.data()) != 0) return ObjectiveFail(error);
      for (int j = 0; j < no_; ++j) values[j] += w * obj_vals_[j];
    }
    if (terminal) {
      if (obj_.Terminal(x, obj_vals_.data()) != 0) return ObjectiveFail(error);
      for (int j = 0; j < no_; ++j) values[j] += obj_vals_[j];
    }
    for (int j = 0; j < no_; ++j) {
      const bool integral = w > 0 && obj_.has_integral(j);
      const bool term = terminal && obj_.has_terminal(j);
      if (!integral && !term) continue;
      ObjectiveGradient g = target(j);
      std::fill(obj_wts_.begin(), obj_wts_.end(), 0.0);
      if (integral) {
        obj_wts_[j] = w;
        if (obj_.IntegrandGradient(x, obj_wts_.data(), &g) != 0) return ObjectiveFail(error);
      }
      if (term) {
        obj_wts_[j] = 1;
        if (obj_.TerminalGradient(x, obj_wts_.data(), &g) != 0) return ObjectiveFail(error);
      }
      done(j);
    }
    return true;
  }
  bool ObjectiveFail(std::string* error) const {
    *error = std::string("objective evaluation failed: ") + obj_.last_error();
    return false;
  }
  ObjectivePoint Point(int n) const {
    ObjectivePoint x;
    x.t = traj_.t(n);
    x.q = win_.q(n);
    x.v = win_.v(n);
    x.a = win_.a(n);
    x.lambda = win_.lambda(n);
    return x;
  }

  dae::MechanicalSystem& sys_;
  ObjectiveFunction& obj_;
  const HhtTrajectory& traj_;
  HhtStateWindow win_;
  int win_first_ = 0;  // first step of the loaded segment
  dae::HhtNewtonMatrix newton_;
  SystemMatrices sm_, sm_prev_;
  SystemMatrices::Request all_, prev_;
  int nq_ = 0, nc_ = 0, np_ = 0, no_ = 0;
  Scheme sc_;
  dae::HhtRotationScheme rotation_scheme_;  // the rotation update's constants
  std::vector<int> groups_;
  std::vector<bool> quat_;
  std::vector<GroupJac> T_;
  std::vector<double> rotation_;  // the Newton matrix's rotation blocks, 32 per group
  std::vector<double> jac_;
  std::unique_ptr<dae::KluSolver> klu_;
  std::vector<double> b_, mu_, res_, tmp_, rq_, rv_, wbar_;
  std::vector<double> obj_vals_, obj_wts_;  // objective values and weights (no_)
  long solves_ = 0, factorizations_ = 0;
};

// Per-objective state adjoints, stored objective after objective.
struct StateVectors {
  int nq = 0, nc = 0, ng = 0, no = 0;
  std::vector<double> q, v, a, l, ab, wb;
  void Resize(int nq_, int nc_, int ng_, int no_) {
    nq = nq_, nc = nc_, ng = ng_, no = no_;
    q.assign(size_t(nq) * no, 0.0);
    v.assign(size_t(nq) * no, 0.0);
    a.assign(size_t(nq) * no, 0.0);
    ab.assign(size_t(nq) * no, 0.0);
    l.assign(size_t(nc) * no, 0.0);
    wb.assign(size_t(3 * ng) * no, 0.0);
  }
  void Zero() {
    for (auto* x : {&q, &v, &a, &l, &ab, &wb}) std::fill(x->begin(), x->end(), 0.0);
  }
};

bool Sweeps::Adjoint(const InitialStateDerivatives& dx0, HhtSensitivityResult* out,
                     std::string* error) {
  const int N = this->N();
  const int ng = static_cast<int>(groups_.size());
  out->values.assign(no_, 0.0);
  out->gradient.assign(size_t(no_) * np_, 0.0);
  StateVectors sig, prev;
  sig.Resize(nq_, nc_, ng, no_);
  prev.Resize(nq_, nc_, ng, no_);
  // Running and terminal terms at state n into sig (objective j: weights e_j).
  auto add_terms = [&](int n, bool terminal) {
    auto target = [&](int j) {
      ObjectiveGradient g;
      g.dq = sig.q.data() + size_t(j) * nq_;
      g.dv = sig.v.data() + size_t(j) * nq_;
      g.da = sig.a.data() + size_t(j) * nq_;
      g.dlambda = sig.l.data() + size_t(j) * nc_;
      g.dp = &out->gradient[size_t(j) * np_];
      return g;
    };
    return ObjectiveTerms(n, terminal, out->values.data(), target, [](int) {}, error);
  };
  const int segments = win_.segments();
  if (!LoadSegment(segments - 1, error)) return false;
  if (!add_terms(N, true)) return false;

  std::vector<double> sq(nq_), sv(nq_), rhs(nq_ + nc_);
  for (int seg = segments - 1, k = N; k >= 1; --k) {
    if (k == win_.first(seg)) {
      if (!LoadSegment(--seg, error)) return false;
    }
    if (!Linearise(k, error)) return false;
    const double h = traj_.h(k), r = Ratio(k);
    prev.Zero();
    for (int j = 0; j < no_; ++j) {
      const double* Sq = sig.q.data() + size_t(j) * nq_;
      const double* Sv = sig.v.data() + size_t(j) * nq_;
      const double* Sa = sig.a.data() + size_t(j) * nq_;
      const double* Sab = sig.ab.data() + size_t(j) * nq_;
      const double* Sl = sig.l.data() + size_t(j) * nc_;
      const double* Swb = sig.wb.data() + size_t(j) * 3 * ng;
      // b = Phi_u^T sigma.
      std::fill(rhs.begin(), rhs.end(), 0.0);
      for (int i = 0; i < nq_; ++i) rhs[i] = Sa[i] + (sc_.eq && !quat_[i] ? (1 + sc_.alpha) * Sab[i] : 0.0);
      PhiAT(h, Sq, Sv, rhs.data());
      for (int grp = 0; grp < ng; ++grp) {
        if (!sc_.eq) break;
        const int g = groups_[grp];
        Eigen::Map<Eigen::Vector4d>(rhs.data() + g) +=
            T_[grp].block<3, 4>(L::kWbar1, L::kA1).transpose() * Eigen::Map<const Eigen::Vector3d>(Swb + 3 * grp);
      }
      for (int c = 0; c < nc_; ++c) rhs[nq_ + c] = Sl[c];
      if (!Solve(h, true, rhs.data(), error)) return false;
      const double* mu = rhs.data();
      // Parameters: dG/dp -= R_p^T mu.
      double* gp = &out->gradient[size_t(j) * np_];
      if (np_ > 0) {
        sm_.MulT(ParameterMatrix::kMassTimesAccDp, -sc_.c1, mu, gp);
        sm_.MulT(ParameterMatrix::kConstraintTDp, -sc_.c2, mu, gp);
        sm_.MulT(ParameterMatrix::kForceDp, sc_.c2, mu, gp);
        sm_.MulT(ParameterMatrix::kConstraintDp, -1 / (sc_.mix * sc_.beta * h * h), mu + nq_, gp);
      }
      // sigma' of q_k, v_k.
      RqvT(h, mu, rq_.data(), rv_.data());
      for (int i = 0; i < nq_; ++i) {
        sq[i] = Sq[i] - rq_[i];
        sv[i] = Sv[i] - rv_[i];
      }
      double* Pq = prev.q.data() + size_t(j) * nq_;
      double* Pv = prev.v.data() + size_t(j) * nq_;
      double* Pa = prev.a.data() + size_t(j) * nq_;
      double* Pab = prev.ab.data() + size_t(j) * nq_;
      double* Pl = prev.l.data() + size_t(j) * nc_;
      double* Pwb = prev.wb.data() + size_t(j) * 3 * ng;
      for (int i = 0; i < nq_; ++i) {
        if (quat_[i]) continue;
        Pq[i] += sq[i];
        Pv[i] += h * sq[i] + sv[i];
        const double a0 = h * h * (0.5 - sc_.beta) * sq[i] + h * (1 - sc_.gamma) * sv[i];
        if (sc_.eq) {
          const double ab1 = Sab[i] + h * h * sc_.beta * sq[i] + h * sc_.gamma * sv[i];
          Pa[i] += (1 - r) * a0 - sc_.alpha * ab1;
          Pab[i] += r * a0;
        } else {
          Pa[i] += a0;
        }
      }
      for (int grp = 0; grp < ng; ++grp) {
        const int g = groups_[grp];
        Eigen::Matrix<double, L::kOutputs, 1> ybar;
        ybar.segment<4>(L::kE1) = Eigen::Map<const Eigen::Vector4d>(sq.data() + g);
        ybar.segment<4>(L::kEd1) = Eigen::Map<const Eigen::Vector4d>(sv.data() + g);
        if (sc_.eq)
          ybar.segment<3>(L::kWbar1) = Eigen::Map<const Eigen::Vector3d>(Swb + 3 * grp);
        else
          ybar.segment<3>(L::kWbar1).setZero();
        const Eigen::Matrix<double, kGx, 1> xbar = T_[grp].transpose() * ybar;
        for (int i = 0; i < 4; ++i) {
          Pq[g + i] += xbar[L::kE0 + i];
          Pv[g + i] += xbar[L::kEd0 + i];
          Pa[g + i] += xbar[L::kA0 + i];
        }
        if (sc_.eq)
          for (int i = 0; i < 3; ++i) Pwb[3 * grp + i] += xbar[L::kWbar0 + i];
      }
      // Negrut form: R_q has -alpha/(1+alpha) F_{k-1}, F = C_q^T lambda - Q.
      if (!sc_.eq) {
        const double c = sc_.alpha * sc_.s;
        sm_prev_.MulT(Matrix::kConstraintTDq, c, mu, Pq);
        sm_prev_.MulT(Matrix::kForceDq, -c, mu, Pq);
        sm_prev_.MulT(Matrix::kForceDv, -c, mu, Pv);
        sm_prev_.Mul(Matrix::kConstraintDq, c, mu, Pl);
        if (np_ > 0) {
          sm_prev_.MulT(ParameterMatrix::kConstraintTDp, c, mu, gp);
          sm_prev_.MulT(ParameterMatrix::kForceDp, -c, mu, gp);
        }
      }
    }
    std::swap(sig, prev);
    if (!add_terms(k - 1, false)) return false;
  }

  // The initial state: abar_0 = a_0, wbar_0 = 2 G(e_0) a_0 per group.
  for (int j = 0; j < no_; ++j) {
    double* gp = &out->gradient[size_t(j) * np_];
    const double* Sq = sig.q.data() + size_t(j) * nq_;
    const double* Sv = sig.v.data() + size_t(j) * nq_;
    const double* Sa = sig.a.data() + size_t(j) * nq_;
    const double* Sab = sig.ab.data() + size_t(j) * nq_;
    const double* Sl = sig.l.data() + size_t(j) * nc_;
    const double* Swb = sig.wb.data() + size_t(j) * 3 * ng;
    for (int k = 0; k < np_; ++k) {
      const double* dq = dx0.dq.data() + size_t(k) * nq_;
      const double* dv = dx0.dv.data() + size_t(k) * nq_;
      const double* da = dx0.da.data() + size_t(k) * nq_;
      const double* dl = dx0.dlambda.data() + size_t(k) * nc_;
      double sum = 0;
      for (int i = 0; i < nq_; ++i) sum += Sq[i] * dq[i] + Sv[i] * dv[i] + (Sa[i] + Sab[i]) * da[i];
      for (int c = 0; c < nc_; ++c) sum += Sl[c] * dl[c];
      for (int grp = 0; grp < ng && sc_.eq; ++grp) {
        const int g = groups_[grp];
        double w1[3], w2[3];
        dae::HhtRotationG(dq + g, win_.a(0) + g, w1);
        dae::HhtRotationG(win_.q(0) + g, da + g, w2);
        for (int i = 0; i < 3; ++i) sum += Swb[3 * grp + i] * 2 * (w1[i] + w2[i]);
      }
      gp[k] += sum;
    }
  }
  Finish(out);
  return true;
}

bool Sweeps::Forward(const InitialStateDerivatives& dx0, HhtSensitivityResult* out,
                     std::string* error) {
  const int N = this->N();
  const int ng = static_cast<int>(groups_.size());
  out->values.assign(no_, 0.0);
  out->gradient.assign(size_t(no_) * np_, 0.0);
  // Sensitivities of the state, parameter after parameter (column k at [k * size]).
  StateVectors ds, dn;
  ds.Resize(nq_, nc_, ng, np_);
  dn.Resize(nq_, nc_, ng, np_);
  ds.q = dx0.dq;
  ds.v = dx0.dv;
  ds.a = dx0.da;
  ds.ab = dx0.da;
  ds.l = dx0.dlambda;
  if (!LoadSegment(0, error)) return false;
  for (int k = 0; k < np_; ++k)
    for (int grp = 0; grp < ng && sc_.eq; ++grp) {
      const int g = groups_[grp];
      double w1[3], w2[3];
      dae::HhtRotationG(ds.q.data() + size_t(k) * nq_ + g, win_.a(0) + g, w1);
      dae::HhtRotationG(win_.q(0) + g, ds.a.data() + size_t(k) * nq_ + g, w2);
      for (int i = 0; i < 3; ++i) ds.wb[size_t(k) * 3 * ng + 3 * grp + i] = 2 * (w1[i] + w2[i]);
    }
  // dG += (w grad g + [terminal] grad phi) . ds_n + partials in p.
  std::vector<double> gq(nq_), gv(nq_), ga(nq_), gl(nc_), gpp(np_);
  auto add_terms = [&](int n, bool terminal) {
    auto target = [&](int) {
      for (auto* z : {&gq, &gv, &ga, &gl, &gpp}) std::fill(z->begin(), z->end(), 0.0);
      ObjectiveGradient g;
      g.dq = gq.data();
      g.dv = gv.data();
      g.da = ga.data();
      g.dlambda = gl.data();
      g.dp = gpp.data();
      return g;
    };
    auto done = [&](int j) {
      for (int k = 0; k < np_; ++k) {
        double sum = gpp[k];
        const size_t oq = size_t(k) * nq_, oc = size_t(k) * nc_;
        for (int i = 0; i < nq_; ++i)
          sum += gq[i] * ds.q[oq + i] + gv[i] * ds.v[oq + i] + ga[i] * ds.a[oq + i];
        for (int c = 0; c < nc_; ++c) sum += gl[c] * ds.l[oc + c];
        out->gradient[size_t(j) * np_ + k] += sum;
      }
    };
    return ObjectiveTerms(n, terminal, out->values.data(), target, done, error);
  };
  if (!add_terms(0, N == 0)) return false;

  std::vector<double> dqe(nq_), dve(nq_), rhs(nq_ + nc_), dqa(nq_), dva(nq_);
  for (int seg = 0, k = 1; k <= N; ++k) {
    if (k > win_.last(seg)) {
      if (!LoadSegment(++seg, error)) return false;
    }
    if (!Linearise(k, error)) return false;
    const double h = traj_.h(k), r = Ratio(k);
    for (int p = 0; p < np_; ++p) {
      const size_t oq = size_t(p) * nq_, oc = size_t(p) * nc_, ow = size_t(p) * 3 * ng;
      const double* dq = ds.q.data() + oq;
      const double* dv = ds.v.data() + oq;
      const double* da = ds.a.data() + oq;
      const double* dab = ds.ab.data() + oq;
      // Explicit part of q_k, v_k (a_k held).
      for (int i = 0; i < nq_; ++i) {
        const double a0 = sc_.eq ? (1 - r) * da[i] + r * dab[i] : da[i];
        const double ab1 = sc_.eq ? -sc_.alpha * da[i] : 0.0;
        dqe[i] = dq[i] + h * dv[i] + h * h * ((0.5 - sc_.beta) * a0 + sc_.beta * ab1);
        dve[i] = dv[i] + h * ((1 - sc_.gamma) * a0 + sc_.gamma * ab1);
      }
      Eigen::Matrix<double, kGx, 1> xg;
      for (int grp = 0; grp < ng; ++grp) {
        const int g = groups_[grp];
        for (int i = 0; i < 4; ++i) {
          xg[L::kE0 + i] = dq[g + i];
          xg[L::kEd0 + i] = dv[g + i];
          xg[L::kA0 + i] = da[g + i];
          xg[L::kA1 + i] = 0;
        }
        for (int i = 0; i < 3; ++i) xg[L::kWbar0 + i] = sc_.eq ? ds.wb[ow + 3 * grp + i] : 0.0;
        const Eigen::Matrix<double, L::kOutputs, 1> y = T_[grp] * xg;
        for (int i = 0; i < 4; ++i) {
          dqe[g + i] = y[L::kE1 + i];
          dve[g + i] = y[L::kEd1 + i];
        }
      }
      // Rt_u du = -(R_q dq_e + R_v dv_e + R_p e_p [- alpha s dF_{k-1}]).
      Rqv(h, dqe.data(), dve.data(), rhs.data());
      sm_.AddColumn(ParameterMatrix::kMassTimesAccDp, p, sc_.c1, rhs.data());
      sm_.AddColumn(ParameterMatrix::kConstraintTDp, p, sc_.c2, rhs.data());
      sm_.AddColumn(ParameterMatrix::kForceDp, p, -sc_.c2, rhs.data());
      sm_.AddColumn(ParameterMatrix::kConstraintDp, p, 1 / (sc_.mix * sc_.beta * h * h),
                    rhs.data() + nq_);
      if (!sc_.eq) {
        const double c = -sc_.alpha * sc_.s;
        sm_prev_.Mul(Matrix::kConstraintTDq, c, dq, rhs.data());
        sm_prev_.Mul(Matrix::kForceDq, -c, dq, rhs.data());
        sm_prev_.Mul(Matrix::kForceDv, -c, dv, rhs.data());
        sm_prev_.MulT(Matrix::kConstraintDq, c, ds.l.data() + oc, rhs.data());
        sm_prev_.AddColumn(ParameterMatrix::kConstraintTDp, p, c, rhs.data());
        sm_prev_.AddColumn(ParameterMatrix::kForceDp, p, -c, rhs.data());
      }
      for (double& x : rhs) x = -x;
      if (!Solve(h, false, rhs.data(), error)) return false;
      // ds_k = explicit + Phi_u du.
      PhiA(h, rhs.data(), dqa.data(), dva.data());
      double* nq = dn.q.data() + oq;
      double* nv = dn.v.data() + oq;
      double* na = dn.a.data() + oq;
      double* nab = dn.ab.data() + oq;
      for (int i = 0; i < nq_; ++i) {
        nq[i] = dqe[i] + dqa[i];
        nv[i] = dve[i] + dva[i];
        na[i] = rhs[i];
        nab[i] = sc_.eq ? (1 + sc_.alpha) * rhs[i] - sc_.alpha * da[i] : rhs[i];
      }
      for (int c = 0; c < nc_; ++c) dn.l[oc + c] = rhs[nq_ + c];
      for (int grp = 0; grp < ng; ++grp) {
        const int g = groups_[grp];
        for (int i = 0; i < 4; ++i) xg[L::kA1 + i] = rhs[g + i];
        for (int i = 0; i < 4; ++i) {
          xg[L::kE0 + i] = dq[g + i];
          xg[L::kEd0 + i] = dv[g + i];
          xg[L::kA0 + i] = da[g + i];
        }
        for (int i = 0; i < 3; ++i) xg[L::kWbar0 + i] = sc_.eq ? ds.wb[ow + 3 * grp + i] : 0.0;
        const Eigen::Matrix<double, L::kOutputs, 1> y = T_[grp] * xg;
        for (int i = 0; i < 3; ++i) dn.wb[ow + 3 * grp + i] = y[L::kWbar1 + i];
      }
    }
    std::swap(ds, dn);
    if (!add_terms(k, k == N)) return false;
  }
  Finish(out);
  return true;
}

bool Check(dae::MechanicalSystem& system, ObjectiveFunction& objective,
           const HhtTrajectory& traj, const InitialStateDerivatives& dx0, std::string* error) {
  const int nq = system.num_coordinates(), nc = system.num_constraints();
  const int np = system.num_parameters();
  if (traj.nq() != nq || traj.nc() != nc) {
    *error = "the trajectory does not belong to this system";
    return false;
  }
  if (traj.size() < 1) {
    *error = "the trajectory is empty (record the run with HhtTrajectory::Attach or Recorder)";
    return false;
  }
  if (dx0.np != np || dx0.dq.size() != size_t(nq) * np || dx0.dv.size() != size_t(nq) * np ||
      dx0.da.size() != size_t(nq) * np || dx0.dlambda.size() != size_t(nc) * np) {
    *error = "the initial-state derivatives do not match the system's parameters";
    return false;
  }
  (void)objective;
  return true;
}

}  // namespace

bool HhtAdjointGradient(dae::MechanicalSystem& system, const dae::HhtOptions& options,
                        ObjectiveFunction& objective, const HhtTrajectory& trajectory,
                        const InitialStateDerivatives& dx0, HhtSensitivityResult* result,
                        std::string* error) {
  if (!Check(system, objective, trajectory, dx0, error)) return false;
  Sweeps s(system, options, objective, trajectory);
  return s.Adjoint(dx0, result, error);
}

bool HhtForwardGradient(dae::MechanicalSystem& system, const dae::HhtOptions& options,
                        ObjectiveFunction& objective, const HhtTrajectory& trajectory,
                        const InitialStateDerivatives& dx0, HhtSensitivityResult* result,
                        std::string* error) {
  if (!Check(system, objective, trajectory, dx0, error)) return false;
  Sweeps s(system, options, objective, trajectory);
  return s.Forward(dx0, result, error);
}

}  // namespace mbdae::sens
