// The C API's measures, vectors and sparse matrices at the current state (api/mbdae.h),
// through the C header only, each against an independent computation:
// - at solved states (HHT and IDA) the equations of motion M a + C_q^T lambda - Q = 0,
//   Q = Q_v + external, C = 0 and (IDA, and the assembled state) C_q v + C_t = 0;
//   at states whose a and lambda solve the equations of motion also the acceleration
//   level C_q a + d(C_q)/dt q' + C_tt = 0;
// - C_t, C_tt and d(C_q)/dt q' against central differences in time, Q_v against
//   Lagrange's dT/dq - (dM/dt) q' from M a (a = q') along q + s q';
// - every matrix against central differences of the vector it differentiates (set_state
//   moves q, v, a, lambda), the measure gradients against differences of the values;
// - the Newton matrices against differences of the integrators' residuals written out
//   here from the vectors (HHT: both forms, through Newmark's formulas; IDA: the GGL
//   residual) and against their definition composed from the single matrices;
// - CSC against CSR, and compositions (scaled, transposed, overlapping) against a dense
//   composition; sizes and arguments that are wrong.
// The largest errors are printed at the end of each test.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "mbdae.h"

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

// A spatial model with everything the vectors and matrices see: a body on a spherical
// joint with three different moments of inertia (gyroscopic terms), a slider on a
// cylindrical joint along it driven by a motion joint over t (C_t, C_tt), a
// spring-damper (dQ/dq, dQ/dv), a torque over an angular-velocity measure (dQ/dv through
// a measure) and measures of every quantity.
const char* kModel = R"yaml(
format: 1
name: api matrices
gravity: [0, 0, -9.81]
ground:
  markers:
    A: {position: [0.4, 0.5, 0.3]}
bodies:
  - name: arm
    mass: 2.0
    inertia: [0.1, 0.25, 0.3]
    position: [0.5, 0, 0]
    velocity: [0, 1.0, -0.3]
    angular_velocity: [0.4, 0.6, 2.0]
    markers:
      pivot: {position: [-0.5, 0, 0]}
      rail: {position: [0, 0, 0], orientation: {axis: [0, 1, 0], angle: "pi/2"}}
  - name: slider
    mass: 0.5
    inertia: [0.01, 0.02, 0.015]
    position: [0.6, 0, 0]
    orientation: {axis: [0, 1, 0], angle: "pi/2"}
    angular_velocity: [0.4, 0.6, 2.0]
    markers:
      c: {position: [0, 0, 0]}
      tip: {position: [0.05, 0.02, 0]}
measures:
  - {name: s, type: translational, i: slider.c, j: arm.rail, component: z}
  - {name: height, type: translational, i: slider.tip, component: z, frame: world}
  - {name: reach, type: translational, i: slider.tip, j: ground.A, component: distance,
     quantity: velocity}
  - {name: spin, type: rotational, i: slider.c, j: arm.rail, axis: z, quantity: angular_velocity}
  - {name: swing, type: rotational, i: arm.rail, axis: x, offset_initial: true}
  - {name: whirl, type: rotational, i: slider.c, j: arm.rail, axis: z,
     quantity: angular_acceleration}
  - {name: pull, type: translational, i: slider.tip, j: ground.A, component: y,
     quantity: acceleration}
joints:
  - {name: pivot, type: spherical, i: arm.pivot, j: ground.O}
  - {name: guide, type: cylindrical, i: slider.c, j: arm.rail}
  - {name: drive, type: motion, measure: s, value: "0.1 + 0.05*sin(3*t)"}
forces:
  - {name: spring, type: spring_damper, i: slider.tip, j: ground.A, stiffness: 40,
     damping: 1.5, free_length: 0.3}
  - {name: friction, type: torque, i: slider.c, j: arm.rail, frame: j, value: [0, 0, "-0.05*spin"]}
simulation:
  t_end: 1.0
  output_step: 0.05
  integrator: ida
  hht: {alpha: -0.2, step: 1.0e-3}
  ida: {rtol: 1.0e-10, atol: 1.0e-12}
)yaml";

// Largest errors by name, printed at the end of the test that measured them.
class Worst {
 public:
  explicit Worst(std::string title) : title_(std::move(title)) {}
  ~Worst() {
    std::cout << "  " << title_ << ":\n";
    for (const auto& [what, err] : worst_) std::cout << "    " << what << ": " << err << "\n";
  }
  double Record(const std::string& what, double err) {
    worst_[what] = std::max(worst_[what], err);
    return err;
  }

 private:
  std::string title_;
  std::map<std::string, double> worst_;
};

// max |a - ref| / max(1, max |ref|).
double RelErr(const MatrixXd& a, const MatrixXd& ref) {
  if (a.size() == 0) return 0;
  return (a - ref).cwiseAbs().maxCoeff() / std::max(1.0, ref.cwiseAbs().maxCoeff());
}

struct State {
  double t = 0;
  VectorXd q, v, a, lambda;
};

// RAII handle with the calls the tests need; every call must succeed.
class Model {
 public:
  explicit Model(const std::string& text, const std::vector<std::pair<std::string, std::string>>&
                                              options = {}) {
    EXPECT_EQ(mbdae_model_from_string(text.c_str(), "api matrices", &m_), MBDAE_OK)
        << mbdae_last_error();
    for (const auto& [k, v] : options)
      EXPECT_EQ(mbdae_set_option(m_, k.c_str(), v.c_str()), MBDAE_OK) << mbdae_last_error();
    Init();
  }
  static Model FromFile(const std::string& path) { return Model(path, 0); }
  Model(Model&& o) noexcept : m_(o.m_), nq_(o.nq_), nm_(o.nm_) { o.m_ = nullptr; }
  ~Model() { mbdae_model_free(m_); }
  mbdae_model* get() { return m_; }
  int nq() const { return nq_; }
  int nm() const { return nm_; }

  void SolveTo(double t) { ASSERT_EQ(mbdae_solve_to(m_, t), MBDAE_OK) << mbdae_last_error(); }

  State GetState() {
    State s;
    s.q.resize(nq_);
    s.v.resize(nq_);
    s.a.resize(nq_);
    s.lambda.resize(nm_);
    EXPECT_EQ(mbdae_get_state(m_, &s.t, s.q.data(), s.v.data(), s.a.data(), s.lambda.data(),
                              nq_, nm_),
              MBDAE_OK)
        << mbdae_last_error();
    return s;
  }
  void SetState(const State& s) {
    EXPECT_EQ(mbdae_set_state(m_, s.t, s.q.data(), s.v.data(), s.a.data(), s.lambda.data(), nq_,
                              nm_),
              MBDAE_OK)
        << mbdae_last_error();
  }
  // a and lambda from the equations of motion at (t, q, v).
  void SetPositionsAndVelocities(double t, const VectorXd& q, const VectorXd& v) {
    EXPECT_EQ(mbdae_set_state(m_, t, q.data(), v.data(), nullptr, nullptr, nq_, nm_), MBDAE_OK)
        << mbdae_last_error();
  }

  VectorXd Vector(mbdae_vector which) {
    const int n = which <= MBDAE_VEC_SUM_OF_FORCES ? nq_ : nm_;
    VectorXd out = VectorXd::Constant(n, NAN);
    EXPECT_EQ(mbdae_get_vector(m_, which, out.data(), n), MBDAE_OK) << mbdae_last_error();
    return out;
  }

  // A composition as a dense matrix, read in the given format; checks the index arrays.
  MatrixXd Composed(const std::vector<mbdae_block>& blocks, int rows, int cols,
                    mbdae_sparse_format format = MBDAE_CSC, int* nnz_out = nullptr) {
    int nnz = -1;
    EXPECT_EQ(mbdae_get_matrix(m_, blocks.data(), static_cast<int>(blocks.size()), rows, cols,
                               format, &nnz, nullptr, nullptr, nullptr),
              MBDAE_OK)
        << mbdae_last_error();
    const int outer = format == MBDAE_CSC ? cols : rows;
    const int inner = format == MBDAE_CSC ? rows : cols;
    std::vector<int> ptr(outer + 1, -1), idx(nnz, -1);
    std::vector<double> val(nnz, NAN);
    EXPECT_EQ(mbdae_get_matrix(m_, blocks.data(), static_cast<int>(blocks.size()), rows, cols,
                               format, &nnz, ptr.data(), idx.data(), val.data()),
              MBDAE_OK)
        << mbdae_last_error();
    if (nnz_out) *nnz_out = nnz;
    MatrixXd d = MatrixXd::Zero(rows, cols);
    EXPECT_EQ(ptr[0], 0);
    EXPECT_EQ(ptr[outer], nnz);
    for (int o = 0; o < outer; ++o) {
      EXPECT_LE(ptr[o], ptr[o + 1]);
      for (int k = ptr[o]; k < ptr[o + 1]; ++k) {
        EXPECT_GE(idx[k], 0);
        EXPECT_LT(idx[k], inner);
        if (k > ptr[o]) {
          EXPECT_LT(idx[k - 1], idx[k]) << "indices sorted, no duplicates";
        }
        if (format == MBDAE_CSC)
          d(idx[k], o) = val[k];
        else
          d(o, idx[k]) = val[k];
      }
    }
    return d;
  }
  MatrixXd Matrix(mbdae_matrix which, bool transpose = false, double scale = 1) {
    const int nq = nq_, nm = nm_;
    int r = nq, c = nq;
    if (which == MBDAE_MAT_CONSTRAINT_DQ) r = nm;
    if (which == MBDAE_MAT_NEWTON_HHT) r = c = nq + nm;
    if (which == MBDAE_MAT_NEWTON_IDA) r = c = 2 * nq + 2 * nm;
    if (transpose) std::swap(r, c);
    mbdae_block b{which, scale, 0, 0, transpose ? 1 : 0};
    return Composed({b}, r, c);
  }

  std::vector<double> Measures() {
    int n = 0;
    EXPECT_EQ(mbdae_count(m_, MBDAE_MEASURES, &n), MBDAE_OK);
    std::vector<double> out(n, NAN);
    if (n > 0) {
      EXPECT_EQ(mbdae_measure_values(m_, out.data(), n), MBDAE_OK) << mbdae_last_error();
    }
    return out;
  }

 private:
  Model(const std::string& path, int) {
    EXPECT_EQ(mbdae_model_from_file(path.c_str(), &m_), MBDAE_OK) << mbdae_last_error();
    Init();
  }
  void Init() {
    if (!m_) return;
    EXPECT_EQ(mbdae_assemble(m_), MBDAE_OK) << mbdae_last_error();
    EXPECT_EQ(mbdae_count(m_, MBDAE_COORDINATES, &nq_), MBDAE_OK);
    EXPECT_EQ(mbdae_count(m_, MBDAE_MULTIPLIERS, &nm_), MBDAE_OK);
  }
  mbdae_model* m_ = nullptr;
  int nq_ = 0, nm_ = 0;
};

// Central differences of f (a vector) in the components of x, step h.
MatrixXd Jacobian(const std::function<VectorXd(const VectorXd&)>& f, const VectorXd& x,
                  double h) {
  MatrixXd j;
  for (int k = 0; k < x.size(); ++k) {
    VectorXd xp = x, xm = x;
    xp[k] += h;
    xm[k] -= h;
    const VectorXd d = (f(xp) - f(xm)) / (2 * h);
    if (k == 0) j.resize(d.size(), x.size());
    j.col(k) = d;
  }
  return j;
}

// The equations of motion and the constraints at the current state.
void CheckSolvedState(Model& m, bool velocity_level, double tol, Worst& worst,
                      const std::string& what) {
  const VectorXd ma = m.Vector(MBDAE_VEC_MASS_TIMES_ACC);
  const VectorXd cf = m.Vector(MBDAE_VEC_CONSTRAINT_FORCES);
  const VectorXd qv = m.Vector(MBDAE_VEC_QUADRATIC_VELOCITY);
  const VectorXd ext = m.Vector(MBDAE_VEC_EXTERNAL_FORCES);
  const VectorXd q = m.Vector(MBDAE_VEC_SUM_OF_FORCES);
  const double scale = std::max({ma.cwiseAbs().maxCoeff(), cf.cwiseAbs().maxCoeff(),
                                 q.cwiseAbs().maxCoeff()});
  EXPECT_LT(worst.Record(what + ": |M a + C_q^T lambda - Q| / max|terms|",
                         (ma + cf - q).cwiseAbs().maxCoeff() / scale),
            tol);
  EXPECT_LT(worst.Record("Q - (Q_v + external), relative", RelErr(qv + ext, q)), 1e-14);
  EXPECT_GT(qv.cwiseAbs().maxCoeff(), 1e-3);  // there are gyroscopic terms
  EXPECT_GT(cf.cwiseAbs().maxCoeff(), 1e-3);
  const State s = m.GetState();
  EXPECT_LT(worst.Record(what + ": |C|", m.Vector(MBDAE_VEC_CONSTRAINTS).cwiseAbs().maxCoeff()),
            1e-9);
  if (velocity_level) {
    const VectorXd cv = m.Matrix(MBDAE_MAT_CONSTRAINT_DQ) * s.v + m.Vector(MBDAE_VEC_CONSTRAINTS_DT);
    EXPECT_LT(worst.Record(what + ": |C_q v + C_t|", cv.cwiseAbs().maxCoeff()), 1e-8);
  }
  // M a and C_q^T lambda are the products of the matrices with the state.
  EXPECT_LT(worst.Record("M a vs matrix M times a", RelErr(ma, m.Matrix(MBDAE_MAT_MASS) * s.a)),
            1e-14);
  EXPECT_LT(worst.Record("C_q^T lambda vs matrix C_q^T times lambda",
                         RelErr(cf, m.Matrix(MBDAE_MAT_CONSTRAINT_DQ).transpose() * s.lambda)),
            1e-14);
}

TEST(StateMatrices, EquationsHoldAtSolvedStates) {
  Worst worst("equations at solved states");
  for (const char* integrator : {"ida", "hht"}) {
    SCOPED_TRACE(integrator);
    Model m(kModel, {{"integrator", integrator}});
    ASSERT_GT(m.nq(), 0);
    EXPECT_EQ(m.nq(), 14);
    EXPECT_EQ(m.nm(), 3 + 4 + 1 + 2);
    const std::string name = integrator;
    // The assembled state: consistent at every level.
    CheckSolvedState(m, true, 1e-12, worst, "assembled");
    for (double t : {0.35, 0.8}) {
      m.SolveTo(t);
      CheckSolvedState(m, name == "ida", 1e-8, worst, name);
    }
    // Acceleration level at a state whose a, lambda solve the equations of motion:
    // C_q a = gamma = -d(C_q)/dt q' - C_tt (no mixed term C_qt in this model).
    const State s = m.GetState();
    m.SetPositionsAndVelocities(s.t, s.q, s.v);
    const State e = m.GetState();
    CheckSolvedState(m, name == "ida", 1e-12, worst, "a, lambda from the equations of motion");
    const VectorXd acc = m.Matrix(MBDAE_MAT_CONSTRAINT_DQ) * e.a +
                         m.Vector(MBDAE_VEC_CONSTRAINTS_QDOT) + m.Vector(MBDAE_VEC_CONSTRAINTS_DTT);
    EXPECT_LT(worst.Record("|C_q a + d(C_q)/dt q' + C_tt| / |C_q a|",
                           acc.cwiseAbs().maxCoeff() /
                               (m.Matrix(MBDAE_MAT_CONSTRAINT_DQ) * e.a).cwiseAbs().maxCoeff()),
              1e-10);
  }
}

TEST(StateMatrices, TimeDerivativeVectorsAgainstFiniteDifferences) {
  Worst worst("time-derivative vectors vs central differences");
  Model m(kModel);
  m.SolveTo(0.45);
  const State s = m.GetState();
  const VectorXd ct = m.Vector(MBDAE_VEC_CONSTRAINTS_DT);
  const VectorXd ctt = m.Vector(MBDAE_VEC_CONSTRAINTS_DTT);
  const VectorXd cqdot = m.Vector(MBDAE_VEC_CONSTRAINTS_QDOT);
  const VectorXd qv = m.Vector(MBDAE_VEC_QUADRATIC_VELOCITY);
  EXPECT_GT(ct.cwiseAbs().maxCoeff(), 1e-3);   // the motion joint's time terms are there
  EXPECT_GT(ctt.cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_GT(cqdot.cwiseAbs().maxCoeff(), 1e-3);
  auto at = [&](double t, const VectorXd& q, const VectorXd& v, const VectorXd& a) {
    State x = s;
    x.t = t;
    x.q = q;
    x.v = v;
    x.a = a;
    m.SetState(x);
  };
  const double h = 1e-5;
  // Partial time derivatives at fixed q.
  at(s.t + h, s.q, s.v, s.a);
  const VectorXd cp = m.Vector(MBDAE_VEC_CONSTRAINTS), ctp = m.Vector(MBDAE_VEC_CONSTRAINTS_DT);
  at(s.t - h, s.q, s.v, s.a);
  const VectorXd cm = m.Vector(MBDAE_VEC_CONSTRAINTS), ctm = m.Vector(MBDAE_VEC_CONSTRAINTS_DT);
  at(s.t, s.q, s.v, s.a);
  const VectorXd c0 = m.Vector(MBDAE_VEC_CONSTRAINTS);
  EXPECT_LT(worst.Record("C_t vs dC/dt", RelErr(ct, (cp - cm) / (2 * h))), 1e-8);
  EXPECT_LT(worst.Record("C_tt vs dC_t/dt", RelErr(ctt, (ctp - ctm) / (2 * h))), 1e-8);
  const double h2 = 1e-4;
  at(s.t + h2, s.q, s.v, s.a);
  const VectorXd cp2 = m.Vector(MBDAE_VEC_CONSTRAINTS);
  at(s.t - h2, s.q, s.v, s.a);
  const VectorXd cm2 = m.Vector(MBDAE_VEC_CONSTRAINTS);
  EXPECT_LT(worst.Record("C_tt vs second difference of C",
                         RelErr(ctt, (cp2 - 2 * c0 + cm2) / (h2 * h2))),
            1e-5);
  // d(C_q)/dt q': the total derivative of C_q along (q + s v, t + s).
  at(s.t + h, s.q + h * s.v, s.v, s.a);
  const MatrixXd cq_p = m.Matrix(MBDAE_MAT_CONSTRAINT_DQ);
  at(s.t - h, s.q - h * s.v, s.v, s.a);
  const MatrixXd cq_m = m.Matrix(MBDAE_MAT_CONSTRAINT_DQ);
  EXPECT_LT(worst.Record("d(C_q)/dt q' vs differences of C_q along the motion",
                         RelErr(cqdot, (cq_p - cq_m) / (2 * h) * s.v)),
            1e-8);
  // Q_v = dT/dq - (dM/dt) q' with T = v^T M(q) v / 2: both from the vector M a with a = v.
  const VectorXd dTdq =
      Jacobian(
          [&](const VectorXd& q) -> VectorXd {
            at(s.t, q, s.v, s.v);
            return VectorXd::Constant(1, 0.5 * s.v.dot(m.Vector(MBDAE_VEC_MASS_TIMES_ACC)));
          },
          s.q, 1e-6)
          .transpose();
  at(s.t, s.q + h * s.v, s.v, s.v);
  const VectorXd mv_p = m.Vector(MBDAE_VEC_MASS_TIMES_ACC);
  at(s.t, s.q - h * s.v, s.v, s.v);
  const VectorXd mv_m = m.Vector(MBDAE_VEC_MASS_TIMES_ACC);
  EXPECT_LT(worst.Record("Q_v vs dT/dq - (dM/dt) q'", RelErr(qv, dTdq - (mv_p - mv_m) / (2 * h))),
            1e-7);
  // The external forces do not contain the inertia terms: at v = 0 they are all of Q,
  // and Q_v is zero.
  at(s.t, s.q, VectorXd::Zero(m.nq()), s.a);
  EXPECT_EQ(m.Vector(MBDAE_VEC_QUADRATIC_VELOCITY).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(m.Vector(MBDAE_VEC_EXTERNAL_FORCES), m.Vector(MBDAE_VEC_SUM_OF_FORCES));
}

// Every single matrix against central differences of its vector, at a solved state.
void CheckMatrices(Model& m, Worst& worst, double tol, double smallest_entry) {
  const State s = m.GetState();
  const int nq = m.nq();
  auto at = [&](const VectorXd& q, const VectorXd& v, const VectorXd& a, const VectorXd& l) {
    State x = s;
    x.q = q;
    x.v = v;
    x.a = a;
    x.lambda = l;
    m.SetState(x);
  };
  const MatrixXd M = m.Matrix(MBDAE_MAT_MASS), Cq = m.Matrix(MBDAE_MAT_CONSTRAINT_DQ);
  const MatrixXd Kma = m.Matrix(MBDAE_MAT_MASS_ACC_DQ), Qq = m.Matrix(MBDAE_MAT_FORCE_DQ);
  const MatrixXd Qv = m.Matrix(MBDAE_MAT_FORCE_DV), Kc = m.Matrix(MBDAE_MAT_CONSTRAINT_T_DQ);
  const double h = 1e-6;
  // Perturbing q: M a, C_q^T lambda, Q, C together.
  std::vector<VectorXd> plus(4), minus(4);
  MatrixXd dMa(nq, nq), dCf(nq, nq), dQ(nq, nq), dC(m.nm(), nq);
  for (int k = 0; k < nq; ++k) {
    for (int sign : {1, -1}) {
      VectorXd q = s.q;
      q[k] += sign * h;
      at(q, s.v, s.a, s.lambda);
      auto& r = sign > 0 ? plus : minus;
      r[0] = m.Vector(MBDAE_VEC_MASS_TIMES_ACC);
      r[1] = m.Vector(MBDAE_VEC_CONSTRAINT_FORCES);
      r[2] = m.Vector(MBDAE_VEC_SUM_OF_FORCES);
      r[3] = m.Vector(MBDAE_VEC_CONSTRAINTS);
    }
    dMa.col(k) = (plus[0] - minus[0]) / (2 * h);
    dCf.col(k) = (plus[1] - minus[1]) / (2 * h);
    dQ.col(k) = (plus[2] - minus[2]) / (2 * h);
    dC.col(k) = (plus[3] - minus[3]) / (2 * h);
  }
  EXPECT_LT(worst.Record("d(M a)/dq", RelErr(Kma, dMa)), tol);
  EXPECT_LT(worst.Record("d(C_q^T lambda)/dq", RelErr(Kc, dCf)), tol);
  EXPECT_LT(worst.Record("dQ/dq", RelErr(Qq, dQ)), tol);
  EXPECT_LT(worst.Record("C_q", RelErr(Cq, dC)), tol);
  // dQ/dv
  const MatrixXd dQv = Jacobian(
      [&](const VectorXd& v) -> VectorXd {
        at(s.q, v, s.a, s.lambda);
        return m.Vector(MBDAE_VEC_SUM_OF_FORCES);
      },
      s.v, h);
  EXPECT_LT(worst.Record("dQ/dv", RelErr(Qv, dQv)), tol);
  // M = d(M a)/da (linear in a: a unit step).
  const MatrixXd dMda = Jacobian(
      [&](const VectorXd& a) -> VectorXd {
        at(s.q, s.v, a, s.lambda);
        return m.Vector(MBDAE_VEC_MASS_TIMES_ACC);
      },
      s.a, 1.0);
  EXPECT_LT(worst.Record("M vs d(M a)/da", RelErr(M, dMda)), 1e-13);
  EXPECT_LT(worst.Record("M symmetric", RelErr(M, M.transpose())), 1e-15);
  m.SetState(s);
  // Nothing trivially zero.
  for (const MatrixXd* x : {&M, &Cq, &Kma, &Qq, &Qv, &Kc})
    EXPECT_GT(x->cwiseAbs().maxCoeff(), smallest_entry);
}

TEST(StateMatrices, MatricesAgainstFiniteDifferences) {
  Worst worst("matrices vs central differences of their vectors");
  for (const char* integrator : {"ida", "hht"}) {
    SCOPED_TRACE(integrator);
    Model m(kModel, {{"integrator", integrator}});
    m.SolveTo(0.3);
    CheckMatrices(m, worst, 1e-7, 1e-3);
  }
}

#ifdef MBDAE_SOURCE_DIR
// The same on the models of the verification studies (spatial, closed loops, springs).
TEST(StateMatrices, MatricesOfExampleModels) {
  Worst worst("matrices of verification models vs central differences");
  for (const char* file : {"verification/andrews/andrews.yaml",
                           "verification/orders/tumbling_pendulum.yaml"}) {
    SCOPED_TRACE(file);
    Model m = Model::FromFile(std::string(MBDAE_SOURCE_DIR) + "/" + file);
    ASSERT_EQ(mbdae_set_option(m.get(), "t_end", "0.01"), MBDAE_OK);
    m.SolveTo(0.002);
    const VectorXd r = m.Vector(MBDAE_VEC_MASS_TIMES_ACC) + m.Vector(MBDAE_VEC_CONSTRAINT_FORCES) -
                       m.Vector(MBDAE_VEC_SUM_OF_FORCES);
    EXPECT_LT(worst.Record("|M a + C_q^T lambda - Q| / max|Q|",
                           r.cwiseAbs().maxCoeff() /
                               std::max(1.0, m.Vector(MBDAE_VEC_SUM_OF_FORCES).cwiseAbs().maxCoeff())),
              1e-8);
    CheckMatrices(m, worst, 1e-6, 1e-5);
  }
}
#endif

// HHT's Newton matrix is the derivative of the step residual with respect to
// (a_{n+1}, lambda_{n+1}) through Newmark's formulas (docs/hht.md):
//   equilibrium: r = [(M a + C_q^T lambda - Q) / (1 + alpha); C / ((1 + alpha) beta h^2)],
//     dq/da = (1 + alpha) beta h^2, dv/da = (1 + alpha) gamma h;
//   negrut: r = [M a / (1 + alpha) + C_q^T lambda - Q; C / (beta h^2)], dq/da = beta h^2,
//     dv/da = gamma h.
TEST(StateMatrices, HhtNewtonMatrixIsTheDerivativeOfTheStepResidual) {
  Worst worst("HHT Newton matrix");
  for (const char* form : {"equilibrium", "negrut"}) {
    SCOPED_TRACE(form);
    const double alpha = -0.2, h = 0.02;
    Model m(kModel, {{"integrator", "hht"}, {"hht.form", form}, {"hht.alpha", "-0.2"}});
    m.SolveTo(0.25);
    ASSERT_EQ(mbdae_set_newton_step(m.get(), h), MBDAE_OK);
    const State s = m.GetState();
    const int nq = m.nq(), nm = m.nm(), n = nq + nm;
    const bool eq = std::string(form) == "equilibrium";
    const double beta = (1 - alpha) * (1 - alpha) / 4, gamma = 0.5 - alpha;
    const double mix = eq ? 1 + alpha : 1.0;
    const MatrixXd J = m.Matrix(MBDAE_MAT_NEWTON_HHT);
    auto residual = [&](const VectorXd& x) -> VectorXd {
      State y = s;
      y.q = s.q + mix * beta * h * h * x.head(nq);
      y.v = s.v + mix * gamma * h * x.head(nq);
      y.a = s.a + x.head(nq);
      y.lambda = s.lambda + x.tail(nm);
      m.SetState(y);
      const VectorXd ma = m.Vector(MBDAE_VEC_MASS_TIMES_ACC);
      const VectorXd f = m.Vector(MBDAE_VEC_CONSTRAINT_FORCES) - m.Vector(MBDAE_VEC_SUM_OF_FORCES);
      VectorXd r(n);
      r.head(nq) = eq ? VectorXd((ma + f) / (1 + alpha)) : VectorXd(ma / (1 + alpha) + f);
      r.tail(nm) = m.Vector(MBDAE_VEC_CONSTRAINTS) / (mix * beta * h * h);
      return r;
    };
    // The residual is nearly linear (the state moves by h^2 da): a large step keeps the
    // rounding of C / (beta h^2) small.
    const MatrixXd J_fd = Jacobian(residual, VectorXd::Zero(n), 1e-3);
    m.SetState(s);
    EXPECT_LT(worst.Record(std::string(form) + ": vs differences of the residual", RelErr(J, J_fd)),
              1e-7);
    // The definition composed from the single matrices (docs/hht.md).
    const double sc = 1 / (1 + alpha), bh2 = beta * h * h;
    const MatrixXd J_def = m.Composed({{MBDAE_MAT_MASS, sc, 0, 0, 0},
                                       {MBDAE_MAT_MASS_ACC_DQ, eq ? bh2 : bh2 * sc, 0, 0, 0},
                                       {MBDAE_MAT_CONSTRAINT_T_DQ, bh2, 0, 0, 0},
                                       {MBDAE_MAT_FORCE_DQ, -bh2, 0, 0, 0},
                                       {MBDAE_MAT_FORCE_DV, -gamma * h, 0, 0, 0},
                                       {MBDAE_MAT_CONSTRAINT_DQ, eq ? sc : 1.0, 0, nq, 1},
                                       {MBDAE_MAT_CONSTRAINT_DQ, 1.0, nq, 0, 0}},
                                      n, n);
    EXPECT_LT(worst.Record(std::string(form) + ": vs the composition of its definition",
                           RelErr(J, J_def)),
              1e-14);
  }
  // Without mbdae_set_newton_step the step is the option hht.step.
  Model by_option(kModel, {{"integrator", "hht"}, {"hht.step", "0.02"}});
  Model by_call(kModel, {{"integrator", "hht"}});
  ASSERT_EQ(mbdae_set_newton_step(by_call.get(), 0.02), MBDAE_OK);
  EXPECT_EQ(by_option.Matrix(MBDAE_MAT_NEWTON_HHT), by_call.Matrix(MBDAE_MAT_NEWTON_HHT));
  EXPECT_NE(by_option.Matrix(MBDAE_MAT_NEWTON_HHT),
            Model(kModel, {{"integrator", "hht"}}).Matrix(MBDAE_MAT_NEWTON_HHT));
}

// IDA's Newton matrix dF/dy + c_j dF/dy' of the GGL residual at y = (q, v, lambda, 0),
// y' = (v, a, ., .), c_j = 1/h:
//   F1 = q' - v + C_q^T mu, F2 = M v' + C_q^T lambda - Q, F3 = C, F4 = C_q v + C_t.
TEST(StateMatrices, IdaNewtonMatrixIsTheDerivativeOfTheGglResidual) {
  Worst worst("IDA Newton matrix");
  Model m(kModel);
  m.SolveTo(0.25);
  const double h = 5e-3, cj = 1 / h;
  ASSERT_EQ(mbdae_set_newton_step(m.get(), h), MBDAE_OK);
  const State s = m.GetState();
  const int nq = m.nq(), nm = m.nm(), n = 2 * nq + 2 * nm;
  const MatrixXd J = m.Matrix(MBDAE_MAT_NEWTON_IDA);
  ASSERT_EQ(J.rows(), n);
  // F at y = (q, v, lambda, mu), y' = (qp, vp); mu enters F1 only (C_q^T mu).
  auto F = [&](const VectorXd& y, const VectorXd& yp) -> VectorXd {
    State x = s;
    x.q = y.segment(0, nq);
    x.v = y.segment(nq, nq);
    x.lambda = y.segment(2 * nq, nm);
    x.a = yp.segment(nq, nq);
    m.SetState(x);
    const MatrixXd Cq = m.Matrix(MBDAE_MAT_CONSTRAINT_DQ);
    VectorXd r(n);
    r.segment(0, nq) = yp.segment(0, nq) - x.v + Cq.transpose() * y.segment(2 * nq + nm, nm);
    r.segment(nq, nq) = m.Vector(MBDAE_VEC_MASS_TIMES_ACC) + m.Vector(MBDAE_VEC_CONSTRAINT_FORCES) -
                        m.Vector(MBDAE_VEC_SUM_OF_FORCES);
    r.segment(2 * nq, nm) = m.Vector(MBDAE_VEC_CONSTRAINTS);
    r.segment(2 * nq + nm, nm) = Cq * x.v + m.Vector(MBDAE_VEC_CONSTRAINTS_DT);
    return r;
  };
  VectorXd y = VectorXd::Zero(n), yp = VectorXd::Zero(n);
  y << s.q, s.v, s.lambda, VectorXd::Zero(nm);
  yp << s.v, s.a, VectorXd::Zero(2 * nm);
  const MatrixXd dFdy = Jacobian([&](const VectorXd& z) { return F(z, yp); }, y, 1e-6);
  const MatrixXd dFdyp = Jacobian([&](const VectorXd& z) { return F(y, z); }, yp, 1e-3);
  m.SetState(s);
  EXPECT_LT(worst.Record("vs differences of the GGL residual", RelErr(J, dFdy + cj * dFdyp)), 1e-7);
  // The residual vanishes at the solved state (to IDA's tolerance; mu = 0), relative to
  // the forces.
  const VectorXd F0 = F(y, yp);
  EXPECT_LT(worst.Record("|F| at the solved state / max|Q|",
                         F0.cwiseAbs().maxCoeff() /
                             std::max(1.0, m.Vector(MBDAE_VEC_SUM_OF_FORCES).cwiseAbs().maxCoeff())),
            1e-7);
  m.SetState(s);
}

TEST(StateMatrices, CompositionsCscCsrAndDense) {
  Worst worst("compositions");
  Model m(kModel);
  m.SolveTo(0.2);
  const int nq = m.nq(), nm = m.nm();
  const MatrixXd M = m.Matrix(MBDAE_MAT_MASS), Cq = m.Matrix(MBDAE_MAT_CONSTRAINT_DQ);
  const MatrixXd Qq = m.Matrix(MBDAE_MAT_FORCE_DQ), Kc = m.Matrix(MBDAE_MAT_CONSTRAINT_T_DQ);
  const MatrixXd Qv = m.Matrix(MBDAE_MAT_FORCE_DV);
  // A transposed single block equals the transpose.
  EXPECT_EQ(m.Matrix(MBDAE_MAT_CONSTRAINT_DQ, true, 1.0), Cq.transpose());
  // Scaled, transposed, overlapping blocks in a larger matrix.
  const int rows = nq + nm + 3, cols = nq + 2 * nm + 2;
  const std::vector<mbdae_block> blocks = {
      {MBDAE_MAT_MASS, 2.0, 0, 0, 0},
      {MBDAE_MAT_FORCE_DQ, -0.5, 0, 0, 0},           // on top of M
      {MBDAE_MAT_FORCE_DV, 0.25, 1, 2, 0},           // shifted: overlaps both
      {MBDAE_MAT_CONSTRAINT_DQ, 1.5, 0, nq, 1},      // C_q^T
      {MBDAE_MAT_CONSTRAINT_DQ, -1.0, nq + 3, 2, 0}, // C_q, offset
      {MBDAE_MAT_CONSTRAINT_T_DQ, 3.0, 2, 1, 1},     // transposed, overlapping
      {MBDAE_MAT_CONSTRAINT_DQ, 0.5, 3, nq + nm + 2, 1}};
  MatrixXd dense = MatrixXd::Zero(rows, cols);
  dense.block(0, 0, nq, nq) += 2.0 * M - 0.5 * Qq;
  dense.block(1, 2, nq, nq) += 0.25 * Qv;
  dense.block(0, nq, nq, nm) += 1.5 * Cq.transpose();
  dense.block(nq + 3, 2, nm, nq) += -1.0 * Cq;
  dense.block(2, 1, nq, nq) += 3.0 * Kc.transpose();
  dense.block(3, nq + nm + 2, nq, nm) += 0.5 * Cq.transpose();
  int nnz_csc = 0, nnz_csr = 0;
  const MatrixXd csc = m.Composed(blocks, rows, cols, MBDAE_CSC, &nnz_csc);
  const MatrixXd csr = m.Composed(blocks, rows, cols, MBDAE_CSR, &nnz_csr);
  EXPECT_EQ(nnz_csc, nnz_csr);
  EXPECT_EQ(csc, csr);  // the same numbers, bitwise
  EXPECT_LT(worst.Record("composition vs dense composition", RelErr(csc, dense)), 1e-14);
  // The pattern is the structural one: at least the non-zeros, at most the union of the
  // blocks' patterns.
  int nonzeros = 0;
  for (int c = 0; c < cols; ++c)
    for (int r = 0; r < rows; ++r) nonzeros += dense(r, c) != 0;
  EXPECT_GE(nnz_csc, nonzeros);
  // The Newton matrices in CSR equal their CSC.
  for (mbdae_matrix w : {MBDAE_MAT_NEWTON_HHT, MBDAE_MAT_NEWTON_IDA}) {
    const int size = w == MBDAE_MAT_NEWTON_HHT ? nq + nm : 2 * nq + 2 * nm;
    EXPECT_EQ(m.Composed({{w, 1.0, 0, 0, 0}}, size, size, MBDAE_CSC),
              m.Composed({{w, 1.0, 0, 0, 0}}, size, size, MBDAE_CSR));
  }
  // No blocks: an empty matrix.
  int nnz = -1;
  EXPECT_EQ(mbdae_get_matrix(m.get(), nullptr, 0, 3, 2, MBDAE_CSR, &nnz, nullptr, nullptr, nullptr),
            MBDAE_OK);
  EXPECT_EQ(nnz, 0);
}

TEST(StateMatrices, MeasureGradientsAgainstFiniteDifferences) {
  Worst worst("measure gradients vs central differences");
  Model m(kModel);
  int nmeas = 0;
  ASSERT_EQ(mbdae_count(m.get(), MBDAE_MEASURES, &nmeas), MBDAE_OK);
  ASSERT_EQ(nmeas, 7);
  // At the assembled state the values are the first stored row (offset_initial: 0).
  std::vector<double> row0(nmeas);
  ASSERT_EQ(mbdae_get_output(m.get(), 0, MBDAE_OUT_MEASURES, row0.data(), nmeas), MBDAE_OK)
      << mbdae_last_error();
  const std::vector<double> values0 = m.Measures();
  for (int k = 0; k < nmeas; ++k)
    EXPECT_NEAR(values0[k], row0[k], 1e-14 * std::max(1.0, std::abs(row0[k]))) << k;
  EXPECT_EQ(values0[4], 0.0);  // swing: offset_initial
  m.SolveTo(0.4);
  const State s = m.GetState();
  const int nq = m.nq();
  MatrixXd G(nmeas, nq);
  for (int k = 0; k < nmeas; ++k) {
    VectorXd g = VectorXd::Constant(nq, NAN);
    ASSERT_EQ(mbdae_measure_gradient(m.get(), k, g.data(), nq), MBDAE_OK) << mbdae_last_error();
    G.row(k) = g.transpose();
  }
  const MatrixXd G_fd = Jacobian(
      [&](const VectorXd& q) -> VectorXd {
        State x = s;
        x.q = q;
        m.SetState(x);
        const std::vector<double> v = m.Measures();
        return Eigen::Map<const VectorXd>(v.data(), nmeas);
      },
      s.q, 1e-6);
  const char* names[] = {"s (position)", "height (position, world)", "reach (velocity)",
                         "spin (angular velocity)", "swing (angle)",
                         "whirl (angular acceleration)", "pull (acceleration)"};
  for (int k = 0; k < nmeas; ++k) {
    EXPECT_LT(worst.Record(names[k], RelErr(G.row(k), G_fd.row(k))), 1e-7) << names[k];
    EXPECT_GT(G.row(k).cwiseAbs().maxCoeff(), 1e-3) << names[k];
  }
}

TEST(StateMatrices, WrongArgumentsAreRejectedWithoutTouchingTheOutputs) {
  Model m(kModel);
  const int nq = m.nq(), nm = m.nm();
  std::vector<double> out(nq + 5, 7.0);
  auto untouched = [&] {
    return std::all_of(out.begin(), out.end(), [](double x) { return x == 7.0; });
  };
  auto message = [] { return std::string(mbdae_last_error()); };
  EXPECT_EQ(mbdae_get_vector(m.get(), MBDAE_VEC_MASS_TIMES_ACC, out.data(), nq + 1), MBDAE_ERROR_SIZE);
  EXPECT_NE(message().find("expected " + std::to_string(nq)), std::string::npos) << message();
  EXPECT_EQ(mbdae_get_vector(m.get(), MBDAE_VEC_CONSTRAINTS, out.data(), nq), MBDAE_ERROR_SIZE);
  EXPECT_NE(message().find("expected " + std::to_string(nm)), std::string::npos) << message();
  EXPECT_EQ(mbdae_get_vector(m.get(), static_cast<mbdae_vector>(9), out.data(), nq),
            MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_measure_values(m.get(), out.data(), 3), MBDAE_ERROR_SIZE);
  EXPECT_NE(message().find("expected 7"), std::string::npos) << message();
  EXPECT_EQ(mbdae_measure_gradient(m.get(), 7, out.data(), nq), MBDAE_ERROR_ARGUMENT);
  EXPECT_NE(message().find("measure index 7"), std::string::npos) << message();
  EXPECT_EQ(mbdae_measure_gradient(m.get(), -1, out.data(), nq), MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_measure_gradient(m.get(), 0, out.data(), nq - 1), MBDAE_ERROR_SIZE);
  EXPECT_TRUE(untouched());
  EXPECT_EQ(mbdae_get_vector(m.get(), MBDAE_VEC_CONSTRAINTS, out.data(), nm), MBDAE_OK);
  EXPECT_EQ(std::string(mbdae_last_error()), "");

  int nnz = -1;
  std::vector<int> ptr(nq + 1, -3), idx(1000, -3);
  std::vector<double> val(1000, 7.0);
  const mbdae_block ok{MBDAE_MAT_MASS, 1.0, 0, 0, 0};
  // A block that does not fit, a negative position, an unknown matrix, a bad format.
  const mbdae_block too_far{MBDAE_MAT_CONSTRAINT_DQ, 1.0, 1, 0, 1};  // nq x nm at row 1
  EXPECT_EQ(mbdae_get_matrix(m.get(), &too_far, 1, nq, nm, MBDAE_CSC, &nnz, nullptr, nullptr,
                             nullptr),
            MBDAE_ERROR_ARGUMENT);
  EXPECT_NE(message().find("does not fit"), std::string::npos) << message();
  EXPECT_NE(message().find("transposed"), std::string::npos) << message();
  const mbdae_block negative{MBDAE_MAT_MASS, 1.0, -1, 0, 0};
  EXPECT_EQ(mbdae_get_matrix(m.get(), &negative, 1, nq + 1, nq, MBDAE_CSC, &nnz, nullptr, nullptr,
                             nullptr),
            MBDAE_ERROR_ARGUMENT);
  const mbdae_block unknown{static_cast<mbdae_matrix>(8), 1.0, 0, 0, 0};
  EXPECT_EQ(mbdae_get_matrix(m.get(), &unknown, 1, nq, nq, MBDAE_CSC, &nnz, nullptr, nullptr,
                             nullptr),
            MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_get_matrix(m.get(), &ok, 1, nq, nq, static_cast<mbdae_sparse_format>(2), &nnz,
                             nullptr, nullptr, nullptr),
            MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(nnz, -1);
  // The query, then a fill with a wrong nnz, and with only some arrays.
  ASSERT_EQ(mbdae_get_matrix(m.get(), &ok, 1, nq, nq, MBDAE_CSC, &nnz, nullptr, nullptr, nullptr),
            MBDAE_OK);
  EXPECT_EQ(nnz, 2 * (3 + 16));  // two bodies: 3 + 16 entries each
  int wrong = nnz - 1;
  EXPECT_EQ(mbdae_get_matrix(m.get(), &ok, 1, nq, nq, MBDAE_CSC, &wrong, ptr.data(), idx.data(),
                             val.data()),
            MBDAE_ERROR_SIZE);
  EXPECT_NE(message().find("expected " + std::to_string(nnz)), std::string::npos) << message();
  EXPECT_EQ(mbdae_get_matrix(m.get(), &ok, 1, nq, nq, MBDAE_CSC, &nnz, ptr.data(), nullptr,
                             val.data()),
            MBDAE_ERROR_ARGUMENT);
  EXPECT_TRUE(std::all_of(ptr.begin(), ptr.end(), [](int x) { return x == -3; }));
  EXPECT_TRUE(std::all_of(val.begin(), val.end(), [](double x) { return x == 7.0; }));
  EXPECT_EQ(mbdae_set_newton_step(m.get(), 0.0), MBDAE_ERROR_ARGUMENT);
}

}  // namespace
