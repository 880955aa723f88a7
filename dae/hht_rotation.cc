#include "dae/hht_rotation.h"

#include <Eigen/Dense>

namespace mbdae::dae {

void HhtRotationDerivative(const HhtRotationScheme& sc, double h, double r, const double* x,
                           double* de_da, double* ded_da) {
  using L = HhtRotationLayout;
  HhtRotationInside<double> m;
  double y[L::kOutputs];
  HhtRotationMap(sc, h, r, x, y, &m);
  const double bh2 = sc.beta * h * h, gh = sc.gamma * h;
  const double mb = sc.mix * bh2, mg = sc.mix * gh, rho = mb * m.s;
  // d cos(|theta|/2) / d|theta|^2 and d (sin(|theta|/2)/|theta|) / d|theta|^2, on the
  // map's branches.
  double dc, dsc;
  if (m.ang2 > 1e-16) {
    dc = -m.sc / 4;
    dsc = (m.c / 2 - m.sc) / (2 * m.ang2);
  } else {
    dc = -1.0 / 8 + m.ang2 / 192;
    dsc = -1.0 / 48;
  }
  // D (8 x 3): the derivative of (e_{n+1}, e'_{n+1}) with respect to omegabar'_{n+1}
  // (theta moves by beta h^2, omega_{n+1} by gamma h).
  Eigen::Matrix<double, 8, 3> D;
  const double* e0 = x + L::kE0;
  const double* a1 = x + L::kA1;
  for (int k = 0; k < 3; ++k) {
    const double dang2 = 2 * m.th[k] * bh2;
    double drq[4];
    drq[0] = dc * dang2;
    for (int j = 0; j < 3; ++j) drq[1 + j] = dsc * dang2 * m.th[j] + (j == k ? m.sc * bh2 : 0);
    double deu[4];  // e_n (x) drq
    HhtQuatMul(e0, drq, deu);
    // ed = G(u)^T omega_{n+1} / 2: d ed = (G(du)^T omega_{n+1} + gamma h G(u)^T e_k) / 2.
    const double* u = m.eu;
    double ded[4];
    HhtRotationGt(deu, m.w1, ded);
    const double gtu[3][4] = {{-u[1], u[0], u[3], -u[2]},   // G(u)^T columns
                              {-u[2], -u[3], u[0], u[1]},
                              {-u[3], u[2], -u[1], u[0]}};
    double ds = 0;
    for (int i = 0; i < 4; ++i) {
      ded[i] = 0.5 * (ded[i] + gh * gtu[k][i]);
      ds += deu[i] * a1[i] + 2 * m.ed[i] * ded[i];
    }
    for (int i = 0; i < 4; ++i) {
      D(i, k) = mb * ds * u[i] + (1 + rho) * deu[i];
      D(4 + i, k) = ded[i] + mg * (ds * u[i] + m.s * deu[i]);
    }
  }
  // omegabar'_{n+1} = 2 mix G(e_iter) a_{n+1} + (terms of step n), and G(e) a = -G(a) e.
  auto G = [](const double* e) {
    Eigen::Matrix<double, 3, 4> g;
    g << -e[1], e[0], e[3], -e[2], -e[2], -e[3], e[0], e[1], -e[3], e[2], -e[1], e[0];
    return g;
  };
  const Eigen::Map<const Eigen::Vector4d> u(m.eu);
  Eigen::Matrix<double, 8, 4> Ja = 2 * sc.mix * D * G(x + L::kEIter);
  Ja.topRows<4>() += mb * u * u.transpose();  // a_{n+1} in s
  Ja.bottomRows<4>() += mg * u * u.transpose();
  const Eigen::Matrix<double, 8, 4> Jit = -2 * sc.mix * D * G(a1);
  const Eigen::Matrix4d A = Eigen::Matrix4d::Identity() - Jit.topRows<4>();
  const Eigen::Matrix4d de = A.inverse() * Ja.topRows<4>();  // closed form for 4 x 4
  const Eigen::Matrix4d ded = Ja.bottomRows<4>() + Jit.bottomRows<4>() * de;
  using RowMajor4 = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>;
  Eigen::Map<RowMajor4> out_e(de_da), out_ed(ded_da);
  out_e = de;
  out_ed = ded;
}

}  // namespace mbdae::dae
