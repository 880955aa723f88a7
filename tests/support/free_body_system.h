// A single free rigid body with Euler parameters written directly as a mechanical DAE,
// for testing integrators without the multibody layer. Coordinates q = (r, e), r the
// position of the centre of mass (world), e the Euler parameters (scalar first).
// Following Nikravesh, Computer-Aided Analysis of Mechanical Systems (1988), ch. 11:
//   M(q) = blockdiag(m I3, 4 G^T J G),
//   Q    = (f, 2 G^T n + 8 G'^T J G' e),     G = G(e), G' = G(e'),
//   C    = e^T e - 1,
// with J = diag(J1, J2, J3) the principal inertia, f a constant world force and n a
// constant body-fixed moment. G(e) is the 3x4 matrix with omega_body = 2 G(e) e'.
#pragma once

#include <array>
#include <vector>

#include "dae/mechanical_system.h"

namespace mbdae::testing {

class FreeBodySystem : public dae::MechanicalSystem {
 public:
  FreeBodySystem(double m, std::array<double, 3> J, std::array<double, 3> f,
                 std::array<double, 3> n_body)
      : m_(m), J_(J), f_(f), n_(n_body), quats_{3} {
    using dae::CscPattern;
    std::vector<std::pair<int, int>> mass, rot, cq, none;
    for (int i = 0; i < 3; ++i) mass.push_back({i, i});
    for (int i = 3; i < 7; ++i)
      for (int j = 3; j < 7; ++j) {
        mass.push_back({i, j});
        rot.push_back({i, j});
      }
    for (int j = 3; j < 7; ++j) cq.push_back({0, j});
    mass_ = CscPattern::FromEntries(7, 7, mass);
    rot_ = CscPattern::FromEntries(7, 7, rot);
    cq_ = CscPattern::FromEntries(1, 7, cq);
    empty_ = CscPattern::FromEntries(7, 7, none);
  }

  int num_coordinates() const override { return 7; }
  int num_constraints() const override { return 1; }
  const std::vector<int>& quaternion_offsets() const override { return quats_; }
  const dae::CscPattern& pattern(dae::Matrix m) const override {
    switch (m) {
      case dae::Matrix::kMass: return mass_;
      case dae::Matrix::kMassTimesAccDq:
      case dae::Matrix::kForceDq:
      case dae::Matrix::kForceDv:
      case dae::Matrix::kConstraintTDq: return rot_;
      case dae::Matrix::kConstraintDq:
      case dae::Matrix::kConstraintVelDq: return cq_;
    }
    return empty_;
  }

  // G(e) x and G(e)^T y (bilinear in their arguments).
  static void Gx(const double* e, const double* x, double* out) {
    out[0] = -e[1] * x[0] + e[0] * x[1] + e[3] * x[2] - e[2] * x[3];
    out[1] = -e[2] * x[0] - e[3] * x[1] + e[0] * x[2] + e[1] * x[3];
    out[2] = -e[3] * x[0] + e[2] * x[1] - e[1] * x[2] + e[0] * x[3];
  }
  static void Gt(const double* e, const double* y, double* out) {
    out[0] = -e[1] * y[0] - e[2] * y[1] - e[3] * y[2];
    out[1] = e[0] * y[0] - e[3] * y[1] + e[2] * y[2];
    out[2] = e[3] * y[0] + e[0] * y[1] - e[1] * y[2];
    out[3] = -e[2] * y[0] + e[1] * y[1] + e[0] * y[2];
  }
  // Body angular velocity 2 G(e) e'.
  static std::array<double, 3> Omega(const double* e, const double* ed) {
    std::array<double, 3> w;
    Gx(e, ed, w.data());
    for (double& x : w) x *= 2;
    return w;
  }

  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override {
    const double* e = in.q + 3;
    const double* ed = in.v ? in.v + 3 : nullptr;
    static const double unit[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    auto J = [&](double* y) { for (int k = 0; k < 3; ++k) y[k] *= J_[k]; };
    if (out.force) {
      for (int i = 0; i < 3; ++i) out.force[i] = f_[i];
      double t1[4], w[3], t2[4];
      Gt(e, n_.data(), t1);
      Gx(ed, e, w);  // G(e') e
      J(w);
      Gt(ed, w, t2);
      for (int k = 0; k < 4; ++k) out.force[3 + k] = 2 * t1[k] + 8 * t2[k];
    }
    if (out.constraint) out.constraint[0] = e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3] - 1;
    if (out.constraint_dt) out.constraint_dt[0] = 0;
    if (out.acc_rhs)
      out.acc_rhs[0] = -2 * (ed[0] * ed[0] + ed[1] * ed[1] + ed[2] * ed[2] + ed[3] * ed[3]);
    // Dense 4x4 rotational blocks are stored column-major in rows/cols 3..6; for the
    // mass pattern they follow the three translational diagonal entries.
    if (double* M = out[dae::Matrix::kMass]) {
      for (int i = 0; i < 3; ++i) M[i] = m_;
      for (int c = 0; c < 4; ++c) {  // column c of 4 G^T J G = 4 G^T J G u_c
        double w[3], col[4];
        Gx(e, unit[c], w);
        J(w);
        Gt(e, w, col);
        for (int r = 0; r < 4; ++r) M[3 + 4 * c + r] = 4 * col[r];
      }
    }
    if (double* K = out[dae::Matrix::kMassTimesAccDq]) {
      // d(4 G(e)^T J G(e) a)/de, column c: 4 G(u_c)^T J G(e) a + 4 G(e)^T J G(u_c) a.
      const double* a = in.a + 3;
      double JGa[3];
      Gx(e, a, JGa);
      J(JGa);
      for (int c = 0; c < 4; ++c) {
        double c1[4], w[3], c2[4];
        Gt(unit[c], JGa, c1);
        Gx(unit[c], a, w);
        J(w);
        Gt(e, w, c2);
        for (int r = 0; r < 4; ++r) K[4 * c + r] = 4 * (c1[r] + c2[r]);
      }
    }
    if (double* K = out[dae::Matrix::kForceDq]) {
      // d/de of 2 G(e)^T n + 8 G(e')^T J G(e') e: 2 G(u_c)^T n + 8 G(e')^T J G(e') u_c.
      for (int c = 0; c < 4; ++c) {
        double c1[4], w[3], c2[4];
        Gt(unit[c], n_.data(), c1);
        Gx(ed, unit[c], w);
        J(w);
        Gt(ed, w, c2);
        for (int r = 0; r < 4; ++r) K[4 * c + r] = 2 * c1[r] + 8 * c2[r];
      }
    }
    if (double* K = out[dae::Matrix::kForceDv]) {
      // d/de' of 8 G(e')^T J G(e') e: 8 G(u_c)^T J G(e') e + 8 G(e')^T J G(u_c) e.
      double JGe[3];
      Gx(ed, e, JGe);
      J(JGe);
      for (int c = 0; c < 4; ++c) {
        double c1[4], w[3], c2[4];
        Gt(unit[c], JGe, c1);
        Gx(unit[c], e, w);
        J(w);
        Gt(ed, w, c2);
        for (int r = 0; r < 4; ++r) K[4 * c + r] = 8 * (c1[r] + c2[r]);
      }
    }
    if (double* C = out[dae::Matrix::kConstraintDq])
      for (int k = 0; k < 4; ++k) C[k] = 2 * e[k];
    if (double* C = out[dae::Matrix::kConstraintVelDq])
      for (int k = 0; k < 4; ++k) C[k] = 2 * ed[k];
    if (double* K = out[dae::Matrix::kConstraintTDq])
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) K[4 * c + r] = r == c ? 2 * in.w[0] : 0.0;
    return 0;
  }

 private:
  double m_;
  std::array<double, 3> J_, f_, n_;
  std::vector<int> quats_;
  dae::CscPattern mass_, rot_, cq_, empty_;
};

}  // namespace mbdae::testing
