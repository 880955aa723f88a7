// The rotation update of one Euler-parameter group in HHT's modified scheme (dae/hht.cc,
// docs/hht.md, "Euler parameters"), as a function that both the integrator's Newton
// matrix and the sensitivities (sensitivities/hht_sensitivity.cc) differentiate.
#pragma once

#include <cmath>

namespace mbdae::dae {

// The scheme's constants: alpha, beta = (1 - alpha)^2 / 4, gamma = 1/2 - alpha, mix = 1 +
// alpha in the equilibrium form (dq/dabar) and 1 in the negrut form.
struct HhtRotationScheme {
  double alpha = 0, beta = 0, gamma = 0, mix = 1;
  bool equilibrium = true;
  // The constants of HHT with this alpha in the equilibrium (or else negrut) form.
  static HhtRotationScheme Of(double alpha, bool equilibrium) {
    HhtRotationScheme sc;
    sc.alpha = alpha;
    sc.beta = (1 - alpha) * (1 - alpha) / 4;
    sc.gamma = 0.5 - alpha;
    sc.mix = equilibrium ? 1 + alpha : 1.0;
    sc.equilibrium = equilibrium;
    return sc;
  }
};

// Inputs x of the map: e_n (4), e'_n (4), a_n (4), wbar_n (3), a_{n+1} (4) and the
// iterate e_iter at which G(e_{n+1}) is taken (4); outputs y: e_{n+1} (4), e'_{n+1} (4),
// wbar_{n+1} (3). r = h / h_prev scales wbar's history term (equilibrium form; 1 else).
struct HhtRotationLayout {
  enum : int { kE0 = 0, kEd0 = 4, kA0 = 8, kWbar0 = 12, kA1 = 15, kEIter = 19, kInputs = 23 };
  enum : int { kE1 = 0, kEd1 = 4, kWbar1 = 8, kOutputs = 11 };
};

// Values inside the map that its derivative (HhtRotationDerivative) reuses: theta,
// omega_{n+1}, |theta|^2, cos(|theta|/2), sin(|theta|/2)/|theta|, the unit update u, its
// rate G(u)^T omega_{n+1} / 2 and the normalisation defect s.
template <class T>
struct HhtRotationInside {
  T th[3], w1[3], ang2, c, sc, eu[4], ed[4], s;
};

// G(e) v for the 4-vector v (Nikravesh's body matrix G: omega_body = 2 G(e) e').
template <class T>
inline void HhtRotationG(const T* e, const T* v, T* out) {
  out[0] = -e[1] * v[0] + e[0] * v[1] + e[3] * v[2] - e[2] * v[3];
  out[1] = -e[2] * v[0] - e[3] * v[1] + e[0] * v[2] + e[1] * v[3];
  out[2] = -e[3] * v[0] + e[2] * v[1] - e[1] * v[2] + e[0] * v[3];
}

// G(e)^T w for the 3-vector w (4 numbers).
template <class T>
inline void HhtRotationGt(const T* e, const T* w, T* out) {
  out[0] = -e[1] * w[0] - e[2] * w[1] - e[3] * w[2];
  out[1] = e[0] * w[0] - e[3] * w[1] + e[2] * w[2];
  out[2] = e[3] * w[0] + e[0] * w[1] - e[1] * w[2];
  out[3] = -e[2] * w[0] + e[1] * w[1] + e[0] * w[2];
}

// The quaternion product p (x) r (Hamilton, scalar first).
template <class T>
inline void HhtQuatMul(const T* p, const T* r, T* out) {
  out[0] = p[0] * r[0] - p[1] * r[1] - p[2] * r[2] - p[3] * r[3];
  out[1] = p[0] * r[1] + p[1] * r[0] + p[2] * r[3] - p[3] * r[2];
  out[2] = p[0] * r[2] - p[1] * r[3] + p[2] * r[0] + p[3] * r[1];
  out[3] = p[0] * r[3] + p[1] * r[2] - p[2] * r[1] + p[3] * r[0];
}

// The map's last part, from theta and omega_{n+1} (HhtRotationMap and HhtRotationIterate).
template <class T>
void HhtRotationFinish(const HhtRotationScheme& sc, double h, const T* e0, const T* a1,
                       const T* th, const T* w1, T* y, HhtRotationInside<T>* inside) {
  using L = HhtRotationLayout;
  const T ang2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2];
  T c, sc_;
  using std::cos;
  using std::sin;
  using std::sqrt;
  if (ang2 > 1e-16) {
    const T ang = sqrt(ang2);
    c = cos(ang / 2);
    sc_ = sin(ang / 2) / ang;
  } else {  // the series (exact to round-off there; no derivative of sqrt at 0)
    c = 1 - ang2 / 8 + ang2 * ang2 / 384;
    sc_ = 0.5 - ang2 / 48;
  }
  const T rq[4] = {c, sc_ * th[0], sc_ * th[1], sc_ * th[2]};
  T eu[4], ed[4];
  HhtQuatMul(e0, rq, eu);
  HhtRotationGt<T>(eu, w1, ed);
  T s = T(0);
  for (int k = 0; k < 4; ++k) {
    ed[k] *= 0.5;
    s += eu[k] * a1[k] + ed[k] * ed[k];
  }
  const T rho = sc.mix * sc.beta * h * h * s;
  for (int k = 0; k < 4; ++k) {
    y[L::kE1 + k] = (1 + rho) * eu[k];
    y[L::kEd1 + k] = ed[k] + sc.mix * sc.gamma * h * s * eu[k];
  }
  if (inside) {
    for (int k = 0; k < 3; ++k) {
      inside->th[k] = th[k];
      inside->w1[k] = w1[k];
    }
    for (int k = 0; k < 4; ++k) {
      inside->eu[k] = eu[k];
      inside->ed[k] = ed[k];
    }
    inside->ang2 = ang2;
    inside->c = c;
    inside->sc = sc_;
    inside->s = s;
  }
}

template <class T>
void HhtRotationMap(const HhtRotationScheme& sc, double h, double r, const T* x, T* y,
                    HhtRotationInside<T>* inside = nullptr) {
  using L = HhtRotationLayout;
  const T* e0 = x + L::kE0;
  const T* ed0 = x + L::kEd0;
  const T* an = x + L::kA0;
  const T* wb0 = x + L::kWbar0;
  const T* a1 = x + L::kA1;
  const T* eg = x + L::kEIter;
  T w0[3], dw0[3], dw1[3], th[3], w1[3];
  HhtRotationG(e0, ed0, w0);
  HhtRotationG(eg, a1, dw1);
  if (sc.equilibrium) {
    T dwn[3];
    HhtRotationG(e0, an, dwn);
    for (int k = 0; k < 3; ++k) {
      dw0[k] = 2 * dwn[k] + r * (wb0[k] - 2 * dwn[k]);
      dw1[k] = 2 * ((1 + sc.alpha) * dw1[k] - sc.alpha * dwn[k]);
    }
  } else {
    HhtRotationG(e0, an, dw0);
    for (int k = 0; k < 3; ++k) {
      dw0[k] *= 2;
      dw1[k] *= 2;
    }
  }
  for (int k = 0; k < 3; ++k) {
    w0[k] *= 2;
    y[L::kWbar1 + k] = dw1[k];
    th[k] = h * w0[k] + h * h * ((0.5 - sc.beta) * dw0[k] + sc.beta * dw1[k]);
    w1[k] = w0[k] + h * ((1 - sc.gamma) * dw0[k] + sc.gamma * dw1[k]);
  }
  HhtRotationFinish(sc, h, e0, a1, th, w1, y, inside);
}

// The map split for the integrator's Newton iteration, where only a_{n+1} and e_iter
// change: HhtRotationStartOf takes what the step fixes (e_n, e'_n, a_n, wbar_n, h, r)
// once per step, HhtRotationIterate the rest at each iterate. The same operations in the
// same order as HhtRotationMap: the same numbers to the last bit
// (HhtRotation.SplitMapIsTheMap).
struct HhtRotationStart {
  double w0[3];   // omega_n = 2 G(e_n) e'_n
  double hw0[3];  // h omega_n
  double qa[3];   // (1/2 - beta) omegabar'_n: theta's history term
  double va[3];   // (1 - gamma) omegabar'_n: omega_{n+1}'s
  double adw[3];  // alpha G(e_n) a_n (equilibrium form: omegabar'_{n+1}'s)
};

// x: the map's inputs (HhtRotationLayout; a_{n+1} and e_iter are not read).
inline void HhtRotationStartOf(const HhtRotationScheme& sc, double h, double r, const double* x,
                               HhtRotationStart* st) {
  using L = HhtRotationLayout;
  const double* e0 = x + L::kE0;
  const double* an = x + L::kA0;
  const double* wb0 = x + L::kWbar0;
  double w0[3], dw0[3], dwn[3];
  HhtRotationG(e0, x + L::kEd0, w0);
  HhtRotationG(e0, an, dwn);
  for (int k = 0; k < 3; ++k) {
    if (sc.equilibrium) {
      dw0[k] = 2 * dwn[k] + r * (wb0[k] - 2 * dwn[k]);
      st->adw[k] = sc.alpha * dwn[k];
    } else {
      dw0[k] = dwn[k] * 2;
      st->adw[k] = 0;
    }
    w0[k] *= 2;
    st->w0[k] = w0[k];
    st->hw0[k] = h * w0[k];
    st->qa[k] = (0.5 - sc.beta) * dw0[k];
    st->va[k] = (1 - sc.gamma) * dw0[k];
  }
}

// y: the map's outputs, from e_n, a_{n+1} and e_iter.
inline void HhtRotationIterate(const HhtRotationScheme& sc, double h, const HhtRotationStart& st,
                               const double* e0, const double* a1, const double* eg, double* y) {
  using L = HhtRotationLayout;
  double dw1[3], th[3], w1[3];
  HhtRotationG(eg, a1, dw1);
  for (int k = 0; k < 3; ++k) {
    dw1[k] = sc.equilibrium ? 2 * ((1 + sc.alpha) * dw1[k] - st.adw[k]) : dw1[k] * 2;
    y[L::kWbar1 + k] = dw1[k];
    th[k] = st.hw0[k] + h * h * (st.qa[k] + sc.beta * dw1[k]);
    w1[k] = st.w0[k] + h * (st.va[k] + sc.gamma * dw1[k]);
  }
  HhtRotationFinish<double>(sc, h, e0, a1, th, w1, y, nullptr);
}

// The exact derivative of the group's e_{n+1} and e'_{n+1} with respect to a_{n+1} (4 x 4
// each, row-major into de_da and ded_da) at the inputs x, with G(e_{n+1}) at e_{n+1}
// itself: the map's fixed point in e_iter resolved by the implicit function theorem,
// de/da = (I - dy_e/de_iter)^{-1} dy_e/da. It replaces the first-order mix beta h^2 I and
// mix gamma h I of the Newton matrix (HhtOptions::rotation_jacobian). Written out by the
// chain rule (a_{n+1} and e_iter enter the update through omegabar'_{n+1} = 2 mix
// G(e_iter) a_{n+1} + ..., and a_{n+1} also through s), about 0.3 us a group
// (bench/bench_rotation.cc); the tests check it against forward-mode AutoDiff of
// HhtRotationMap and the Newton matrix against finite differences.
void HhtRotationDerivative(const HhtRotationScheme& sc, double h, double r, const double* x,
                           double* de_da, double* ded_da);

// A group's block of the Newton matrix with rotation blocks (HhtNewtonMatrix::Assemble),
// 32 numbers from de_da and ded_da (row-major): de/da / (mix beta h^2) - I, then
// ded/da / (mix gamma h) - I.
inline void HhtRotationBlock(const HhtRotationScheme& sc, double h, const double* de_da,
                             const double* ded_da, double* block) {
  const double cq = 1 / (sc.mix * sc.beta * h * h), cv = 1 / (sc.mix * sc.gamma * h);
  for (int i = 0; i < 16; ++i) {
    const double one = i % 5 == 0 ? 1 : 0;  // the diagonal of a row-major 4 x 4
    block[i] = de_da[i] * cq - one;
    block[16 + i] = ded_da[i] * cv - one;
  }
}

}  // namespace mbdae::dae
