// Measures with exact first and second derivatives (definitions and formulas:
// docs/measures.md). Euler-parameter kinematics after Nikravesh, Computer-Aided
// Analysis of Mechanical Systems, 1988, ch. 6: A(e) = E G^T is a quadratic form in e
// for every e (unit or not), so d(A u)/de = B(e, u) is linear in e and the Hessian of
// w . A(e) u is a constant 4x4 matrix.
#include "mbs/measure_kinematics.h"

#include <cassert>
#include <cmath>
#include <stdexcept>
#include <string>

#include "mbs/kinematics.h"

namespace mbdae::mbs {
namespace {

using Mat3x14 = Eigen::Matrix<double, 3, 14>;
using Mat4 = Eigen::Matrix4d;

// B(e, u) = d(A(e) u)/de = 2 [e0 u + e_v x u,  (e_v . u) I + e_v u^T - u e_v^T - e0 [u]x]
// (the B matrix of Nikravesh 1988, ch. 6, written out from the expansion
// A u = (e0^2 - e_v.e_v) u + 2 e_v (e_v.u) + 2 e0 e_v x u).
Mat34 BMat(const Quat& e, const Vec3& u) {
  const Vec3 ev = e.tail<3>();
  Mat34 b;
  b.col(0) = 2 * (e[0] * u + ev.cross(u));
  b.rightCols<3>() = 2 * (ev.dot(u) * Mat3::Identity() + ev * u.transpose() -
                          u * ev.transpose() - e[0] * Skew(u));
  return b;
}

// The constant Hessian of w . A(e) u with respect to e (from the same expansion):
// [[2 w.u, 2 (u x w)^T], [2 (u x w), -2 (w.u) I + 2 (w u^T + u w^T)]].
Mat4 HDot(const Vec3& u, const Vec3& w) {
  Mat4 h;
  const double wu = w.dot(u);
  const Vec3 c = 2 * u.cross(w);
  h(0, 0) = 2 * wu;
  h.block<3, 1>(1, 0) = c;
  h.block<1, 3>(0, 1) = c.transpose();
  h.block<3, 3>(1, 1) = -2 * wu * Mat3::Identity() + 2 * (w * u.transpose() + u * w.transpose());
  return h;
}

// Coordinates of the two slots.
struct Slots {
  Vec3 r[2];
  Quat e[2];
  Mat3 A[2];
};

void GatherSlots(const MeasureDef& def, const double* q, Slots* s) {
  for (int k = 0; k < 2; ++k) {
    const int o = def.offset[k];
    if (o < 0) continue;
    s->r[k] = Eigen::Map<const Vec3>(q + o);
    s->e[k] = Eigen::Map<const Quat>(q + o + 3);
    s->A[k] = RotationMatrix(s->e[k]);
  }
}

// A world vector: sign * (A(e_slot) u [+ r_slot if point]), or the constant sign * u
// if slot < 0.
struct Term {
  int slot = -1;
  Vec3 u = Vec3::Zero();
  bool point = false;
  double sign = 1;

  Vec3 Value(const Slots& s) const {
    if (slot < 0) return sign * u;
    Vec3 x = s.A[slot] * u;
    if (point) x += s.r[slot];
    return sign * x;
  }
  void AddJacobian(const Slots& s, Mat3x14* j) const {
    if (slot < 0) return;
    if (point) j->block<3, 3>(0, 7 * slot).diagonal().array() += sign;
    j->block<3, 4>(0, 7 * slot + 3) += sign * BMat(s.e[slot], u);
  }
  // h += scale * d2(w . x)/dq2 at fixed w.
  void AddHessianDot(const Vec3& w, double scale, Mat14* h) const {
    if (slot < 0) return;
    h->block<4, 4>(7 * slot + 3, 7 * slot + 3) += (scale * sign) * HDot(u, w);
  }
};

// Value, Jacobian of a field made of one or two terms.
struct Field {
  Term t[2];
  int n = 0;
  Vec3 value;
  Mat3x14 jac;

  void Evaluate(const Slots& s) {
    value.setZero();
    jac.setZero();
    for (int k = 0; k < n; ++k) {
      value += t[k].Value(s);
      t[k].AddJacobian(s, &jac);
    }
  }
  void AddHessianDot(const Vec3& w, double scale, Mat14* h) const {
    for (int k = 0; k < n; ++k) t[k].AddHessianDot(w, scale, h);
  }
};

Field One(int slot, const Vec3& u) {
  Field f;
  f.t[0].slot = slot;
  f.t[0].u = u;
  f.n = 1;
  return f;
}

Field Separation(const MeasureDef& def) {
  Field f;
  f.t[0].slot = def.slot_i;
  f.t[0].u = def.s_i;
  f.t[0].point = true;
  f.t[1].slot = def.slot_j;
  f.t[1].u = def.s_j;
  f.t[1].point = true;
  f.t[1].sign = -1;
  f.n = 2;
  return f;
}

// m = a . b for two fields: value, gradient, and (if h) Hessian
// a_q^T b_q + b_q^T a_q + Hess(b . a at fixed b) + Hess(a . b at fixed a).
void DotProduct(const Field& a, const Field& b, double* m, Vec14* g, Mat14* h) {
  *m = a.value.dot(b.value);
  *g = a.jac.transpose() * b.value + b.jac.transpose() * a.value;
  if (h) {
    h->noalias() = a.jac.transpose() * b.jac;
    *h += h->transpose().eval();
    a.AddHessianDot(b.value, 1.0, h);
    b.AddHessianDot(a.value, 1.0, h);
  }
}

}  // namespace

MeasureDef ResolveMeasure(const Model& model, int measure) {
  if (measure < 0 || measure >= static_cast<int>(model.measures.size()))
    throw std::invalid_argument("measure index " + std::to_string(measure) +
                                " out of range (model has " +
                                std::to_string(model.measures.size()) + " measures)");
  const Measure& m = model.measures[measure];
  const int nm = static_cast<int>(model.markers.size());
  if (m.i < 0 || m.i >= nm || m.j < 0 || m.j >= nm)
    throw std::invalid_argument("measure '" + m.name + "': marker index out of range");
  const Marker& mi = model.markers[m.i];
  const Marker& mj = model.markers[m.j];
  MeasureDef d;
  d.type = m.type;
  d.quantity = m.quantity;
  d.component = m.component;
  d.frame = m.frame;
  d.s_i = mi.position;
  d.s_j = mj.position;
  d.axes_i = mi.orientation;
  d.axes_j = mj.orientation;
  if (mi.body >= 0) {
    d.slot_i = 0;
    d.offset[0] = Model::coordinate_offset(mi.body);
  }
  if (mj.body >= 0) {
    if (mj.body == mi.body) {
      d.slot_j = 0;  // folded: both markers' terms act on slot 0
    } else {
      d.slot_j = 1;
      d.offset[1] = Model::coordinate_offset(mj.body);
    }
  }
  return d;
}

void EvaluateMeasurePosition(const MeasureDef& def, const double* q, bool with_hessian,
                             MeasureJacobian* out) {
  out->offset[0] = def.offset[0];
  out->offset[1] = def.offset[1];
  Slots s;
  GatherSlots(def, q, &s);
  Mat14* h = with_hessian ? &out->hessian : nullptr;

  if (def.type == MeasureType::kTranslational) {
    Field d = Separation(def);
    d.Evaluate(s);
    if (def.component == Component::kDistance) {
      // m = |d|, g = D^T d / m, H = (D^T D - g g^T) / m + Hess(d . x at fixed d) / m
      const double len = d.value.norm();
      out->value = len;
      if (!(len > 0)) {
        out->gradient.setZero();
        if (h) h->setZero();
        return;
      }
      out->gradient = d.jac.transpose() * (d.value / len);
      if (h) {
        h->noalias() = d.jac.transpose() * d.jac;
        h->noalias() -= out->gradient * out->gradient.transpose();
        *h /= len;
        d.AddHessianDot(d.value, 1.0 / len, h);
      }
      return;
    }
    const int axis = static_cast<int>(def.component);
    Field u = def.frame == MeasureFrame::kWorld ? One(-1, Vec3::Unit(axis))
                                                : One(def.slot_j, def.axes_j.col(axis));
    u.Evaluate(s);
    DotProduct(u, d, &out->value, &out->gradient, h);
    return;
  }

  // Rotational about axis k of marker j: X = p_i . p_j, Y = p_i . n_j, m = atan2(Y, X).
  const int axis = std::min(static_cast<int>(def.component), 2);
  const int p = (axis + 1) % 3, n = (axis + 2) % 3;
  Field pi = One(def.slot_i, def.axes_i.col(p));
  Field pj = One(def.slot_j, def.axes_j.col(p));
  Field nj = One(def.slot_j, def.axes_j.col(n));
  pi.Evaluate(s);
  pj.Evaluate(s);
  nj.Evaluate(s);
  double X, Y;
  Vec14 gX, gY;
  Mat14 HX, HY;
  DotProduct(pi, pj, &X, &gX, h ? &HX : nullptr);
  DotProduct(pi, nj, &Y, &gY, h ? &HY : nullptr);
  double x = std::atan2(Y, X);
  if (x <= -M_PI) x = M_PI;
  out->value = x;
  const double D = X * X + Y * Y;
  if (!(D > 0)) {
    out->gradient.setZero();
    if (h) h->setZero();
    return;
  }
  // d atan2(Y, X) = (X dY - Y dX) / D;
  // d2 = (X HY - Y HX) / D
  //      - [2 X Y (gY gY^T - gX gX^T) + (X^2 - Y^2) (gX gY^T + gY gX^T)] / D^2,
  // symmetric by construction (the antisymmetric parts of the plain product rule cancel).
  out->gradient = (X * gY - Y * gX) / D;
  if (h) {
    const double D2 = D * D;
    h->noalias() = (X / D) * HY;
    h->noalias() -= (Y / D) * HX;
    h->noalias() -= (2 * X * Y / D2) * (gY * gY.transpose() - gX * gX.transpose());
    h->noalias() -= ((X * X - Y * Y) / D2) * (gX * gY.transpose() + gY * gX.transpose());
  }
}

void EvaluateMeasureState(const MeasureDef& def, const double* q, const double* v,
                          MeasureStateJacobian* out) {
  out->offset[0] = def.offset[0];
  out->offset[1] = def.offset[1];
  switch (def.quantity) {
    case Quantity::kPosition: {
      MeasureJacobian j;
      EvaluateMeasurePosition(def, q, false, &j);
      out->value = j.value;
      out->dq = j.gradient;
      out->dv.setZero();
      return;
    }
    case Quantity::kVelocity: {
      MeasureJacobian j;
      EvaluateMeasurePosition(def, q, true, &j);
      const Vec14 vl = GatherLocal(def.offset, v);
      out->value = j.gradient.dot(vl);
      out->dq.noalias() = j.hessian * vl;
      out->dv = j.gradient;
      return;
    }
    case Quantity::kAcceleration:
      break;
  }
  throw std::invalid_argument(
      "an acceleration measure has no state derivative (output only)");
}

double EvaluateMeasureValue(const MeasureDef& def, const double* q, const double* v,
                            const double* a) {
  MeasureJacobian j;
  EvaluateMeasurePosition(def, q, def.quantity == Quantity::kAcceleration, &j);
  if (def.quantity == Quantity::kPosition) return j.value;
  const Vec14 vl = v ? GatherLocal(def.offset, v) : Vec14::Zero();
  if (def.quantity == Quantity::kVelocity) return j.gradient.dot(vl);
  const Vec14 al = a ? GatherLocal(def.offset, a) : Vec14::Zero();
  return j.gradient.dot(al) + vl.dot(j.hessian * vl);
}

Vec14 GatherLocal(const int offset[2], const double* x) {
  Vec14 l = Vec14::Zero();
  for (int s = 0; s < 2; ++s)
    if (offset[s] >= 0)
      l.segment<7>(7 * s) = Eigen::Map<const Eigen::Matrix<double, 7, 1>>(x + offset[s]);
  return l;
}

double UnwrapAngle(double value, double reference) {
  constexpr double kTwoPi = 6.283185307179586476925286766559;
  return value + kTwoPi * std::round((reference - value) / kTwoPi);
}

double UnwrapAngle(double value, double previous, double previous_rate, double rate, double dt) {
  return UnwrapAngle(value, previous + 0.5 * dt * (previous_rate + rate));
}

bool IsAngleMeasure(const Measure& measure) {
  return measure.type == MeasureType::kRotational && measure.quantity == Quantity::kPosition;
}

MeasureDef AngleRate(MeasureDef angle) {
  angle.quantity = Quantity::kVelocity;
  return angle;
}

}  // namespace mbdae::mbs
