#include "mbs/reaction.h"

#include <unsupported/Eigen/AutoDiff>

#include <stdexcept>
#include <string>
#include <utility>

#include "dae/sparse.h"
#include "mbs/system.h"

namespace mbdae::mbs {

namespace {

using Vec14 = Eigen::Matrix<double, 14, 1>;
using Ad = Eigen::AutoDiffScalar<Vec14>;
template <typename T>
using V3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using M3 = Eigen::Matrix<T, 3, 3>;

// A(e) = E G^T for any e (as mbs/kinematics.h RotationMatrix).
template <typename T>
M3<T> Rotation(const T* e) {
  const T &e0 = e[0], &e1 = e[1], &e2 = e[2], &e3 = e[3];
  M3<T> A;
  A(0, 0) = e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3;
  A(1, 1) = e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3;
  A(2, 2) = e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3;
  A(0, 1) = 2.0 * (e1 * e2 - e0 * e3);
  A(1, 0) = 2.0 * (e1 * e2 + e0 * e3);
  A(0, 2) = 2.0 * (e1 * e3 + e0 * e2);
  A(2, 0) = 2.0 * (e1 * e3 - e0 * e2);
  A(1, 2) = 2.0 * (e2 * e3 - e0 * e1);
  A(2, 1) = 2.0 * (e2 * e3 + e0 * e1);
  return A;
}

// n_body = 1/2 G(e) g_e, G = [-e_v, -skew(e_v) + e0 I].
template <typename T>
V3<T> HalfG(const T* e, const double* ge) {
  V3<T> n;
  n[0] = 0.5 * (-e[1] * ge[0] + e[0] * ge[1] + e[3] * ge[2] - e[2] * ge[3]);
  n[1] = 0.5 * (-e[2] * ge[0] - e[3] * ge[1] + e[0] * ge[2] + e[1] * ge[3]);
  n[2] = 0.5 * (-e[3] * ge[0] + e[2] * ge[1] - e[1] * ge[2] + e[0] * ge[3]);
  return n;
}

}  // namespace

struct ReactionMeasures::Impl {
  const Model& model;
  MultibodySystem system;
  int nq = 0, nc = 0;
  std::vector<int> measures;
  std::vector<std::vector<int>> joint_rows;  // by joint: its equations
  std::vector<double> cq, tdq, w, gen, zeros;
  std::string error;

  Impl(const Model& m, std::vector<double> p) : model(m), system(m, std::move(p)) {
    nq = system.num_coordinates();
    nc = system.num_constraints();
    joint_rows.resize(model.joints.size());
    for (int r = 0; r < nc; ++r) {
      const int j = system.constraint_joint()[r];
      if (j >= 0) joint_rows[j].push_back(r);
    }
    for (size_t k = 0; k < model.measures.size(); ++k) {
      const Measure& me = model.measures[k];
      if (me.type != MeasureType::kReaction) continue;
      if (me.joint < 0 || me.joint >= static_cast<int>(model.joints.size()))
        throw std::invalid_argument("measure '" + me.name + "': a reaction measure needs a joint");
      measures.push_back(static_cast<int>(k));
    }
    cq.assign(system.pattern(dae::Matrix::kConstraintDq).nnz(), 0.0);
    tdq.assign(system.pattern(dae::Matrix::kConstraintTDq).nnz(), 0.0);
    w.assign(nc, 0.0);
    gen.assign(nq, 0.0);
    zeros.assign(nq, 0.0);
  }

  // C_q (and d(C_q^T w)/dq with w = lambda on the joint's rows) at q; gen = -C_q^T w.
  int Prepare(int joint, double t, const double* q, const double* lambda, bool with_dq) {
    std::fill(w.begin(), w.end(), 0.0);
    for (int r : joint_rows[joint]) w[r] = lambda[r];
    dae::EvalInput in;
    in.t = t;
    in.q = q;
    in.v = zeros.data();
    in.a = zeros.data();
    in.w = w.data();
    dae::EvalOutput out;
    out[dae::Matrix::kConstraintDq] = cq.data();
    if (with_dq) out[dae::Matrix::kConstraintTDq] = tdq.data();
    const int rc = system.Evaluate(in, out);
    if (rc != 0) {
      error = system.last_error();
      return rc;
    }
    std::fill(gen.begin(), gen.end(), 0.0);
    dae::MultiplyTransposeAdd(system.pattern(dae::Matrix::kConstraintDq), cq.data(), -1.0, w.data(),
                              gen.data());
    return 0;
  }

  // The markers (i, j) whose body slots a joint's wrench uses: the joint's own, or
  // those of the driven measure (motion: its measure; gear: the second measure).
  std::pair<int, int> JointMarkers(int joint) const {
    const Joint& jt = model.joints.at(joint);
    if (jt.type == JointType::kMotion || jt.type == JointType::kGear) {
      const Measure& me = model.measures.at(jt.measures[jt.type == JointType::kGear ? 1 : 0]);
      return {me.i, me.j < 0 ? 0 : me.j};
    }
    return {jt.i, jt.j};
  }

  // The wrench (world axes) on the body of marker mi about its origin from the
  // generalised force `g` (local entries of the body slots) at local coordinates x
  // (slot 0: body of marker i, slot 1: body of marker j).
  template <typename T>
  void Wrench(int mi, const T* x0, const T* x1, const double* g0, const double* g1, int body_i,
              int body_j, V3<T>* f, V3<T>* n) const {
    const Marker& marker_i = model.markers[mi];
    *f = V3<T>::Zero();
    *n = V3<T>::Zero();
    if (body_i >= 0) {
      const M3<T> A = Rotation(x0 + 3);
      *f = Eigen::Map<const Eigen::Vector3d>(g0).template cast<T>();
      const V3<T> nc = A * HalfG(x0 + 3, g0 + 3);
      const V3<T> s = A * marker_i.position.template cast<T>();
      *n = nc - s.cross(*f);
    } else if (body_j >= 0) {
      const M3<T> A = Rotation(x1 + 3);
      const V3<T> fj = Eigen::Map<const Eigen::Vector3d>(g1).template cast<T>();
      const V3<T> nj = A * HalfG(x1 + 3, g1 + 3);
      const V3<T> arm = V3<T>(x1[0], x1[1], x1[2]) - marker_i.position.template cast<T>();
      *f = -fj;
      *n = -nj - arm.cross(fj);
    }
  }

  // The measure's component from the generalised force `g` (as Wrench).
  template <typename T>
  T Component(const Measure& me, const T* x0, const T* x1, const double* g0, const double* g1,
              int body_i, int body_j) const {
    const Marker& mj = model.markers[me.j];
    V3<T> f, n;
    Wrench<T>(me.i, x0, x1, g0, g1, body_i, body_j, &f, &n);
    const V3<T>& vec = me.torque ? n : f;
    const int axis = static_cast<int>(me.component);
    if (me.frame == MeasureFrame::kWorld) return vec[axis];
    V3<T> u;  // marker j's axis `axis` in world
    if (body_j >= 0) {
      u = Rotation(x1 + 3) * mj.orientation.col(axis).template cast<T>();
    } else {
      u = mj.orientation.col(axis).template cast<T>();
    }
    return u.dot(vec);
  }

  int JointWrench(int joint, double t, const double* q, const double* lambda, double* force,
                  double* torque) {
    if (const int rc = Prepare(joint, t, q, lambda, false); rc != 0) return rc;
    const auto [mi, mj] = JointMarkers(joint);
    const int bi = model.markers[mi].body, bj = model.markers[mj].body;
    double x0[7] = {0, 0, 0, 1, 0, 0, 0}, x1[7] = {0, 0, 0, 1, 0, 0, 0};
    double g0[7] = {0, 0, 0, 0, 0, 0, 0}, g1[7] = {0, 0, 0, 0, 0, 0, 0};
    if (bi >= 0) {
      const int o = Model::coordinate_offset(bi);
      std::copy(q + o, q + o + 7, x0);
      std::copy(gen.begin() + o, gen.begin() + o + 7, g0);
    }
    if (bj >= 0) {
      const int o = Model::coordinate_offset(bj);
      std::copy(q + o, q + o + 7, x1);
      std::copy(gen.begin() + o, gen.begin() + o + 7, g1);
    }
    V3<double> f, n;
    Wrench<double>(mi, x0, x1, g0, g1, bi, bj, &f, &n);
    for (int k = 0; k < 3; ++k) {
      force[k] = f[k];
      torque[k] = n[k];
    }
    return 0;
  }

  int Derivatives(int measure, double t, const double* q, const double* lambda, double weight,
                  double* value, double* dq, double* dlambda) {
    const Measure& me = model.measures.at(measure);
    if (me.type != MeasureType::kReaction) throw std::invalid_argument("measure '" + me.name + "' is not a reaction");
    const bool want = dq || dlambda;
    if (const int rc = Prepare(me.joint, t, q, lambda, dq != nullptr); rc != 0) return rc;
    const int bi = model.markers[me.i].body, bj = model.markers[me.j].body;
    const int oi = bi >= 0 ? Model::coordinate_offset(bi) : -1;
    const int oj = bj >= 0 ? Model::coordinate_offset(bj) : -1;
    double g0[7] = {0, 0, 0, 0, 0, 0, 0}, g1[7] = {0, 0, 0, 0, 0, 0, 0};
    if (oi >= 0) std::copy(gen.begin() + oi, gen.begin() + oi + 7, g0);
    if (oj >= 0) std::copy(gen.begin() + oj, gen.begin() + oj + 7, g1);
    // Which body's generalised force the wrench reads (slot 0: marker i's, 1: marker j's).
    const int read = bi >= 0 ? 0 : bj >= 0 ? 1 : -1;
    if (!want) {
      double x0[7] = {0, 0, 0, 1, 0, 0, 0}, x1[7] = {0, 0, 0, 1, 0, 0, 0};
      if (oi >= 0) std::copy(q + oi, q + oi + 7, x0);
      if (oj >= 0) std::copy(q + oj, q + oj + 7, x1);
      if (value) *value = Component<double>(me, x0, x1, g0, g1, bi, bj);
      return 0;
    }
    Ad x0[7], x1[7];
    for (int k = 0; k < 7; ++k) {
      x0[k] = Ad(oi >= 0 ? q[oi + k] : (k == 3 ? 1.0 : 0.0), 14, k);
      x1[k] = Ad(oj >= 0 ? q[oj + k] : (k == 3 ? 1.0 : 0.0), 14, 7 + k);
    }
    const Ad c = Component<Ad>(me, x0, x1, g0, g1, bi, bj);
    if (value) *value = c.value();
    if (read < 0) return 0;
    const int o_read = read == 0 ? oi : oj;
    // The component's gradient with respect to the 7 generalised-force entries it reads
    // (linear: evaluate the map on unit vectors at fixed q).
    double x0d[7] = {0, 0, 0, 1, 0, 0, 0}, x1d[7] = {0, 0, 0, 1, 0, 0, 0};
    if (oi >= 0) std::copy(q + oi, q + oi + 7, x0d);
    if (oj >= 0) std::copy(q + oj, q + oj + 7, x1d);
    double wg[7];
    for (int k = 0; k < 7; ++k) {
      double e0[7] = {0, 0, 0, 0, 0, 0, 0}, e1[7] = {0, 0, 0, 0, 0, 0, 0};
      (read == 0 ? e0 : e1)[k] = 1;
      wg[k] = Component<double>(me, x0d, x1d, e0, e1, bi, bj);
    }
    if (dq) {
      // Direct dependence on the coordinates of the marker bodies.
      for (int k = 0; k < 7; ++k) {
        if (oi >= 0) dq[oi + k] += weight * c.derivatives()[k];
        if (oj >= 0) dq[oj + k] += weight * c.derivatives()[7 + k];
      }
      // Through gen = -C_q^T w: d(gen_r)/dq = -TDq[r, :].
      const dae::CscPattern& p = system.pattern(dae::Matrix::kConstraintTDq);
      for (int col = 0; col < nq; ++col)
        for (int e = p.col_start[col]; e < p.col_start[col + 1]; ++e) {
          const int r = p.row_index[e] - o_read;
          if (r >= 0 && r < 7) dq[col] -= weight * wg[r] * tdq[e];
        }
    }
    if (dlambda) {
      // d(gen_r)/dlambda_row = -C_q[row, r] for the joint's rows.
      const dae::CscPattern& p = system.pattern(dae::Matrix::kConstraintDq);
      for (int r = 0; r < 7; ++r) {
        const int col = o_read + r;
        for (int e = p.col_start[col]; e < p.col_start[col + 1]; ++e) {
          const int row = p.row_index[e];
          if (system.constraint_joint()[row] == me.joint) dlambda[row] -= weight * wg[r] * cq[e];
        }
      }
    }
    return 0;
  }
};

ReactionMeasures::ReactionMeasures(const Model& model, std::vector<double> parameters)
    : impl_(std::make_unique<Impl>(model, std::move(parameters))) {}
ReactionMeasures::~ReactionMeasures() = default;

const std::vector<int>& ReactionMeasures::measures() const { return impl_->measures; }
int ReactionMeasures::num_coordinates() const { return impl_->nq; }
int ReactionMeasures::num_constraints() const { return impl_->nc; }
std::vector<double>& ReactionMeasures::parameters() { return impl_->system.parameters(); }
const char* ReactionMeasures::last_error() const { return impl_->error.c_str(); }

int ReactionMeasures::Evaluate(double t, const double* q, const double* lambda, double* values) {
  for (int m : impl_->measures)
    if (const int rc = impl_->Derivatives(m, t, q, lambda, 1.0, &values[m], nullptr, nullptr); rc != 0)
      return rc;
  return 0;
}

int ReactionMeasures::JointWrench(int joint, double t, const double* q, const double* lambda,
                                  double* force, double* torque) {
  if (joint < 0 || joint >= static_cast<int>(impl_->model.joints.size()))
    throw std::invalid_argument("ReactionMeasures::JointWrench: no joint " + std::to_string(joint));
  return impl_->JointWrench(joint, t, q, lambda, force, torque);
}

int ReactionMeasures::Derivatives(int measure, double t, const double* q, const double* lambda,
                                  double weight, double* value, double* dq, double* dlambda) {
  return impl_->Derivatives(measure, t, q, lambda, weight, value, dq, dlambda);
}

}  // namespace mbdae::mbs
