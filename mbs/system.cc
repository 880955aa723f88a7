// The multibody model as a mechanical DAE (see system.h).
//
// Formulation (Nikravesh, Computer-Aided Analysis of Mechanical Systems, 1988, ch. 6
// and 11): per body q = (r, e), M = blockdiag(m I, 4 G^T J G),
//   Q_r = m g + sum F,   Q_e = 8 G(e')^T J G(e') e + sum 2 G^T (s x A^T F) + 2 G^T A^T T.
// The quadratic velocity term follows from Lagrange's equations with
// T = 2 e'^T G^T J G e' (G e' = -G(e') e, G(e') e' = 0).
//
// Derivatives. Every body-fixed vector u gives the world vector A(e) u, whose components
// are quadratic forms in e: A(e) u = 1/2 B(e, u) e with B(e, u) = d(A(e) u)/de, which is
// linear in e, so d(B(e, u) x)/de = B(x, u) and the Hessian of w . A(e) u is the
// constant 4x4 matrix with columns B(unit_m, u)^T w. G(e) is linear in e:
// G(e) x = -G(x) e. Every joint equation is a dot product of two such vector fields,
// so its gradient and Hessian are exact; the matrices the integrators need follow:
//   C_q = grad c^T,  d(C_q v)/dq = (H v)^T,  gamma = -v^T H v,  d(C_q^T w)/dq = w H.
//
// Sparsity. Each matrix is written through a Sink: at construction the evaluation runs
// once in recording mode and every (row, col) it adds is collected; the pattern is their
// union and each add gets its position in the value array. Later evaluations replay the
// same adds in the same order (the sequence depends only on the model, never on values),
// so nothing is searched or allocated while evaluating.
//
// Speed. Per call the rotation matrix of every body is computed once; each joint
// equation c = U . W (two fields, see JointField) gets its gradient, H v and Hessian
// blocks from closed forms of B(e, u) products, and a joint's weighted Hessians are
// summed into one 14x14 block before they are written. Entries that are structurally
// zero for an evaluation are declared in the pattern but never written.
#include "mbs/system.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <functional>
#include <iomanip>
#include <random>
#include <sstream>
#include <stdexcept>

#include "mbs/bushing.h"
#include "mbs/kinematics.h"
#include "mbs/loader.h"
#include "mbs/measure_kinematics.h"
#include "mbs/user_force.h"

namespace mbdae::mbs {
namespace {

using Mat4 = Eigen::Matrix4d;
using Vec14 = Eigen::Matrix<double, 14, 1>;
using Mat3x14 = Eigen::Matrix<double, 3, 14>;
using Mat14 = Eigen::Matrix<double, 14, 14>;
using Mat43 = Eigen::Matrix<double, 4, 3>;
using Mat37 = Eigen::Matrix<double, 3, 7>;

// B(e, u) = d(A(e) u)/de = 2 [e0 u + e_v x u, (e_v.u) I + e_v u^T - u e_v^T - e0 skew(u)];
// B(e, u) e = 2 A(e) u.
#define MBDAE_INLINE inline __attribute__((always_inline))

MBDAE_INLINE Mat34 BMatrix(const Quat& e, const Vec3& u) {
  const Vec3 ev = e.tail<3>();
  const double e0 = e[0];
  Mat34 b;
  b.col(0) = 2 * (e0 * u + ev.cross(u));
  Mat3 m = ev * u.transpose() - u * ev.transpose();
  m.diagonal().array() += ev.dot(u);
  // - e0 skew(u)
  m(0, 1) += e0 * u[2];
  m(0, 2) -= e0 * u[1];
  m(1, 0) -= e0 * u[2];
  m(1, 2) += e0 * u[0];
  m(2, 0) += e0 * u[1];
  m(2, 1) -= e0 * u[0];
  b.rightCols<3>() = 2 * m;
  return b;
}

// X^T J Y (4x4) for 3x4 X, Y.
MBDAE_INLINE Mat4 XtJY(const Mat34& X, const Mat3& J, const Mat34& Y) {
  Mat34 jy;
  for (int c = 0; c < 4; ++c) jy.col(c) = J.col(0) * Y(0, c) + J.col(1) * Y(1, c) + J.col(2) * Y(2, c);
  Mat4 r;
  for (int c = 0; c < 4; ++c)
    for (int k = 0; k < 4; ++k) r(k, c) = X.col(k).dot(jy.col(c));
  return r;
}

// Closed forms of products with B(e, u), without forming it (same values up to rounding):
//   B(e, u)^T w = 2 [e0 u.w + e_v.(u x w);  (e_v.u) w + (e_v.w) u - (u.w) e_v + e0 u x w],
//   B(e, u) x   = 2 [x0 (e0 u + e_v x u) + (e_v.u) x_v + (u.x_v) e_v - (e_v.x_v) u - e0 u x x_v].
MBDAE_INLINE Quat BtW(const Quat& e, const Vec3& u, const Vec3& w) {
  // Scalar code: a 3-vector expression written into a 4-vector stalls store forwarding.
  const double e0 = e[0], e1 = e[1], e2 = e[2], e3 = e[3];
  const double c0 = u[1] * w[2] - u[2] * w[1], c1 = u[2] * w[0] - u[0] * w[2],
               c2 = u[0] * w[1] - u[1] * w[0];  // u x w
  const double uw = u[0] * w[0] + u[1] * w[1] + u[2] * w[2];
  const double eu = e1 * u[0] + e2 * u[1] + e3 * u[2];
  const double ew = e1 * w[0] + e2 * w[1] + e3 * w[2];
  Quat g;
  g[0] = 2 * (e0 * uw + e1 * c0 + e2 * c1 + e3 * c2);
  g[1] = 2 * (eu * w[0] + ew * u[0] - uw * e1 + e0 * c0);
  g[2] = 2 * (eu * w[1] + ew * u[1] - uw * e2 + e0 * c1);
  g[3] = 2 * (eu * w[2] + ew * u[2] - uw * e3 + e0 * c2);
  return g;
}
MBDAE_INLINE Vec3 BTimes(const Quat& e, const Vec3& u, const Quat& x) {
  const Vec3 ev = e.tail<3>(), xv = x.tail<3>();
  return 2 * (x[0] * (e[0] * u + ev.cross(u)) + ev.dot(u) * xv + u.dot(xv) * ev -
              ev.dot(xv) * u - e[0] * u.cross(xv));
}
// The Hessian of w . A(e) u (B(e, u)^T w = H e), closed form:
//   H = 2 [u.w, (u x w)^T;  u x w, u w^T + w u^T - (u.w) I].
MBDAE_INLINE Mat4 HessDot(const Vec3& u, const Vec3& w) {
  const double uw = u.dot(w);
  const Vec3 uxw = u.cross(w);
  Mat4 h;
  h(0, 0) = 2 * uw;
  h.block<1, 3>(0, 1) = 2 * uxw.transpose();
  h.block<3, 1>(1, 0) = 2 * uxw;
  h.block<3, 3>(1, 1) = 2 * (u * w.transpose() + w * u.transpose());
  h.block<3, 3>(1, 1).diagonal().array() -= 2 * uw;
  return h;
}

// d(G(e)^T y)/de for fixed y: G^T y = (-e_v.y, e_v x y + e0 y).
Mat4 GtJacobian(const Vec3& y) {
  Mat4 m;
  m(0, 0) = 0;
  m.block<1, 3>(0, 1) = -y.transpose();
  m.block<3, 1>(1, 0) = y;
  m.block<3, 3>(1, 1) = -Skew(y);
  return m;
}

// d(A(e)^T F)/de: A(e)^T = A(conj(e)), conj(e) = (e0, -e_v).
Mat34 BTransposeMatrix(const Quat& e, const Vec3& f) {
  const Quat c(e[0], -e[1], -e[2], -e[3]);
  Mat34 b = BMatrix(c, f);
  b.rightCols<3>() *= -1;
  return b;
}

// The coordinates of (up to) two bodies, slot 0 and slot 1, and their rates.
struct Local {
  int offset[2] = {-1, -1};  // 7 * body, -1 for ground
  Vec3 r[2], rd[2], rdd[2];
  Quat e[2], ed[2], edd[2];
  Vec14 v, a;  // rates of the 14 local coordinates (zero for ground slots)
};

// One body-fixed vector (or point, if `point`: r + A u) of slot `slot`, times `sign`;
// slot -1: a constant world vector u.
struct Term {
  int slot = -1;
  Vec3 u = Vec3::Zero();
  bool point = false;
  double sign = 1;
};

// A world vector field: the sum of one or two terms.
struct Field {
  Term t[2];
  int n = 0;

  Vec3 Value(const Local& l) const {
    Vec3 x = Vec3::Zero();
    for (int k = 0; k < n; ++k) {
      const Term& t = this->t[k];
      if (t.slot < 0) {
        x += t.sign * t.u;
      } else {
        x += t.sign * RotationMatrix(l.e[t.slot]) * t.u;
        if (t.point) x += t.sign * l.r[t.slot];
      }
    }
    return x;
  }
  // d x / dq_local
  Mat3x14 Jacobian(const Local& l) const {
    Mat3x14 j = Mat3x14::Zero();
    for (int k = 0; k < n; ++k) {
      const Term& t = this->t[k];
      if (t.slot < 0) continue;
      if (t.point) j.block<3, 3>(0, 7 * t.slot) += t.sign * Mat3::Identity();
      j.block<3, 4>(0, 7 * t.slot + 3) += t.sign * BMatrix(l.e[t.slot], t.u);
    }
    return j;
  }
  // d(J v)/dq_local
  Mat3x14 JacobianDot(const Local& l) const {
    Mat3x14 j = Mat3x14::Zero();
    for (int k = 0; k < n; ++k) {
      const Term& t = this->t[k];
      if (t.slot < 0) continue;
      j.block<3, 4>(0, 7 * t.slot + 3) += t.sign * BMatrix(l.ed[t.slot], t.u);
    }
    return j;
  }
  // First and second time derivatives.
  void Rates(const Local& l, Vec3* xd, Vec3* xdd) const {
    const Mat3x14 j = Jacobian(l);
    *xd = j * l.v;
    *xdd = j * l.a + JacobianDot(l) * l.v;
  }
};

// Records (row, col) of every add at construction, then replays the adds into the
// values in the recorded order. Declare(r, c) puts an entry into the pattern without
// writing it (a structural zero of this evaluation that the pattern keeps).
class Sink {
 public:
  void StartRecording() { recording_ = true; entries_.clear(); written_.clear(); }
  void Finish(int rows, int cols) {
    pattern_ = dae::CscPattern::FromEntries(rows, cols, entries_);
    position_.clear();
    position_.reserve(std::count(written_.begin(), written_.end(), true));
    std::vector<int> last_row(cols, -1);
    std::vector<char> seen(pattern_.nnz(), 0);
    adds_once_by_row_ = true;
    for (size_t k = 0; k < entries_.size(); ++k) {
      if (!written_[k]) continue;
      const auto [r, c] = entries_[k];
      position_.push_back(pattern_.find(r, c));
      if (seen[position_.back()] || r <= last_row[c]) adds_once_by_row_ = false;
      seen[position_.back()] = 1;
      last_row[c] = r;
    }
    entries_.clear();
    entries_.shrink_to_fit();
    written_.clear();
    written_.shrink_to_fit();
    recording_ = false;
  }
  void Begin(double* values) {
    values_ = values;
    cursor_ = 0;
    if (values_ && !recording_) std::fill(values_, values_ + pattern_.nnz(), 0.0);
  }
  bool active() const { return values_ != nullptr || recording_; }
  MBDAE_INLINE void Add(int r, int c, double v) {
    if (__builtin_expect(recording_, false)) {
      Record(r, c, true);
    } else {
      // Only for an active sink (values given): callers skip the adds of the others.
      assert(values_ != nullptr && cursor_ < static_cast<int>(position_.size()));
      values_[position_[cursor_++]] += v;
    }
  }
  MBDAE_INLINE void Declare(int r, int c) {
    if (recording_) Record(r, c, false);
  }
  void End() {
    assert(recording_ || !values_ || cursor_ == static_cast<int>(position_.size()));
    values_ = nullptr;
  }
  const dae::CscPattern& pattern() const { return pattern_; }
  // Whether the recorded adds write each entry once and, column by column, in increasing
  // rows: then a product with the matrix summed in the order of the adds (as
  // EvalOutput::constraint_transpose_w) equals a product by the pattern's columns.
  bool adds_once_by_row() const { return adds_once_by_row_; }

 private:
  // Out of line: keeps Add small enough to be inlined in the evaluation loops.
  __attribute__((noinline)) void Record(int r, int c, bool written) {
    entries_.push_back({r, c});
    written_.push_back(written);
  }
  bool recording_ = false;
  std::vector<std::pair<int, int>> entries_;
  std::vector<bool> written_;
  std::vector<int> position_;
  dae::CscPattern pattern_;
  double* values_ = nullptr;
  int cursor_ = 0;
  bool adds_once_by_row_ = false;
};

// Which entries of a local 14x14 (or 14-vector) block are structurally present.
enum class Part { kAll, kRotation /* the Euler parameter coordinates */ };
inline bool InPart(Part p, int local) { return p == Part::kAll || local % 7 >= 3; }

// The state of one body during an evaluation, computed once per Evaluate.
struct BodyState {
  Vec3 r, rd;
  Quat e, ed;
  Mat3 A;  // RotationMatrix(e)
};

// A joint's constants. Slot 0 is marker i's body, slot 1 marker j's (body -1: ground,
// the marker's position and axes are then world values).
struct JointInfo {
  int body[2] = {-1, -1};
  int offset[2] = {-1, -1};
  Vec3 s[2];                                 // marker positions
  Mat3 axes[2];                              // marker orientations
  bool trans = false, rot = false;           // has translational / rotational locks
  bool need_axis[2][3] = {{false}, {false}};  // marker axes the equations use
};

// One factor of a joint equation c = U . W, evaluated: the world vector
//   x = sum_s (sig[s] r_s + A(e_s) ub[s])  (+ a constant from ground),
// so dx/dr_s = sig[s] I and dx/de_s = B[s] = B(e_s, ub[s]) (rot[s]); xd = dx/dt.
// sig and rot depend only on the model, never on values.
// (Deliberately not initialised: Clear() sets what every use reads; ub, B and xd are
// read only where rot, need_b and need_rates say they were set.)
struct JointField {
  Vec3 x, xd;
  double sig[2];
  bool rot[2];
  Vec3 ub[2];
  Mat34 B[2];
  void Clear() {
    sig[0] = sig[1] = 0;
    rot[0] = rot[1] = false;
  }
};

// H += wgt * (Hessian of U . W) in a joint's 14 local coordinates:
//   dU^T dW + dW^T dU + sum_s [HessDot(U.ub[s], W.x) + HessDot(W.ub[s], U.x)] on (e_s, e_s).
// nz[g][h] marks the structurally non-zero blocks, groups g = r0, e0, r1, e1.
void AddDotHessian(const JointField& U, const JointField& W, double wgt, Mat14& H,
                   bool nz[4][4]) {
  for (int pass = 0; pass < 2; ++pass) {
    const JointField& X = pass == 0 ? U : W;
    const JointField& Y = pass == 0 ? W : U;
    for (int s = 0; s < 2; ++s) {
      for (int t = 0; t < 2; ++t) {
        if (X.sig[s] != 0 && Y.sig[t] != 0) {
          H.block<3, 3>(7 * s, 7 * t).diagonal().array() += wgt * X.sig[s] * Y.sig[t];
          nz[2 * s][2 * t] = true;
        }
        if (X.sig[s] != 0 && Y.rot[t]) {
          H.block<3, 4>(7 * s, 7 * t + 3) += (wgt * X.sig[s]) * Y.B[t];
          nz[2 * s][2 * t + 1] = true;
        }
        if (X.rot[s] && Y.sig[t] != 0) {
          H.block<4, 3>(7 * s + 3, 7 * t) += (wgt * Y.sig[t]) * X.B[s].transpose();
          nz[2 * s + 1][2 * t] = true;
        }
        if (X.rot[s] && Y.rot[t]) {
          H.block<4, 4>(7 * s + 3, 7 * t + 3).noalias() += wgt * (X.B[s].transpose() * Y.B[t]);
          nz[2 * s + 1][2 * t + 1] = true;
        }
      }
      if (X.rot[s]) {
        H.block<4, 4>(7 * s + 3, 7 * s + 3) += wgt * HessDot(X.ub[s], Y.x);
        nz[2 * s + 1][2 * s + 1] = true;
      }
    }
  }
}

const char* kLockNames[6] = {"x", "y", "z", "rx", "ry", "rz"};

}  // namespace

struct MultibodySystem::Impl {
  const Model& model;
  std::vector<double> params;
  int nq = 0, nc = 0;
  std::vector<int> quaternion_offsets;
  std::vector<std::string> coordinate_names, constraint_names;
  std::vector<int> constraint_joint;
  // Per joint: its equations (lock index 0..5) and the first constraint row.
  std::vector<std::vector<int>> joint_locks;
  std::vector<int> joint_row;
  std::vector<JointInfo> joint_info;
  std::vector<BodyState> state;  // per body, filled at the start of Run
  // Cached force-element constants, evaluated at the start of Evaluate.
  struct ForceValues {
    double k = 0, c = 0, l0 = 0, preload = 0;
    Vec3 value = Vec3::Zero();
  };
  std::vector<ForceValues> force_values;
  // Force values over t, measures and splines. The seven expressions of an element are
  // numbered 0 stiffness, 1 damping, 2 free_length, 3 preload, 4..6 value components.
  // Per element: the measures its expressions use (union, model indices), resolved once,
  // their state Jacobians of the current evaluation, and dE_e/dm_u (d_expr[u][e]).
  struct ForceExpressions {
    std::vector<int> measures;
    std::vector<MeasureDef> defs;
    std::vector<MeasureStateJacobian> jac;
    std::vector<std::array<double, 7>> d_expr;
    // For expression e: the union index of each entry of its measures_used().
    std::array<std::vector<int>, 7> slot;
  };
  std::vector<ForceExpressions> force_expr;
  // User force elements (by force index; null for the other types), bound at Setup.
  std::vector<std::unique_ptr<UserForce>> user_forces;
  // Motion and gear joints: one equation each, C = sum_u coef[u] m_u(q) + constant - f(t)
  // (f only for a motion), over one or two position-level measures.
  struct MeasureConstraint {
    int joint = -1, row = -1, n = 0;
    MeasureDef def[2];
    double coef[2] = {0, 0};
    double constant = 0;
    bool motion = false, wrap = false;  // wrap: a motion on an angle, C in (-pi, pi]
    // Gear angles are continued across the +-pi cut from the previous evaluation.
    bool unwrap[2] = {false, false};
    double last[2] = {0, 0};
    MeasureJacobian jac[2];
  };
  std::vector<MeasureConstraint> measure_constraints;
  std::vector<double> measure_values;          // by model measure index (used ones set)
  // Subtracted from a measure with offset_initial in expressions: its value at the
  // initial state of the model file (before assembly); 0 for the others.
  std::vector<double> measure_offsets;
  std::vector<const Spline*> spline_pointers;  // by model spline index
  Sink sink[dae::kNumMatrices];
  std::vector<double> zeros;  // nq + nc zeros for absent inputs
  std::string error;

  Impl(const Model& m, std::vector<double> p) : model(m), params(std::move(p)) {}

  // ---- parameter derivatives (see system.h and docs/parameter-derivatives.md) ----
  std::vector<SensitivityParameter> sens;
  std::vector<std::vector<double>> chain;      // [k][j] = d value_j / d sens_k
  std::vector<std::vector<char>> param_dep;    // structural: value_j depends on sens_k
  std::vector<std::vector<char>> spline_dep;   // structural: spline s's ordinates depend on sens_k
  std::vector<std::vector<std::vector<double>>> spline_dy;  // [k][s] ordinate direction
  // Tangent splines (Spline::Tangent) per [k][s], rebuilt when the spline's points change
  // (the points they were built from: tangent_x/y[s], per spline; tangent_valid[s]).
  std::vector<std::vector<Spline>> tangents;
  std::vector<std::vector<double>> tangent_x, tangent_y;
  std::vector<char> tangent_valid;
  std::vector<std::vector<const Spline*>> tangent_ptrs;
  Sink psink[dae::kNumParameterMatrices];

  // Compact dependency lists, built once (SetupSensitivity), so that an evaluation costs
  // in proportion to the nonzeros of the parameter matrices, not to elements x parameters.
  // Each list is in ascending k: the adds happen in the order of the dense loops they
  // replace, so the values are the same bit for bit.
  std::vector<std::vector<int>> param_users;   // [j]: the k with param_dep[k][j]
  std::vector<std::vector<int>> spline_users;  // [s]: the k with spline_dep[k][s]
  // Bodies: the k reaching the mass (dm), the inertia (dj) or gravity (dg), with the
  // derivatives of those parameter-only values (cached: recomputed when params change).
  struct BodyTerm {
    int k = 0;
    bool dm_dep = false, dj_dep = false, dg_dep = false;
    double dm = 0;
    Mat3 dJ = Mat3::Zero();
    Vec3 dg = Vec3::Zero();
  };
  std::vector<std::vector<BodyTerm>> body_terms;
  // Force elements: the k reaching one of its expressions; mask bit e: expression e
  // (ForceExpression numbering) depends on k. Bushings: the derivatives of the stiffness
  // and damping (parameter-only, cached like the bodies').
  struct ForceTerm {
    int k = 0;
    unsigned mask = 0;
    BushingParameters dbp;
  };
  std::vector<std::vector<ForceTerm>> force_terms;
  // Motion joints, by measure_constraints index: the k reaching the motion value.
  std::vector<std::vector<int>> motion_terms;
  // The parameter values the cached derivatives were computed at.
  std::vector<double> cached_params;
  bool cache_valid = false;

  bool Depends(const Expression& e, int k) const {
    for (int j : e.parameters_used())
      if (param_dep[k][j]) return true;
    for (int s : e.splines_used())
      if (spline_dep[k][s]) return true;
    return false;
  }
  // Total derivative of a parameter-only expression along sens_k.
  double ParamDerivative(const Expression& e, int k) const {
    if (e.parameters_used().empty()) return 0;
    ExpressionInputs in;
    in.parameters = params.data();
    ExpressionGradient g;
    e.EvaluateGradient(in, &g);
    double d = 0;
    for (size_t u = 0; u < e.parameters_used().size(); ++u)
      if (chain[k][e.parameters_used()[u]] != 0) d += g.d_parameters[u] * chain[k][e.parameters_used()[u]];
    return d;
  }
  ParameterDirection Direction(int k) const {
    ParameterDirection d;
    d.parameters = chain[k].data();
    d.spline_tangents = tangent_ptrs[k].empty() ? nullptr : tangent_ptrs[k].data();
    return d;
  }
  // Adds to *ks the k whose direction reaches e (Depends(e, k)), each once: mark[k] is
  // set for the k in *ks (the caller sorts *ks and clears mark).
  void AddUsers(const Expression& e, std::vector<char>& mark, std::vector<int>* ks) const {
    auto add = [&](const std::vector<int>& users) {
      for (int k : users)
        if (!mark[k]) {
          mark[k] = 1;
          ks->push_back(k);
        }
    };
    for (int j : e.parameters_used()) add(param_users[j]);
    for (int sp : e.splines_used()) add(spline_users[sp]);
  }
  static void TakeUsers(std::vector<char>& mark, std::vector<int>* ks) {
    std::sort(ks->begin(), ks->end());
    for (int k : *ks) mark[k] = 0;
  }
  void SetupSensitivity();
  void BuildParameterTerms();
  void UpdateParameterCache();
  void UpdateTangents();
  // values_current: force_values, force_expr and measure_values hold the values of this
  // (t, q, v) (Run computed them just before); else they are recomputed here.
  void RunParameters(const dae::EvalInput& in, dae::EvalOutput& out, bool values_current);

  int BodyOf(int marker) const { return model.markers[marker].body; }

  // Local coordinates of the bodies of markers i (slot 0) and j (slot 1).
  void Gather(int body0, int body1, const double* q, const double* v, const double* a,
              Local& l) const {
    const int body[2] = {body0, body1};
    l.v.setZero();
    l.a.setZero();
    for (int s = 0; s < 2; ++s) {
      if (body[s] < 0) {
        l.offset[s] = -1;
        l.r[s].setZero(); l.rd[s].setZero(); l.rdd[s].setZero();
        l.e[s] = Quat(1, 0, 0, 0); l.ed[s].setZero(); l.edd[s].setZero();
        continue;
      }
      const int o = Model::coordinate_offset(body[s]);
      l.offset[s] = o;
      l.r[s] = Eigen::Map<const Vec3>(q + o);
      l.e[s] = Eigen::Map<const Quat>(q + o + 3);
      l.rd[s] = Eigen::Map<const Vec3>(v + o);
      l.ed[s] = Eigen::Map<const Quat>(v + o + 3);
      l.rdd[s] = Eigen::Map<const Vec3>(a + o);
      l.edd[s] = Eigen::Map<const Quat>(a + o + 3);
      l.v.segment<7>(7 * s) = Eigen::Map<const Eigen::Matrix<double, 7, 1>>(v + o);
      l.a.segment<7>(7 * s) = Eigen::Map<const Eigen::Matrix<double, 7, 1>>(a + o);
    }
  }

  // Marker position (point) or marker axis k (0..2) as a field of slot `slot`.
  Term MarkerPoint(int marker, int slot, double sign) const {
    const Marker& mk = model.markers[marker];
    Term t;
    t.slot = mk.body < 0 ? -1 : slot;
    t.u = mk.position;
    t.point = true;
    t.sign = sign;
    return t;
  }
  Term MarkerAxis(int marker, int slot, int axis) const {
    const Marker& mk = model.markers[marker];
    Term t;
    t.slot = mk.body < 0 ? -1 : slot;
    t.u = mk.orientation.col(axis);
    return t;
  }
  static Field One(const Term& a) { Field f; f.t[0] = a; f.n = 1; return f; }
  Field Separation(int mi, int mj) const {  // d = x_i - x_j
    Field f;
    f.t[0] = MarkerPoint(mi, 0, 1.0);
    f.t[1] = MarkerPoint(mj, 1, -1.0);
    f.n = 2;
    return f;
  }

  // The two factors of joint equation `lock` (c = u . w).
  void JointFactors(const Joint& jt, int lock, Field& u, Field& w) const {
    switch (lock) {
      case 0: case 1: case 2:
        u = One(MarkerAxis(jt.j, 1, lock));
        w = Separation(jt.i, jt.j);
        return;
      case 3: u = One(MarkerAxis(jt.j, 1, 1)); w = One(MarkerAxis(jt.i, 0, 2)); return;
      case 4: u = One(MarkerAxis(jt.j, 1, 0)); w = One(MarkerAxis(jt.i, 0, 2)); return;
      default: u = One(MarkerAxis(jt.j, 1, 0)); w = One(MarkerAxis(jt.i, 0, 1)); return;
    }
  }

  // c = u . w and its gradient in the local coordinates (for JointReaction).
  static void DotEquation(const Field& u, const Field& w, const Local& l, double* c,
                          Vec14* grad) {
    const Vec3 uv = u.Value(l), wv = w.Value(l);
    const Mat3x14 ju = u.Jacobian(l), jw = w.Jacobian(l);
    *c = uv.dot(wv);
    *grad = ju.transpose() * wv + jw.transpose() * uv;
  }

  static const Expression& ForceExpression(const Force& f, int e) {
    switch (e) {
      case 0: return f.stiffness;
      case 1: return f.damping;
      case 2: return f.free_length;
      case 3: return f.preload;
      default: return f.value[e - 4];
    }
  }
  static bool TwoMarkerLaw(const Force& f) {
    return f.type == ForceType::kBushing || f.type == ForceType::kUser;
  }
  static int FirstExpression(const Force& f) {
    return TwoMarkerLaw(f) ? 0 : f.type == ForceType::kSpringDamper ? 0 : 4;
  }
  static int EndExpression(const Force& f) {
    return TwoMarkerLaw(f) ? 0 : f.type == ForceType::kSpringDamper ? 4 : 7;
  }

  // Two-marker force laws (bushing, user; mbs/force_law.h). The inputs x (24) of the
  // law as functions of the local coordinates and rates of the element's bodies:
  //   p = r + A(e) s,                  dp/dr = I, dp/de = B(e, s);
  //   R = A(e/|e|) O,                  dphi = 2 E(e) de / |e|^2 (E(e) e = 0; = 2 E de
  //                                    for unit e, Nikravesh eq. 6.90);
  //   v = r' + B(e, s) e',             dv/de = B(e', s), dv/dr' = I, dv/de' = B(e, s);
  //   w = 2 E(e) e' = -2 E(e') e,      dw/de = -2 E(e'), dw/de' = 2 E(e).
  // Ground markers: p = s, R = O, v = w = 0.
  using Mat24x14 = Eigen::Matrix<double, 24, 14>;
  void TwoMarkerInputs(const Force& fe, const Local& l, MarkerPairKinematics* k, Mat24x14* xq,
                       Mat24x14* xv) const {
    if (xq) {
      xq->setZero();
      xv->setZero();
    }
    const int markers[2] = {fe.i, fe.j};
    for (int s = 0; s < 2; ++s) {
      const Marker& mk = model.markers[markers[s]];
      Vec3& p = s == 0 ? k->p_i : k->p_j;
      Mat3& R = s == 0 ? k->R_i : k->R_j;
      Vec3& vel = s == 0 ? k->v_i : k->v_j;
      Vec3& w = s == 0 ? k->w_i : k->w_j;
      if (mk.body < 0 || l.offset[s] < 0) {
        p = mk.position;
        R = mk.orientation;
        vel.setZero();
        w.setZero();
        continue;
      }
      const Quat& e = l.e[s];
      const Quat& ed = l.ed[s];
      const double n2 = e.squaredNorm();
      const Mat34 Be = BMatrix(e, mk.position);
      p = l.r[s] + RotationMatrix(e) * mk.position;
      R = RotationMatrix(Quat(e / std::sqrt(n2))) * mk.orientation;
      vel = l.rd[s] + Be * ed;
      const Mat34 E = EMatrix(e), Ed = EMatrix(ed);
      w = 2 * E * ed;
      if (!xq) continue;
      const int cp = s == 0 ? kPi : kPj, cphi = s == 0 ? kPhiI : kPhiJ;
      const int cv = s == 0 ? kVi : kVj, cw = s == 0 ? kWi : kWj;
      const int o = 7 * s;
      xq->block<3, 3>(cp, o).setIdentity();
      xq->block<3, 4>(cp, o + 3) = Be;
      xq->block<3, 4>(cphi, o + 3) = (2 / n2) * E;
      xq->block<3, 4>(cv, o + 3) = BMatrix(ed, mk.position);
      xv->block<3, 3>(cv, o).setIdentity();
      xv->block<3, 4>(cv, o + 3) = Be;
      xq->block<3, 4>(cw, o + 3) = -2 * Ed;
      xv->block<3, 4>(cw, o + 3) = 2 * E;
    }
  }

  // Force and torque on marker i of a bushing or user element at (t, l); J (if not
  // null) their Jacobian. A user function's error is caught here: *error gets the
  // message and the values are zero.
  ForceTorque TwoMarkerLawValue(int k, double t, const MarkerPairKinematics& km,
                                ForceJacobian* J, std::string* error) const {
    const Force& fe = model.forces[k];
    if (fe.type == ForceType::kBushing) {
      BushingParameters bp;
      for (int c = 0; c < 6; ++c) {
        bp.stiffness[c] = fe.bushing_stiffness[c].Evaluate(params.data());
        bp.damping[c] = fe.bushing_damping[c].Evaluate(params.data());
      }
      return EvaluateBushing(bp, km, J);
    }
    try {
      return user_forces[k]->Evaluate(t, km, J);
    } catch (const std::exception& ex) {
      if (error) *error = "user force '" + fe.name + "': " + ex.what();
      if (J) J->setZero();
      return ForceTorque();
    }
  }


  // The values of element k at (t, q, v): the measures its expressions use are evaluated
  // into fx->jac and *mvalues (by model measure index), then every expression with its
  // gradient; fx->d_expr[u][e] = dE_e/dm_u. No allocation.
  ForceValues ComputeForceValues(int k, double t, const double* q, const double* v,
                                 ForceExpressions* fx, double* mvalues) const {
    const Force& f = model.forces[k];
    for (size_t u = 0; u < fx->measures.size(); ++u) {
      EvaluateMeasureState(fx->defs[u], q, v, &fx->jac[u]);
      mvalues[fx->measures[u]] = fx->jac[u].value - measure_offsets[fx->measures[u]];
      fx->d_expr[u].fill(0.0);
    }
    ExpressionInputs in;
    in.t = t;
    in.parameters = params.data();
    in.measures = mvalues;
    in.splines = spline_pointers.empty() ? nullptr : spline_pointers.data();
    double x[7] = {0, 0, 0, 0, 0, 0, 0};
    ExpressionGradient g;
    for (int e = FirstExpression(f); e < EndExpression(f); ++e) {
      const Expression& ex = ForceExpression(f, e);
      if (fx->slot[e].empty()) {
        x[e] = ex.Evaluate(in);
        continue;
      }
      x[e] = ex.EvaluateGradient(in, &g);
      for (size_t m = 0; m < fx->slot[e].size(); ++m) fx->d_expr[fx->slot[e][m]][e] = g.d_measures[m];
    }
    ForceValues fv;
    fv.k = x[0];
    fv.c = x[1];
    fv.l0 = x[2];
    fv.preload = x[3];
    fv.value = Vec3(x[4], x[5], x[6]);
    return fv;
  }

  // "" if the values of element k are all finite, else which one is not: "'value'
  // entry 2 ('1/x') is inf" (the first such, in the order stiffness, damping,
  // free_length, preload, value entries 1 to 3).
  std::string NonFiniteForceValue(int k, const ForceValues& fv) const {
    const Force& f = model.forces[k];
    static const char* const kKeys[4] = {"stiffness", "damping", "free_length", "preload"};
    const double x[7] = {fv.k, fv.c, fv.l0, fv.preload, fv.value[0], fv.value[1], fv.value[2]};
    for (int e = FirstExpression(f); e < EndExpression(f); ++e) {
      if (std::isfinite(x[e])) continue;
      std::ostringstream s;
      s << std::setprecision(10);
      if (e < 4)
        s << "'" << kKeys[e] << "'";
      else
        s << "'value' entry " << e - 3;
      s << " ('" << ForceExpression(f, e).text() << "') is ";
      if (std::isnan(x[e]))
        s << "nan";  // whatever its sign bit
      else
        s << x[e];
      return s.str();
    }
    return "";
  }

  // The force (or torque) vector of element k on marker i, world axes, and its
  // derivatives with respect to the local coordinates and rates (skipped when dfdq is
  // null; then dfdv must be null too). Returns false if a
  // spring has zero length (the values are then finite but meaningless).
  // dfde (if not null): df/dE_e for the seven expression values (columns as in
  // ForceExpressions).
  bool ForceVector(int k, const ForceValues& fv, const Local& l, Vec3* f, Mat3x14* dfdq,
                   Mat3x14* dfdv, Mat37* dfde = nullptr) const {
    const Force& fe = model.forces[k];
    if (dfdq) {
      dfdq->setZero();
      dfdv->setZero();
    }
    if (dfde) dfde->setZero();
    if (fe.type == ForceType::kSpringDamper) {
      const Field d = Separation(fe.i, fe.j);
      const Vec3 dv = d.Value(l);
      const Mat3x14 jd = d.Jacobian(l);
      const Vec3 ddot = jd * l.v;
      double len = dv.norm();
      bool ok = len > 1e-12;
      if (!ok) len = 1;
      const Vec3 n = dv / len;
      const double ld = n.dot(ddot);
      const double s = -fv.k * (len - fv.l0) - fv.c * ld + fv.preload;
      *f = s * n;
      if (dfde) {
        dfde->col(0) = -(len - fv.l0) * n;
        dfde->col(1) = -ld * n;
        dfde->col(2) = fv.k * n;
        dfde->col(3) = n;
      }
      if (!dfdq) return ok;
      const Mat3 dn = (Mat3::Identity() - n * n.transpose()) / len;  // dn/dd
      const Eigen::Matrix<double, 1, 14> dl = n.transpose() * jd;
      const Eigen::Matrix<double, 1, 14> dld =
          ddot.transpose() * dn * jd + n.transpose() * d.JacobianDot(l);
      const Eigen::Matrix<double, 1, 14> ds = -fv.k * dl - fv.c * dld;
      *dfdq = n * ds + s * dn * jd;
      *dfdv = -fv.c * n * dl;
      return ok;
    }
    // force / torque: constant components in the frame's axes
    if (fe.frame == ForceFrame::kWorld) {
      *f = fv.value;
      if (dfde) dfde->rightCols<3>().setIdentity();
      return true;
    }
    const int marker = fe.frame == ForceFrame::kI ? fe.i : fe.j;
    const int slot = fe.frame == ForceFrame::kI ? 0 : 1;
    Term t = MarkerAxis(marker, slot, 0);
    t.u = model.markers[marker].orientation * fv.value;
    const Field u = One(t);
    *f = u.Value(l);
    if (dfdq) *dfdq = u.Jacobian(l);
    if (dfde) {
      const Marker& mk = model.markers[marker];
      dfde->rightCols<3>() =
          mk.body < 0 ? mk.orientation : Mat3(RotationMatrix(l.e[slot]) * mk.orientation);
    }
    return true;
  }

  // Structural dependencies of element k's vector on q and v.
  bool ForceDependsOnQ(int k) const {
    const Force& fe = model.forces[k];
    if (fe.type == ForceType::kSpringDamper) return true;
    if (fe.frame == ForceFrame::kWorld) return false;
    const int marker = fe.frame == ForceFrame::kI ? fe.i : fe.j;
    return BodyOf(marker) >= 0;
  }
  bool ForceDependsOnV(int k) const {
    return model.forces[k].type == ForceType::kSpringDamper;
  }

  // Adds a local 14x14 matrix to a sink, entries (r, c) with InPart(rows, r) and
  // InPart(cols, c) and both slots on bodies.
  static void AddLocal(Sink& s, const Local& l, const Mat14& m, Part rows, Part cols) {
    for (int c = 0; c < 14; ++c) {
      const int oc = l.offset[c / 7];
      if (oc < 0 || !InPart(cols, c)) continue;
      for (int r = 0; r < 14; ++r) {
        const int orow = l.offset[r / 7];
        if (orow < 0 || !InPart(rows, r)) continue;
        s.Add(orow + r % 7, oc + c % 7, m(r, c));
      }
    }
  }

  // Adds the outer product col * row^T: rows in the local coordinates of roff (InPart
  // rows), columns in those of coff.
  static void AddCross(Sink& s, const int roff[2], const int coff[2], const Vec14& col,
                       const Vec14& row, Part rows) {
    for (int c = 0; c < 14; ++c) {
      const int oc = coff[c / 7];
      if (oc < 0) continue;
      for (int r = 0; r < 14; ++r) {
        const int orow = roff[r / 7];
        if (orow < 0 || !InPart(rows, r)) continue;
        s.Add(orow + r % 7, oc + c % 7, col[r] * row[c]);
      }
    }
  }

  int Run(const dae::EvalInput& in, dae::EvalOutput& out);
  void Setup();
};

void MultibodySystem::Impl::Setup() {
  const int nb = static_cast<int>(model.bodies.size());
  const int nm = static_cast<int>(model.markers.size());
  nq = model.num_coordinates();
  if (params.empty())
    for (const Parameter& p : model.parameters) params.push_back(p.value);
  if (params.size() != model.parameters.size()) {
    std::ostringstream msg;
    msg << "MultibodySystem: " << params.size() << " parameter values given, the model has "
        << model.parameters.size();
    throw std::invalid_argument(msg.str());
  }
  auto check_marker = [&](int m, const std::string& what) {
    if (m < 0 || m >= nm) {
      std::ostringstream msg;
      msg << what << ": marker index " << m << " out of range (" << nm << " markers)";
      throw std::invalid_argument(msg.str());
    }
  };
  for (const Marker& mk : model.markers)
    if (mk.body < -1 || mk.body >= nb)
      throw std::invalid_argument("marker '" + mk.name + "': body index out of range");
  static const char* kCoord[7] = {"x", "y", "z", "e0", "e1", "e2", "e3"};
  // Sized once (regrowing joint_info alone took 3 % of building a 10^4-body chain).
  quaternion_offsets.reserve(nb);
  coordinate_names.reserve(7 * static_cast<size_t>(nb));
  // An upper bound: at most 6 equations per joint, 1 per body.
  const size_t equations = nb + 6 * model.joints.size();
  constraint_names.reserve(equations);
  constraint_joint.reserve(equations);
  joint_row.reserve(model.joints.size());
  joint_locks.reserve(model.joints.size());
  joint_info.reserve(model.joints.size());
  for (int b = 0; b < nb; ++b) {
    quaternion_offsets.push_back(7 * b + 3);
    for (int k = 0; k < 7; ++k) coordinate_names.push_back(model.bodies[b].name + "." + kCoord[k]);
  }
  const int nmeasures = static_cast<int>(model.measures.size());
  for (size_t k = 0; k < model.joints.size(); ++k) {
    const Joint& jt = model.joints[k];
    if (jt.type == JointType::kMotion || jt.type == JointType::kGear) {
      const bool motion = jt.type == JointType::kMotion;
      MeasureConstraint mc;
      mc.joint = static_cast<int>(k);
      mc.row = nc;
      mc.motion = motion;
      mc.n = motion ? 1 : 2;
      for (int u = 0; u < mc.n; ++u) {
        const int m = jt.measures[u];
        if (m < 0 || m >= nmeasures)
          throw std::invalid_argument("joint '" + jt.name + "': measure index " + std::to_string(m) +
                                      " out of range (" + std::to_string(nmeasures) + " measures)");
        if (model.measures[m].quantity != Quantity::kPosition ||
            (!motion && model.measures[m].type != MeasureType::kRotational))
          throw std::invalid_argument("joint '" + jt.name + "': measure '" + model.measures[m].name +
                                      "' is not a position-level " + (motion ? "measure" : "angle"));
        mc.def[u] = ResolveMeasure(model, m);
      }
      if (motion) {
        if (jt.value.depends_on_state())
          throw std::invalid_argument("joint '" + jt.name + "': the motion value depends on measures");
        for (int sp : jt.value.splines_used())
          if (sp < 0 || sp >= static_cast<int>(model.splines.size()))
            throw std::invalid_argument("joint '" + jt.name + "': spline index out of range");
        mc.coef[0] = 1;
        mc.wrap = model.measures[jt.measures[0]].type == MeasureType::kRotational;
      } else {
        mc.coef[0] = -jt.ratio;
        mc.coef[1] = 1;
        mc.unwrap[0] = mc.unwrap[1] = true;
      }
      measure_constraints.push_back(mc);
      joint_row.push_back(nc);
      joint_locks.emplace_back();
      constraint_names.push_back(jt.name + (motion ? ".motion" : ".gear"));
      constraint_joint.push_back(static_cast<int>(k));
      ++nc;
      continue;
    }
    check_marker(jt.i, "joint '" + jt.name + "'");
    check_marker(jt.j, "joint '" + jt.name + "'");
    if (BodyOf(jt.i) < 0 && BodyOf(jt.j) < 0)
      throw std::invalid_argument("joint '" + jt.name + "': both markers are on ground");
    joint_row.push_back(nc);
    joint_locks.emplace_back();
    for (int b = 0; b < 6; ++b) {
      if (!(jt.locks & (1u << b))) continue;
      joint_locks.back().push_back(b);
      constraint_names.push_back(jt.name + "." + kLockNames[b]);
      constraint_joint.push_back(static_cast<int>(k));
      ++nc;
    }
  }
  for (int b = 0; b < nb; ++b) {
    constraint_names.push_back(model.bodies[b].name + ".euler_norm");
    constraint_joint.push_back(-1);
    ++nc;
  }
  for (const Force& f : model.forces) {
    check_marker(f.i, "force '" + f.name + "'");
    check_marker(f.j, "force '" + f.name + "'");
  }
  for (const Measure& m : model.measures) {
    check_marker(m.i, "measure '" + m.name + "'");
    check_marker(m.j, "measure '" + m.name + "'");
  }
  for (const Joint& jt : model.joints) {
    JointInfo ji;
    if (jt.type == JointType::kMotion || jt.type == JointType::kGear) {
      joint_info.push_back(ji);
      continue;
    }
    const int mk[2] = {jt.i, jt.j};
    for (int s = 0; s < 2; ++s) {
      const Marker& m = model.markers[mk[s]];
      ji.body[s] = m.body;
      ji.offset[s] = m.body < 0 ? -1 : Model::coordinate_offset(m.body);
      ji.s[s] = m.position;
      ji.axes[s] = m.orientation;
    }
    for (int b = 0; b < 6; ++b) {
      if (!(jt.locks & (1u << b))) continue;
      if (b < 3) {
        ji.trans = true;
        ji.need_axis[1][b] = true;
      } else {
        ji.rot = true;
        ji.need_axis[1][b == 3 ? 1 : 0] = true;
        ji.need_axis[0][b == 5 ? 1 : 2] = true;
      }
    }
    joint_info.push_back(ji);
  }
  state.resize(nb);
  force_values.resize(model.forces.size());
  const int nmeas = static_cast<int>(model.measures.size());
  const int nspl = static_cast<int>(model.splines.size());
  measure_values.assign(nmeas, 0.0);
  for (const SplineDef& sd : model.splines) spline_pointers.push_back(&sd.spline);
  force_expr.resize(model.forces.size());
  for (size_t k = 0; k < model.forces.size(); ++k) {
    const Force& f = model.forces[k];
    ForceExpressions& fx = force_expr[k];
    for (int e = FirstExpression(f); e < EndExpression(f); ++e) {
      const Expression& ex = ForceExpression(f, e);
      for (int s : ex.splines_used())
        if (s < 0 || s >= nspl)
          throw std::invalid_argument("force '" + f.name + "': spline index " + std::to_string(s) +
                                      " out of range (" + std::to_string(nspl) + " splines)");
      for (int m : ex.measures_used()) {
        if (m < 0 || m >= nmeas)
          throw std::invalid_argument("force '" + f.name + "': measure index " + std::to_string(m) +
                                      " out of range (" + std::to_string(nmeas) + " measures)");
        if (model.measures[m].quantity == Quantity::kAcceleration)
          throw std::invalid_argument("force '" + f.name + "': measure '" + model.measures[m].name +
                                      "' is an acceleration; forces may use position and velocity "
                                      "measures only");
        auto it = std::find(fx.measures.begin(), fx.measures.end(), m);
        if (it == fx.measures.end()) {
          fx.measures.push_back(m);
          fx.defs.push_back(ResolveMeasure(model, m));
          it = fx.measures.end() - 1;
        }
        fx.slot[e].push_back(static_cast<int>(it - fx.measures.begin()));
      }
    }
    fx.jac.resize(fx.measures.size());
    fx.d_expr.resize(fx.measures.size());
  }
  measure_offsets.assign(nmeas, 0.0);
  {
    std::vector<double> q0(nq, 0.0), v0(nq, 0.0);
    for (int b = 0; b < nb; ++b) {
      const Body& body = model.bodies[b];
      const int o = Model::coordinate_offset(b);
      Eigen::Map<Vec3>(q0.data() + o) = body.position;
      Eigen::Map<Quat>(q0.data() + o + 3) = body.orientation;
      Eigen::Map<Vec3>(v0.data() + o) = body.velocity;
      Eigen::Map<Quat>(v0.data() + o + 3) =
          0.5 * EMatrix(body.orientation).transpose() * body.angular_velocity;
    }
    for (const ForceExpressions& fx : force_expr)
      for (size_t u = 0; u < fx.measures.size(); ++u)
        if (model.measures[fx.measures[u]].offset_initial)
          measure_offsets[fx.measures[u]] = EvaluateMeasureValue(fx.defs[u], q0.data(), v0.data(), nullptr);
    // Force values at the initial state of the file (t = 0): one that is not finite
    // there is a mistake of the model file, refused before any library code runs.
    std::vector<double> mvalues(nmeas, 0.0);
    for (size_t k = 0; k < model.forces.size(); ++k) {
      const Force& f = model.forces[k];
      if (FirstExpression(f) == EndExpression(f)) continue;
      const ForceValues fv =
          ComputeForceValues(static_cast<int>(k), 0.0, q0.data(), v0.data(), &force_expr[k], mvalues.data());
      const std::string bad = NonFiniteForceValue(static_cast<int>(k), fv);
      if (!bad.empty()) {
        throw ModelError(f.where, "force '" + f.name + "'",
                         bad + " at the initial state of the model file (t = 0); a force value must be finite");
      }
    }
    for (MeasureConstraint& mc : measure_constraints) {
      if (mc.motion) continue;
      // Gear: C = (m2 - m2_0) - r (m1 - m1_0), m_0 at the initial state of the file.
      mc.constant = 0;
      for (int u = 0; u < 2; ++u) {
        MeasureJacobian mj;
        EvaluateMeasurePosition(mc.def[u], q0.data(), false, &mj);
        mc.last[u] = mj.value;
        mc.constant -= mc.coef[u] * mj.value;
      }
    }
  }
  user_forces.resize(model.forces.size());
  for (size_t k = 0; k < model.forces.size(); ++k) {
    const Force& f = model.forces[k];
    if (f.type == ForceType::kBushing) {
      for (int c = 0; c < 12; ++c) {
        const Expression& ex = c < 6 ? f.bushing_stiffness[c] : f.bushing_damping[c - 6];
        if (ex.depends_on_state() || ex.uses_time() || !ex.splines_used().empty())
          throw std::invalid_argument("bushing '" + f.name +
                                      "': stiffness and damping may depend on the parameters only");
      }
    } else if (f.type == ForceType::kUser) {
      if (!f.library) throw std::invalid_argument("user force '" + f.name + "': no library");
      std::vector<double> values;
      for (const Expression& ex : f.user_parameters) {
        if (ex.depends_on_state() || ex.uses_time() || !ex.splines_used().empty())
          throw std::invalid_argument("user force '" + f.name + "': parameters may depend on the model's parameters only");
        values.push_back(ex.Evaluate(params.data()));
      }
      try {
        user_forces[k] = std::make_unique<UserForce>(f.library, f.function, std::move(values));
      } catch (const std::exception& e) {
        throw std::runtime_error("user force '" + f.name + "': " + e.what());
      }
    }
  }
  zeros.assign(nq + nc + 1, 0.0);

  // Record the patterns with a generic state.
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> q(nq), v(nq), a(nq), w(nc + 1);
  for (int b = 0; b < nb; ++b) {
    for (int k = 0; k < 3; ++k) q[7 * b + k] = 10 * u(rng);
    Quat e(u(rng), u(rng), u(rng), u(rng));
    e.normalize();
    for (int k = 0; k < 4; ++k) q[7 * b + 3 + k] = e[k];
  }
  for (auto& x : v) x = u(rng);
  for (auto& x : a) x = u(rng);
  for (auto& x : w) x = u(rng);
  for (Sink& s : sink) s.StartRecording();
  dae::EvalInput ein;
  ein.q = q.data(); ein.v = v.data(); ein.a = a.data(); ein.w = w.data();
  dae::EvalOutput eout;
  std::vector<double> f(nq), c(nc + 1), ct(nc + 1), g(nc + 1);
  eout.force = f.data(); eout.constraint = c.data(); eout.constraint_dt = ct.data();
  eout.acc_rhs = g.data();
  std::vector<std::array<double, 2>> last(measure_constraints.size());
  for (size_t k = 0; k < measure_constraints.size(); ++k)
    last[k] = {measure_constraints[k].last[0], measure_constraints[k].last[1]};
  Run(ein, eout);
  error.clear();  // the generic state may be outside a force value's domain: not an error
  for (size_t k = 0; k < measure_constraints.size(); ++k) {
    measure_constraints[k].last[0] = last[k][0];
    measure_constraints[k].last[1] = last[k][1];
  }
  for (int m = 0; m < dae::kNumMatrices; ++m) {
    const auto mm = static_cast<dae::Matrix>(m);
    const bool qrows = mm == dae::Matrix::kConstraintDq || mm == dae::Matrix::kConstraintVelDq;
    sink[m].Finish(qrows ? nc : nq, nq);
  }
}

int MultibodySystem::Impl::Run(const dae::EvalInput& in, dae::EvalOutput& out) {
  using dae::Matrix;
  const double* q = in.q;
  assert(q != nullptr);
  const double* v = in.v ? in.v : zeros.data();
  const double* a = in.a ? in.a : zeros.data();
  const double* w = in.w ? in.w : zeros.data();
  const int nb = static_cast<int>(model.bodies.size());
  Sink& sM = sink[static_cast<int>(Matrix::kMass)];
  Sink& sMa = sink[static_cast<int>(Matrix::kMassTimesAccDq)];
  Sink& sKq = sink[static_cast<int>(Matrix::kForceDq)];
  Sink& sKv = sink[static_cast<int>(Matrix::kForceDv)];
  Sink& sCq = sink[static_cast<int>(Matrix::kConstraintDq)];
  Sink& sCtw = sink[static_cast<int>(Matrix::kConstraintTDq)];
  Sink& sCv = sink[static_cast<int>(Matrix::kConstraintVelDq)];
  for (int m = 0; m < dae::kNumMatrices; ++m) sink[m].Begin(out.matrix[m]);
  // C_q^T w without C_q (EvalOutput::constraint_transpose_w): each C_q entry's product
  // with w added where the entry is added to the sink (adds_once_by_row: in the order of
  // a product by the pattern's columns).
  double* const cqtw = out.constraint_transpose_w;
  if (cqtw) std::fill(cqtw, cqtw + nq, 0.0);
  const bool cq = sCq.active() || cqtw;
  // Every entry of C_q goes through here, n of a row in consecutive columns from col: to
  // the sink, and their products with w to cqtw (the tests outside the loops).
  auto add_cq = [&](int row, int col, const double* values, int n) __attribute__((always_inline)) {
    if (sCq.active())
      for (int i = 0; i < n; ++i) sCq.Add(row, col + i, values[i]);
    if (cqtw)
      for (int i = 0; i < n; ++i) cqtw[col + i] += values[i] * w[row];
  };
  if (out.force) std::fill(out.force, out.force + nq, 0.0);
  if (out.constraint) std::fill(out.constraint, out.constraint + nc, 0.0);
  if (out.constraint_dt) std::fill(out.constraint_dt, out.constraint_dt + nc, 0.0);
  if (out.acc_rhs) std::fill(out.acc_rhs, out.acc_rhs + nc, 0.0);
  if (out.force_quadratic_velocity)
    std::fill(out.force_quadratic_velocity, out.force_quadratic_velocity + nq, 0.0);
  if (out.constraint_dtt) std::fill(out.constraint_dtt, out.constraint_dtt + nc, 0.0);
  bool spring_ok = true;
  int bad_spring = -1;
  std::string law_error;  // first error of a user force function (no allocation if none)

  for (int b = 0; b < nb; ++b) {
    const int o = Model::coordinate_offset(b);
    BodyState& st = state[b];
    st.r = Eigen::Map<const Vec3>(q + o);
    st.e = Eigen::Map<const Quat>(q + o + 3);
    st.rd = Eigen::Map<const Vec3>(v + o);
    st.ed = Eigen::Map<const Quat>(v + o + 3);
    st.A = RotationMatrix(st.e);
  }

  // Bodies: mass matrix, gravity, quadratic velocity terms.
  for (int b = 0; b < nb; ++b) {
    const Body& body = model.bodies[b];
    const int o = Model::coordinate_offset(b);
    const Quat e = Eigen::Map<const Quat>(q + o + 3);
    const Quat ed = Eigen::Map<const Quat>(v + o + 3);
    const Mat34 G = GMatrix(e), Gd = GMatrix(ed);
    const Mat3& J = body.inertia;
    if (sM.active()) {
      for (int k = 0; k < 3; ++k) sM.Add(o + k, o + k, body.mass);
      const Mat4 Me = 4 * XtJY(G, J, G);
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) sM.Add(o + 3 + r, o + 3 + c, Me(r, c));
    }
    if (sMa.active()) {
      // d(4 G^T J G a_e)/de = 4 dG^T/de (J G a_e) + 4 G^T J d(G a_e)/de
      const Quat ae = Eigen::Map<const Quat>(a + o + 3);
      const Mat4 K = 4 * GtJacobian(J * (G * ae)) - 4 * XtJY(G, J, GMatrix(ae));
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) sMa.Add(o + 3 + r, o + 3 + c, K(r, c));
    }
    const Vec3 ge = Gd * e;  // = -G e' = -omega'/2
    if (out.force || out.force_quadratic_velocity) {
      // Q_v = 8 G(e')^T J G(e') e = dT/de - (dM/dt) e' (Lagrange's equations with
      // T = 2 e'^T G^T J G e'; the translational part has none).
      const Quat qv = 8 * (Gd.transpose() * (J * ge));
      if (out.force) {
        Eigen::Map<Vec3>(out.force + o) += body.mass * model.gravity;
        Eigen::Map<Quat>(out.force + o + 3) += qv;
      }
      if (out.force_quadratic_velocity) Eigen::Map<Quat>(out.force_quadratic_velocity + o + 3) = qv;
    }
    if (sKq.active()) {
      const Mat4 K = 8 * XtJY(Gd, J, Gd);
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) sKq.Add(o + 3 + r, o + 3 + c, K(r, c));
    }
    if (sKv.active()) {
      // d(8 G(e')^T J G(e') e)/de' with G(e') e = -G(e) e'
      const Mat4 K = 8 * GtJacobian(J * ge) - 8 * XtJY(Gd, J, G);
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) sKv.Add(o + 3 + r, o + 3 + c, K(r, c));
    }
  }

  // Joints. Every equation is c = U . W of two fields (JointField): translational
  // lock k: U = axis k of marker j, W = d = x_i - x_j; rx: j's y-axis . i's z-axis,
  // ry: j's x . i's z, rz: j's x . i's y. Then
  //   grad c = dU^T W + dW^T U,   H v = dU^T W' + dW^T U' + B(e_s', ub)^T terms,
  // and the weighted Hessians of the joint are summed into one local 14x14 block
  // (the translational equations share W = d: sum_k w_k H_k is the Hessian of
  // (sum_k w_k U_k) . d).
  const bool need_b = sCtw.active() || sCv.active() || out.acc_rhs;
  const bool need_rates = sCv.active() || out.acc_rhs;
  Mat14 H;
  for (size_t k = 0; k < model.joints.size(); ++k) {
    if (joint_locks[k].empty()) continue;  // motion and gear joints: below
    const JointInfo& ji = joint_info[k];
    const BodyState* bs[2] = {ji.body[0] >= 0 ? &state[ji.body[0]] : nullptr,
                              ji.body[1] >= 0 ? &state[ji.body[1]] : nullptr};
    // B matrices and the rate of a field whose x, sig, rot and ub are set.
    auto finish = [&](JointField& f) {
      if (!need_b) return;
      f.xd.setZero();
      for (int s = 0; s < 2; ++s) {
        if (!bs[s]) continue;
        if (f.rot[s]) f.B[s] = BMatrix(bs[s]->e, f.ub[s]);
        if (need_rates) {
          if (f.sig[s] != 0) f.xd += f.sig[s] * bs[s]->rd;
          if (f.rot[s]) f.xd.noalias() += f.B[s] * bs[s]->ed;
        }
      }
    };
    JointField d, axis[2][3];
    d.Clear();
    Vec3 P[2];
    for (int s = 0; s < 2; ++s) {
      if (bs[s]) {
        P[s] = bs[s]->r + bs[s]->A * ji.s[s];
        d.sig[s] = s == 0 ? 1.0 : -1.0;
        d.rot[s] = true;
        d.ub[s] = d.sig[s] * ji.s[s];
      } else {
        P[s] = ji.s[s];
      }
      for (int c = 0; c < 3; ++c) {
        if (!ji.need_axis[s][c]) continue;
        JointField& f = axis[s][c];
        f.Clear();
        if (bs[s]) {
          f.rot[s] = true;
          f.ub[s] = ji.axes[s].col(c);
          f.x = bs[s]->A * f.ub[s];
        } else {
          f.x = ji.axes[s].col(c);
        }
        finish(f);
      }
    }
    d.x = P[0] - P[1];
    if (ji.trans) finish(d);

    const bool ctw = sCtw.active();
    bool nz[4][4] = {{false}};
    if (ctw) H.setZero();
    int row = joint_row[k];
    for (int lock : joint_locks[k]) {
      const JointField& U = lock < 3 ? axis[1][lock] : axis[1][lock == 3 ? 1 : 0];
      const JointField& W = lock < 3 ? d : axis[0][lock == 5 ? 1 : 2];
      if (out.constraint) out.constraint[row] = U.x.dot(W.x);
      if (cq) {
        for (int s = 0; s < 2; ++s) {
          if (!bs[s]) continue;
          const int o = ji.offset[s];
          if (U.sig[s] != 0 || W.sig[s] != 0) {
            const Vec3 gr = U.sig[s] * W.x + W.sig[s] * U.x;
            add_cq(row, o, gr.data(), 3);
          } else {
            for (int i = 0; i < 3; ++i) sCq.Declare(row, o + i);
          }
          if (U.rot[s] || W.rot[s]) {
            Quat ge = Quat::Zero();
            if (U.rot[s]) ge += BtW(bs[s]->e, U.ub[s], W.x);
            if (W.rot[s]) ge += BtW(bs[s]->e, W.ub[s], U.x);
            add_cq(row, o + 3, ge.data(), 4);
          } else {
            for (int i = 0; i < 4; ++i) sCq.Declare(row, o + 3 + i);
          }
        }
      }
      if (need_rates) {
        double vhv = 0;
        for (int s = 0; s < 2; ++s) {
          if (!bs[s]) continue;
          const int o = ji.offset[s];
          const bool has_r = U.sig[s] != 0 || W.sig[s] != 0;
          const bool has_e = U.rot[s] || W.rot[s];
          const Vec3 hr = U.sig[s] * W.xd + W.sig[s] * U.xd;
          Quat he = Quat::Zero();
          if (U.rot[s]) he += U.B[s].transpose() * W.xd + BtW(bs[s]->ed, U.ub[s], W.x);
          if (W.rot[s]) he += W.B[s].transpose() * U.xd + BtW(bs[s]->ed, W.ub[s], U.x);
          vhv += bs[s]->rd.dot(hr) + bs[s]->ed.dot(he);
          if (sCv.active()) {
            for (int i = 0; i < 3; ++i)
              if (has_r) sCv.Add(row, o + i, hr[i]); else sCv.Declare(row, o + i);
            for (int i = 0; i < 4; ++i)
              if (has_e) sCv.Add(row, o + 3 + i, he[i]); else sCv.Declare(row, o + 3 + i);
          }
        }
        if (out.acc_rhs) out.acc_rhs[row] = -vhv;
      }
      if (ctw && lock >= 3) AddDotHessian(U, W, w[row], H, nz);
      ++row;
    }
    if (!ctw) continue;
    if (ji.trans) {
      JointField uw;  // sum_k w_k (axis k of marker j) over the translational locks
      uw.Clear();
      uw.x.setZero();
      Vec3 ub = Vec3::Zero();
      row = joint_row[k];
      for (int lock : joint_locks[k]) {
        if (lock < 3) {
          uw.x += w[row] * axis[1][lock].x;
          ub += w[row] * ji.axes[1].col(lock);
        }
        ++row;
      }
      if (bs[1]) {
        uw.rot[1] = true;
        uw.ub[1] = ub;
        uw.B[1] = BMatrix(bs[1]->e, ub);
      }
      AddDotHessian(uw, d, 1.0, H, nz);
    }
    // Write the block. The pattern keeps what the joint's equations could touch:
    // with translational equations everything but the r-r blocks, else the e-e blocks;
    // blocks that are structurally zero here are declared, not written.
    static const int kStart[4] = {0, 3, 7, 10};
    for (int h = 0; h < 4; ++h) {
      if (!bs[h / 2]) continue;
      const int oc = ji.offset[h / 2] + (h % 2) * 3, nc_h = h % 2 ? 4 : 3;
      for (int g = 0; g < 4; ++g) {
        if (!bs[g / 2]) continue;
        const int orow = ji.offset[g / 2] + (g % 2) * 3, nr_g = g % 2 ? 4 : 3;
        const bool in_pattern = ji.trans ? (g % 2 == 1 || h % 2 == 1) : (g % 2 == 1 && h % 2 == 1);
        assert(in_pattern || !nz[g][h]);
        if (nz[g][h]) {
          for (int c2 = 0; c2 < nc_h; ++c2)
            for (int r2 = 0; r2 < nr_g; ++r2)
              sCtw.Add(orow + r2, oc + c2, H(kStart[g] + r2, kStart[h] + c2));
        } else if (in_pattern) {
          for (int c2 = 0; c2 < nc_h; ++c2)
            for (int r2 = 0; r2 < nr_g; ++r2) sCtw.Declare(orow + r2, oc + c2);
        }
      }
    }
  }
  // Motion and gear joints: C = sum_u c_u m_u(q) + constant - f(t), so
  //   C_q = sum c_u g_u,  C_t = -f'(t),  gamma = -sum c_u v^T H_u v + f''(t),
  //   d(C_q^T w)/dq = w sum c_u H_u,  d(C_q v + C_t)/dq = sum c_u (H_u v)^T.
  {
    const bool need_h = sCtw.active() || sCv.active() || out.acc_rhs;
    ExpressionInputs ein;
    ein.t = in.t;
    ein.parameters = params.data();
    ein.splines = spline_pointers.empty() ? nullptr : spline_pointers.data();
    for (MeasureConstraint& mc : measure_constraints) {
      const int row = mc.row;
      double c = mc.constant, gamma = 0;
      for (int u = 0; u < mc.n; ++u) {
        MeasureJacobian& mj = mc.jac[u];
        EvaluateMeasurePosition(mc.def[u], q, need_h, &mj);
        double value = mj.value;
        if (mc.unwrap[u]) {
          value += 2 * M_PI * std::round((mc.last[u] - value) / (2 * M_PI));
          mc.last[u] = value;
        }
        c += mc.coef[u] * value;
        for (int b = 0; b < 2 && cq; ++b) {
          if (mj.offset[b] < 0) continue;
          double g[7];
          for (int i = 0; i < 7; ++i) g[i] = mc.coef[u] * mj.gradient[7 * b + i];
          add_cq(row, mj.offset[b], g, 7);
        }
        if (!need_h) continue;
        const Vec14 vl = GatherLocal(mj.offset, v);
        const Vec14 hv = mj.hessian * vl;
        gamma -= mc.coef[u] * vl.dot(hv);
        if (sCv.active())
          for (int r = 0; r < 14; ++r)
            if (mj.offset[r / 7] >= 0) sCv.Add(row, mj.offset[r / 7] + r % 7, mc.coef[u] * hv[r]);
        if (sCtw.active()) {
          const double wc = w[row] * mc.coef[u];
          for (int cc = 0; cc < 14; ++cc) {
            if (mj.offset[cc / 7] < 0) continue;
            for (int r = 0; r < 14; ++r)
              if (mj.offset[r / 7] >= 0)
                sCtw.Add(mj.offset[r / 7] + r % 7, mj.offset[cc / 7] + cc % 7, wc * mj.hessian(r, cc));
          }
        }
      }
      if (mc.motion) {
        double f1 = 0, f2 = 0;
        const double f = model.joints[mc.joint].value.EvaluateTimeDerivatives(ein, &f1, &f2);
        c -= f;
        if (mc.wrap) c = std::remainder(c, 2 * M_PI);
        if (out.constraint_dt) out.constraint_dt[row] = -f1;
        if (out.constraint_dtt) out.constraint_dtt[row] = -f2;
        gamma += f2;
      }
      if (out.constraint) out.constraint[row] = c;
      if (out.acc_rhs) out.acc_rhs[row] = gamma;
    }
  }

  // Normalisation of the Euler parameters: e^T e - 1 = 0.
  for (int b = 0; b < nb; ++b) {
    const int row = nc - nb + b;
    const int o = Model::coordinate_offset(b) + 3;
    const Quat e = Eigen::Map<const Quat>(q + o);
    const Quat ed = Eigen::Map<const Quat>(v + o);
    if (out.constraint) out.constraint[row] = e.squaredNorm() - 1;
    if (out.acc_rhs) out.acc_rhs[row] = -2 * ed.squaredNorm();
    if (cq) {
      const double ge[4] = {2 * e[0], 2 * e[1], 2 * e[2], 2 * e[3]};
      add_cq(row, o, ge, 4);
    }
    for (int k = 0; k < 4; ++k) {
      if (sCv.active()) sCv.Add(row, o + k, 2 * ed[k]);
      if (sCtw.active()) sCtw.Add(o + k, o + k, 2 * w[row]);
    }
  }

  // Force elements.
  Local l;
  for (size_t k = 0; k < model.forces.size(); ++k) {
    const Force& fe = model.forces[k];
    Gather(BodyOf(fe.i), BodyOf(fe.j), q, v, a, l);
    if (TwoMarkerLaw(fe)) {
      // Bushing / user force: y = (F, T) on marker i from the law, chained through the
      // marker kinematics (TwoMarkerInputs). Wrenches at the markers: (F, T) on i and
      // (-F, -T - (p_i - p_j) x F) on j; each gives Q_r = F_s,
      // Q_e = 2 G^T skew(s) A^T F_s + 2 G^T A^T T_s (as the force and torque elements).
      const bool derivs = sKq.active() || sKv.active();
      MarkerPairKinematics km;
      Mat24x14 xq, xv;
      TwoMarkerInputs(fe, l, &km, derivs ? &xq : nullptr, derivs ? &xv : nullptr);
      ForceJacobian J;
      const ForceTorque y =
          TwoMarkerLawValue(static_cast<int>(k), in.t, km, derivs ? &J : nullptr, &law_error);
      const Vec3 dpos = km.p_i - km.p_j;
      const Vec3 Fs[2] = {y.force, -y.force};
      const Vec3 Ts[2] = {y.torque, -y.torque - dpos.cross(y.force)};
      Mat3x14 dFq[2], dTq[2], dFv[2], dTv[2];
      if (derivs) {
        const Eigen::Matrix<double, 6, 14> yq = J * xq, yv = J * xv;
        dFq[0] = yq.topRows<3>();
        dTq[0] = yq.bottomRows<3>();
        dFv[0] = yv.topRows<3>();
        dTv[0] = yv.bottomRows<3>();
        const Mat3x14 ddq = xq.middleRows<3>(kPi) - xq.middleRows<3>(kPj);
        const Mat3 Sd = Skew(dpos);
        dFq[1] = -dFq[0];
        dFv[1] = -dFv[0];
        dTq[1] = -dTq[0] - Sd * dFq[0] + Skew(y.force) * ddq;
        dTv[1] = -dTv[0] - Sd * dFv[0];
      }
      Vec14 gq = Vec14::Zero();
      Mat14 kq, kv;
      kq.setZero();
      kv.setZero();
      for (int s = 0; s < 2; ++s) {
        if (l.offset[s] < 0) continue;
        const Quat& e = l.e[s];
        const Mat34 G = GMatrix(e);
        const Mat3 A = RotationMatrix(e);
        const Mat3 S = Skew(model.markers[s == 0 ? fe.i : fe.j].position);
        const Mat43 Pt = 2 * G.transpose() * A.transpose();
        const Mat43 P = 2 * G.transpose() * S * A.transpose();
        gq.segment<3>(7 * s) += Fs[s];
        gq.segment<4>(7 * s + 3) += P * Fs[s] + Pt * Ts[s];
        if (!derivs) continue;
        kq.block<3, 14>(7 * s, 0) += dFq[s];
        kv.block<3, 14>(7 * s, 0) += dFv[s];
        kq.block<4, 14>(7 * s + 3, 0) += P * dFq[s] + Pt * dTq[s];
        kv.block<4, 14>(7 * s + 3, 0) += P * dFv[s] + Pt * dTv[s];
        kq.block<4, 4>(7 * s + 3, 7 * s + 3) +=
            2 * GtJacobian(S * A.transpose() * Fs[s]) + 2 * G.transpose() * S * BTransposeMatrix(e, Fs[s]) +
            2 * GtJacobian(A.transpose() * Ts[s]) + 2 * G.transpose() * BTransposeMatrix(e, Ts[s]);
      }
      if (out.force)
        for (int r = 0; r < 14; ++r)
          if (l.offset[r / 7] >= 0) out.force[l.offset[r / 7] + r % 7] += gq[r];
      if (sKq.active()) AddLocal(sKq, l, kq, Part::kAll, Part::kAll);
      if (sKv.active()) AddLocal(sKv, l, kv, Part::kAll, Part::kAll);
      continue;
    }
    ForceExpressions& fx = force_expr[k];
    force_values[k] =
        ComputeForceValues(static_cast<int>(k), in.t, q, v, &fx, measure_values.data());
    if (law_error.empty()) {
      // A value that is not finite is fatal: the model says something impossible there.
      const std::string bad = NonFiniteForceValue(static_cast<int>(k), force_values[k]);
      if (!bad.empty()) {
        std::ostringstream msg;
        msg << std::setprecision(10) << "force '" << fe.name << "': " << bad << " at t = " << in.t;
        law_error = msg.str();
      }
    }
    const bool state_values = !fx.measures.empty();
    Vec3 f;
    Mat3x14 dfdq, dfdv;
    Mat37 dfde;
    Eigen::Matrix<double, 14, 3> Pfull;  // dQ_local/df
    const bool derivs = sKq.active() || sKv.active();
    if (!ForceVector(static_cast<int>(k), force_values[k], l, &f, derivs ? &dfdq : nullptr,
                     derivs ? &dfdv : nullptr, derivs && state_values ? &dfde : nullptr) &&
        spring_ok) {
      spring_ok = false;
      bad_spring = static_cast<int>(k);
    }
    const bool depq = ForceDependsOnQ(static_cast<int>(k));
    const bool depv = ForceDependsOnV(static_cast<int>(k));
    const bool torque = fe.type == ForceType::kTorque;
    Vec14 gq = Vec14::Zero();
    Mat14 kq, kv;
    if (derivs) {
      kq.setZero();
      kv.setZero();
      Pfull.setZero();
    }
    for (int s = 0; s < 2; ++s) {
      if (l.offset[s] < 0) continue;
      const double sign = s == 0 ? 1.0 : -1.0;
      const Vec3 fs = sign * f;
      const Quat& e = l.e[s];
      const Mat34 G = GMatrix(e);
      const Mat3 A = RotationMatrix(e);
      Mat43 P;       // dQ_e/dF
      Mat4 Kown;     // dQ_e/de_s at fixed F
      if (torque) {
        P = 2 * G.transpose() * A.transpose();
        if (derivs)
          Kown = 2 * GtJacobian(A.transpose() * fs) + 2 * G.transpose() * BTransposeMatrix(e, fs);
      } else {
        const Vec3 sp = model.markers[s == 0 ? fe.i : fe.j].position;
        const Mat3 S = Skew(sp);
        P = 2 * G.transpose() * S * A.transpose();
        gq.segment<3>(7 * s) += fs;
        if (derivs)
          Kown = 2 * GtJacobian(S * A.transpose() * fs) +
                 2 * G.transpose() * S * BTransposeMatrix(e, fs);
      }
      gq.segment<4>(7 * s + 3) += P * fs;
      if (!derivs) continue;
      if (!torque) Pfull.block<3, 3>(7 * s, 0) = sign * Mat3::Identity();
      Pfull.block<4, 3>(7 * s + 3, 0) = sign * P;
      kq.block<4, 4>(7 * s + 3, 7 * s + 3) += Kown;
      if (!torque) {
        kq.block<3, 14>(7 * s, 0) += sign * dfdq;
        kv.block<3, 14>(7 * s, 0) += sign * dfdv;
      }
      kq.block<4, 14>(7 * s + 3, 0) += sign * P * dfdq;
      kv.block<4, 14>(7 * s + 3, 0) += sign * P * dfdv;
    }
    if (out.force)
      for (int r = 0; r < 14; ++r)
        if (l.offset[r / 7] >= 0) out.force[l.offset[r / 7] + r % 7] += gq[r];
    if (sKq.active()) {
      if (depq) AddLocal(sKq, l, kq, torque ? Part::kRotation : Part::kAll, Part::kAll);
      else AddLocal(sKq, l, kq, Part::kRotation, Part::kRotation);
    }
    if (sKv.active() && depv) AddLocal(sKv, l, kv, Part::kAll, Part::kAll);
    // Values over measures: dQ/dq += P df/dE dE/dm dm/dq (and the same for v), in the
    // columns of the measure's bodies (Sink keeps the union with the entries above).
    if (derivs && state_values) {
      const Part rows = torque ? Part::kRotation : Part::kAll;
      for (size_t u = 0; u < fx.measures.size(); ++u) {
        const Eigen::Matrix<double, 7, 1> de =
            Eigen::Map<const Eigen::Matrix<double, 7, 1>>(fx.d_expr[u].data());
        const Eigen::Matrix<double, 14, 1> col = Pfull * (dfde * de);
        const MeasureStateJacobian& mj = fx.jac[u];
        if (sKq.active()) AddCross(sKq, l.offset, mj.offset, col, mj.dq, rows);
        if (sKv.active() && fx.defs[u].quantity == Quantity::kVelocity)
          AddCross(sKv, l.offset, mj.offset, col, mj.dv, rows);
      }
    }
  }

  for (Sink& s : sink) s.End();
  if (!sens.empty()) {
    bool any = false;
    for (double* pm : out.parameter_matrix) any = any || pm != nullptr;
    if (any) RunParameters(in, out, /*values_current=*/true);
  }
  if (!law_error.empty()) {
    // A user function's error is fatal (negative code): retrying with a smaller step
    // would not change what the library reports.
    error = law_error;
    return -1;
  }
  if (!spring_ok) {
    error = "spring_damper '" + model.forces[bad_spring].name + "': length zero";
    return 1;
  }
  return 0;
}

// ---------------------------------------------------------------------------------
// Parameter derivatives.

namespace {

std::string Where(const SourceLocation& w) {
  return w.file + (w.line > 0 ? ":" + std::to_string(w.line) : std::string());
}

}  // namespace

void MultibodySystem::Impl::SetupSensitivity() {
  const int np = static_cast<int>(sens.size());
  const int nm = static_cast<int>(model.parameters.size());
  const int ns = static_cast<int>(model.splines.size());
  for (const SensitivityParameter& p : sens) {
    const bool ok = p.parameter >= 0 ? p.parameter < nm
                                     : (p.spline >= 0 && p.spline < ns && p.point >= 0 &&
                                        p.point < static_cast<int>(model.splines[p.spline].spline.x().size()));
    if (!ok) throw std::invalid_argument("sensitivity parameter '" + p.name + "': index out of range");
  }
  chain = ParameterChain(model, sens);
  param_dep.assign(np, std::vector<char>(nm, 0));
  spline_dep.assign(np, std::vector<char>(ns, 0));
  spline_dy.assign(np, std::vector<std::vector<double>>(ns));
  for (int k = 0; k < np; ++k) {
    // Structural dependence over the formulas (independent of the values).
    if (sens[k].parameter >= 0) {
      std::vector<int> state(nm, 0);
      std::function<bool(int)> dep = [&](int j) -> bool {
        if (state[j] == 2) return param_dep[k][j] != 0;
        state[j] = 2;
        bool d = j == sens[k].parameter;
        if (!d && !model.parameters[j].overridden)
          for (int u : model.parameters[j].formula.parameters_used()) d = dep(u) || d;
        param_dep[k][j] = d;
        return d;
      };
      for (int j = 0; j < nm; ++j) dep(j);
      for (int sp = 0; sp < ns; ++sp)
        for (const Expression& e : model.splines[sp].y_expressions)
          for (int j : e.parameters_used())
            if (param_dep[k][j]) spline_dep[k][sp] = 1;
    } else {
      spline_dep[k][sens[k].spline] = 1;
    }
    for (int sp = 0; sp < ns; ++sp)
      if (spline_dep[k][sp]) spline_dy[k][sp] = SplineOrdinateDirection(model, sens[k], chain[k], sp);
  }
  // Refusals: what a selected parameter reaches but is not differentiated.
  for (int k = 0; k < np; ++k) {
    const std::string who = "sensitivity parameter '" + sens[k].name + "': ";
    const std::string tail = "; its parameter derivative is not supported (choose other parameters)";
    for (const LoadTimeValue& lv : model.load_time_values) {
      if (!lv.kept && Depends(lv.expression, k))
        throw std::invalid_argument(who + lv.element + " '" + lv.key + "' (" + Where(lv.where) +
                                    ") is computed from it at load time" + tail);
    }
    for (const Force& f : model.forces) {
      if (f.type != ForceType::kUser) continue;
      for (const Expression& e : f.user_parameters)
        if (Depends(e, k))
          throw std::invalid_argument(who + "user force '" + f.name + "' (" + Where(f.where) +
                                      ") has parameters computed from it" + tail);
    }
    bool initial = false;
    for (const Body& b : model.bodies) {
      const BodyExpressions& x = b.expressions;
      for (const auto* list : {&x.position, &x.orientation, &x.velocity, &x.angular_velocity})
        for (const Expression& e : *list) initial = initial || Depends(e, k);
    }
    if (!initial) continue;
    for (size_t f = 0; f < model.forces.size(); ++f)
      for (int m : force_expr[f].measures)
        if (model.measures[m].offset_initial)
          throw std::invalid_argument(who + "force '" + model.forces[f].name + "' (" + Where(model.forces[f].where) +
                                      ") uses measure '" + model.measures[m].name +
                                      "' with offset_initial, and the initial state depends on it" + tail);
    for (const Joint& jt : model.joints)
      if (jt.type == JointType::kGear)
        throw std::invalid_argument(who + "gear joint '" + jt.name + "' (" + Where(jt.where) +
                                    ") is relative to the initial angles, and the initial state depends on it" +
                                    tail);
  }
  tangents.assign(np, std::vector<Spline>(ns));
  tangent_x.assign(ns, {});
  tangent_y.assign(ns, {});
  tangent_valid.assign(ns, 0);
  tangent_ptrs.assign(np, std::vector<const Spline*>(ns, nullptr));
  BuildParameterTerms();
  UpdateTangents();
}

// The dependency lists of every element (see Impl): for each element the union of the
// users of its expressions' parameters and splines, ascending.
void MultibodySystem::Impl::BuildParameterTerms() {
  const int np = static_cast<int>(sens.size());
  const int nm = static_cast<int>(model.parameters.size());
  const int ns = static_cast<int>(model.splines.size());
  param_users.assign(nm, {});
  spline_users.assign(ns, {});
  for (int k = 0; k < np; ++k) {
    for (int j = 0; j < nm; ++j)
      if (param_dep[k][j]) param_users[j].push_back(k);
    for (int sp = 0; sp < ns; ++sp)
      if (spline_dep[k][sp]) spline_users[sp].push_back(k);
  }
  std::vector<char> mark(np, 0), mark_all(np, 0);
  std::vector<int> ks, all;
  // The k reaching one expression of `list` (ascending).
  auto users = [&](const std::vector<Expression>& list) {
    ks.clear();
    for (const Expression& e : list) AddUsers(e, mark, &ks);
    TakeUsers(mark, &ks);
    return ks;
  };
  // Merges a sorted list into `all` (through mark_all).
  auto merge = [&](const std::vector<int>& list) {
    for (int k : list)
      if (!mark_all[k]) {
        mark_all[k] = 1;
        all.push_back(k);
      }
  };
  const std::vector<int> gravity_users = users(model.gravity_expressions);
  body_terms.assign(model.bodies.size(), {});
  for (size_t b = 0; b < model.bodies.size(); ++b) {
    const BodyExpressions& x = model.bodies[b].expressions;
    const std::vector<int> mass_users = users(x.mass);
    const std::vector<int> inertia_users = users(x.inertia);
    all.clear();
    merge(mass_users);
    merge(inertia_users);
    merge(gravity_users);
    TakeUsers(mark_all, &all);
    for (int k : all) {
      BodyTerm t;
      t.k = k;
      t.dm_dep = std::binary_search(mass_users.begin(), mass_users.end(), k);
      t.dj_dep = std::binary_search(inertia_users.begin(), inertia_users.end(), k);
      t.dg_dep = std::binary_search(gravity_users.begin(), gravity_users.end(), k);
      body_terms[b].push_back(t);
    }
  }
  motion_terms.assign(measure_constraints.size(), {});
  for (size_t i = 0; i < measure_constraints.size(); ++i) {
    if (!measure_constraints[i].motion) continue;
    ks.clear();
    AddUsers(model.joints[measure_constraints[i].joint].value, mark, &ks);
    TakeUsers(mark, &ks);
    motion_terms[i] = ks;
  }
  force_terms.assign(model.forces.size(), {});
  std::vector<unsigned> mask(np, 0);
  for (size_t fk = 0; fk < model.forces.size(); ++fk) {
    const Force& fe = model.forces[fk];
    if (fe.type == ForceType::kUser) continue;
    all.clear();
    if (fe.type == ForceType::kBushing) {
      for (int c = 0; c < 6; ++c) {
        merge(users({fe.bushing_stiffness[c]}));
        merge(users({fe.bushing_damping[c]}));
      }
    } else {
      for (int e = FirstExpression(fe); e < EndExpression(fe); ++e) {
        const std::vector<int>& u = users({ForceExpression(fe, e)});
        for (int k : u) mask[k] |= 1u << e;
        merge(u);
      }
    }
    TakeUsers(mark_all, &all);
    for (int k : all) {
      ForceTerm t;
      t.k = k;
      t.mask = mask[k];
      mask[k] = 0;
      force_terms[fk].push_back(t);
    }
  }
  cache_valid = false;
}

// The parameter-only derivatives of the body and bushing terms, at the current params
// (recomputed only when they change).
void MultibodySystem::Impl::UpdateParameterCache() {
  if (cache_valid && cached_params == params) return;
  for (size_t b = 0; b < model.bodies.size(); ++b) {
    const BodyExpressions& x = model.bodies[b].expressions;
    for (BodyTerm& t : body_terms[b]) {
      const int k = t.k;
      t.dm = t.dm_dep ? ParamDerivative(x.mass[0], k) : 0.0;
      t.dJ.setZero();
      if (t.dj_dep) {
        for (int c = 0; c < 3; ++c) t.dJ(c, c) = ParamDerivative(x.inertia[c], k);
        if (x.inertia.size() == 6) {
          t.dJ(0, 1) = t.dJ(1, 0) = ParamDerivative(x.inertia[3], k);
          t.dJ(0, 2) = t.dJ(2, 0) = ParamDerivative(x.inertia[4], k);
          t.dJ(1, 2) = t.dJ(2, 1) = ParamDerivative(x.inertia[5], k);
        }
      }
      t.dg.setZero();
      if (t.dg_dep)
        for (int c = 0; c < 3; ++c) t.dg[c] = ParamDerivative(model.gravity_expressions[c], k);
    }
  }
  for (size_t fk = 0; fk < model.forces.size(); ++fk) {
    const Force& fe = model.forces[fk];
    if (fe.type != ForceType::kBushing) continue;
    for (ForceTerm& t : force_terms[fk]) {
      for (int c = 0; c < 6; ++c) {
        t.dbp.stiffness[c] = ParamDerivative(fe.bushing_stiffness[c], t.k);
        t.dbp.damping[c] = ParamDerivative(fe.bushing_damping[c], t.k);
      }
    }
  }
  cached_params = params;
  cache_valid = true;
}

// Rebuilds the tangent splines of a spline whose points changed since they were built
// (one comparison per spline and call, not per parameter).
void MultibodySystem::Impl::UpdateTangents() {
  for (size_t sp = 0; sp < model.splines.size(); ++sp) {
    if (spline_users[sp].empty()) continue;
    const Spline& s = model.splines[sp].spline;
    if (tangent_valid[sp] && tangent_x[sp] == s.x() && tangent_y[sp] == s.y()) continue;
    for (int k : spline_users[sp]) {
      tangents[k][sp] = s.Tangent(spline_dy[k][sp]);
      tangent_ptrs[k][sp] = &tangents[k][sp];
    }
    tangent_x[sp] = s.x();
    tangent_y[sp] = s.y();
    tangent_valid[sp] = 1;
  }
}

// Writes the requested parameter matrices (fixed patterns: every entry a structural
// dependence can reach is added, in the same order at every call). Only the terms of
// the dependency lists are visited; the adds of a matrix not requested are skipped
// (its sink is neither recording nor has values).
void MultibodySystem::Impl::RunParameters(const dae::EvalInput& in, dae::EvalOutput& out,
                                          bool values_current) {
  using dae::ParameterMatrix;
  const double* q = in.q;
  const double* v = in.v ? in.v : zeros.data();
  const double* a = in.a ? in.a : zeros.data();
  const int nb = static_cast<int>(model.bodies.size());
  for (int m = 0; m < dae::kNumParameterMatrices; ++m) psink[m].Begin(out.parameter_matrix[m]);
  Sink& pMa = psink[static_cast<int>(ParameterMatrix::kMassTimesAccDp)];
  Sink& pQ = psink[static_cast<int>(ParameterMatrix::kForceDp)];
  Sink& pC = psink[static_cast<int>(ParameterMatrix::kConstraintDp)];
  Sink& pCv = psink[static_cast<int>(ParameterMatrix::kConstraintVelDp)];
  Sink& pG = psink[static_cast<int>(ParameterMatrix::kAccRhsDp)];
  const bool ma = pMa.active(), fq = pQ.active();
  const bool motion = pC.active() || pCv.active() || pG.active();
  if (ma || fq) UpdateParameterCache();
  if (motion || fq) UpdateTangents();

  // Bodies: M = blockdiag(m I, 4 G^T J G), Q_r = m g, Q_e = 8 G(e')^T J G(e') e.
  for (int b = 0; b < nb && (ma || fq); ++b) {
    if (body_terms[b].empty()) continue;
    const Body& body = model.bodies[b];
    const int o = Model::coordinate_offset(b);
    const Quat e = Eigen::Map<const Quat>(q + o + 3);
    const Quat ed = Eigen::Map<const Quat>(v + o + 3);
    const Quat ae = Eigen::Map<const Quat>(a + o + 3);
    const Mat34 G = GMatrix(e), Gd = GMatrix(ed);
    for (const BodyTerm& t : body_terms[b]) {
      const int k = t.k;
      const double dm = t.dm;
      const Mat3& dJ = t.dJ;
      const Vec3& dg = t.dg;
      if (ma) {
        if (t.dm_dep)
          for (int c = 0; c < 3; ++c) pMa.Add(o + c, k, dm * a[o + c]);
        if (t.dj_dep) {
          const Quat r = 4 * (G.transpose() * (dJ * (G * ae)));
          for (int c = 0; c < 4; ++c) pMa.Add(o + 3 + c, k, r[c]);
        }
      }
      if (fq) {
        if (t.dm_dep || t.dg_dep) {
          const Vec3 r = dm * model.gravity + body.mass * dg;
          for (int c = 0; c < 3; ++c) pQ.Add(o + c, k, r[c]);
        }
        if (t.dj_dep) {
          const Quat r = 8 * (Gd.transpose() * (dJ * (Gd * e)));
          for (int c = 0; c < 4; ++c) pQ.Add(o + 3 + c, k, r[c]);
        }
      }
    }
  }

  // Motion joints: C = m(q) - f(t, p): dC/dp = -df/dp, d(C_q v + C_t)/dp = -df'/dp,
  // dgamma/dp = df''/dp.
  if (motion) {
    ExpressionInputs ein;
    ein.t = in.t;
    ein.parameters = params.data();
    ein.splines = spline_pointers.empty() ? nullptr : spline_pointers.data();
    for (size_t i = 0; i < measure_constraints.size(); ++i) {
      const MeasureConstraint& mc = measure_constraints[i];
      if (!mc.motion) continue;
      const Expression& f = model.joints[mc.joint].value;
      for (int k : motion_terms[i]) {
        const DirectionalDerivatives d = f.EvaluateDirectional(ein, Direction(k));
        if (pC.active()) pC.Add(mc.row, k, -d.dir);
        if (pCv.active()) pCv.Add(mc.row, k, -d.dir_t);
        if (pG.active()) pG.Add(mc.row, k, d.dir_tt);
      }
    }
  }

  // Force elements: dQ_local/dp = P df/dE dE/dp (expressions at fixed measures);
  // bushings: linear in their stiffness and damping.
  Local l;
  for (size_t fk = 0; fk < model.forces.size() && fq; ++fk) {
    const std::vector<ForceTerm>& terms = force_terms[fk];
    if (terms.empty()) continue;
    const Force& fe = model.forces[fk];
    Gather(BodyOf(fe.i), BodyOf(fe.j), q, v, a, l);
    if (fe.type == ForceType::kBushing) {
      MarkerPairKinematics km;
      TwoMarkerInputs(fe, l, &km, nullptr, nullptr);
      const Vec3 dpos = km.p_i - km.p_j;
      for (const ForceTerm& t : terms) {
        const ForceTorque y = EvaluateBushing(t.dbp, km, nullptr);
        const Vec3 Fs[2] = {y.force, -y.force};
        const Vec3 Ts[2] = {y.torque, -y.torque - dpos.cross(y.force)};
        for (int sl = 0; sl < 2; ++sl) {
          if (l.offset[sl] < 0) continue;
          const Quat& e = l.e[sl];
          const Mat34 G = GMatrix(e);
          const Mat3 A = RotationMatrix(e);
          const Mat3 S = Skew(model.markers[sl == 0 ? fe.i : fe.j].position);
          const Quat ge = 2 * G.transpose() * S * A.transpose() * Fs[sl] + 2 * G.transpose() * A.transpose() * Ts[sl];
          for (int c = 0; c < 3; ++c) pQ.Add(l.offset[sl] + c, t.k, Fs[sl][c]);
          for (int c = 0; c < 4; ++c) pQ.Add(l.offset[sl] + 3 + c, t.k, ge[c]);
        }
      }
      continue;
    }
    // The element's values and measures at this (t, q, v): Run has just computed them
    // (force_values, force_expr, measure_values), else they are computed here.
    ForceExpressions& fx = force_expr[fk];
    const ForceValues fv =
        values_current ? force_values[fk]
                       : ComputeForceValues(static_cast<int>(fk), in.t, q, v, &fx, measure_values.data());
    Vec3 f;
    Mat37 dfde;
    ForceVector(static_cast<int>(fk), fv, l, &f, nullptr, nullptr, &dfde);
    const bool torque = fe.type == ForceType::kTorque;
    Eigen::Matrix<double, 14, 3> Pfull = Eigen::Matrix<double, 14, 3>::Zero();
    for (int sl = 0; sl < 2; ++sl) {
      if (l.offset[sl] < 0) continue;
      const double sign = sl == 0 ? 1.0 : -1.0;
      const Quat& e = l.e[sl];
      const Mat34 G = GMatrix(e);
      const Mat3 A = RotationMatrix(e);
      if (torque) {
        Pfull.block<4, 3>(7 * sl + 3, 0) = sign * 2 * G.transpose() * A.transpose();
      } else {
        const Mat3 S = Skew(model.markers[sl == 0 ? fe.i : fe.j].position);
        Pfull.block<3, 3>(7 * sl, 0) = sign * Mat3::Identity();
        Pfull.block<4, 3>(7 * sl + 3, 0) = sign * 2 * G.transpose() * S * A.transpose();
      }
    }
    ExpressionInputs xin;
    xin.t = in.t;
    xin.parameters = params.data();
    xin.measures = measure_values.data();
    xin.splines = spline_pointers.empty() ? nullptr : spline_pointers.data();
    for (const ForceTerm& t : terms) {
      Eigen::Matrix<double, 7, 1> dE = Eigen::Matrix<double, 7, 1>::Zero();
      for (int e = FirstExpression(fe); e < EndExpression(fe); ++e)
        if (t.mask & (1u << e)) dE[e] = ForceExpression(fe, e).EvaluateDirectional(xin, Direction(t.k)).dir;
      const Eigen::Matrix<double, 14, 1> col = Pfull * (dfde * dE);
      for (int r = 0; r < 14; ++r) {
        if (l.offset[r / 7] < 0 || (torque && r % 7 < 3)) continue;
        pQ.Add(l.offset[r / 7] + r % 7, t.k, col[r]);
      }
    }
  }
  for (Sink& s : psink) s.End();
}

// ---------------------------------------------------------------------------------

MultibodySystem::MultibodySystem(const Model& model, std::vector<SensitivityParameter> sensitivity,
                                 std::vector<double> parameters)
    : impl_(std::make_unique<Impl>(model, std::move(parameters))) {
  impl_->Setup();
  impl_->sens = std::move(sensitivity);
  impl_->SetupSensitivity();
  // Record the parameter patterns at a generic state.
  const int nq = impl_->nq, nb = static_cast<int>(model.bodies.size());
  std::mt19937 rng(54321);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> q(nq), v(nq), a(nq), w(impl_->nc + 1);
  for (int b = 0; b < nb; ++b) {
    for (int k = 0; k < 3; ++k) q[7 * b + k] = 10 * u(rng);
    Quat e(u(rng), u(rng), u(rng), u(rng));
    e.normalize();
    for (int k = 0; k < 4; ++k) q[7 * b + 3 + k] = e[k];
  }
  for (auto& x : v) x = u(rng);
  for (auto& x : a) x = u(rng);
  for (auto& x : w) x = u(rng);
  for (Sink& s : impl_->psink) s.StartRecording();
  dae::EvalInput ein;
  ein.q = q.data(); ein.v = v.data(); ein.a = a.data(); ein.w = w.data();
  dae::EvalOutput eout;
  impl_->RunParameters(ein, eout, /*values_current=*/false);
  const int np = static_cast<int>(impl_->sens.size());
  for (int m = 0; m < dae::kNumParameterMatrices; ++m) {
    const auto pm = static_cast<dae::ParameterMatrix>(m);
    const bool qrows = pm == dae::ParameterMatrix::kMassTimesAccDp || pm == dae::ParameterMatrix::kForceDp ||
                       pm == dae::ParameterMatrix::kConstraintTDp;
    impl_->psink[m].Finish(qrows ? nq : impl_->nc, np);
  }
}

int MultibodySystem::num_parameters() const { return static_cast<int>(impl_->sens.size()); }
const dae::CscPattern& MultibodySystem::parameter_pattern(dae::ParameterMatrix m) const {
  if (impl_->sens.empty()) return dae::MechanicalSystem::parameter_pattern(m);
  return impl_->psink[static_cast<int>(m)].pattern();
}
const std::vector<SensitivityParameter>& MultibodySystem::sensitivity_parameters() const {
  return impl_->sens;
}

void MultibodySystem::InitialStateParameterDerivatives(std::vector<double>& dq,
                                                       std::vector<double>& dv) const {
  const Impl& im = *impl_;
  const Model& m = im.model;
  const int nq = im.nq, np = static_cast<int>(im.sens.size());
  dq.assign(static_cast<size_t>(nq) * np, 0.0);
  dv.assign(static_cast<size_t>(nq) * np, 0.0);
  for (int k = 0; k < np; ++k) {
    double* dqk = dq.data() + static_cast<size_t>(k) * nq;
    double* dvk = dv.data() + static_cast<size_t>(k) * nq;
    auto d3 = [&](const std::vector<Expression>& x) {
      Vec3 r = Vec3::Zero();
      if (x.size() == 3)
        for (int c = 0; c < 3; ++c) r[c] = im.ParamDerivative(x[c], k);
      return r;
    };
    auto values = [&](const std::vector<Expression>& x) {
      std::vector<double> r;
      for (const Expression& e : x) r.push_back(e.Evaluate(im.params.data()));
      return r;
    };
    for (size_t b = 0; b < m.bodies.size(); ++b) {
      const Body& body = m.bodies[b];
      const BodyExpressions& x = body.expressions;
      const int o = Model::coordinate_offset(static_cast<int>(b));
      Eigen::Map<Vec3>(dqk + o) = d3(x.position);
      Eigen::Map<Vec3>(dvk + o) = d3(x.velocity);
      Quat de = Quat::Zero();
      if (x.orientation_form == OrientationForm::kEulerParameters && x.orientation.size() == 4) {
        // e = w / |w|: de = (I - e e^T) dw / |w|
        const std::vector<double> w = values(x.orientation);
        const Quat wq(w[0], w[1], w[2], w[3]);
        Quat dw;
        for (int c = 0; c < 4; ++c) dw[c] = im.ParamDerivative(x.orientation[c], k);
        const double n = wq.norm();
        const Quat e = wq / n;
        de = (dw - e * e.dot(dw)) / n;
      } else if (x.orientation_form == OrientationForm::kAxisAngle && x.orientation.size() == 4) {
        // e = (cos(a/2), sin(a/2) u / |u|)
        const std::vector<double> w = values(x.orientation);
        const Vec3 axis(w[0], w[1], w[2]);
        // Scaled by the largest component first (as QuaternionFromAxisAngle), so that
        // |axis| neither overflows nor underflows.
        const double angle = w[3], scale = axis.cwiseAbs().maxCoeff();
        const double n = (axis / scale).norm();
        const Vec3 un = axis / scale / n;
        Vec3 daxis;
        for (int c = 0; c < 3; ++c) daxis[c] = im.ParamDerivative(x.orientation[c], k) / scale;
        const double dangle = im.ParamDerivative(x.orientation[3], k);
        de[0] = -0.5 * std::sin(angle / 2) * dangle;
        de.tail<3>() = 0.5 * std::cos(angle / 2) * dangle * un +
                       std::sin(angle / 2) * (daxis - un * un.dot(daxis)) / n;
      }
      Eigen::Map<Quat>(dqk + o + 3) = de;
      // e' = 1/2 E(e)^T omega, E linear in e.
      const Vec3 dw = d3(x.angular_velocity);
      Eigen::Map<Quat>(dvk + o + 3) = 0.5 * EMatrix(de).transpose() * body.angular_velocity +
                                      0.5 * EMatrix(body.orientation).transpose() * dw;
    }
  }
}

MultibodySystem::MultibodySystem(const Model& model, std::vector<double> parameters)
    : impl_(std::make_unique<Impl>(model, std::move(parameters))) {
  impl_->Setup();
}

MultibodySystem::~MultibodySystem() = default;

int MultibodySystem::num_coordinates() const { return impl_->nq; }
int MultibodySystem::num_constraints() const { return impl_->nc; }
const dae::CscPattern& MultibodySystem::pattern(dae::Matrix m) const {
  return impl_->sink[static_cast<int>(m)].pattern();
}
const std::vector<int>& MultibodySystem::quaternion_offsets() const {
  return impl_->quaternion_offsets;
}
int MultibodySystem::Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) {
  return impl_->Run(in, out);
}
bool MultibodySystem::provides_constraint_transpose_w() const {
  return impl_->sink[static_cast<int>(dae::Matrix::kConstraintDq)].adds_once_by_row();
}
const char* MultibodySystem::last_error() const { return impl_->error.c_str(); }
const Model& MultibodySystem::model() const { return impl_->model; }
const std::vector<std::string>& MultibodySystem::coordinate_names() const {
  return impl_->coordinate_names;
}
const std::vector<std::string>& MultibodySystem::constraint_names() const {
  return impl_->constraint_names;
}
const std::vector<int>& MultibodySystem::constraint_joint() const {
  return impl_->constraint_joint;
}
std::vector<double>& MultibodySystem::parameters() { return impl_->params; }
const std::vector<double>& MultibodySystem::parameters() const { return impl_->params; }

void MultibodySystem::InitialState(std::vector<double>& q, std::vector<double>& v) const {
  const Model& m = impl_->model;
  q.assign(impl_->nq, 0.0);
  v.assign(impl_->nq, 0.0);
  for (size_t b = 0; b < m.bodies.size(); ++b) {
    const Body& body = m.bodies[b];
    const int o = Model::coordinate_offset(static_cast<int>(b));
    Eigen::Map<Vec3>(q.data() + o) = body.position;
    Eigen::Map<Quat>(q.data() + o + 3) = body.orientation;
    Eigen::Map<Vec3>(v.data() + o) = body.velocity;
    // omega = 2 E e'  and  E E^T = I, E e = 0  =>  e' = 1/2 E^T omega
    Eigen::Map<Quat>(v.data() + o + 3) = 0.5 * EMatrix(body.orientation).transpose() *
                                         body.angular_velocity;
  }
}

// Translational measures: the component (x, y, z of marker j's axes, or of the world
// axes) of d = x_i - x_j, or |d|; velocity and acceleration are the exact first and
// second time derivatives of that scalar (with v = q', a = q'').
// Rotational measures about axis k of marker j (k, p = k+1, n = k+2 cyclic): the angle
// atan2(p_i . n_j, p_i . p_j) in (-pi, pi], where p_i is marker i's p-axis; velocity and
// acceleration are its exact first and second time derivatives. When marker i's k-axis
// stays parallel to marker j's (e.g. across a revolute joint) these equal the component
// along j's k-axis of the relative angular velocity and acceleration.
void MultibodySystem::EvaluateMeasures(double /*t*/, const double* q, const double* v,
                                       const double* a, double* values) const {
  const Impl& im = *impl_;
  const double* vv = v ? v : im.zeros.data();
  const double* aa = a ? a : im.zeros.data();
  Local l;
  for (size_t k = 0; k < im.model.measures.size(); ++k) {
    const Measure& m = im.model.measures[k];
    if (m.type == MeasureType::kReaction) {  // needs the multipliers: mbs/reaction.h
      values[k] = 0;
      continue;
    }
    im.Gather(im.BodyOf(m.i), im.BodyOf(m.j), q, vv, aa, l);
    double x = 0, xd = 0, xdd = 0;
    if (m.type == MeasureType::kTranslational) {
      const Field d = im.Separation(m.i, m.j);
      const Vec3 dv = d.Value(l);
      Vec3 dd, ddd;
      d.Rates(l, &dd, &ddd);
      if (m.component == Component::kDistance) {
        x = dv.norm();
        if (x > 0) {
          xd = dv.dot(dd) / x;
          xdd = (dd.dot(dd) + dv.dot(ddd) - xd * xd) / x;
        }
      } else {
        const int axis = static_cast<int>(m.component);
        Field u;
        if (m.frame == MeasureFrame::kWorld) {
          Term t;
          t.u = Vec3::Unit(axis);
          u = Impl::One(t);
        } else {
          u = Impl::One(im.MarkerAxis(m.j, 1, axis));
        }
        const Vec3 uv = u.Value(l);
        Vec3 ud, udd;
        u.Rates(l, &ud, &udd);
        x = uv.dot(dv);
        xd = ud.dot(dv) + uv.dot(dd);
        xdd = udd.dot(dv) + 2 * ud.dot(dd) + uv.dot(ddd);
      }
    } else {
      const int axis = std::min(static_cast<int>(m.component), 2);
      const int p = (axis + 1) % 3, n = (axis + 2) % 3;
      const Field pi = Impl::One(im.MarkerAxis(m.i, 0, p));
      const Field pj = Impl::One(im.MarkerAxis(m.j, 1, p));
      const Field nj = Impl::One(im.MarkerAxis(m.j, 1, n));
      Vec3 piv = pi.Value(l), pjv = pj.Value(l), njv = nj.Value(l);
      Vec3 pid, pidd, pjd, pjdd, njd, njdd;
      pi.Rates(l, &pid, &pidd);
      pj.Rates(l, &pjd, &pjdd);
      nj.Rates(l, &njd, &njdd);
      const double X = piv.dot(pjv), Y = piv.dot(njv);
      const double Xd = pid.dot(pjv) + piv.dot(pjd), Yd = pid.dot(njv) + piv.dot(njd);
      const double Xdd = pidd.dot(pjv) + 2 * pid.dot(pjd) + piv.dot(pjdd);
      const double Ydd = pidd.dot(njv) + 2 * pid.dot(njd) + piv.dot(njdd);
      x = std::atan2(Y, X);
      if (x <= -M_PI) x = M_PI;
      const double D = X * X + Y * Y;
      if (D > 0) {
        const double N = X * Yd - Y * Xd;
        const double Nd = X * Ydd - Y * Xdd;
        const double Dd = 2 * (X * Xd + Y * Yd);
        xd = N / D;
        xdd = (Nd * D - N * Dd) / (D * D);
      }
    }
    values[k] = m.quantity == Quantity::kPosition   ? x
                : m.quantity == Quantity::kVelocity ? xd
                                                    : xdd;
  }
}

void MultibodySystem::JointReaction(int joint, double /*t*/, const double* q,
                                    const double* lambda, double* force, double* torque) const {
  const Impl& im = *impl_;
  const Joint& jt = im.model.joints.at(joint);
  if (jt.type == JointType::kMotion || jt.type == JointType::kGear) {
    // No markers: the multiplier of NAME.motion / NAME.gear is the driving effort.
    Eigen::Map<Vec3>(force).setZero();
    Eigen::Map<Vec3>(torque).setZero();
    return;
  }
  Local l;
  im.Gather(im.BodyOf(jt.i), im.BodyOf(jt.j), q, im.zeros.data(), im.zeros.data(), l);
  // Generalised reaction -C_q^T lambda on the local coordinates.
  Vec14 g = Vec14::Zero();
  int row = im.joint_row[joint];
  for (int lock : im.joint_locks[joint]) {
    Field fu, fw;
    im.JointFactors(jt, lock, fu, fw);
    double c;
    Vec14 grad;
    Impl::DotEquation(fu, fw, l, &c, &grad);
    g -= lambda[row] * grad;
    ++row;
  }
  // Force and moment about the centre of mass (world) of the body in slot s.
  auto wrench = [&](int s, Vec3* f, Vec3* n) {
    *f = g.segment<3>(7 * s);
    const Vec3 nb = 0.5 * GMatrix(l.e[s]) * g.segment<4>(7 * s + 3);
    *n = RotationMatrix(l.e[s]) * nb;
  };
  Vec3 f = Vec3::Zero(), n = Vec3::Zero();
  const Marker& mi = im.model.markers[jt.i];
  if (l.offset[0] >= 0) {
    Vec3 nc;
    wrench(0, &f, &nc);
    // moment about marker i: n_C + (C - P) x F with C - P = -A s_i
    n = nc - (RotationMatrix(l.e[0]) * mi.position).cross(f);
  } else if (l.offset[1] >= 0) {
    // marker i on ground: the reaction on ground is minus the one on body j.
    Vec3 fj, nj;
    wrench(1, &fj, &nj);
    f = -fj;
    n = -nj - (l.r[1] - mi.position).cross(fj);
  }
  Eigen::Map<Vec3>(force, 3) = f;
  Eigen::Map<Vec3>(torque, 3) = n;
}

double MultibodySystem::KineticEnergy(const double* q, const double* v) const {
  double t = 0;
  const Model& m = impl_->model;
  for (size_t b = 0; b < m.bodies.size(); ++b) {
    const int o = Model::coordinate_offset(static_cast<int>(b));
    const Vec3 rd = Eigen::Map<const Vec3>(v + o);
    const Vec3 wb = 2 * GMatrix(Eigen::Map<const Quat>(q + o + 3)) *
                    Eigen::Map<const Quat>(v + o + 3);
    t += 0.5 * m.bodies[b].mass * rd.squaredNorm() + 0.5 * wb.dot(m.bodies[b].inertia * wb);
  }
  return t;
}

double MultibodySystem::PotentialEnergy(double t, const double* q) const {
  const Impl& im = *impl_;
  const Model& m = im.model;
  double u = 0;
  for (size_t b = 0; b < m.bodies.size(); ++b) {
    const int o = Model::coordinate_offset(static_cast<int>(b));
    u -= m.bodies[b].mass * m.gravity.dot(Eigen::Map<const Vec3>(q + o));
  }
  Local l;
  std::vector<double> mvalues(m.measures.size(), 0.0);
  for (size_t k = 0; k < m.forces.size(); ++k) {
    const Force& f = m.forces[k];
    if (f.type == ForceType::kBushing) {
      im.Gather(im.BodyOf(f.i), im.BodyOf(f.j), q, im.zeros.data(), im.zeros.data(), l);
      MarkerPairKinematics km;
      im.TwoMarkerInputs(f, l, &km, nullptr, nullptr);
      BushingParameters bp;
      for (int c = 0; c < 6; ++c) bp.stiffness[c] = f.bushing_stiffness[c].Evaluate(im.params.data());
      u += BushingPotential(bp, km);
      continue;
    }
    if (f.type != ForceType::kSpringDamper) continue;
    im.Gather(im.BodyOf(f.i), im.BodyOf(f.j), q, im.zeros.data(), im.zeros.data(), l);
    const double len = im.Separation(f.i, f.j).Value(l).norm();
    // Values over t and the state: taken at (t, q, v = 0), not a potential in general.
    Impl::ForceExpressions fx = im.force_expr[k];
    const Impl::ForceValues fv =
        im.ComputeForceValues(static_cast<int>(k), t, q, im.zeros.data(), &fx, mvalues.data());
    const double dl = len - fv.l0;
    u += 0.5 * fv.k * dl * dl - fv.preload * dl;
  }
  return u;
}

void MultibodySystem::ForceAction(int element, double t, const double* q, const double* v,
                                  double* f_out, double* t_out) const {
  const int force = element;
  const Impl& im = *impl_;
  const Force& fe = im.model.forces.at(force);
  Local l;
  const double* vv = v ? v : im.zeros.data();
  im.Gather(im.BodyOf(fe.i), im.BodyOf(fe.j), q, vv, im.zeros.data(), l);
  if (Impl::TwoMarkerLaw(fe)) {
    MarkerPairKinematics km;
    im.TwoMarkerInputs(fe, l, &km, nullptr, nullptr);
    std::string err;
    const ForceTorque y = im.TwoMarkerLawValue(force, t, km, nullptr, &err);
    if (!err.empty()) throw std::runtime_error(err);
    Eigen::Map<Vec3> fo(f_out), to(t_out);
    fo = y.force;
    to = y.torque;
    return;
  }
  Vec3 f;
  Mat3x14 dq, dv;
  Impl::ForceExpressions fx = im.force_expr[force];
  std::vector<double> mvalues(im.model.measures.size(), 0.0);
  im.ForceVector(force, im.ComputeForceValues(force, t, q, vv, &fx, mvalues.data()), l, &f, &dq,
                 &dv);
  Eigen::Map<Vec3> F(f_out), T(t_out);
  if (fe.type == ForceType::kTorque) {
    F.setZero();
    T = f;
  } else {
    F = f;
    T.setZero();
  }
}

}  // namespace mbdae::mbs
