// MultibodySystem: every emitted matrix against central finite differences of the
// vector it differentiates, on random states of random models with every element
// type; patterns; repeatability; measures; joint reactions; energies.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <new>
#include <cstdlib>
#include <random>

#include "dae/consistent.h"
#include "mbs/kinematics.h"
#include "mbs/system.h"
#include "tests/support/random_models.h"

#include "tests/support/count_allocations.h"

namespace mbdae::mbs {
namespace {

using dae::Matrix;
using Eigen::MatrixXd;
using Eigen::VectorXd;
using testing::MakeRandomState;
using testing::RandomModel;
using testing::RandomModelOptions;
using testing::RandomState;

// Everything Evaluate can produce at one point.
struct Outputs {
  VectorXd force, constraint, constraint_dt, acc_rhs;
  VectorXd force_quadratic_velocity, constraint_dtt;  // the optional outputs
  std::vector<double> matrix[dae::kNumMatrices];
  int code = 0;
};

Outputs EvaluateAll(MultibodySystem& sys, const double* q, const double* v, const double* a,
                    const double* w, double t = 0) {
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  Outputs o;
  o.force.setZero(nq);
  o.constraint.setZero(nc);
  o.constraint_dt.setZero(nc);
  o.acc_rhs.setZero(nc);
  o.force_quadratic_velocity.setConstant(nq, 12345.0);  // must be overwritten
  o.constraint_dtt.setConstant(nc, 12345.0);
  dae::EvalInput in;
  in.q = q; in.v = v; in.a = a; in.w = w;
  in.t = t;
  dae::EvalOutput out;
  out.force = o.force.data();
  out.constraint = o.constraint.data();
  out.constraint_dt = o.constraint_dt.data();
  out.acc_rhs = o.acc_rhs.data();
  out.force_quadratic_velocity = o.force_quadratic_velocity.data();
  out.constraint_dtt = o.constraint_dtt.data();
  for (int m = 0; m < dae::kNumMatrices; ++m) {
    // Fill with garbage: Evaluate must overwrite every entry.
    o.matrix[m].assign(sys.pattern(static_cast<Matrix>(m)).nnz(), 12345.0);
    out.matrix[m] = o.matrix[m].data();
  }
  o.code = sys.Evaluate(in, out);
  return o;
}

MatrixXd Dense(const dae::CscPattern& p, const std::vector<double>& val) {
  MatrixXd d = MatrixXd::Zero(p.rows, p.cols);
  for (int c = 0; c < p.cols; ++c)
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) d(p.row_index[k], c) = val[k];
  return d;
}

MatrixXd DenseOf(const MultibodySystem& sys, const Outputs& o, Matrix m) {
  return Dense(sys.pattern(m), o.matrix[static_cast<int>(m)]);
}

// Central differences of f around x.
MatrixXd FiniteDifferences(const std::function<VectorXd(const std::vector<double>&)>& f,
                           const std::vector<double>& x, double h = 1e-6) {
  const VectorXd f0 = f(x);
  MatrixXd j(f0.size(), x.size());
  for (size_t k = 0; k < x.size(); ++k) {
    std::vector<double> xp = x, xm = x;
    xp[k] += h;
    xm[k] -= h;
    j.col(k) = (f(xp) - f(xm)) / (2 * h);
  }
  return j;
}

// Largest relative error seen by the derivative test, by name, printed at its end.
std::map<std::string, double>& WorstErrors() {
  static std::map<std::string, double> worst;
  return worst;
}

double RelativeError(const MatrixXd& a, const MatrixXd& ref, const char* what = nullptr) {
  if (a.size() == 0) return 0;
  const double scale = std::max(1.0, ref.cwiseAbs().maxCoeff());
  const double err = (a - ref).cwiseAbs().maxCoeff() / scale;
  if (what) WorstErrors()[what] = std::max(WorstErrors()[what], err);
  return err;
}

constexpr double kTol = 1e-6;

Model DefaultRandomModel(unsigned seed) {
  std::mt19937 rng(seed);
  return RandomModel(rng);
}

TEST(MultibodySystem, SizesNamesAndPatterns) {
  const Model model = DefaultRandomModel(7);
  MultibodySystem sys(model);
  const int nb = static_cast<int>(model.bodies.size());
  int nj = 0;
  for (const Joint& j : model.joints)
    for (int b = 0; b < 6; ++b) nj += (j.locks >> b) & 1u;
  EXPECT_EQ(sys.num_coordinates(), 7 * nb);
  EXPECT_EQ(sys.num_constraints(), nj + nb);
  ASSERT_EQ(sys.coordinate_names().size(), 7u * nb);
  EXPECT_EQ(sys.coordinate_names()[0], "b0.x");
  EXPECT_EQ(sys.coordinate_names()[3], "b0.e0");
  EXPECT_EQ(sys.coordinate_names()[13], "b1.e3");
  ASSERT_EQ(sys.constraint_names().size(), static_cast<size_t>(nj + nb));
  // j0 is fixed: all six locks in the order x y z rx ry rz
  EXPECT_EQ(sys.constraint_names()[0], "j0.x");
  EXPECT_EQ(sys.constraint_names()[5], "j0.rz");
  EXPECT_EQ(sys.constraint_joint()[5], 0);
  EXPECT_EQ(sys.constraint_names()[nj], "b0.euler_norm");
  EXPECT_EQ(sys.constraint_joint()[nj], -1);
  ASSERT_EQ(sys.quaternion_offsets().size(), static_cast<size_t>(nb));
  EXPECT_EQ(sys.quaternion_offsets()[1], 10);
  for (int m = 0; m < dae::kNumMatrices; ++m) {
    std::string err;
    EXPECT_TRUE(sys.pattern(static_cast<Matrix>(m)).IsValid(&err)) << m << ": " << err;
    const bool crows = m == static_cast<int>(Matrix::kConstraintDq) ||
                       m == static_cast<int>(Matrix::kConstraintVelDq);
    EXPECT_EQ(sys.pattern(static_cast<Matrix>(m)).rows, crows ? nj + nb : 7 * nb);
    EXPECT_EQ(sys.pattern(static_cast<Matrix>(m)).cols, 7 * nb);
  }
  // a normalisation row touches only its body's four Euler parameters
  const dae::CscPattern& cq = sys.pattern(Matrix::kConstraintDq);
  int count = 0;
  for (int k = 0; k < cq.nnz(); ++k) count += cq.row_index[k] == nj;
  EXPECT_EQ(count, 4);
  EXPECT_GE(cq.find(nj, 3), 0);
  EXPECT_EQ(cq.find(nj, 0), -1);
  // the mass matrix: 3 + 16 entries per body
  EXPECT_EQ(sys.pattern(Matrix::kMass).nnz(), 19 * nb);
}

// The acceptance test of the multibody layer: every analytic derivative matches central
// differences on random states of random models.
TEST(MultibodySystem, DerivativesMatchFiniteDifferences) {
  for (unsigned seed = 1; seed <= 6; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937 rng(seed);
    RandomModelOptions opt;
    opt.bodies = 2 + seed % 3;
    opt.expression_forces = true;  // values over measures, t and splines
    opt.motion_gear = seed % 2 == 0;  // rheonomic motion constraints and a gear
    opt.bushings = true;
    const Model model = RandomModel(rng, opt);
    MultibodySystem sys(model);
    const int nq = sys.num_coordinates(), nc = sys.num_constraints();
    for (int trial = 0; trial < 2; ++trial) {
      const RandomState s = MakeRandomState(rng, model, nc);
      const double t = 0.37 + 0.41 * trial;
      const Outputs o = EvaluateAll(sys, s.q.data(), s.v.data(), s.a.data(), s.w.data(), t);
      ASSERT_EQ(o.code, 0) << sys.last_error();
      auto at_q = [&](const std::vector<double>& q) {
        return EvaluateAll(sys, q.data(), s.v.data(), s.a.data(), s.w.data(), t);
      };
      auto at_t = [&](double tt) {
        return EvaluateAll(sys, s.q.data(), s.v.data(), s.a.data(), s.w.data(), tt);
      };
      const Eigen::Map<const VectorXd> v(s.v.data(), nq), a(s.a.data(), nq), w(s.w.data(), nc);

      // M = d^2 T / dv^2, from the independent kinetic energy (T is quadratic in v).
      const MatrixXd M = DenseOf(sys, o, Matrix::kMass);
      MatrixXd M_ref(nq, nq);
      for (int i = 0; i < nq; ++i)
        for (int j = 0; j < nq; ++j) {
          std::vector<double> p(nq, 0.0), m(nq, 0.0);
          p[i] += 1; p[j] += 1;
          m[i] += 1; m[j] -= 1;
          M_ref(i, j) = (sys.KineticEnergy(s.q.data(), p.data()) -
                         sys.KineticEnergy(s.q.data(), m.data())) / 2;
        }
      EXPECT_LT(RelativeError(M, M_ref, "M vs d2T/dv2"), 1e-12);
      EXPECT_NEAR(0.5 * v.dot(M * v), sys.KineticEnergy(s.q.data(), s.v.data()),
                  1e-12 * std::max(1.0, v.dot(M * v)));

      // d(M a)/dq
      const MatrixXd dMa = FiniteDifferences(
          [&](const std::vector<double>& q) -> VectorXd {
            return DenseOf(sys, at_q(q), Matrix::kMass) * a;
          },
          s.q);
      EXPECT_LT(RelativeError(DenseOf(sys, o, Matrix::kMassTimesAccDq), dMa, "d(Ma)/dq"), kTol);

      // dQ/dq and dQ/dv
      const MatrixXd dQdq = FiniteDifferences(
          [&](const std::vector<double>& q) -> VectorXd { return at_q(q).force; }, s.q);
      EXPECT_LT(RelativeError(DenseOf(sys, o, Matrix::kForceDq), dQdq, "dQ/dq"), kTol);
      const MatrixXd dQdv = FiniteDifferences(
          [&](const std::vector<double>& vv) -> VectorXd {
            return EvaluateAll(sys, s.q.data(), vv.data(), s.a.data(), s.w.data(), t).force;
          },
          s.v);
      EXPECT_LT(RelativeError(DenseOf(sys, o, Matrix::kForceDv), dQdv, "dQ/dv"), kTol);

      // C_q = dC/dq
      const MatrixXd Cq = DenseOf(sys, o, Matrix::kConstraintDq);
      const MatrixXd dC = FiniteDifferences(
          [&](const std::vector<double>& q) -> VectorXd { return at_q(q).constraint; }, s.q);
      EXPECT_LT(RelativeError(Cq, dC, "C_q"), kTol);

      // d(C_q^T w)/dq
      const MatrixXd dCtw = FiniteDifferences(
          [&](const std::vector<double>& q) -> VectorXd {
            return DenseOf(sys, at_q(q), Matrix::kConstraintDq).transpose() * w;
          },
          s.q);
      EXPECT_LT(RelativeError(DenseOf(sys, o, Matrix::kConstraintTDq), dCtw, "d(C_q^T w)/dq"), kTol);

      // d(C_q v + C_t)/dq
      const MatrixXd dCv = FiniteDifferences(
          [&](const std::vector<double>& q) -> VectorXd {
            const Outputs p = at_q(q);
            return DenseOf(sys, p, Matrix::kConstraintDq) * v + p.constraint_dt;
          },
          s.q);
      EXPECT_LT(RelativeError(DenseOf(sys, o, Matrix::kConstraintVelDq), dCv, "d(C_q v)/dq"), kTol);

      // C_t = dC/dt; gamma = -d/ds (C_q(q + s v) v) at s = 0 - dC_t/dt (C_qt = 0: the
      // motion values depend on t alone)
      const double h = 1e-6;
      const VectorXd Ct_fd = (at_t(t + h).constraint - at_t(t - h).constraint) / (2 * h);
      EXPECT_LT(RelativeError(o.constraint_dt, Ct_fd, "C_t"), kTol);
      const VectorXd Ctt_fd = (at_t(t + h).constraint_dt - at_t(t - h).constraint_dt) / (2 * h);
      std::vector<double> qp = s.q, qm = s.q;
      for (int k = 0; k < nq; ++k) { qp[k] += h * v[k]; qm[k] -= h * v[k]; }
      const VectorXd gamma_fd = -(DenseOf(sys, at_q(qp), Matrix::kConstraintDq) * v -
                                  DenseOf(sys, at_q(qm), Matrix::kConstraintDq) * v) / (2 * h) -
                                Ctt_fd;
      EXPECT_LT(RelativeError(o.acc_rhs, gamma_fd, "gamma"), kTol);
      EXPECT_LT(RelativeError(o.constraint_dtt, Ctt_fd, "C_tt"), kTol);
      // The identity the C API uses: d(C_q)/dt v = d(C_q v + C_t)/dq v = -gamma - C_tt.
      EXPECT_LT(RelativeError(DenseOf(sys, o, Matrix::kConstraintVelDq) * v,
                              -o.acc_rhs - o.constraint_dtt, "d(C_q)/dt v = -gamma - C_tt"),
                1e-12);
      // Q_v = dT/dq - (dM/dt) v (Lagrange's equations), from the kinetic energy and the
      // mass matrix along q + s v; and it is quadratic in v.
      {
        const MatrixXd dTdq = FiniteDifferences(
            [&](const std::vector<double>& q) -> VectorXd {
              return VectorXd::Constant(1, sys.KineticEnergy(q.data(), s.v.data()));
            },
            s.q);
        const VectorXd Mdot_v = (DenseOf(sys, at_q(qp), Matrix::kMass) * v -
                                 DenseOf(sys, at_q(qm), Matrix::kMass) * v) / (2 * h);
        const VectorXd qv_ref = dTdq.transpose() - Mdot_v;
        EXPECT_LT(RelativeError(o.force_quadratic_velocity, qv_ref, "Q_v vs dT/dq - dM/dt v"),
                  kTol);
        EXPECT_GT(o.force_quadratic_velocity.cwiseAbs().maxCoeff(), 1e-3);
        std::vector<double> v2(s.v);
        for (double& x : v2) x *= 2;
        const Outputs o2 = EvaluateAll(sys, s.q.data(), v2.data(), s.a.data(), s.w.data(), t);
        EXPECT_LT(RelativeError(o2.force_quadratic_velocity, 4 * o.force_quadratic_velocity,
                                "Q_v(2 v) = 4 Q_v(v)"),
                  1e-12);
      }
      if (!opt.motion_gear) EXPECT_EQ(o.constraint_dt.cwiseAbs().maxCoeff(), 0.0);
      else EXPECT_GT(o.constraint_dt.cwiseAbs().maxCoeff(), 0.0);
      // dQ/dt (force values over t), against the time derivative of the force values
      // seen through ForceAction: central differences agree with a tighter step.
      const VectorXd Qt_fd = (at_t(t + h).force - at_t(t - h).force) / (2 * h);
      const VectorXd Qt_fd2 = (at_t(t + h / 4).force - at_t(t - h / 4).force) / (h / 2);
      EXPECT_LT(RelativeError(Qt_fd2, Qt_fd, "dQ/dt (FD at h and h/4)"), 1e-6);
      EXPECT_GT(Qt_fd.cwiseAbs().maxCoeff(), 1e-3);  // the forces do depend on t
    }
  }
  for (const auto& [what, err] : WorstErrors())
    std::cout << "  largest relative error " << what << ": " << err << "\n";
}

// Same numbers from a second call, and after a call at another state with only some
// outputs requested (nothing may be left over from an earlier call).
// The view of the kept equations (dae::KeepConstraints, what the driver and the C API
// integrate) passes the optional outputs through: Q_v whole, C_tt of the kept rows.
TEST(MultibodySystem, KeptViewPassesTheOptionalOutputs) {
  std::mt19937 rng(4);
  RandomModelOptions opt;
  opt.motion_gear = true;
  const Model model = RandomModel(rng, opt);
  MultibodySystem sys(model);
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  std::vector<int> kept;
  for (int r = 0; r < nc; r += 2) kept.push_back(r);
  for (int r = 0; r < nc; ++r)
    if (sys.constraint_names()[r].find(".motion") != std::string::npos && r % 2 == 1)
      kept.insert(std::lower_bound(kept.begin(), kept.end(), r), r);
  auto view = dae::KeepConstraints(sys, kept);
  const RandomState s = MakeRandomState(rng, model, nc);
  const Outputs full = EvaluateAll(sys, s.q.data(), s.v.data(), s.a.data(), s.w.data(), 0.6);
  VectorXd qv = VectorXd::Constant(nq, 7.0), ctt = VectorXd::Constant(view->num_constraints(), 7.0);
  dae::EvalInput in;
  in.t = 0.6;
  in.q = s.q.data();
  in.v = s.v.data();
  dae::EvalOutput out;
  out.force_quadratic_velocity = qv.data();
  out.constraint_dtt = ctt.data();
  ASSERT_EQ(view->Evaluate(in, out), 0);
  EXPECT_EQ(qv, full.force_quadratic_velocity);
  double largest = 0;
  for (size_t k = 0; k < kept.size(); ++k) {
    EXPECT_EQ(ctt[k], full.constraint_dtt[kept[k]]) << sys.constraint_names()[kept[k]];
    largest = std::max(largest, std::abs(ctt[k]));
  }
  EXPECT_GT(largest, 1e-3);  // a motion joint with a time term is among the kept rows
}

// EvalOutput::constraint_transpose_w: C_q^T w without C_q, equal to the last bit to the
// product by C_q's pattern (what the HHT residual computed before, so its runs keep their
// numbers) where the system says it gives it, and to a dense product to round-off. Motion
// and gear joints put first make rows that the evaluation reaches after later joints'
// rows: then the system must say no.
TEST(MultibodySystem, ConstraintTransposeProductIsThePatternProduct) {
  int provided = 0, refused = 0;
  for (unsigned seed = 0; seed < 24; ++seed) {
    std::mt19937 rng(300 + seed);
    RandomModelOptions opt;
    opt.motion_gear = seed % 3 != 0;
    opt.expression_forces = seed % 2 == 0;
    Model model = RandomModel(rng, opt);
    const bool motion_first = opt.motion_gear && seed % 3 == 2;
    if (motion_first) {  // the motion and gear joints (added last) to the front
      auto first = std::stable_partition(model.joints.begin(), model.joints.end(),
                                         [](const Joint& j) {
                                           return j.type == JointType::kMotion ||
                                                  j.type == JointType::kGear;
                                         });
      ASSERT_NE(first, model.joints.begin());
    }
    MultibodySystem sys(model);
    const int nq = sys.num_coordinates(), nc = sys.num_constraints();
    if (!sys.provides_constraint_transpose_w()) {
      ++refused;
      continue;
    }
    EXPECT_FALSE(motion_first) << "seed " << seed;
    ++provided;
    const RandomState s = MakeRandomState(rng, model, nc);
    const Outputs o = EvaluateAll(sys, s.q.data(), s.v.data(), s.a.data(), s.w.data(), 0.4);
    std::vector<double> product(nq, 777.0), reference(nq, 0.0);
    dae::EvalInput in;
    in.t = 0.4;
    in.q = s.q.data();
    in.v = s.v.data();
    in.w = s.w.data();
    dae::EvalOutput out;
    out.constraint_transpose_w = product.data();
    ASSERT_EQ(sys.Evaluate(in, out), 0);
    dae::MultiplyTransposeAdd(sys.pattern(Matrix::kConstraintDq),
                              o.matrix[static_cast<int>(Matrix::kConstraintDq)].data(), 1.0,
                              s.w.data(), reference.data());
    for (int i = 0; i < nq; ++i)
      EXPECT_EQ(product[i], reference[i]) << "seed " << seed << ", " << sys.coordinate_names()[i];
    const VectorXd dense = DenseOf(sys, o, Matrix::kConstraintDq).transpose() *
                           Eigen::Map<const VectorXd>(s.w.data(), nc);
    EXPECT_LT(RelativeError(Eigen::Map<const VectorXd>(product.data(), nq), dense), 1e-13);
    // The view without every other equation: its product over the kept rows, again to
    // the last bit (the dropped rows' weights are zero).
    std::vector<int> kept;
    for (int r = 0; r < nc; r += 2) kept.push_back(r);
    auto view = dae::KeepConstraints(sys, kept);
    ASSERT_TRUE(view->provides_constraint_transpose_w());
    std::vector<double> wk(kept.size()), cqk(view->pattern(Matrix::kConstraintDq).nnz());
    for (size_t k = 0; k < kept.size(); ++k) wk[k] = s.w[kept[k]];
    std::vector<double> vproduct(nq, 777.0), vreference(nq, 0.0);
    in.w = wk.data();
    out.constraint_transpose_w = vproduct.data();
    ASSERT_EQ(view->Evaluate(in, out), 0);
    dae::EvalOutput mout;
    mout[Matrix::kConstraintDq] = cqk.data();
    ASSERT_EQ(view->Evaluate(in, mout), 0);
    dae::MultiplyTransposeAdd(view->pattern(Matrix::kConstraintDq), cqk.data(), 1.0, wk.data(),
                              vreference.data());
    for (int i = 0; i < nq; ++i) EXPECT_EQ(vproduct[i], vreference[i]) << "view, seed " << seed;
  }
  std::cout << "C_q^T w provided by " << provided << " models, refused by " << refused << "\n";
  EXPECT_GE(provided, 8);  // 11 of 24 when written
  EXPECT_GE(refused, 8);   // every motion-first model (8), and gears on one body's measures
}

TEST(MultibodySystem, EvaluateIsRepeatable) {
  std::mt19937 rng(11);
  const Model model = RandomModel(rng);
  MultibodySystem sys(model);
  const int nc = sys.num_constraints();
  const RandomState s1 = MakeRandomState(rng, model, nc);
  const RandomState s2 = MakeRandomState(rng, model, nc);
  const Outputs o1 = EvaluateAll(sys, s1.q.data(), s1.v.data(), s1.a.data(), s1.w.data());
  {
    std::vector<double> f(sys.num_coordinates());
    std::vector<double> kq(sys.pattern(Matrix::kForceDq).nnz());
    dae::EvalInput in;
    in.q = s2.q.data(); in.v = s2.v.data();
    dae::EvalOutput out;
    out.force = f.data();
    out[Matrix::kForceDq] = kq.data();
    ASSERT_EQ(sys.Evaluate(in, out), 0);
  }
  const Outputs o2 = EvaluateAll(sys, s1.q.data(), s1.v.data(), s1.a.data(), s1.w.data());
  EXPECT_EQ(o1.force, o2.force);
  EXPECT_EQ(o1.constraint, o2.constraint);
  EXPECT_EQ(o1.acc_rhs, o2.acc_rhs);
  for (int m = 0; m < dae::kNumMatrices; ++m) EXPECT_EQ(o1.matrix[m], o2.matrix[m]) << m;
}

TEST(MultibodySystem, EvaluateDoesNotAllocate) {
  std::mt19937 rng(12);
  RandomModelOptions opt;
  opt.expression_forces = true;
  opt.motion_gear = true;
  opt.bushings = true;
  const Model model = RandomModel(rng, opt);
  MultibodySystem sys(model);
  const RandomState s = MakeRandomState(rng, model, sys.num_constraints());
  Outputs o = EvaluateAll(sys, s.q.data(), s.v.data(), s.a.data(), s.w.data());
  dae::EvalInput in;
  in.q = s.q.data(); in.v = s.v.data(); in.a = s.a.data(); in.w = s.w.data();
  dae::EvalOutput out;
  out.force = o.force.data();
  out.constraint = o.constraint.data();
  out.constraint_dt = o.constraint_dt.data();
  out.acc_rhs = o.acc_rhs.data();
  for (int m = 0; m < dae::kNumMatrices; ++m) out.matrix[m] = o.matrix[m].data();
  const long before = g_allocations;
  EXPECT_EQ(sys.Evaluate(in, out), 0);
  EXPECT_EQ(g_allocations - before, 0);
  // the counter does count
  auto probe = std::make_unique<std::vector<double>>(100);
  EXPECT_GT(g_allocations - before, 0);
}

// Measures: the velocity is the time derivative of the position along q + s v, and the
// acceleration that of the velocity along (q + s v + s^2/2 a, v + s a).
TEST(MultibodySystem, MeasureRatesAreTimeDerivatives) {
  for (unsigned seed = 21; seed <= 23; ++seed) {
    std::mt19937 rng(seed);
    Model model = RandomModel(rng);
    // Every measure three times: position, velocity, acceleration.
    std::vector<Measure> expanded;
    for (const Measure& m : model.measures)
      for (Quantity qt : {Quantity::kPosition, Quantity::kVelocity, Quantity::kAcceleration}) {
        Measure c = m;
        c.quantity = qt;
        expanded.push_back(c);
      }
    model.measures = expanded;
    MultibodySystem sys(model);
    const int nq = sys.num_coordinates(), n = static_cast<int>(model.measures.size());
    const RandomState s = MakeRandomState(rng, model, sys.num_constraints());
    const double h = 1e-5;
    auto values = [&](double t) {
      std::vector<double> q(nq), v(nq), out(n);
      for (int k = 0; k < nq; ++k) {
        q[k] = s.q[k] + t * s.v[k] + 0.5 * t * t * s.a[k];
        v[k] = s.v[k] + t * s.a[k];
      }
      sys.EvaluateMeasures(0.0, q.data(), v.data(), s.a.data(), out.data());
      return out;
    };
    const std::vector<double> x0 = values(0), xp = values(h), xm = values(-h);
    for (int k = 0; k < n; k += 3) {
      SCOPED_TRACE("seed " + std::to_string(seed) + " measure " + std::to_string(k / 3));
      double dpos = xp[k] - xm[k];
      if (model.measures[k].type == MeasureType::kRotational) {
        dpos = std::remainder(dpos, 2 * M_PI);
        EXPECT_GT(x0[k], -M_PI);
        EXPECT_LE(x0[k], M_PI);
      }
      const double vel_fd = dpos / (2 * h);
      const double acc_fd = (xp[k + 1] - xm[k + 1]) / (2 * h);
      EXPECT_NEAR(x0[k + 1], vel_fd, 1e-6 * std::max(1.0, std::abs(vel_fd)));
      EXPECT_NEAR(x0[k + 2], acc_fd, 1e-6 * std::max(1.0, std::abs(acc_fd)));
    }
  }
}

// Measure values against closed forms on a simple configuration.
TEST(MultibodySystem, MeasureValuesClosedForm) {
  Model model;
  model.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
  Body b;
  b.name = "b";
  b.mass = 1;
  b.inertia = Mat3::Identity();
  model.bodies.push_back(b);
  model.markers.push_back(Marker{"b.cm", 0, Vec3::Zero(), Mat3::Identity(), {}});
  model.markers.push_back(Marker{"b.P", 0, Vec3(1, 0, 0), Mat3::Identity(), {}});
  auto add = [&](MeasureType type, Component c, MeasureFrame fr, Quantity qt) {
    Measure m;
    m.type = type; m.i = 2; m.j = 0; m.component = c; m.frame = fr; m.quantity = qt;
    model.measures.push_back(m);
  };
  add(MeasureType::kTranslational, Component::kX, MeasureFrame::kWorld, Quantity::kPosition);
  add(MeasureType::kTranslational, Component::kY, MeasureFrame::kJ, Quantity::kPosition);
  add(MeasureType::kTranslational, Component::kDistance, MeasureFrame::kJ, Quantity::kPosition);
  add(MeasureType::kRotational, Component::kZ, MeasureFrame::kJ, Quantity::kPosition);
  add(MeasureType::kRotational, Component::kZ, MeasureFrame::kJ, Quantity::kVelocity);
  add(MeasureType::kTranslational, Component::kY, MeasureFrame::kJ, Quantity::kVelocity);
  add(MeasureType::kRotational, Component::kZ, MeasureFrame::kJ, Quantity::kAcceleration);
  MultibodySystem sys(model);
  // body at (2, 3, 0) turned by 2.5 rad about z, spinning at 0.7 rad/s, accelerating at
  // 0.3 rad/s^2 (e'' from omega' = 2 E e'' for a fixed axis).
  const double th = 2.5, w = 0.7, al = 0.3;
  const Quat e = QuaternionFromAxisAngle(Vec3::UnitZ(), th);
  const Quat ed = 0.5 * EMatrix(e).transpose() * Vec3(0, 0, w);
  // e(t) = (cos(th/2), 0, 0, sin(th/2)):  e'' = -w^2/4 e + al/2 (-sin, 0, 0, cos)
  const Quat edd = -w * w / 4 * e + al / 2 * Quat(-std::sin(th / 2), 0, 0, std::cos(th / 2));
  std::vector<double> q = {2, 3, 0, e[0], e[1], e[2], e[3]};
  std::vector<double> v = {0, 0, 0, ed[0], ed[1], ed[2], ed[3]};
  std::vector<double> a = {0, 0, 0, edd[0], edd[1], edd[2], edd[3]};
  std::vector<double> out(model.measures.size());
  sys.EvaluateMeasures(0, q.data(), v.data(), a.data(), out.data());
  const Vec3 p(2 + std::cos(th), 3 + std::sin(th), 0);
  EXPECT_NEAR(out[0], p.x(), 1e-14);
  EXPECT_NEAR(out[1], p.y(), 1e-14);
  EXPECT_NEAR(out[2], p.norm(), 1e-14);
  EXPECT_NEAR(out[3], th, 1e-14);
  EXPECT_NEAR(out[4], w, 1e-14);
  EXPECT_NEAR(out[5], w * std::cos(th), 1e-14);
  EXPECT_NEAR(out[6], al, 1e-14);
  // past pi the angle wraps into (-pi, pi]
  const Quat e2 = QuaternionFromAxisAngle(Vec3::UnitZ(), 3.5);
  for (int k = 0; k < 4; ++k) q[3 + k] = e2[k];
  sys.EvaluateMeasures(0, q.data(), v.data(), a.data(), out.data());
  EXPECT_NEAR(out[3], 3.5 - 2 * M_PI, 1e-14);
}

// Solves the acceleration-level system [M C_q^T; C_q 0] [a; lambda] = [Q; gamma].
void SolveAccelerations(MultibodySystem& sys, const std::vector<double>& q,
                        const std::vector<double>& v, VectorXd* a, VectorXd* lambda) {
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  const Outputs o = EvaluateAll(sys, q.data(), v.data(), nullptr, nullptr);
  MatrixXd K = MatrixXd::Zero(nq + nc, nq + nc);
  const MatrixXd Cq = DenseOf(sys, o, Matrix::kConstraintDq);
  K.topLeftCorner(nq, nq) = DenseOf(sys, o, Matrix::kMass);
  K.topRightCorner(nq, nc) = Cq.transpose();
  K.bottomLeftCorner(nc, nq) = Cq;
  VectorXd rhs(nq + nc);
  rhs << o.force, o.acc_rhs;
  const VectorXd x = K.fullPivLu().solve(rhs);
  *a = x.head(nq);
  *lambda = x.tail(nc);
}

// A body at rest hanging below a spherical joint, and one held by a fixed joint with
// its centre of mass off to the side: the reaction on the body is -m g, and its moment
// about the marker balances the moment of gravity.
TEST(MultibodySystem, JointReactionAtRest) {
  std::mt19937 rng(5);
  for (JointType type : {JointType::kSpherical, JointType::kFixed}) {
    for (bool body_is_i : {true, false}) {
      Model model;
      model.gravity = Vec3(0, 0, -9.81);
      model.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
      model.markers.push_back(Marker{"ground.A", -1, Vec3(0.2, -0.1, 0.4),
                                     RotationMatrix(testing::RandomUnitQuaternion(rng)), {}});
      Body b;
      b.name = "b";
      b.mass = 2.5;
      const Mat3 R = RotationMatrix(testing::RandomUnitQuaternion(rng));
      b.inertia = R * Vec3(0.3, 0.5, 0.6).asDiagonal() * R.transpose();
      b.orientation = testing::RandomUnitQuaternion(rng);
      const Mat3 A = RotationMatrix(b.orientation);
      // centre of mass below the joint point (spherical), or off to the side (fixed)
      const Vec3 offset = type == JointType::kSpherical ? Vec3(0, 0, -0.7) : Vec3(0.5, 0.2, -0.3);
      b.position = Vec3(0.2, -0.1, 0.4) + offset;
      model.bodies.push_back(b);
      model.markers.push_back(Marker{"b.cm", 0, Vec3::Zero(), Mat3::Identity(), {}});
      // the marker at the joint point, with a random orientation matching ground.A's
      model.markers.push_back(
          Marker{"b.P", 0, A.transpose() * (-offset), A.transpose() * model.markers[1].orientation, {}});
      Joint j;
      j.name = "joint";
      j.type = type;
      j.locks = testing::JointTypeLocks(type);
      j.i = body_is_i ? 3 : 1;
      j.j = body_is_i ? 1 : 3;
      model.joints.push_back(j);
      MultibodySystem sys(model);
      std::vector<double> q, v;
      sys.InitialState(q, v);
      VectorXd a, lambda;
      SolveAccelerations(sys, q, v, &a, &lambda);
      EXPECT_LT(a.cwiseAbs().maxCoeff(), 1e-12);  // at rest, in equilibrium
      Vec3 f, n;
      sys.JointReaction(0, 0.0, q.data(), lambda.data(), f.data(), n.data());
      const Vec3 mg = b.mass * model.gravity;
      // on the body: -m g and, about the joint point, minus the moment of gravity
      const Vec3 f_body = -mg, n_body = -offset.cross(mg);
      const double sign = body_is_i ? 1 : -1;  // on ground: the opposite
      EXPECT_LT((f - sign * f_body).norm(), 1e-10) << f.transpose();
      EXPECT_LT((n - sign * n_body).norm(), 1e-10) << n.transpose();
    }
  }
}

// With gravity and undamped springs, d/dt (T + V) = 0 along the motion; with damping,
// d/dt (T + V) = -sum c l'^2. Checks M, Q (quadratic velocity, spring forces), gamma and
// the potential energy together. Free bodies (only the normalisations constrain them).
TEST(MultibodySystem, EnergyBalance) {
  for (bool damped : {false, true}) {
    std::mt19937 rng(damped ? 31 : 32);
    RandomModelOptions opt;
    opt.joints = false;
    opt.forces = true;
    opt.measures = false;
    Model model = RandomModel(rng, opt);
    std::vector<Force> springs;
    for (Force f : model.forces)
      if (f.type == ForceType::kSpringDamper) {
        if (!damped) f.damping = Expression::Constant(0);
        springs.push_back(f);
      }
    model.forces = springs;
    MultibodySystem sys(model);
    const int nq = sys.num_coordinates();
    const RandomState s = MakeRandomState(rng, model, sys.num_constraints(), true);
    VectorXd a, lambda;
    SolveAccelerations(sys, s.q, s.v, &a, &lambda);
    auto energy = [&](double t) {
      std::vector<double> q(nq), v(nq);
      for (int k = 0; k < nq; ++k) {
        q[k] = s.q[k] + t * s.v[k] + 0.5 * t * t * a[k];
        v[k] = s.v[k] + t * a[k];
      }
      return sys.KineticEnergy(q.data(), v.data()) + sys.PotentialEnergy(0, q.data());
    };
    const double h = 1e-5;
    const double dE = (energy(h) - energy(-h)) / (2 * h);
    double power = 0;  // of the dampers
    for (size_t k = 0; k < model.forces.size(); ++k) {
      const Force& f = model.forces[k];
      // l' from the measure machinery-free formula: d = x_i - x_j
      auto point = [&](int marker, const std::vector<double>& q) -> Vec3 {
        const Marker& m = model.markers[marker];
        if (m.body < 0) return m.position;
        const int o = 7 * m.body;
        return Eigen::Map<const Vec3>(q.data() + o) +
               RotationMatrix(Eigen::Map<const Quat>(q.data() + o + 3)) * m.position;
      };
      std::vector<double> qp = s.q, qm = s.q;
      for (int i = 0; i < nq; ++i) { qp[i] += h * s.v[i]; qm[i] -= h * s.v[i]; }
      const double ld = ((point(f.i, qp) - point(f.j, qp)).norm() -
                         (point(f.i, qm) - point(f.j, qm)).norm()) / (2 * h);
      power -= f.damping.Evaluate(nullptr) * ld * ld;
    }
    const double scale = std::max(1.0, sys.KineticEnergy(s.q.data(), s.v.data()));
    EXPECT_NEAR(dE, power, 1e-6 * scale) << (damped ? "damped" : "undamped");
    if (damped) EXPECT_LT(power, 0.0);
  }
}

// A free body under every kind of force element (reactions on ground): the accelerations
// of the DAE satisfy the Newton-Euler equations m r'' = m g + sum F and
// J w' + w x J w = sum (s x A^T F + A^T T) (body axes, w = 2 G e', w' = 2 G e'').
// Independent of the Lagrangian form of M and Q; the quadratic velocity term does no
// work, so the energy balance cannot see it but this test does.
TEST(MultibodySystem, FreeBodyFollowsNewtonEuler) {
  for (unsigned seed = 61; seed <= 64; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937 rng(seed);
    RandomModelOptions opt;
    opt.bodies = 1;
    opt.joints = false;
    opt.measures = false;
    const Model model = RandomModel(rng, opt);
    MultibodySystem sys(model);
    const RandomState s = MakeRandomState(rng, model, sys.num_constraints(), true);
    VectorXd a, lambda;
    SolveAccelerations(sys, s.q, s.v, &a, &lambda);
    const Body& b = model.bodies[0];
    const Quat e = Eigen::Map<const Quat>(s.q.data() + 3);
    const Quat ed = Eigen::Map<const Quat>(s.v.data() + 3);
    const Mat3 A = RotationMatrix(e);
    Vec3 f_total = b.mass * model.gravity, n_total = Vec3::Zero();
    for (size_t k = 0; k < model.forces.size(); ++k) {
      ASSERT_EQ(model.markers[model.forces[k].i].body, 0);
      ASSERT_EQ(model.markers[model.forces[k].j].body, -1);
      Vec3 f, t;
      sys.ForceAction(static_cast<int>(k), 0, s.q.data(), s.v.data(), f.data(), t.data());
      f_total += f;
      n_total += model.markers[model.forces[k].i].position.cross(A.transpose() * f) +
                 A.transpose() * t;
    }
    const Vec3 w = 2 * GMatrix(e) * ed;
    const Vec3 wd = 2 * GMatrix(e) * a.segment<4>(3);
    const Vec3 lhs = b.inertia * wd + w.cross(b.inertia * w);
    EXPECT_LT((b.mass * a.head<3>() - f_total).norm(), 1e-10 * std::max(1.0, f_total.norm()));
    EXPECT_LT((lhs - n_total).norm(), 1e-10 * std::max(1.0, n_total.norm()))
        << lhs.transpose() << " vs " << n_total.transpose();
  }
}

// ForceAction and the potential energy: the spring force is minus the derivative of the
// spring energy along the separation, the applied force/torque are the given values.
TEST(MultibodySystem, ForceActionMatchesDefinitions) {
  std::mt19937 rng(41);
  const Model model = RandomModel(rng);
  MultibodySystem sys(model);
  const RandomState s = MakeRandomState(rng, model, sys.num_constraints());
  for (size_t k = 0; k < model.forces.size(); ++k) {
    const Force& fe = model.forces[k];
    Vec3 f, t;
    sys.ForceAction(static_cast<int>(k), 0, s.q.data(), s.v.data(), f.data(), t.data());
    auto axes = [&](int marker) -> Mat3 {
      const Marker& m = model.markers[marker];
      if (m.body < 0) return m.orientation;
      return RotationMatrix(Eigen::Map<const Quat>(s.q.data() + 7 * m.body + 3)) * m.orientation;
    };
    if (fe.type == ForceType::kSpringDamper) {
      EXPECT_EQ(t.norm(), 0.0);
      continue;  // checked through the energy balance and dQ/dq
    }
    Vec3 value(fe.value[0].Evaluate(nullptr), fe.value[1].Evaluate(nullptr),
               fe.value[2].Evaluate(nullptr));
    if (fe.frame == ForceFrame::kI) value = axes(fe.i) * value;
    if (fe.frame == ForceFrame::kJ) value = axes(fe.j) * value;
    const Vec3& act = fe.type == ForceType::kTorque ? t : f;
    const Vec3& zero = fe.type == ForceType::kTorque ? f : t;
    EXPECT_LT((act - value).norm(), 1e-13) << fe.name;
    EXPECT_EQ(zero.norm(), 0.0);
  }
}

TEST(MultibodySystem, InitialStateGivesAngularVelocity) {
  std::mt19937 rng(51);
  const Model model = RandomModel(rng);
  const MultibodySystem sys(model);
  std::vector<double> q, v;
  sys.InitialState(q, v);
  for (size_t b = 0; b < model.bodies.size(); ++b) {
    const int o = 7 * static_cast<int>(b);
    const Quat e = Eigen::Map<const Quat>(q.data() + o + 3);
    const Quat ed = Eigen::Map<const Quat>(v.data() + o + 3);
    EXPECT_LT((Eigen::Map<const Vec3>(q.data() + o) - model.bodies[b].position).norm(), 1e-15);
    EXPECT_LT((e - model.bodies[b].orientation).norm(), 1e-15);
    EXPECT_LT((Eigen::Map<const Vec3>(v.data() + o) - model.bodies[b].velocity).norm(), 1e-15);
    EXPECT_LT((2 * EMatrix(e) * ed - model.bodies[b].angular_velocity).norm(), 1e-14);
    EXPECT_NEAR(e.dot(ed), 0.0, 1e-15);
  }
}

TEST(MultibodySystem, ZeroLengthSpringIsRecoverable) {
  Model model;
  model.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
  Body b;
  b.name = "b";
  b.mass = 1;
  b.inertia = Mat3::Identity();
  model.bodies.push_back(b);
  model.markers.push_back(Marker{"b.cm", 0, Vec3::Zero(), Mat3::Identity(), {}});
  Force f;
  f.name = "spring";
  f.type = ForceType::kSpringDamper;
  f.i = 1;
  f.j = 0;
  f.stiffness = Expression::Constant(10);
  model.forces.push_back(f);
  MultibodySystem sys(model);
  std::vector<double> q = {0, 0, 0, 1, 0, 0, 0}, v(7, 0.0);
  const Outputs o = EvaluateAll(sys, q.data(), v.data(), nullptr, nullptr);
  EXPECT_GT(o.code, 0);
  EXPECT_NE(std::string(sys.last_error()).find("spring"), std::string::npos);
  q[0] = 0.5;
  EXPECT_EQ(EvaluateAll(sys, q.data(), v.data(), nullptr, nullptr).code, 0);
  // spring pulled towards its free length 0: force on b is -k d
  EXPECT_NEAR(EvaluateAll(sys, q.data(), v.data(), nullptr, nullptr).force[0], -5.0, 1e-14);
}

// Force constants are expressions of the parameters, evaluated at every Evaluate from
// the system's current parameter values.
TEST(MultibodySystem, ForceConstantsFollowParameters) {
  Model model;
  model.parameters.push_back(Parameter{"k", 10.0, "", {}});
  model.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
  Body b;
  b.name = "b";
  b.mass = 1;
  b.inertia = Mat3::Identity();
  model.bodies.push_back(b);
  model.markers.push_back(Marker{"b.cm", 0, Vec3::Zero(), Mat3::Identity(), {}});
  SymbolTable symbols;
  symbols.parameters = {"k"};
  Force f;
  f.name = "spring";
  f.type = ForceType::kSpringDamper;
  f.i = 1;
  f.j = 0;
  f.stiffness = Expression::Parse("2*k", symbols);
  f.free_length = Expression::Constant(0.25);
  model.forces.push_back(f);
  MultibodySystem sys(model);
  ASSERT_EQ(sys.parameters().size(), 1u);
  EXPECT_EQ(sys.parameters()[0], 10.0);
  std::vector<double> q = {0, 0.75, 0, 1, 0, 0, 0}, v(7, 0.0);
  // f = -2 k (l - l0) along +y
  EXPECT_NEAR(EvaluateAll(sys, q.data(), v.data(), nullptr, nullptr).force[1], -2 * 10 * 0.5, 1e-13);
  sys.parameters()[0] = 3.0;
  EXPECT_NEAR(EvaluateAll(sys, q.data(), v.data(), nullptr, nullptr).force[1], -2 * 3 * 0.5, 1e-13);
  EXPECT_NEAR(sys.PotentialEnergy(0, q.data()), 0.5 * 2 * 3 * 0.25, 1e-13);
  MultibodySystem other(model, {7.0});
  EXPECT_NEAR(EvaluateAll(other, q.data(), v.data(), nullptr, nullptr).force[1], -2 * 7 * 0.5, 1e-13);
  EXPECT_THROW(MultibodySystem(model, {1.0, 2.0}), std::invalid_argument);
}

TEST(MultibodySystem, RejectsBadInput) {
  Model model;
  model.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
  model.markers.push_back(Marker{"ground.A", -1, Vec3::Zero(), Mat3::Identity(), {}});
  Joint j;
  j.name = "bad";
  j.i = 0;
  j.j = 1;
  j.locks = kLockX;
  model.joints.push_back(j);
  EXPECT_THROW(MultibodySystem{model}, std::invalid_argument);
  model.joints[0].j = 7;
  EXPECT_THROW(MultibodySystem{model}, std::invalid_argument);
}

}  // namespace
}  // namespace mbdae::mbs
