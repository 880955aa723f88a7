// A small mechanical DAE in which every matrix of the interface is non-trivial, for
// finite-difference tests of Jacobians built from the system's derivatives:
//   q = (x, y, z),   M(q) = diag(1 + x^2, 2 + sin y, 3),
//   Q(q, v, t) = [-k x + c v0 y,  -g - d v1^2,  sin(t) z v2],
//   C0 = x^2 + y^2 + z^2 - L^2,   C1 = x - z cos t - s t   (time dependent).
#pragma once

#include <cmath>

#include "dae/mechanical_system.h"

namespace mbdae::testing {

class NonlinearSystem : public dae::MechanicalSystem {
 public:
  double k = 3.0, c = 0.5, g = 9.81, d = 0.2, L = 1.0, s = 0.1;

  NonlinearSystem() {
    using dae::CscPattern;
    diag_ = CscPattern::FromEntries(3, 3, {{0, 0}, {1, 1}, {2, 2}});
    madq_ = CscPattern::FromEntries(3, 3, {{0, 0}, {1, 1}});
    fdq_ = CscPattern::FromEntries(3, 3, {{0, 0}, {0, 1}, {2, 2}});
    cq_ = CscPattern::FromEntries(2, 3, {{0, 0}, {1, 0}, {0, 1}, {0, 2}, {1, 2}});
    veldq_ = CscPattern::FromEntries(2, 3, {{0, 0}, {0, 1}, {0, 2}, {1, 2}});
  }
  int num_coordinates() const override { return 3; }
  int num_constraints() const override { return 2; }
  const dae::CscPattern& pattern(dae::Matrix m) const override {
    switch (m) {
      case dae::Matrix::kMass: return diag_;
      case dae::Matrix::kMassTimesAccDq: return madq_;
      case dae::Matrix::kForceDq: return fdq_;
      case dae::Matrix::kForceDv: return diag_;
      case dae::Matrix::kConstraintDq: return cq_;
      case dae::Matrix::kConstraintTDq: return diag_;
      case dae::Matrix::kConstraintVelDq: return veldq_;
    }
    return diag_;
  }
  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override {
    using dae::Matrix;
    const double t = in.t;
    const double* q = in.q;
    const double* v = in.v;
    const double x = q[0], y = q[1], z = q[2];
    const double st = std::sin(t), ct = std::cos(t);
    if (out.force) {
      out.force[0] = -k * x + c * v[0] * y;
      out.force[1] = -g - d * v[1] * v[1];
      out.force[2] = st * z * v[2];
    }
    if (out.constraint) {
      out.constraint[0] = x * x + y * y + z * z - L * L;
      out.constraint[1] = x - z * ct - s * t;
    }
    if (out.constraint_dt) {
      out.constraint_dt[0] = 0;
      out.constraint_dt[1] = z * st - s;
    }
    if (out.acc_rhs) {
      out.acc_rhs[0] = -2 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      out.acc_rhs[1] = -(2 * st * v[2] + z * ct);
    }
    if (double* M = out[Matrix::kMass]) { M[0] = 1 + x * x; M[1] = 2 + std::sin(y); M[2] = 3; }
    if (double* K = out[Matrix::kMassTimesAccDq]) {
      K[0] = 2 * x * in.a[0];
      K[1] = std::cos(y) * in.a[1];
    }
    if (double* K = out[Matrix::kForceDq]) { K[0] = -k; K[1] = c * v[0]; K[2] = st * v[2]; }
    if (double* K = out[Matrix::kForceDv]) { K[0] = c * y; K[1] = -2 * d * v[1]; K[2] = st * z; }
    if (double* C = out[Matrix::kConstraintDq]) {
      // CSC order: (0,0) (1,0) | (0,1) | (0,2) (1,2)
      C[0] = 2 * x; C[1] = 1; C[2] = 2 * y; C[3] = 2 * z; C[4] = -ct;
    }
    if (double* K = out[Matrix::kConstraintTDq]) {
      K[0] = K[1] = K[2] = 2 * in.w[0];
    }
    if (double* K = out[Matrix::kConstraintVelDq]) {
      // CSC order: (0,0) | (0,1) | (0,2) (1,2)
      K[0] = 2 * v[0]; K[1] = 2 * v[1]; K[2] = 2 * v[2]; K[3] = st;
    }
    return 0;
  }

 private:
  dae::CscPattern diag_, madq_, fdq_, cq_, veldq_;
};

}  // namespace mbdae::testing
