// Joint space of a tree. See joint_space.h.
#include "mbs/joint_space.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "dae/mechanical_system.h"
#include "mbs/kinematics.h"
#include "mbs/system.h"

namespace mbdae::mbs {

namespace {

Mat3 Rz(double q) {
  const double c = std::cos(q), s = std::sin(q);
  Mat3 R;
  R << c, -s, 0, s, c, 0, 0, 0, 1;
  return R;
}

// A marker's frame on its body (ground: world).
void MarkerOnBody(const Marker& m, Vec3* s, Mat3* O) {
  *s = m.position;
  *O = m.orientation;
}

struct BodyMotion {
  Mat3 R = Mat3::Identity();
  Vec3 x = Vec3::Zero(), w = Vec3::Zero(), v = Vec3::Zero(), alpha = Vec3::Zero(), a = Vec3::Zero();
};

}  // namespace

JointSpace::JointSpace(const Model& model) : model_(model) {
  const int nb = static_cast<int>(model.bodies.size());
  std::vector<bool> placed(nb, false);
  std::vector<bool> used(model.joints.size(), false);
  for (size_t k = 0; k < model.joints.size(); ++k) {
    const Joint& j = model.joints[k];
    if (j.type == JointType::kMotion || j.type == JointType::kGear) {
      used[k] = true;  // constraints on the coordinates, not part of the tree
      continue;
    }
    if (j.type != JointType::kRevolute && j.type != JointType::kPrismatic && j.type != JointType::kFixed)
      throw std::invalid_argument("joint '" + j.name +
                                  "': joint space needs a tree of revolute, prismatic and fixed joints (this joint "
                                  "is of another type)");
  }
  auto on_ground = [&](int body) { return body < 0 || placed[body]; };
  bool progress = true;
  while (progress) {
    progress = false;
    for (size_t k = 0; k < model.joints.size(); ++k) {
      if (used[k]) continue;
      const Joint& j = model.joints[k];
      const int bi = model.markers[j.i].body, bj = model.markers[j.j].body;
      const bool pi = on_ground(bi), pj = on_ground(bj);
      if (pi && pj)
        throw std::invalid_argument("joint '" + j.name + "' closes a loop: joint space needs a tree (one joint per body)");
      if (!pi && !pj) continue;
      Link l;
      l.joint = static_cast<int>(k);
      l.child_is_i = pj;
      l.body = l.child_is_i ? bi : bj;
      l.parent = l.child_is_i ? bj : bi;
      l.prismatic = j.type == JointType::kPrismatic;
      MarkerOnBody(model.markers[j.i], &l.s_i, &l.O_i);
      MarkerOnBody(model.markers[j.j], &l.s_j, &l.O_j);
      // The markers at the model's initial state.
      auto frame = [&](int body, const Vec3& s, const Mat3& O, Vec3* p, Mat3* R) {
        if (body < 0) {
          *p = s;
          *R = O;
          return;
        }
        const Mat3 A = RotationMatrix(model.bodies[body].orientation);
        *p = model.bodies[body].position + A * s;
        *R = A * O;
      };
      Vec3 p_i, p_j;
      Mat3 R_i, R_j;
      frame(bi, l.s_i, l.O_i, &p_i, &R_i);
      frame(bj, l.s_j, l.O_j, &p_j, &R_j);
      const Mat3 R_ji = R_j.transpose() * R_i;
      const Vec3 d = R_j.transpose() * (p_i - p_j);
      l.D = R_ji;
      l.d0 = d;
      if (j.type == JointType::kRevolute) {
        l.D = Rz(-std::atan2(R_ji(1, 0), R_ji(0, 0))) * R_ji;
      } else if (l.prismatic) {
        l.d0.z() = 0;
      }
      if (j.type != JointType::kFixed) {
        l.coordinate = static_cast<int>(coordinate_joint_.size());
        coordinate_joint_.push_back(static_cast<int>(k));
        names_.push_back(j.name);
        is_angle_.push_back(j.type == JointType::kRevolute);
      }
      placed[l.body] = true;
      used[k] = true;
      links_.push_back(l);
      progress = true;
    }
  }
  for (int b = 0; b < nb; ++b)
    if (!placed[b])
      throw std::invalid_argument("body '" + model.bodies[b].name +
                                  "' is not joined to the ground by joints: joint space needs a tree from the ground");
  // Coordinates in the model's joint order.
  std::vector<int> sorted = coordinate_joint_;
  std::sort(sorted.begin(), sorted.end());
  for (Link& l : links_)
    if (l.coordinate >= 0)
      l.coordinate = static_cast<int>(std::lower_bound(sorted.begin(), sorted.end(), l.joint) - sorted.begin());
  coordinate_joint_ = sorted;
  names_.clear();
  is_angle_.clear();
  for (int k : coordinate_joint_) {
    names_.push_back(model.joints[k].name);
    is_angle_.push_back(model.joints[k].type == JointType::kRevolute);
  }
}

void JointSpace::Absolute(const double* q, const double* qd, const double* qdd, double* x, double* xd, double* xdd,
                          double* J) const {
  const int nb = static_cast<int>(model_.bodies.size()), n = size();
  // One pass from the ground: positions, velocities (of qd) and accelerations (of qd, qdd).
  auto pass = [&](const double* rate, const double* acc, std::vector<BodyMotion>* motion) {
    motion->assign(nb, BodyMotion{});
    const BodyMotion ground;
    for (const Link& l : links_) {
      const BodyMotion& P = l.parent < 0 ? ground : (*motion)[l.parent];
      BodyMotion& C = (*motion)[l.body];
      const double qk = l.coordinate >= 0 ? q[l.coordinate] : 0.0;
      const double rk = l.coordinate >= 0 && rate ? rate[l.coordinate] : 0.0;
      const double ak = l.coordinate >= 0 && acc ? acc[l.coordinate] : 0.0;
      const bool revolute = l.coordinate >= 0 && !l.prismatic;
      const Mat3 R_rel = revolute ? Mat3(Rz(qk) * l.D) : l.D;
      const Vec3 d = l.prismatic ? Vec3(l.d0 + qk * Vec3::UnitZ()) : l.d0;
      Mat3 R_Wi, R_Wj;
      Vec3 p_i;
      if (l.child_is_i) {
        R_Wj = P.R * l.O_j;
        const Vec3 p_j = P.x + P.R * l.s_j;
        R_Wi = R_Wj * R_rel;
        p_i = p_j + R_Wj * d;
        C.R = R_Wi * l.O_i.transpose();
        C.x = p_i - C.R * l.s_i;
      } else {
        R_Wi = P.R * l.O_i;
        p_i = P.x + P.R * l.s_i;
        R_Wj = R_Wi * R_rel.transpose();
        const Vec3 p_j = p_i - R_Wj * d;
        C.R = R_Wj * l.O_j.transpose();
        C.x = p_j - C.R * l.s_j;
      }
      const Vec3 s = (l.child_is_i ? 1.0 : -1.0) * (R_Wj * Vec3::UnitZ());  // sigma z_j
      if (revolute) {
        C.w = P.w + s * rk;
        C.alpha = P.alpha + s * ak + P.w.cross(s * rk);
        const Vec3 r1 = p_i - P.x, r2 = C.x - p_i;
        C.v = P.v + P.w.cross(r1) + C.w.cross(r2);
        C.a = P.a + P.alpha.cross(r1) + P.w.cross(P.w.cross(r1)) + C.alpha.cross(r2) + C.w.cross(C.w.cross(r2));
      } else {
        const Vec3 r = C.x - P.x;
        C.w = P.w;
        C.alpha = P.alpha;
        C.v = P.v + P.w.cross(r) + s * rk;
        C.a = P.a + P.alpha.cross(r) + P.w.cross(P.w.cross(r)) + 2 * P.w.cross(s * rk) + s * ak;
      }
    }
  };
  auto write = [&](const std::vector<BodyMotion>& motion, double* xo, double* xdo, double* xddo) {
    for (int b = 0; b < nb; ++b) {
      const BodyMotion& m = motion[b];
      Quat e = QuaternionFromMatrix(m.R);
      e.normalize();
      const Mat34 E = EMatrix(e);
      const Eigen::Vector4d ed = 0.5 * E.transpose() * m.w;
      const Eigen::Vector4d edd = 0.5 * E.transpose() * m.alpha - ed.squaredNorm() * e;
      for (int k = 0; k < 3; ++k) {
        if (xo) xo[7 * b + k] = m.x[k];
        if (xdo) xdo[7 * b + k] = m.v[k];
        if (xddo) xddo[7 * b + k] = m.a[k];
      }
      for (int k = 0; k < 4; ++k) {
        if (xo) xo[7 * b + 3 + k] = e[k];
        if (xdo) xdo[7 * b + 3 + k] = ed[k];
        if (xddo) xddo[7 * b + 3 + k] = edd[k];
      }
    }
  };
  std::vector<BodyMotion> motion;
  pass(qd, qdd, &motion);
  write(motion, x, xd, xdd);
  if (J) {
    std::vector<double> unit(n, 0.0);
    for (int k = 0; k < n; ++k) {
      unit.assign(n, 0.0);
      unit[k] = 1;
      pass(unit.data(), nullptr, &motion);
      write(motion, nullptr, J + static_cast<size_t>(k) * 7 * nb, nullptr);
    }
  }
}

void JointSpace::JointState(const double* x, const double* xd, const double* xdd, const double* previous, double* q,
                       double* qd, double* qdd) const {
  const int n = size(), nx = 7 * static_cast<int>(model_.bodies.size());
  auto frame = [&](int body, const Vec3& s, const Mat3& O, Vec3* p, Mat3* R) {
    if (body < 0) {
      *p = s;
      *R = O;
      return;
    }
    Quat e(x[7 * body + 3], x[7 * body + 4], x[7 * body + 5], x[7 * body + 6]);
    e.normalize();
    const Mat3 A = RotationMatrix(e);
    *p = Vec3(x[7 * body], x[7 * body + 1], x[7 * body + 2]) + A * s;
    *R = A * O;
  };
  for (const Link& l : links_) {
    if (l.coordinate < 0) continue;
    const Joint& j = model_.joints[l.joint];
    Vec3 p_i, p_j;
    Mat3 R_i, R_j;
    frame(model_.markers[j.i].body, l.s_i, l.O_i, &p_i, &R_i);
    frame(model_.markers[j.j].body, l.s_j, l.O_j, &p_j, &R_j);
    double value;
    if (l.prismatic) {
      value = (R_j.transpose() * (p_i - p_j)).z();
    } else {
      const Mat3 Rz_q = R_j.transpose() * R_i * l.D.transpose();
      value = std::atan2(Rz_q(1, 0), Rz_q(0, 0));
      if (previous) value += 2 * M_PI * std::round((previous[l.coordinate] - value) / (2 * M_PI));
    }
    q[l.coordinate] = value;
  }
  if (!qd && !qdd) return;
  // The rates: J q' = x' and J q'' = x'' - J' q', solved in least squares (exact for rates
  // the joints allow).
  std::vector<double> Jv(static_cast<size_t>(nx) * n), bias(nx);
  std::vector<double> rate(n, 0.0);
  Absolute(q, nullptr, nullptr, nullptr, nullptr, nullptr, Jv.data());
  const Eigen::Map<const Eigen::MatrixXd> Jm(Jv.data(), nx, n);
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Jm);
  if (xd) {
    const Eigen::VectorXd r = qr.solve(Eigen::Map<const Eigen::VectorXd>(xd, nx));
    for (int k = 0; k < n; ++k) rate[k] = r[k];
  }
  if (qd) std::copy(rate.begin(), rate.end(), qd);
  if (qdd) {
    if (!xdd) {
      std::fill(qdd, qdd + n, 0.0);
      return;
    }
    Absolute(q, rate.data(), nullptr, nullptr, nullptr, bias.data(), nullptr);
    Eigen::VectorXd rhs = Eigen::Map<const Eigen::VectorXd>(xdd, nx) - Eigen::Map<const Eigen::VectorXd>(bias.data(), nx);
    const Eigen::VectorXd r = qr.solve(rhs);
    for (int k = 0; k < n; ++k) qdd[k] = r[k];
  }
}

namespace {

// M x (dense nq-vector) with the system's sparse mass matrix values.
Eigen::MatrixXd MassTimes(const dae::CscPattern& P, const std::vector<double>& values, const Eigen::MatrixXd& X) {
  Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(P.rows, X.cols());
  for (int c = 0; c < P.cols; ++c)
    for (int k = P.col_start[c]; k < P.col_start[c + 1]; ++k) Y.row(P.row_index[k]) += values[k] * X.row(c);
  return Y;
}

void Evaluate(MultibodySystem& system, double t, const double* x, const double* xd, const double* xdd,
              std::vector<double>* mass, std::vector<double>* force) {
  dae::EvalInput in;
  in.t = t;
  in.q = x;
  in.v = xd;
  in.a = xdd;
  dae::EvalOutput out;
  if (mass) {
    mass->assign(system.pattern(dae::Matrix::kMass).nnz(), 0.0);
    out[dae::Matrix::kMass] = mass->data();
  }
  if (force) {
    force->assign(system.num_coordinates(), 0.0);
    out.force = force->data();
  }
  if (system.Evaluate(in, out) != 0)
    throw std::runtime_error(std::string("the model could not be evaluated: ") + system.last_error());
}

}  // namespace

void JointSpace::RowValues(MultibodySystem& system, double t, const double* x, const double* xd, const double* xdd,
                           const double* previous, double* q, double* qd, double* qdd, double* tau) const {
  const int nb = static_cast<int>(model_.bodies.size()), nx = 7 * nb;
  struct Kin {
    Mat3 R = Mat3::Identity();
    Vec3 p = Vec3::Zero(), v = Vec3::Zero(), a = Vec3::Zero(), w = Vec3::Zero(), alpha = Vec3::Zero();
  };
  std::vector<Kin> kin(nb);
  for (int b = 0; b < nb; ++b) {
    const Quat e(x[7 * b + 3], x[7 * b + 4], x[7 * b + 5], x[7 * b + 6]);
    const Quat ed(xd[7 * b + 3], xd[7 * b + 4], xd[7 * b + 5], xd[7 * b + 6]);
    const Quat edd(xdd[7 * b + 3], xdd[7 * b + 4], xdd[7 * b + 5], xdd[7 * b + 6]);
    const Mat34 E = EMatrix(e);
    kin[b].R = RotationMatrix(e / e.norm());
    kin[b].p = Vec3(x[7 * b], x[7 * b + 1], x[7 * b + 2]);
    kin[b].v = Vec3(xd[7 * b], xd[7 * b + 1], xd[7 * b + 2]);
    kin[b].a = Vec3(xdd[7 * b], xdd[7 * b + 1], xdd[7 * b + 2]);
    kin[b].w = 2 * E * ed;      // omega = 2 E e'
    kin[b].alpha = 2 * E * edd; // alpha = 2 E e'' (E(e') e' = 0)
  }
  const Kin ground;
  // Residual forces of the bodies: f (3) and the torque 1/2 E r_e (world), from M x'' - Q.
  std::vector<double> mass, force;
  Evaluate(system, t, x, xd, xdd, &mass, &force);
  const dae::CscPattern& P = system.pattern(dae::Matrix::kMass);
  std::vector<double> r(nx, 0.0);
  for (int c = 0; c < P.cols; ++c)
    for (int k = P.col_start[c]; k < P.col_start[c + 1]; ++k) r[P.row_index[k]] += mass[k] * xdd[c];
  for (int k = 0; k < nx; ++k) r[k] -= force[k];
  std::vector<Vec3> F(nb), N(nb);  // of the subtree of each body; N about the world origin
  for (int b = 0; b < nb; ++b) {
    const Quat e(x[7 * b + 3], x[7 * b + 4], x[7 * b + 5], x[7 * b + 6]);
    F[b] = Vec3(r[7 * b], r[7 * b + 1], r[7 * b + 2]);
    N[b] = 0.5 * EMatrix(e) * Eigen::Vector4d(r[7 * b + 3], r[7 * b + 4], r[7 * b + 5], r[7 * b + 6]) +
           kin[b].p.cross(F[b]);
  }
  for (auto it = links_.rbegin(); it != links_.rend(); ++it)
    if (it->parent >= 0) {
      F[it->parent] += F[it->body];
      N[it->parent] += N[it->body];
    }
  for (const Link& l : links_) {
    if (l.coordinate < 0) continue;
    const Joint& j = model_.joints[l.joint];
    const int bi = model_.markers[j.i].body, bj = model_.markers[j.j].body;
    const Kin& I = bi < 0 ? ground : kin[bi];
    const Kin& J = bj < 0 ? ground : kin[bj];
    const Mat3 R_i = I.R * l.O_i, R_j = J.R * l.O_j;
    const Vec3 ri = I.R * l.s_i, rj = J.R * l.s_j;
    const Vec3 pi = I.p + ri, pj = J.p + rj;
    const Vec3 z = R_j * Vec3::UnitZ();
    const Vec3 zd = J.w.cross(z), zdd = J.alpha.cross(z) + J.w.cross(zd);
    const int k = l.coordinate;
    if (l.prismatic) {
      const Vec3 d = pi - pj;
      const Vec3 dd = (I.v + I.w.cross(ri)) - (J.v + J.w.cross(rj));
      const Vec3 ddd = (I.a + I.alpha.cross(ri) + I.w.cross(I.w.cross(ri))) -
                       (J.a + J.alpha.cross(rj) + J.w.cross(J.w.cross(rj)));
      q[k] = z.dot(d);
      qd[k] = zd.dot(d) + z.dot(dd);
      qdd[k] = zdd.dot(d) + 2 * zd.dot(dd) + z.dot(ddd);
    } else {
      const Mat3 Rz_q = R_j.transpose() * R_i * l.D.transpose();
      double angle = std::atan2(Rz_q(1, 0), Rz_q(0, 0));
      if (previous) angle += 2 * M_PI * std::round((previous[k] - angle) / (2 * M_PI));
      q[k] = angle;
      qd[k] = z.dot(I.w - J.w);
      qdd[k] = z.dot(I.alpha - J.alpha) + zd.dot(I.w - J.w);
    }
    const double sigma = l.child_is_i ? 1.0 : -1.0;
    tau[k] = l.prismatic ? sigma * z.dot(F[l.body]) : sigma * z.dot(N[l.body] - pi.cross(F[l.body]));
  }
}

void JointSpace::MassMatrix(MultibodySystem& system, const double* q, double* M) const {
  const int n = size(), nx = 7 * static_cast<int>(model_.bodies.size());
  std::vector<double> x(nx), xd(nx, 0.0), Jv(static_cast<size_t>(nx) * n), mass;
  Absolute(q, nullptr, nullptr, x.data(), nullptr, nullptr, Jv.data());
  Evaluate(system, 0.0, x.data(), xd.data(), xd.data(), &mass, nullptr);
  const Eigen::Map<const Eigen::MatrixXd> J(Jv.data(), nx, n);
  const Eigen::MatrixXd Mq = J.transpose() * MassTimes(system.pattern(dae::Matrix::kMass), mass, J);
  Eigen::Map<Eigen::MatrixXd>(M, n, n) = 0.5 * (Mq + Mq.transpose());  // symmetric to rounding
}

void JointSpace::InverseDynamics(MultibodySystem& system, double t, const double* q, const double* qd,
                                 const double* qdd, double* tau) const {
  const int n = size(), nx = 7 * static_cast<int>(model_.bodies.size());
  std::vector<double> x(nx), xd(nx), xdd(nx), Jv(static_cast<size_t>(nx) * n), mass, force;
  Absolute(q, qd, qdd, x.data(), xd.data(), xdd.data(), Jv.data());
  Evaluate(system, t, x.data(), xd.data(), xdd.data(), &mass, &force);
  const Eigen::Map<const Eigen::MatrixXd> J(Jv.data(), nx, n);
  const Eigen::VectorXd r = MassTimes(system.pattern(dae::Matrix::kMass), mass,
                                      Eigen::Map<const Eigen::VectorXd>(xdd.data(), nx)) -
                            Eigen::Map<const Eigen::VectorXd>(force.data(), nx);
  Eigen::Map<Eigen::VectorXd>(tau, n) = J.transpose() * r;
}

void JointSpace::Bias(MultibodySystem& system, double t, const double* q, const double* qd, double* b) const {
  InverseDynamics(system, t, q, qd, nullptr, b);
}

void JointSpace::Gravity(MultibodySystem& system, double t, const double* q, double* g) const {
  InverseDynamics(system, t, q, nullptr, nullptr, g);
}

}  // namespace mbdae::mbs
