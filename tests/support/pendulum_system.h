// A point-mass pendulum in Cartesian coordinates written directly as a mechanical DAE,
// for testing integrators without the multibody layer:
//   m a + [2x 2y]^T lambda = [0, -m g],     x^2 + y^2 - L^2 = 0.
// With `redundant` a second copy of the constraint (scaled by 2) is added.
#pragma once

#include <cmath>

#include "dae/mechanical_system.h"

namespace mbdae::testing {

class PendulumSystem : public dae::MechanicalSystem {
 public:
  PendulumSystem(double m, double L, double g, bool redundant = false)
      : m_(m), L_(L), g_(g), nc_(redundant ? 2 : 1) {
    using dae::CscPattern;
    diag_ = CscPattern::FromEntries(2, 2, {{0, 0}, {1, 1}});
    empty_ = CscPattern::FromEntries(2, 2, {});
    std::vector<std::pair<int, int>> cq;
    for (int r = 0; r < nc_; ++r) { cq.push_back({r, 0}); cq.push_back({r, 1}); }
    cq_ = CscPattern::FromEntries(nc_, 2, cq);
  }
  int num_coordinates() const override { return 2; }
  int num_constraints() const override { return nc_; }
  const dae::CscPattern& pattern(dae::Matrix m) const override {
    switch (m) {
      case dae::Matrix::kMass: return diag_;
      case dae::Matrix::kConstraintTDq: return diag_;
      case dae::Matrix::kConstraintDq: return cq_;
      case dae::Matrix::kConstraintVelDq: return cq_;
      default: return empty_;
    }
  }
  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override {
    const double* q = in.q;
    const double* v = in.v;
    const double s[2] = {1.0, 2.0};  // scale of each constraint copy
    if (out.force) { out.force[0] = 0; out.force[1] = -m_ * g_; }
    for (int r = 0; r < nc_; ++r) {
      if (out.constraint) out.constraint[r] = s[r] * (q[0] * q[0] + q[1] * q[1] - L_ * L_);
      if (out.constraint_dt) out.constraint_dt[r] = 0;
      if (out.acc_rhs) out.acc_rhs[r] = -s[r] * 2 * (v[0] * v[0] + v[1] * v[1]);
    }
    if (double* M = out[dae::Matrix::kMass]) { M[0] = m_; M[1] = m_; }
    // C_q entries in CSC order: column 0 rows 0..nc-1, then column 1.
    if (double* C = out[dae::Matrix::kConstraintDq])
      for (int r = 0; r < nc_; ++r) { C[r] = s[r] * 2 * q[0]; C[nc_ + r] = s[r] * 2 * q[1]; }
    if (double* C = out[dae::Matrix::kConstraintVelDq])
      for (int r = 0; r < nc_; ++r) { C[r] = s[r] * 2 * v[0]; C[nc_ + r] = s[r] * 2 * v[1]; }
    if (double* K = out[dae::Matrix::kConstraintTDq]) {
      double w = 0;
      for (int r = 0; r < nc_; ++r) w += s[r] * 2 * in.w[r];
      K[0] = w; K[1] = w;
    }
    return 0;
  }
  // Closed-form period for release at rest from angle theta0 from the downward vertical.
  double m_, L_, g_;
 private:
  int nc_;
  dae::CscPattern diag_, empty_, cq_;
};

}  // namespace mbdae::testing
