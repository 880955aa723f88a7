// A point-mass pendulum in Cartesian coordinates with viscous damping and four
// parameters p = (m, L, g, c), written directly as a mechanical DAE with exact
// parameter derivatives, for testing sensitivity solvers without the multibody layer:
//   m a + [2x 2y]^T lambda = [-c vx, -m g - c vy],     x^2 + y^2 - L^2 = 0.
#pragma once

#include "dae/mechanical_system.h"

namespace mbdae::testing {

class ParametricPendulum : public dae::MechanicalSystem {
 public:
  enum { kMass = 0, kLength = 1, kGravity = 2, kDamping = 3 };
  explicit ParametricPendulum(double m = 1.0, double L = 1.0, double g = 9.81, double c = 0.1)
      : p_{m, L, g, c} {
    using dae::CscPattern;
    diag_ = CscPattern::FromEntries(2, 2, {{0, 0}, {1, 1}});
    empty_ = CscPattern::FromEntries(2, 2, {});
    row2_ = CscPattern::FromEntries(1, 2, {{0, 0}, {0, 1}});
    p_ma_ = CscPattern::FromEntries(2, 4, {{0, kMass}, {1, kMass}});
    p_q_ = CscPattern::FromEntries(2, 4, {{1, kMass}, {1, kGravity}, {0, kDamping}, {1, kDamping}});
    p_nq_ = CscPattern::FromEntries(2, 4, {});
    p_c_ = CscPattern::FromEntries(1, 4, {{0, kLength}});
    p_nc_ = CscPattern::FromEntries(1, 4, {});
  }
  double& parameter(int k) { return p_[k]; }

  int num_coordinates() const override { return 2; }
  int num_constraints() const override { return 1; }
  int num_parameters() const override { return 4; }
  const dae::CscPattern& pattern(dae::Matrix m) const override {
    switch (m) {
      case dae::Matrix::kMass: return diag_;
      case dae::Matrix::kConstraintTDq: return diag_;
      case dae::Matrix::kForceDv: return diag_;
      case dae::Matrix::kConstraintDq: return row2_;
      case dae::Matrix::kConstraintVelDq: return row2_;
      default: return empty_;
    }
  }
  const dae::CscPattern& parameter_pattern(dae::ParameterMatrix m) const override {
    switch (m) {
      case dae::ParameterMatrix::kMassTimesAccDp: return p_ma_;
      case dae::ParameterMatrix::kForceDp: return p_q_;
      case dae::ParameterMatrix::kConstraintDp: return p_c_;
      case dae::ParameterMatrix::kConstraintTDp: return p_nq_;
      default: return p_nc_;
    }
  }
  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override {
    const double m = p_[kMass], L = p_[kLength], g = p_[kGravity], c = p_[kDamping];
    const double* q = in.q;
    const double zero[2] = {0, 0};
    const double* v = in.v ? in.v : zero;
    const double* a = in.a ? in.a : zero;
    if (out.force) { out.force[0] = -c * v[0]; out.force[1] = -m * g - c * v[1]; }
    if (out.constraint) out.constraint[0] = q[0] * q[0] + q[1] * q[1] - L * L;
    if (out.constraint_dt) out.constraint_dt[0] = 0;
    if (out.acc_rhs) out.acc_rhs[0] = -2 * (v[0] * v[0] + v[1] * v[1]);
    if (out.constraint_dtt) out.constraint_dtt[0] = 0;
    if (out.force_quadratic_velocity) out.force_quadratic_velocity[0] = out.force_quadratic_velocity[1] = 0;
    if (double* M = out[dae::Matrix::kMass]) { M[0] = m; M[1] = m; }
    if (double* K = out[dae::Matrix::kForceDv]) { K[0] = -c; K[1] = -c; }
    if (double* C = out[dae::Matrix::kConstraintDq]) { C[0] = 2 * q[0]; C[1] = 2 * q[1]; }
    if (double* C = out[dae::Matrix::kConstraintVelDq]) { C[0] = 2 * v[0]; C[1] = 2 * v[1]; }
    if (double* K = out[dae::Matrix::kConstraintTDq]) { K[0] = 2 * in.w[0]; K[1] = 2 * in.w[0]; }
    if (double* P = out[dae::ParameterMatrix::kMassTimesAccDp]) { P[0] = a[0]; P[1] = a[1]; }
    if (double* P = out[dae::ParameterMatrix::kForceDp]) {
      P[0] = -g;     // dQ_y/dm
      P[1] = -m;     // dQ_y/dg
      P[2] = -v[0];  // dQ_x/dc
      P[3] = -v[1];  // dQ_y/dc
    }
    if (double* P = out[dae::ParameterMatrix::kConstraintDp]) P[0] = -2 * L;
    return 0;
  }

 private:
  double p_[4];
  dae::CscPattern diag_, empty_, row2_, p_ma_, p_q_, p_nq_, p_c_, p_nc_;
};

}  // namespace mbdae::testing
