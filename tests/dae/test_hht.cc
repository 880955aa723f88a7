// HHT integrator: convergence order, the modified scheme for Euler parameters,
// adaptivity, repeatability and failure reporting; and the derivatives of the
// free-body test system against finite differences.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <random>
#include <stdexcept>

#include "dae/hht.h"
#include "dae/hht_rotation.h"
#include "tests/support/free_body_system.h"
#include "tests/support/pendulum_reference.h"
#include "tests/support/pendulum_system.h"

namespace mbdae::dae {
namespace {

using testing::FreeBodySystem;
using testing::PendulumSystem;

Eigen::MatrixXd Dense(const CscPattern& p, const std::vector<double>& v) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(p.rows, p.cols);
  for (int c = 0; c < p.cols; ++c)
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) A(p.row_index[k], c) = v[k];
  return A;
}

// Q, C, gamma, M and C_q of the system at (t, q, v), dense.
struct DenseEvaluation {
  Eigen::VectorXd Q, C, gamma;
  Eigen::MatrixXd M, Cq;
};
DenseEvaluation EvaluateDense(MechanicalSystem& sys, double t, const std::vector<double>& q,
                              const std::vector<double>& v) {
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  DenseEvaluation e{Eigen::VectorXd::Zero(nq), Eigen::VectorXd::Zero(nc), Eigen::VectorXd::Zero(nc),
                    {}, {}};
  std::vector<double> M(sys.pattern(Matrix::kMass).nnz()), Cq(sys.pattern(Matrix::kConstraintDq).nnz());
  EvalInput in;
  in.t = t;
  in.q = q.data();
  in.v = v.data();
  EvalOutput out;
  out.force = e.Q.data();
  out.constraint = e.C.data();
  out.acc_rhs = e.gamma.data();
  out[Matrix::kMass] = M.data();
  out[Matrix::kConstraintDq] = Cq.data();
  EXPECT_EQ(sys.Evaluate(in, out), 0);
  e.M = Dense(sys.pattern(Matrix::kMass), M);
  e.Cq = Dense(sys.pattern(Matrix::kConstraintDq), Cq);
  return e;
}

// Consistent a, lambda at (q, v, t): [M C_q^T; C_q 0] [a; lambda] = [Q; gamma].
State ConsistentState(MechanicalSystem& sys, std::vector<double> q, std::vector<double> v,
                      double t = 0) {
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  const DenseEvaluation e = EvaluateDense(sys, t, q, v);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(nq + nc, nq + nc);
  A.topLeftCorner(nq, nq) = e.M;
  A.topRightCorner(nq, nc) = e.Cq.transpose();
  A.bottomLeftCorner(nc, nq) = e.Cq;
  Eigen::VectorXd b(nq + nc);
  b << e.Q, e.gamma;
  const Eigen::VectorXd x = A.fullPivLu().solve(b);
  State s;
  s.t = t;
  s.q = q;
  s.v = v;
  s.a.assign(x.data(), x.data() + nq);
  s.lambda.assign(x.data() + nq, x.data() + nq + nc);
  return s;
}

// ---------------------------------------------------------------------------------
// Free body: derivatives against central finite differences.

TEST(FreeBodySystem, DerivativesMatchFiniteDifferences) {
  FreeBodySystem sys(2.0, {0.7, 1.3, 2.1}, {0.1, -0.2, 0.3}, {0.4, -0.5, 0.6});
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const int nq = 7;
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<double> q(nq), v(nq), a(nq), w(1);
    for (auto* x : {&q, &v, &a})
      for (double& y : *x) y = u(rng);
    w[0] = u(rng);
    // Evaluates everything at (q, v).
    struct Out {
      std::vector<double> Q, C, M, Kma, Qq, Qv, Cq, Kc, Kcv, gam;
    };
    auto eval = [&](const std::vector<double>& qq, const std::vector<double>& vv) {
      Out o;
      o.Q.resize(nq);
      o.C.resize(1);
      o.gam.resize(1);
      o.M.resize(sys.pattern(Matrix::kMass).nnz());
      o.Kma.resize(16);
      o.Qq.resize(16);
      o.Qv.resize(16);
      o.Kc.resize(16);
      o.Cq.resize(4);
      o.Kcv.resize(4);
      EvalInput in;
      in.q = qq.data();
      in.v = vv.data();
      in.a = a.data();
      in.w = w.data();
      EvalOutput out;
      out.force = o.Q.data();
      out.constraint = o.C.data();
      out.acc_rhs = o.gam.data();
      out[Matrix::kMass] = o.M.data();
      out[Matrix::kMassTimesAccDq] = o.Kma.data();
      out[Matrix::kForceDq] = o.Qq.data();
      out[Matrix::kForceDv] = o.Qv.data();
      out[Matrix::kConstraintDq] = o.Cq.data();
      out[Matrix::kConstraintTDq] = o.Kc.data();
      out[Matrix::kConstraintVelDq] = o.Kcv.data();
      EXPECT_EQ(sys.Evaluate(in, out), 0);
      return o;
    };
    const Out o = eval(q, v);
    const Eigen::MatrixXd M = Dense(sys.pattern(Matrix::kMass), o.M);
    EXPECT_LT((M - M.transpose()).norm(), 1e-14);
    const Eigen::MatrixXd Kma = Dense(sys.pattern(Matrix::kMassTimesAccDq), o.Kma);
    const Eigen::MatrixXd Qq = Dense(sys.pattern(Matrix::kForceDq), o.Qq);
    const Eigen::MatrixXd Qv = Dense(sys.pattern(Matrix::kForceDv), o.Qv);
    const Eigen::MatrixXd Cq = Dense(sys.pattern(Matrix::kConstraintDq), o.Cq);
    const Eigen::MatrixXd Kc = Dense(sys.pattern(Matrix::kConstraintTDq), o.Kc);
    const Eigen::MatrixXd Kcv = Dense(sys.pattern(Matrix::kConstraintVelDq), o.Kcv);
    const Eigen::Map<const Eigen::VectorXd> av(a.data(), nq), vv(v.data(), nq);
    const double eps = 1e-6, tol = 1e-7;
    for (int j = 0; j < nq; ++j) {
      std::vector<double> qp = q, qm = q, vp = v, vm = v;
      qp[j] += eps;
      qm[j] -= eps;
      vp[j] += eps;
      vm[j] -= eps;
      const Out p = eval(qp, v), m = eval(qm, v), pv = eval(q, vp), mv = eval(q, vm);
      const Eigen::VectorXd dMa = (Dense(sys.pattern(Matrix::kMass), p.M) * av -
                                   Dense(sys.pattern(Matrix::kMass), m.M) * av) / (2 * eps);
      const Eigen::MatrixXd Cqp = Dense(sys.pattern(Matrix::kConstraintDq), p.Cq);
      const Eigen::MatrixXd Cqm = Dense(sys.pattern(Matrix::kConstraintDq), m.Cq);
      const Eigen::VectorXd dCtw = (Cqp.transpose() - Cqm.transpose()) * w[0] / (2 * eps);
      const Eigen::VectorXd dCv = (Cqp - Cqm) * vv / (2 * eps);
      for (int i = 0; i < nq; ++i) {
        EXPECT_NEAR(Kma(i, j), dMa[i], tol) << "d(Ma)/dq (" << i << ", " << j << ")";
        EXPECT_NEAR(Qq(i, j), (p.Q[i] - m.Q[i]) / (2 * eps), tol) << "dQ/dq " << i << " " << j;
        EXPECT_NEAR(Qv(i, j), (pv.Q[i] - mv.Q[i]) / (2 * eps), tol) << "dQ/dv " << i << " " << j;
        EXPECT_NEAR(Kc(i, j), dCtw[i], tol) << "d(Cq^T w)/dq " << i << " " << j;
      }
      EXPECT_NEAR(Cq(0, j), (p.C[0] - m.C[0]) / (2 * eps), tol) << "C_q " << j;
      EXPECT_NEAR(Kcv(0, j), dCv[0], tol) << "d(C_q v)/dq " << j;
    }
    // gamma = -(C_q v)_q v.
    EXPECT_NEAR(o.gam[0], -(Kcv * vv)(0), 1e-13);
  }
}

// The HHT step's residual (r_q, r_c) written out from the definitions at (t, q1, v1) with
// a_{n+1} = a1 and lambda_{n+1} = lam (the previous step's terms, constants, left out):
// r_q = (M a + F) / (1 + alpha) (equilibrium form) or M a / (1 + alpha) + F (negrut),
// F = C_q^T lambda - Q, r_c = C / (mix beta h^2) with cq = mix beta h^2.
Eigen::VectorXd StepResidual(MechanicalSystem& sys, double t, const std::vector<double>& q1,
                             const std::vector<double>& v1, const std::vector<double>& a1,
                             const Eigen::VectorXd& lam, bool equilibrium, double alpha,
                             double cq) {
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  const DenseEvaluation e = EvaluateDense(sys, t, q1, v1);
  const Eigen::Map<const Eigen::VectorXd> av(a1.data(), nq);
  const Eigen::VectorXd F = e.Cq.transpose() * lam - e.Q;
  Eigen::VectorXd r(nq + nc);
  r.head(nq) = equilibrium ? Eigen::VectorXd((e.M * av + F) / (1 + alpha))
                           : Eigen::VectorXd(e.M * av / (1 + alpha) + F);
  r.tail(nc) = e.C / cq;
  return r;
}

// The n x n Jacobian of f at 0 by central differences with step eps.
template <class F>
Eigen::MatrixXd CentralDifferences(const F& f, int n, double eps) {
  Eigen::MatrixXd J(n, n);
  for (int k = 0; k < n; ++k) {
    Eigen::VectorXd xp = Eigen::VectorXd::Zero(n), xm = Eigen::VectorXd::Zero(n);
    xp[k] = eps;
    xm[k] = -eps;
    J.col(k) = (f(xp) - f(xm)) / (2 * eps);
  }
  return J;
}

// HhtNewtonMatrix (the integrator's Newton matrix) is the derivative of the step's
// residual with respect to (a_{n+1}, lambda_{n+1}) through Newmark's formulas, in both
// forms: central differences of the residual written out here from the definitions.
TEST(HhtNewtonMatrix, IsTheDerivativeOfTheStepResidual) {
  FreeBodySystem sys(2.0, {0.7, 1.3, 2.1}, {0.1, -0.2, 0.3}, {0.4, -0.5, 0.6});
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  const int nq = 7, nc = 1, n = nq + nc;
  for (HhtOptions::Form form : {HhtOptions::Form::kEquilibrium, HhtOptions::Form::kNegrut}) {
    for (double alpha : {0.0, -0.2}) {
      SCOPED_TRACE(std::string(HhtFormName(form)) + ", alpha " + std::to_string(alpha));
      HhtOptions opt;
      opt.form = form;
      opt.alpha = alpha;
      HhtNewtonMatrix newton(sys, opt);
      ASSERT_EQ(newton.pattern().rows, n);
      ASSERT_EQ(newton.pattern().cols, n);
      for (int i = 0; i < n; ++i) EXPECT_GE(newton.pattern().find(i, i), 0);  // full diagonal
      const bool eq = form == HhtOptions::Form::kEquilibrium;
      const double beta = (1 - alpha) * (1 - alpha) / 4, gamma = 0.5 - alpha;
      const double mix = eq ? 1 + alpha : 1.0, h = 0.05, t = 0.3;
      std::vector<double> q(nq), v(nq), a(nq), lam(nc);
      for (auto* x : {&q, &v, &a, &lam})
        for (double& y : *x) y = u(rng);
      std::vector<double> values(newton.pattern().nnz());
      ASSERT_EQ(newton.Assemble(t, h, q.data(), v.data(), a.data(), lam.data(), values.data()), 0);
      const Eigen::MatrixXd J = Dense(newton.pattern(), values);
      // The residual at (a + da, lambda + dl), with q, v moved by Newmark's formulas
      // (terms of the previous step are constants and left out).
      auto residual = [&](const Eigen::VectorXd& x) {
        std::vector<double> q1(nq), v1(nq), a1(nq);
        for (int i = 0; i < nq; ++i) {
          q1[i] = q[i] + mix * beta * h * h * x[i];
          v1[i] = v[i] + mix * gamma * h * x[i];
          a1[i] = a[i] + x[i];
        }
        Eigen::VectorXd l1(nc);
        for (int j = 0; j < nc; ++j) l1[j] = lam[j] + x[nq + j];
        return StepResidual(sys, t, q1, v1, a1, l1, eq, alpha, mix * beta * h * h);
      };
      // The residual is nearly linear in (da, dl) (the state moves by h^2 da): a large
      // step keeps the rounding of C / (beta h^2) small.
      const Eigen::MatrixXd J_fd = CentralDifferences(residual, n, 1e-3);
      const double err = (J - J_fd).cwiseAbs().maxCoeff() / J_fd.cwiseAbs().maxCoeff();
      std::cout << "  relative error of the HHT Newton matrix: " << err << "\n";
      EXPECT_LT(err, 1e-8);
      EXPECT_GT(J_fd.cwiseAbs().maxCoeff(), 0.1);
    }
  }
}

// The modified scheme's exact Newton matrix (HhtOptions::rotation_jacobian = kExact):
// with the rotation blocks of dae/hht_rotation.h, HhtNewtonMatrix is the derivative of
// the step's residual through the modified map itself, e_{n+1} and e'_{n+1} of the Euler
// parameters from the rotation update at its fixed point G(e_{n+1}) (iterated here to
// round-off), the other coordinates from Newmark's formulas. Without the blocks, the
// same matrix misses that derivative by O(h |omega|).
TEST(HhtNewtonMatrix, RotationBlocksAreTheDerivativeOfTheModifiedStepResidual) {
  FreeBodySystem sys(2.0, {0.7, 1.3, 2.1}, {0.1, -0.2, 0.3}, {0.4, -0.5, 0.6});
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  const int nq = 7, nc = 1, n = nq + nc, g = 3;
  using L = HhtRotationLayout;
  for (HhtOptions::Form form : {HhtOptions::Form::kEquilibrium, HhtOptions::Form::kNegrut}) {
    for (double alpha : {0.0, -0.2}) {
      SCOPED_TRACE(std::string(HhtFormName(form)) + ", alpha " + std::to_string(alpha));
      HhtOptions opt;
      opt.form = form;
      opt.alpha = alpha;
      HhtNewtonMatrix newton(sys, opt, /*rotation_blocks=*/true);
      ASSERT_TRUE(newton.has_rotation_blocks());
      const bool eq = form == HhtOptions::Form::kEquilibrium;
      const HhtRotationScheme sc = HhtRotationScheme::Of(alpha, eq);
      const double h = 0.05, t = 0.3, r = eq ? 1.3 : 1.0;
      const double cq = sc.mix * sc.beta * h * h, cv = sc.mix * sc.gamma * h;
      // The previous state (unit e_n, e'_n orthogonal to it, a fast spin) and the iterate.
      std::vector<double> q0(nq), v0(nq), a0(nq), a1(nq), lam(nc);
      double wbar0[3];
      for (auto* x : {&q0, &v0, &a0, &a1, &lam})
        for (double& y : *x) y = u(rng);
      for (double& w : wbar0) w = u(rng);
      double norm = 0, dot = 0;
      for (int k = 0; k < 4; ++k) norm += q0[g + k] * q0[g + k];
      for (int k = 0; k < 4; ++k) q0[g + k] /= std::sqrt(norm);
      for (int k = 0; k < 4; ++k) v0[g + k] *= 5, dot += q0[g + k] * v0[g + k];
      for (int k = 0; k < 4; ++k) v0[g + k] -= dot * q0[g + k];
      // q_{n+1}, v_{n+1} at a_{n+1} + x: Newmark's increments outside the group, the
      // rotation update at its fixed point inside.
      auto kinematics = [&](const Eigen::VectorXd& x, std::vector<double>* q1,
                            std::vector<double>* v1, std::vector<double>* a) {
        a->assign(nq, 0.0);
        for (int i = 0; i < nq; ++i) (*a)[i] = a1[i] + x[i];
        q1->assign(nq, 0.0);
        v1->assign(nq, 0.0);
        for (int i = 0; i < nq; ++i) {
          (*q1)[i] = q0[i] + h * v0[i] + cq * x[i];
          (*v1)[i] = v0[i] + cv * x[i];
        }
        double in[L::kInputs], y[L::kOutputs];
        for (int k = 0; k < 4; ++k) {
          in[L::kE0 + k] = q0[g + k];
          in[L::kEd0 + k] = v0[g + k];
          in[L::kA0 + k] = a0[g + k];
          in[L::kA1 + k] = (*a)[g + k];
          in[L::kEIter + k] = q0[g + k];
        }
        for (int k = 0; k < 3; ++k) in[L::kWbar0 + k] = wbar0[k];
        for (int it = 0; it < 100; ++it) {
          HhtRotationMap(sc, h, r, in, y);
          double change = 0;
          for (int k = 0; k < 4; ++k) {
            change = std::max(change, std::abs(y[L::kE1 + k] - in[L::kEIter + k]));
            in[L::kEIter + k] = y[L::kE1 + k];
          }
          if (change == 0) break;
        }
        for (int k = 0; k < 4; ++k) {
          (*q1)[g + k] = y[L::kE1 + k];
          (*v1)[g + k] = y[L::kEd1 + k];
        }
      };
      auto residual = [&](const Eigen::VectorXd& x) {
        std::vector<double> q1, v1, a;
        kinematics(x, &q1, &v1, &a);
        Eigen::VectorXd l1(nc);
        for (int j = 0; j < nc; ++j) l1[j] = lam[j] + x[nq + j];
        return StepResidual(sys, t, q1, v1, a, l1, eq, alpha, cq);
      };
      // The matrix at the iterate, with the blocks at its fixed point e_{n+1}.
      std::vector<double> q1, v1, a;
      kinematics(Eigen::VectorXd::Zero(n), &q1, &v1, &a);
      double in[L::kInputs];
      for (int k = 0; k < 4; ++k) {
        in[L::kE0 + k] = q0[g + k];
        in[L::kEd0 + k] = v0[g + k];
        in[L::kA0 + k] = a0[g + k];
        in[L::kA1 + k] = a1[g + k];
        in[L::kEIter + k] = q1[g + k];
      }
      for (int k = 0; k < 3; ++k) in[L::kWbar0 + k] = wbar0[k];
      double de[16], ded[16], rot[32];
      HhtRotationDerivative(sc, h, r, in, de, ded);
      HhtRotationBlock(sc, h, de, ded, rot);
      std::vector<double> exact(newton.pattern().nnz()), first(newton.pattern().nnz());
      ASSERT_EQ(newton.Assemble(t, h, q1.data(), v1.data(), a1.data(), lam.data(),
                                exact.data(), nullptr, nullptr, rot),
                0);
      ASSERT_EQ(newton.Assemble(t, h, q1.data(), v1.data(), a1.data(), lam.data(), first.data()), 0);
      const Eigen::MatrixXd J_fd = CentralDifferences(residual, n, 1e-3);
      const double scale = J_fd.cwiseAbs().maxCoeff();
      const double err = (Dense(newton.pattern(), exact) - J_fd).cwiseAbs().maxCoeff() / scale;
      const double err1 = (Dense(newton.pattern(), first) - J_fd).cwiseAbs().maxCoeff() / scale;
      std::cout << "  relative error of the Newton matrix: exact blocks " << err
                << ", first order " << err1 << "\n";
      EXPECT_LT(err, 1e-7);
      EXPECT_GT(err1, 1e-4);  // the blocks matter here (h |omega| ~ 0.5)
    }
  }
}

// HhtRotationDerivative, written out by the chain rule, against forward-mode AutoDiff of
// HhtRotationMap with the fixed point resolved the same way, on random inputs in both
// forms, at large angles and on the small-angle branch (|theta|^2 <= 1e-16).
TEST(HhtRotationDerivative, MatchesAutoDiffOfTheMap) {
  using L = HhtRotationLayout;
  using AD = Eigen::AutoDiffScalar<Eigen::Matrix<double, 8, 1>>;
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> u(-1, 1);
  double worst = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const HhtRotationScheme sc = HhtRotationScheme::Of(trial % 4 < 2 ? -0.2 : 0.0, trial % 2 == 0);
    const bool tiny = trial >= 30;  // theta ~ 1e-9: the series branch
    const double h = tiny ? 1e-5 : 0.05 * (1 + trial % 3), r = 1.2;
    double x[L::kInputs];
    for (double& v : x) v = u(rng);
    if (tiny) {
      for (int k = 0; k < 4; ++k) x[L::kEd0 + k] = 0;
      for (int k = 0; k < 19; ++k)
        if (k >= L::kA0) x[k] *= 1e-1;
      for (int k = 0; k < 3; ++k) x[L::kWbar0 + k] = 0;
      for (int k = 0; k < 4; ++k) x[L::kA0 + k] = 0;
    }
    double de[16], ded[16];
    HhtRotationDerivative(sc, h, r, x, de, ded);
    AD xa[L::kInputs], y[L::kOutputs];
    for (int i = 0; i < L::kInputs; ++i) xa[i] = AD(x[i], Eigen::Matrix<double, 8, 1>::Zero());
    for (int k = 0; k < 4; ++k) {
      xa[L::kA1 + k].derivatives()[k] = 1;
      xa[L::kEIter + k].derivatives()[4 + k] = 1;
    }
    HhtRotationMap(sc, h, r, xa, y);
    Eigen::Matrix<double, 8, 8> J;
    for (int i = 0; i < 8; ++i) J.row(i) = y[L::kE1 + i].derivatives().transpose();
    const Eigen::Matrix4d A = Eigen::Matrix4d::Identity() - J.block<4, 4>(0, 4);
    const Eigen::Matrix4d de_ad = A.partialPivLu().solve(J.block<4, 4>(0, 0));
    const Eigen::Matrix4d ded_ad = J.block<4, 4>(4, 0) + J.block<4, 4>(4, 4) * de_ad;
    const double scale_e = de_ad.cwiseAbs().maxCoeff(), scale_v = ded_ad.cwiseAbs().maxCoeff();
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        worst = std::max(worst, std::abs(de[4 * i + j] - de_ad(i, j)) / scale_e);
        worst = std::max(worst, std::abs(ded[4 * i + j] - ded_ad(i, j)) / scale_v);
      }
  }
  std::cout << "  largest relative difference to AutoDiff: " << worst << "\n";
  EXPECT_LT(worst, 1e-12);
}

// The map split for the Newton iteration (HhtRotationStartOf once per step,
// HhtRotationIterate per iterate) gives HhtRotationMap's numbers to the last bit, in both
// forms, with r != 1, several iterates per start, and on the small-angle branch; a
// different a_{n+1} changes them (the split reads its inputs).
TEST(HhtRotation, SplitMapIsTheMap) {
  using L = HhtRotationLayout;
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> u(-1, 1);
  int compared = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const HhtRotationScheme sc = HhtRotationScheme::Of(trial % 4 < 2 ? -0.2 : -0.05, trial % 2 == 0);
    const bool tiny = trial >= 30;
    const double h = tiny ? 1e-6 : 0.01 * (1 + trial % 5), r = trial % 3 == 0 ? 1.0 : 0.7;
    double x[L::kInputs];
    for (double& v : x) v = u(rng);
    if (tiny)
      for (int k = L::kEd0; k < L::kInputs; ++k) x[k] *= 1e-3;
    HhtRotationStart st;
    HhtRotationStartOf(sc, h, r, x, &st);
    for (int it = 0; it < 3; ++it) {
      for (int k = 0; k < 4; ++k) {
        x[L::kA1 + k] = u(rng);
        x[L::kEIter + k] = x[L::kE0 + k] + 0.01 * u(rng);
      }
      double y[L::kOutputs], ys[L::kOutputs];
      HhtRotationMap(sc, h, r, x, y);
      HhtRotationIterate(sc, h, st, x + L::kE0, x + L::kA1, x + L::kEIter, ys);
      for (int k = 0; k < L::kOutputs; ++k) EXPECT_EQ(ys[k], y[k]) << "trial " << trial << ", output " << k;
      ++compared;
      x[L::kA1] += 0.5;
      HhtRotationIterate(sc, h, st, x + L::kE0, x + L::kA1, x + L::kEIter, ys);
      EXPECT_NE(ys[L::kWbar1], y[L::kWbar1]);
    }
  }
  EXPECT_EQ(compared, 120);
}

// A Newton matrix with room for the blocks but assembled without them is the
// first-order matrix: the same values at the first-order pattern's entries, zeros at
// the rest.
TEST(HhtNewtonMatrix, RoomForRotationBlocksLeavesTheFirstOrderMatrix) {
  FreeBodySystem sys(2.0, {0.7, 1.3, 2.1}, {0.1, -0.2, 0.3}, {0.4, -0.5, 0.6});
  HhtOptions opt;
  opt.alpha = -0.1;
  HhtNewtonMatrix plain(sys, opt), room(sys, opt, /*rotation_blocks=*/true);
  EXPECT_FALSE(plain.has_rotation_blocks());
  EXPECT_TRUE(room.has_rotation_blocks());
  opt.modified = false;
  EXPECT_FALSE(HhtNewtonMatrix(sys, opt, true).has_rotation_blocks());  // classical: exact already
  std::vector<double> q = {0.1, 0.2, 0.3, 0.5, 0.5, 0.5, 0.5}, v = {1, -1, 2, 0.1, -0.2, 0.3, -0.2},
                      a = {0.3, 0.1, -0.2, 0.4, 0.1, -0.3, -0.2}, lam = {0.7};
  std::vector<double> x(plain.pattern().nnz()), y(room.pattern().nnz());
  ASSERT_EQ(plain.Assemble(0.1, 0.01, q.data(), v.data(), a.data(), lam.data(), x.data()), 0);
  ASSERT_EQ(room.Assemble(0.1, 0.01, q.data(), v.data(), a.data(), lam.data(), y.data()), 0);
  EXPECT_EQ((Dense(plain.pattern(), x) - Dense(room.pattern(), y)).cwiseAbs().maxCoeff(), 0.0);
  double rot[32] = {0};
  EXPECT_THROW(plain.Assemble(0.1, 0.01, q.data(), v.data(), a.data(), lam.data(), x.data(),
                              nullptr, nullptr, rot),
               std::logic_error);
}

// The free body's equations reproduce Euler's equations: J omega' + omega x J omega = n.
TEST(FreeBodySystem, ConsistentAccelerationGivesEulerEquations) {
  const std::array<double, 3> J = {0.7, 1.3, 2.1}, n = {0.4, -0.5, 0.6};
  FreeBodySystem sys(2.0, J, {0, 0, 0}, n);
  // Unit e, and e' = G(e)^T omega / 2 for a chosen body angular velocity.
  std::vector<double> q = {0, 0, 0, 0.5, 0.5, -0.5, 0.5}, v(7, 0.0);
  const double w[3] = {0.3, -1.1, 0.8};
  FreeBodySystem::Gt(&q[3], w, &v[3]);
  for (int k = 3; k < 7; ++k) v[k] *= 0.5;
  const State s = ConsistentState(sys, q, v);
  // omega' = 2 G(e) e'' (G(e') e' = 0).
  double dw[3];
  FreeBodySystem::Gx(&q[3], &s.a[3], dw);
  for (double& x : dw) x *= 2;
  const double Jw[3] = {J[0] * w[0], J[1] * w[1], J[2] * w[2]};
  const double cross[3] = {w[1] * Jw[2] - w[2] * Jw[1], w[2] * Jw[0] - w[0] * Jw[2],
                           w[0] * Jw[1] - w[1] * Jw[0]};
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(J[k] * dw[k] + cross[k], n[k], 1e-12) << k;
}

// ---------------------------------------------------------------------------------
// Pendulum reference: theta'' = -(g/L) sin(theta), theta from the downward vertical,
// integrated with classical RK4 at 200000 steps (tests/support/pendulum_reference.h);
// x = L sin(theta), y = -L cos(theta).
std::array<double, 2> PendulumReference(double L, double g, double theta0, double t_end) {
  const double th = testing::PendulumAngleRk4(theta0, 0.0, g / L, t_end, 200000);
  return {L * std::sin(th), -L * std::cos(th)};
}

// output_every > 0: AdvanceTo every output_every * h (the integrator shortens steps to
// land on the output times, so the step size changes all the time).
double PendulumError(double alpha, double h, const std::array<double, 2>& ref,
                     Summary* summary = nullptr, double output_every = 0,
                     HhtOptions::Form form = HhtOptions::Form::kEquilibrium) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  HhtOptions opt;
  opt.alpha = alpha;
  opt.step = h;
  opt.form = form;
  opt.newton_tolerance = 1e-13;
  auto integ = MakeHhtIntegrator(sys, opt);
  integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
  if (output_every > 0)
    for (int k = 1; k * output_every * h < 1.0; ++k)
      EXPECT_TRUE(integ->AdvanceTo(k * output_every * h)) << integ->summary().BriefReport();
  EXPECT_TRUE(integ->AdvanceTo(1.0)) << integ->summary().BriefReport();
  EXPECT_EQ(integ->state().t, 1.0);
  if (summary) *summary = integ->summary();
  return std::hypot(integ->state().q[0] - ref[0], integ->state().q[1] - ref[1]);
}

class HhtOrder : public ::testing::TestWithParam<double> {};

TEST_P(HhtOrder, PendulumPositionErrorIsSecondOrder) {
  const auto ref = PendulumReference(1.0, 9.81, M_PI / 2, 1.0);
  const double alpha = GetParam();
  double prev = 0;
  for (int k = 0; k < 5; ++k) {
    const double h = 0.01 / (1 << k);
    const double err = PendulumError(alpha, h, ref);
    if (k > 0) {
      const double ratio = prev / err;
      EXPECT_NEAR(ratio, 4.0, 0.4) << "alpha = " << alpha << ", h = " << h << ", errors "
                                   << prev << " -> " << err;
    }
    prev = err;
  }
}

// Output times every 2.5 steps: steps of h, h, h/2 in turn. The equilibrium form rescales
// abar_n - a_n with the step (docs/hht.md), so it stays second order and as accurate as
// with a constant step; without that rescaling the error was 25 times larger (measured
// on examples/pendulum.yaml, 10 s, h = 1e-3) and first order.
TEST_P(HhtOrder, SecondOrderWhenOutputTimesChangeTheStep) {
  const auto ref = PendulumReference(1.0, 9.81, M_PI / 2, 1.0);
  const double alpha = GetParam();
  double prev = 0;
  for (int k = 0; k < 4; ++k) {
    const double h = 0.01 / (1 << k);
    const double err = PendulumError(alpha, h, ref, nullptr, 2.5);
    const double err_constant = PendulumError(alpha, h, ref);
    EXPECT_LT(err, 2 * err_constant) << "alpha = " << alpha << ", h = " << h;
    if (k > 0)
      EXPECT_NEAR(prev / err, 4.0, 0.6) << "alpha = " << alpha << ", h = " << h;
    prev = err;
  }
}

INSTANTIATE_TEST_SUITE_P(Alphas, HhtOrder, ::testing::Values(0.0, -0.1, -0.3));

// ---------------------------------------------------------------------------------
// Free body under a constant moment about a principal axis: omega = n t / J.

double SpinUpError(double alpha, bool modified, double* omega_end = nullptr,
                   HhtOptions::Form form = HhtOptions::Form::kEquilibrium) {
  const double J3 = 2.0, n3 = 0.5, t_end = 10.0;
  FreeBodySystem sys(1.5, {1.0, 1.5, J3}, {0, 0, 0}, {0, 0, n3});
  HhtOptions opt;
  opt.form = form;
  opt.alpha = alpha;
  opt.step = 0.01;
  opt.modified = modified;
  opt.newton_tolerance = 1e-13;
  auto integ = MakeHhtIntegrator(sys, opt);
  integ->Initialize(ConsistentState(sys, {0, 0, 0, 1, 0, 0, 0}, std::vector<double>(7, 0.0)));
  EXPECT_TRUE(integ->AdvanceTo(t_end)) << integ->summary().BriefReport();
  const State& s = integ->state();
  const auto w = FreeBodySystem::Omega(&s.q[3], &s.v[3]);
  const double exact = n3 * t_end / J3;
  // Only the axis component may be non-zero.
  EXPECT_NEAR(w[0], 0.0, 1e-12);
  EXPECT_NEAR(w[1], 0.0, 1e-12);
  if (omega_end) *omega_end = w[2];
  return std::abs(w[2] - exact) / exact;
}

TEST(HhtModified, ConstantMomentSpinUpIsExactForAlphaZero) {
  double w_mod = 0, w_cls = 0;
  const double e_mod = SpinUpError(0.0, true, &w_mod);
  const double e_cls = SpinUpError(0.0, false, &w_cls);
  EXPECT_LT(e_mod, 1e-9) << "modified omega(10) = " << w_mod;
  // Classical Newmark on Euler parameters spins up too slowly.
  EXPECT_GT(e_cls, 1e-5) << "classical omega(10) = " << w_cls;
  EXPECT_LT(w_cls, 2.5);
  ::testing::Test::RecordProperty("modified_rel_error", std::to_string(e_mod));
  ::testing::Test::RecordProperty("classical_rel_error", std::to_string(e_cls));
  std::printf("alpha = 0: relative omega error modified %.3e, classical %.3e\n", e_mod, e_cls);
}

// In the equilibrium form J omegabar' mixes exact equilibria n/J, so the modified
// spin-up stays exact with numerical damping too (measured 3.8e-12 and 1.2e-11); the
// classical scheme keeps its artificial damping (7.9e-5, 9.5e-5).
TEST(HhtModified, SpinUpIsExactWithDampingInTheEquilibriumForm) {
  for (double alpha : {-0.1, -0.3}) {
    const double e_mod = SpinUpError(alpha, true);
    const double e_cls = SpinUpError(alpha, false);
    std::printf("alpha = %.1f: relative omega error modified %.3e, classical %.3e\n", alpha,
                e_mod, e_cls);
    EXPECT_LT(e_mod, 1e-9) << "alpha = " << alpha;
    EXPECT_GT(e_cls, 1e-5) << "alpha = " << alpha;
  }
}

// In the form of Negrut et al. the modification still beats the classical scheme, but is
// not exact for alpha < 0 (the mixed forces meet a mass matrix taken at t_{n+1} only).
TEST(HhtModified, ModifiedBeatsClassicalWithDampingInTheNegrutForm) {
  for (double alpha : {-0.1, -0.3}) {
    const double e_mod = SpinUpError(alpha, true, nullptr, HhtOptions::Form::kNegrut);
    const double e_cls = SpinUpError(alpha, false, nullptr, HhtOptions::Form::kNegrut);
    std::printf("negrut form, alpha = %.1f: relative omega error modified %.3e, classical %.3e\n",
                alpha, e_mod, e_cls);
    EXPECT_LT(e_mod, e_cls) << "alpha = " << alpha;
  }
}

// ---------------------------------------------------------------------------------

TEST(HhtAdaptive, MeetsToleranceRoughlyAndLooserTakesFewerSteps) {
  const auto ref = PendulumReference(1.0, 9.81, M_PI / 2, 1.0);
  long steps[2];
  double errs[2];
  const double tols[2] = {1e-4, 1e-6};
  for (int i = 0; i < 2; ++i) {
    PendulumSystem sys(1.0, 1.0, 9.81);
    HhtOptions opt;
    opt.alpha = -0.1;
    opt.adaptive = true;
    opt.tolerance = tols[i];
    opt.step = 1e-4;
    auto integ = MakeHhtIntegrator(sys, opt);
    integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
    ASSERT_TRUE(integ->AdvanceTo(1.0)) << integ->summary().BriefReport();
    EXPECT_EQ(integ->state().t, 1.0);
    steps[i] = integ->summary().steps_accepted;
    errs[i] = std::hypot(integ->state().q[0] - ref[0], integ->state().q[1] - ref[1]);
    std::printf("tol %.0e: %s, error %.3e\n", tols[i], integ->summary().BriefReport().c_str(),
                errs[i]);
    // The tolerance bounds the local position error of each step; the global error
    // (which also collects the velocity errors the estimate does not see) stays within
    // a small multiple of the sum of the local tolerances (measured: about 1x), and is
    // not absurdly smaller than one of them.
    EXPECT_LT(errs[i], 3 * steps[i] * tols[i]);
    EXPECT_GT(errs[i], tols[i]);
  }
  EXPECT_LT(steps[0], steps[1]);
  // 100 times tighter local tolerance: global error at least 5 times smaller.
  EXPECT_LT(errs[1], errs[0] / 5);
}

TEST(Hht, RepeatedRunsAreIdenticalAndHitTheTarget) {
  FreeBodySystem sys(1.5, {1.0, 1.5, 2.0}, {0.1, 0, 0}, {0.3, 0.2, 0.5});
  HhtOptions opt;
  opt.step = 0.3;  // 1.0 / 0.3 leaves a remainder: the last steps are adjusted
  opt.alpha = -0.2;
  auto integ = MakeHhtIntegrator(sys, opt);
  std::vector<double> v(7, 0.0);
  v[4] = 0.5;  // e' = (0, 0.5, 0, 0) at e = (1,0,0,0): spin about body x
  const State x0 = ConsistentState(sys, {0, 0, 0, 1, 0, 0, 0}, v);
  State first;
  Summary s1;
  for (int run = 0; run < 2; ++run) {
    integ->Initialize(x0);
    ASSERT_TRUE(integ->AdvanceTo(0.5));
    EXPECT_EQ(integ->state().t, 0.5);
    ASSERT_TRUE(integ->AdvanceTo(1.0));
    EXPECT_EQ(integ->state().t, 1.0);
    if (run == 0) {
      first = integ->state();
      s1 = integ->summary();
    } else {
      EXPECT_EQ(integ->state().q, first.q);
      EXPECT_EQ(integ->state().v, first.v);
      EXPECT_EQ(integ->state().a, first.a);
      EXPECT_EQ(integ->state().lambda, first.lambda);
      EXPECT_EQ(integ->summary().steps_accepted, s1.steps_accepted);
      EXPECT_EQ(integ->summary().newton_iterations, s1.newton_iterations);
      EXPECT_EQ(integ->summary().factorizations, s1.factorizations);
    }
  }
  EXPECT_EQ(integ->summary().status, Summary::Status::kDone);
  // Normalisation holds.
  const auto& q = integ->state().q;
  EXPECT_NEAR(q[3] * q[3] + q[4] * q[4] + q[5] * q[5] + q[6] * q[6], 1.0, 1e-9);
}

TEST(Hht, ReusesTheNewtonMatrixAcrossSteps) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  HhtOptions opt;
  opt.step = 1e-3;
  auto integ = MakeHhtIntegrator(sys, opt);
  integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
  ASSERT_TRUE(integ->AdvanceTo(0.5));
  const Summary& s = integ->summary();
  EXPECT_EQ(s.steps_accepted, 500);
  EXPECT_LT(s.factorizations, s.steps_accepted);
  EXPECT_EQ(s.steps_rejected, 0);
}

// A refresh of the Newton matrix evaluates the system at the step's first iterate, and that
// evaluation also gives the first residual: in the equilibrium form a step costs the system
// one evaluation per residual, refresh or not (one more per refresh before). With the
// refresh by cost on (jacobian_cost 3) there are many refreshes; the run is the same with
// the counting wrapper.
class CountingPendulum : public PendulumSystem {
 public:
  CountingPendulum() : PendulumSystem(1.0, 1.0, 9.81) {}
  int Evaluate(const EvalInput& in, EvalOutput& out) override {
    ++calls;
    return PendulumSystem::Evaluate(in, out);
  }
  long calls = 0;
};

TEST(Hht, ARefreshGivesTheFirstResidualItsEvaluation) {
  CountingPendulum sys;
  HhtOptions opt;
  opt.step = 1e-3;
  opt.jacobian_cost = 3;
  auto integ = MakeHhtIntegrator(sys, opt);
  integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
  const long before = sys.calls;
  const Summary at_start = integ->summary();
  ASSERT_TRUE(integ->AdvanceTo(0.5));
  const Summary& s = integ->summary();
  const long residuals = s.residual_evaluations - at_start.residual_evaluations;
  const long refreshes = s.jacobian_evaluations - at_start.jacobian_evaluations;
  EXPECT_EQ(s.steps_rejected, 0);
  EXPECT_GT(refreshes, 50);
  EXPECT_EQ(sys.calls - before, residuals);
}

// x^2 + y^2 + L^2 = 0 has no solution: Newton fails at every step size.
class ImpossiblePendulum : public PendulumSystem {
 public:
  ImpossiblePendulum() : PendulumSystem(1.0, 1.0, 9.81) {}
  int Evaluate(const EvalInput& in, EvalOutput& out) override {
    const int rc = PendulumSystem::Evaluate(in, out);
    if (out.constraint) out.constraint[0] += 2 * L_ * L_;
    return rc;
  }
};

TEST(Hht, ImpossibleConstraintFailsWithAMessage) {
  ImpossiblePendulum sys;
  HhtOptions opt;
  opt.step = 1e-2;
  opt.min_step = 1e-6;
  auto integ = MakeHhtIntegrator(sys, opt);
  State x0;
  x0.Resize(2, 1);
  x0.q = {1.0, 0.0};
  integ->Initialize(x0);
  EXPECT_FALSE(integ->AdvanceTo(1.0));
  const Summary& s = integ->summary();
  EXPECT_EQ(s.status, Summary::Status::kFailed);
  EXPECT_NE(s.message.find("min_step"), std::string::npos) << s.message;
  EXPECT_EQ(s.t_reached, 0.0);
  EXPECT_EQ(integ->state().t, 0.0);
  EXPECT_GE(s.steps_rejected, 13);  // 1e-2 halved below 1e-6
  EXPECT_NE(s.BriefReport().find("FAILED"), std::string::npos);
}

// A collapsing step size ends the call with a message instead of crawling on: here a
// tolerance no step above 1e-5 can meet, with a budget of 5 attempts beyond the 1000 the
// nominal step needs.
TEST(Hht, StepBudgetStopsACollapsedStepWithAMessage) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  HhtOptions opt;
  opt.step = 1e-3;
  opt.adaptive = true;
  opt.tolerance = 1e-13;
  opt.max_steps_per_call = 5;
  auto integ = MakeHhtIntegrator(sys, opt);
  integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
  EXPECT_FALSE(integ->AdvanceTo(1.0));
  EXPECT_EQ(integ->summary().status, Summary::Status::kFailed);
  EXPECT_NE(integ->summary().message.find("1005 step attempts"), std::string::npos)
      << integ->summary().message;
  EXPECT_LT(integ->summary().t_reached, 1.0);
  // The same run without the budget's limit is not stopped by it.
  opt.max_steps_per_call = 0;
  opt.tolerance = 1e-8;
  auto ok = MakeHhtIntegrator(sys, opt);
  ok->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
  EXPECT_TRUE(ok->AdvanceTo(1.0)) << ok->summary().message;
}

// A looser Newton threshold (HhtOptions::newton_tolerance) takes fewer iterations per
// step, and leaves in every step an error that the run accumulates. On the pendulum at
// h = 1e-3 (position error 7.4e-6 m at t = 1 s against the RK4 reference): 1e-10 ends
// 1.4e-8 m from the default run (its error 0.2 % off), 1e-8 ends 2.6e-6 m from it (35 %):
// the threshold must stay well below what the step size makes of the error.
TEST(Hht, LooserNewtonToleranceTakesFewerIterationsAndCostsAccuracy) {
  const auto ref = PendulumReference(1.0, 9.81, M_PI / 2, 1.0);
  auto run = [&](double tol, Summary* s) {
    PendulumSystem sys(1.0, 1.0, 9.81);
    HhtOptions opt;
    opt.step = 1e-3;
    opt.newton_tolerance = tol;
    auto integ = MakeHhtIntegrator(sys, opt);
    integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
    EXPECT_TRUE(integ->AdvanceTo(1.0)) << integ->summary().BriefReport();
    *s = integ->summary();
    return std::array<double, 2>{integ->state().q[0], integ->state().q[1]};
  };
  Summary s12, s10, s8;
  const auto q12 = run(1e-12, &s12), q10 = run(1e-10, &s10), q8 = run(1e-8, &s8);
  EXPECT_LT(s10.newton_iterations, 0.8 * s12.newton_iterations);
  EXPECT_LT(s8.newton_iterations, 0.8 * s10.newton_iterations);
  EXPECT_EQ(s8.steps_rejected, 0);
  const double e12 = std::hypot(q12[0] - ref[0], q12[1] - ref[1]);
  EXPECT_GT(e12, 5e-6);
  const double d10 = std::hypot(q10[0] - q12[0], q10[1] - q12[1]);
  const double d8 = std::hypot(q8[0] - q12[0], q8[1] - q12[1]);
  EXPECT_LT(d10, 1e-7);
  EXPECT_NEAR(std::hypot(q10[0] - ref[0], q10[1] - ref[1]), e12, 1e-2 * e12);
  EXPECT_GT(d8, 10 * d10);
  std::printf("pendulum h = 1e-3: error %.4e m; Newton iterations %d (1e-12), %d (1e-10), %d "
              "(1e-8); end differs by %.2e and %.2e m\n",
              e12, s12.newton_iterations, s10.newton_iterations, s8.newton_iterations, d10, d8);
}

TEST(Hht, InvalidOptionsAreRejected) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  HhtOptions opt;
  std::string err;
  EXPECT_TRUE(opt.IsValid(&err));
  opt.alpha = 0.2;
  EXPECT_FALSE(opt.IsValid(&err));
  EXPECT_NE(err.find("alpha"), std::string::npos);
  EXPECT_THROW(MakeHhtIntegrator(sys, opt), std::invalid_argument);
  opt = HhtOptions();
  opt.step = -1;
  EXPECT_THROW(MakeHhtIntegrator(sys, opt), std::invalid_argument);
  for (double tol : {0.0, -1e-8, 1.0, std::nan("")}) {
    opt = HhtOptions();
    opt.newton_tolerance = tol;
    EXPECT_FALSE(opt.IsValid(&err)) << tol;
    EXPECT_EQ(err, "HhtOptions: newton_tolerance must be in (0, 1)");
  }
  opt = HhtOptions();
  auto integ = MakeHhtIntegrator(sys, opt);
  State bad;
  bad.Resize(3, 1);
  EXPECT_THROW(integ->Initialize(bad), std::invalid_argument);
}

}  // namespace
}  // namespace mbdae::dae

namespace mbdae::dae {
namespace {

// General tumbling motion (reference: the same scheme at a 16 times smaller step than
// the finest one compared). Returns q and v at t = 1.
// At the origin, unrotated, tumbling with body angular velocity (1, 0.5, -0.7) rad/s
// (e' = G^T omega / 2), made consistent.
State TumblingStart(FreeBodySystem& sys) {
  std::vector<double> v(7, 0.0);
  const double w[3] = {1.0, 0.5, -0.7};
  const std::vector<double> q = {0, 0, 0, 1, 0, 0, 0};
  FreeBodySystem::Gt(&q[3], w, &v[3]);
  for (int k = 3; k < 7; ++k) v[k] *= 0.5;
  return ConsistentState(sys, q, v);
}

std::pair<std::vector<double>, std::vector<double>> Tumble(double h, bool modified, double alpha,
                                                           HhtOptions::Form form) {
  FreeBodySystem sys(1.5, {1.0, 1.5, 2.0}, {0, 0, 0}, {0.3, -0.2, 0.5});
  HhtOptions opt;
  opt.alpha = alpha;
  opt.step = h;
  opt.modified = modified;
  opt.form = form;
  opt.newton_tolerance = 1e-11;
  auto integ = MakeHhtIntegrator(sys, opt);
  integ->Initialize(TumblingStart(sys));
  EXPECT_TRUE(integ->AdvanceTo(1.0)) << integ->summary().BriefReport();
  return {integ->state().q, integ->state().v};
}

// Error ratios per halving of h (h = 0.02 ... 0.0025) of the Euler parameters and their
// derivatives at t = 1.
void TumbleRatios(bool modified, double alpha, HhtOptions::Form form, std::vector<double>* rq,
                  std::vector<double>* rv) {
  const auto ref = Tumble(0.02 / 128, modified, alpha, form);
  double pq = 0, pv = 0;
  for (int k = 0; k < 4; ++k) {
    const auto x = Tumble(0.02 / (1 << k), modified, alpha, form);
    double eq = 0, ev = 0;
    for (int i = 3; i < 7; ++i) {
      eq = std::max(eq, std::abs(x.first[i] - ref.first[i]));
      ev = std::max(ev, std::abs(x.second[i] - ref.second[i]));
    }
    if (k > 0) {
      rq->push_back(pq / eq);
      rv->push_back(pv / ev);
    }
    pq = eq;
    pv = ev;
  }
}

// The equilibrium form (generalized-alpha with HHT's parameters) is second order in q and
// v for every alpha, classical and modified, although M(q) = 4 G^T J G depends on q.
TEST(HhtEquilibriumForm, TumblingBodyIsSecondOrderInPositionsAndVelocities) {
  for (bool modified : {true, false}) {
    for (double alpha : {0.0, -0.1, -0.3}) {
      std::vector<double> rq, rv;
      TumbleRatios(modified, alpha, HhtOptions::Form::kEquilibrium, &rq, &rv);
      for (size_t k = 0; k < rq.size(); ++k) {
        // Ratio 4 +- 0.6 per halving: observed order 2 +- 0.2.
        EXPECT_NEAR(rq[k], 4.0, 0.6) << (modified ? "modified" : "classical") << " alpha "
                                     << alpha << " q, halving " << k + 1;
        EXPECT_NEAR(rv[k], 4.0, 0.6) << (modified ? "modified" : "classical") << " alpha "
                                     << alpha << " v, halving " << k + 1;
      }
    }
  }
}

// The residual of Negrut et al. 2007 mixes the forces at t_n and t_{n+1} but not the
// inertia: with M(q) it is second order only for alpha = 0 and first order (ratio about
// 2.05) for alpha < 0, classical and modified alike (docs/hht.md explains why).
TEST(HhtNegrutForm, TumblingBodyIsFirstOrderForNegativeAlpha) {
  for (bool modified : {true, false}) {
    for (double alpha : {0.0, -0.3}) {
      std::vector<double> rq, rv;
      TumbleRatios(modified, alpha, HhtOptions::Form::kNegrut, &rq, &rv);
      for (size_t k = 0; k < rq.size(); ++k) {
        const double expected = alpha == 0.0 ? 4.0 : 2.0;
        EXPECT_NEAR(rq[k], expected, expected == 4.0 ? 0.5 : 0.3)
            << (modified ? "modified" : "classical") << " alpha " << alpha << " halving " << k;
      }
    }
  }
}

// ---------------------------------------------------------------------------------
// Dense output (HhtOptions::dense_output, docs/hht.md "Dense output").

// An adaptive pendulum run with dense output: targets every `every` s up to 1 s; the
// state at each target and the run's counters.
struct DenseRun {
  std::vector<State> rows;
  Summary summary;
};

DenseRun DensePendulum(double every, bool adaptive, double step, double stop_time,
                       bool dense = true) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  HhtOptions opt;
  opt.alpha = -0.1;
  opt.adaptive = adaptive;
  opt.tolerance = 1e-6;
  opt.step = step;
  opt.newton_tolerance = 1e-13;
  opt.dense_output = dense;
  opt.stop_time = stop_time;
  auto integ = MakeHhtIntegrator(sys, opt);
  integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
  DenseRun r;
  const int n = static_cast<int>(std::lround(1.0 / every));
  for (int k = 1; k <= n; ++k) {
    const double t = static_cast<double>(k) / n;
    EXPECT_TRUE(integ->AdvanceTo(t)) << integ->summary().BriefReport();
    EXPECT_EQ(integ->state().t, t);
    r.rows.push_back(integ->state());
  }
  r.summary = integ->summary();
  return r;
}

// The steps do not depend on the output times: rows every 0.01 s and every 0.1 s take
// the same steps, and their states at the common times are the same numbers.
TEST(HhtDenseOutput, StepsDoNotDependOnTheOutputTimes) {
  const DenseRun fine = DensePendulum(0.01, true, 1e-4, 1.0);
  const DenseRun coarse = DensePendulum(0.1, true, 1e-4, 1.0);
  EXPECT_EQ(fine.summary.steps_accepted, coarse.summary.steps_accepted);
  EXPECT_EQ(fine.summary.steps_rejected, coarse.summary.steps_rejected);
  for (int k = 1; k <= 10; ++k) {
    const State& a = fine.rows[10 * k - 1];
    const State& b = coarse.rows[k - 1];
    EXPECT_EQ(a.t, b.t);
    EXPECT_EQ(a.q, b.q) << "t = " << a.t;
    EXPECT_EQ(a.v, b.v) << "t = " << a.t;
    EXPECT_EQ(a.lambda, b.lambda) << "t = " << a.t;
  }
  // Without dense output the output step caps the step: more steps with rows every 0.01 s.
  const DenseRun hit = DensePendulum(0.01, true, 1e-4, 1.0, false);
  EXPECT_GT(hit.summary.steps_accepted, fine.summary.steps_accepted);
  std::printf("adaptive, tol 1e-6: %ld steps dense (both output steps), %ld landing on rows every 0.01 s\n",
              fine.summary.steps_accepted, hit.summary.steps_accepted);
}

// Fixed step h with rows every 1/27 s (mostly not step ends): the interpolated rows converge at second order, as the steps do, against the
// RK4 reference at each row time.
TEST(HhtDenseOutput, InterpolatedRowsAreSecondOrder) {
  const int n_rows = 27;
  std::vector<std::array<double, 2>> ref;
  for (int k = 1; k <= n_rows; ++k) ref.push_back(PendulumReference(1.0, 9.81, M_PI / 2, k / 27.0));
  double prev = 0;
  for (int j = 0; j < 4; ++j) {
    const double h = 0.01 / (1 << j);
    const DenseRun r = DensePendulum(1.0 / n_rows, false, h, 1.0);
    ASSERT_EQ(static_cast<int>(r.rows.size()), n_rows);
    double err = 0;
    for (int k = 0; k < n_rows; ++k)
      err = std::max(err, std::hypot(r.rows[k].q[0] - ref[k][0], r.rows[k].q[1] - ref[k][1]));
    // The constant step is kept: 1 / h steps (the last lands on the stop time).
    EXPECT_NEAR(static_cast<double>(r.summary.steps_accepted), 1.0 / h, 1.0) << "h = " << h;
    std::printf("h = %g: largest error of the 27 rows %.3e\n", h, err);
    if (j > 0) EXPECT_NEAR(prev / err, 4.0, 0.6) << "h = " << h << ", errors " << prev << " -> " << err;
    prev = err;
  }
}

// The rows of the step ends are the steps' states; the last step lands on the stop time,
// and no step passes it; a target beyond it fails with a message.
TEST(HhtDenseOutput, StopTimeIsLandedOnAndNotPassed) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  HhtOptions opt;
  opt.alpha = -0.1;
  opt.step = 0.08;
  opt.dense_output = true;
  opt.stop_time = 1.0;
  auto integ = MakeHhtIntegrator(sys, opt);
  double t_max = 0;
  integ->SetStepObserver([&t_max](const State& x, double) { t_max = std::max(t_max, x.t); });
  integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
  ASSERT_TRUE(integ->AdvanceTo(0.1));
  EXPECT_NEAR(t_max, 0.16, 1e-15);  // two steps of 0.08: the row is interpolated in the second
  ASSERT_TRUE(integ->AdvanceTo(1.0));
  EXPECT_EQ(t_max, 1.0);
  EXPECT_EQ(integ->state().t, 1.0);
  EXPECT_EQ(integ->summary().t_reached, 1.0);
  EXPECT_FALSE(integ->AdvanceTo(1.5));
  EXPECT_NE(integ->summary().message.find("beyond the stop time"), std::string::npos)
      << integ->summary().message;
}

// Euler parameters of interpolated rows are unit and their rates orthogonal to them.
TEST(HhtDenseOutput, InterpolatedEulerParametersAreUnit) {
  FreeBodySystem sys(1.5, {1.0, 1.5, 2.0}, {0.1, 0, 0}, {0.3, 0.2, 0.5});
  HhtOptions opt;
  opt.step = 0.05;
  opt.alpha = -0.2;
  opt.dense_output = true;
  auto integ = MakeHhtIntegrator(sys, opt);
  integ->Initialize(TumblingStart(sys));
  for (int k = 1; k <= 40; ++k) {
    ASSERT_TRUE(integ->AdvanceTo(k * 0.0123)) << integ->summary().BriefReport();
    const State& x = integ->state();
    double n = 0, dot = 0;
    for (int i = 3; i < 7; ++i) {
      n += x.q[i] * x.q[i];
      dot += x.q[i] * x.v[i];
    }
    EXPECT_NEAR(n, 1.0, 1e-14) << "t = " << x.t;
    EXPECT_NEAR(dot, 0.0, 1e-14) << "t = " << x.t;
  }
}

// The quadrature of an interpolated row is the integral of the integrand's linear
// interpolant: exact for an integrand linear in t (g = t, g = 1) at any row time.
TEST(HhtDenseOutput, QuadratureAtInterpolatedRows) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  HhtOptions opt;
  opt.alpha = -0.1;
  opt.adaptive = true;
  opt.tolerance = 1e-5;
  opt.dense_output = true;
  auto integ = MakeHhtIntegrator(sys, opt);
  Quadrature quad;
  quad.size = 2;
  quad.integrand = [](double t, const double*, const double*, const double*, const double*, double* g) {
    g[0] = t;
    g[1] = 1;
    return 0;
  };
  integ->SetQuadrature(quad);
  integ->Initialize(ConsistentState(sys, {1.0, 0.0}, {0.0, 0.0}));
  for (int k = 1; k <= 30; ++k) {
    const double t = k * 0.0333;
    ASSERT_TRUE(integ->AdvanceTo(t));
    EXPECT_NEAR(integ->quadrature()[0], 0.5 * t * t, 1e-14) << "t = " << t;
    EXPECT_NEAR(integ->quadrature()[1], t, 1e-14) << "t = " << t;
  }
}

TEST(HhtDenseOutput, SnapshotsAndReplayAreRefused) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  HhtOptions opt;
  opt.dense_output = true;
  auto integ = MakeHhtIntegrator(sys, opt);
  IntegratorSnapshot snap;
  EXPECT_THROW(integ->SaveSnapshot(&snap), std::logic_error);
  EXPECT_THROW(integ->RestoreSnapshot(snap), std::logic_error);
  opt.replay_steps = {0.1, 0.1};
  std::string err;
  EXPECT_FALSE(opt.IsValid(&err));
  EXPECT_NE(err.find("dense_output and replay_steps"), std::string::npos) << err;
}

}  // namespace
}  // namespace mbdae::dae
