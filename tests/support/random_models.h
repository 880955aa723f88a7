// Random multibody models built in code, for derivative and consistency tests: random
// bodies (mass, full inertia, pose, velocities), random markers with random
// orientations on bodies and on ground, every joint type (generic with a random lock
// set), every force type in every frame, gravity, and measures of every kind; with
// random states (q with unit Euler parameters, v, a, w).
#pragma once

#include <random>
#include <string>
#include <vector>

#include "mbs/kinematics.h"
#include "mbs/model.h"

namespace mbdae::testing {

struct RandomModelOptions {
  int bodies = 3;            // at least 1
  int markers_per_body = 3;  // besides `cm`
  int ground_markers = 2;    // besides ground.O
  bool joints = true;        // one joint of every type
  bool forces = true;        // every force type in every frame
  bool measures = true;      // every measure kind
  bool gravity = true;
  // With measures: a spline `s` and force elements (a spring_damper, forces and a torque
  // in every frame) whose values are expressions over position and velocity measures,
  // t and spline(s, x).
  bool expression_forces = false;
  // With measures: motion joints (a translational component, a distance, an angle;
  // values over t and spline(s, t)) and a gear between two angles.
  bool motion_gear = false;
  // Bushings (random stiffness and damping, some entries zero): body-body, body-ground
  // and ground-body (marker i on ground).
  bool bushings = false;
};

// A smooth spline `s` for the expression elements (added once).
inline void AddTestSpline(mbs::Model& m) {
  using namespace mbs;
  if (m.find_spline("s") >= 0) return;
  SplineDef sd;
  sd.name = "s";
  sd.spline = Spline({-6, -2, -0.5, 0, 1, 2.5, 6}, {0.5, -1, 0.3, 1, 0.2, -0.7, 1.5},
                     Interpolation::kCubic);
  m.splines.push_back(sd);
}

// The motion and gear joints of RandomModelOptions::motion_gear over the measures of
// RandomModel (m2: y component in j axes, m6: distance, m8..m10: angles).
inline void AddMotionAndGear(mbs::Model& m) {
  using namespace mbs;
  AddTestSpline(m);
  SymbolTable sym;
  sym.splines = {"s"};
  sym.allow_time = true;
  auto motion = [&](const char* name, const char* measure, const char* text) {
    Joint j;
    j.name = name;
    j.type = JointType::kMotion;
    j.measures[0] = m.find_measure(measure);
    j.value = Expression::Parse(text, sym);
    m.joints.push_back(j);
  };
  motion("mo_y", "m2", "0.3*sin(2*t) + 0.1*spline(s, t)");
  motion("mo_d", "m6", "0.5 + 0.1*cos(3*t)*t^2");
  motion("mo_a", "m8", "t^2 - 0.3*t + spline(s, 2*t)");
  Joint g;
  g.name = "gear";
  g.type = JointType::kGear;
  g.measures = {m.find_measure("m9"), m.find_measure("m10")};
  g.ratio = -2.5;
  m.joints.push_back(g);
}

// The expression-valued force elements of RandomModelOptions::expression_forces, over
// the measures m0.. of RandomModel (11 per quantity: m0..m10 position, m11..m21
// velocity; m8..m10 and m19..m21 rotational).
inline void AddExpressionForces(mbs::Model& m, std::mt19937& rng, int first_body_marker) {
  using namespace mbs;
  const int nm = static_cast<int>(m.markers.size());
  auto pick = [&](int n) { return static_cast<int>(rng() % static_cast<unsigned>(n)); };
  auto body_marker = [&]() { return first_body_marker + pick(nm - first_body_marker); };
  AddTestSpline(m);
  SymbolTable sym;
  for (const Measure& me : m.measures) sym.measures.push_back(me.name);
  sym.splines = {"s"};
  sym.allow_time = true;
  auto E = [&](const char* text) { return Expression::Parse(text, sym); };
  int n = 0;
  auto add = [&](Force f, bool ground) {
    f.name = "fx" + std::to_string(n++);
    f.i = body_marker();
    if (ground) {
      f.j = 0;
    } else {
      do f.j = body_marker(); while (m.markers[f.j].body == m.markers[f.i].body);
    }
    m.forces.push_back(f);
  };
  Force sp;
  sp.type = ForceType::kSpringDamper;
  sp.stiffness = E("50*(1 + 0.1*m1^2)");
  sp.damping = E("2 + 0.5*sin(m12)");
  sp.free_length = E("0.5 + 0.1*spline(s, t)");
  sp.preload = E("m9 + t*m20");
  add(sp, false);
  Force fw;
  fw.type = ForceType::kForce;
  fw.frame = ForceFrame::kWorld;
  fw.value = {E("-3*m1 - 0.5*m12"), E("spline(s, m9)"), E("sin(t)*m20")};
  add(fw, true);
  Force fi;
  fi.type = ForceType::kForce;
  fi.frame = ForceFrame::kI;
  fi.value = {E("m0*m13"), E("cos(m9) + m3"), E("t")};
  add(fi, false);
  Force tj;
  tj.type = ForceType::kTorque;
  tj.frame = ForceFrame::kJ;
  tj.value = {E("-2*m9 - 0.3*m20"), E("spline(s, m14)"), E("m2*m11")};
  add(tj, false);
  Force tw;
  tw.type = ForceType::kTorque;
  tw.frame = ForceFrame::kWorld;
  tw.value = {E("m10"), E("m21*t"), E("m5")};
  add(tw, true);
}

inline mbs::Quat RandomUnitQuaternion(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  mbs::Quat e(n(rng), n(rng), n(rng), n(rng));
  e.normalize();
  if (e[0] < 0) e = -e;
  return e;
}

inline mbs::Vec3 RandomVector(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  return mbs::Vec3(u(rng), u(rng), u(rng));
}

// Locks of the predefined joint types (model-format.md).
inline unsigned JointTypeLocks(mbs::JointType t) {
  using namespace mbs;
  switch (t) {
    case JointType::kFixed: return kLockX | kLockY | kLockZ | kLockRx | kLockRy | kLockRz;
    case JointType::kSpherical: return kLockX | kLockY | kLockZ;
    case JointType::kRevolute: return kLockX | kLockY | kLockZ | kLockRx | kLockRy;
    case JointType::kPrismatic: return kLockX | kLockY | kLockRx | kLockRy | kLockRz;
    case JointType::kCylindrical: return kLockX | kLockY | kLockRx | kLockRy;
    case JointType::kUniversal: return kLockX | kLockY | kLockZ | kLockRz;
    case JointType::kPlanar: return kLockZ | kLockRx | kLockRy;
    default: return 0;
  }
}

inline mbs::Model RandomModel(std::mt19937& rng, const RandomModelOptions& opt = {}) {
  using namespace mbs;
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto uniform = [&](double a, double b) { return a + (b - a) * u01(rng); };
  auto pick = [&](int n) { return static_cast<int>(rng() % static_cast<unsigned>(n)); };
  auto C = [](double x) { return Expression::Constant(x); };

  Model m;
  m.name = "random";
  if (opt.gravity) m.gravity = RandomVector(rng, 10.0);
  // ground markers: ground.O first
  m.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
  for (int k = 0; k < opt.ground_markers; ++k)
    m.markers.push_back(Marker{"ground.G" + std::to_string(k), -1, RandomVector(rng, 1.0),
                               RotationMatrix(RandomUnitQuaternion(rng)), {}});
  for (int b = 0; b < opt.bodies; ++b) {
    Body body;
    body.name = "b" + std::to_string(b);
    body.mass = uniform(0.5, 3.0);
    // principal moments satisfying the triangle inequality, random principal axes
    const double i1 = uniform(0.1, 1.0), i2 = uniform(0.1, 1.0);
    const double i3 = uniform(std::abs(i1 - i2) + 0.05, i1 + i2);
    const Mat3 R = RotationMatrix(RandomUnitQuaternion(rng));
    body.inertia = R * Vec3(i1, i2, i3).asDiagonal() * R.transpose();
    body.position = RandomVector(rng, 2.0);
    body.orientation = RandomUnitQuaternion(rng);
    body.velocity = RandomVector(rng, 1.0);
    body.angular_velocity = RandomVector(rng, 2.0);
    body.cm_marker = static_cast<int>(m.markers.size());
    m.markers.push_back(Marker{body.name + ".cm", b, Vec3::Zero(), Mat3::Identity(), {}});
    for (int k = 0; k < opt.markers_per_body; ++k)
      m.markers.push_back(Marker{body.name + ".M" + std::to_string(k), b, RandomVector(rng, 0.5),
                                 RotationMatrix(RandomUnitQuaternion(rng)), {}});
    m.bodies.push_back(body);
  }
  const int nm = static_cast<int>(m.markers.size());
  const int first_body_marker = 1 + opt.ground_markers;
  auto body_marker = [&]() { return first_body_marker + pick(nm - first_body_marker); };
  auto any_marker = [&]() { return pick(nm); };
  // marker j for marker i: any marker on another body or on ground
  auto other_marker = [&](int i) {
    for (;;) {
      const int j = any_marker();
      if (m.markers[j].body != m.markers[i].body) return j;
    }
  };

  if (opt.joints) {
    const JointType types[] = {JointType::kFixed,       JointType::kSpherical,
                               JointType::kRevolute,    JointType::kPrismatic,
                               JointType::kCylindrical, JointType::kUniversal,
                               JointType::kPlanar,      JointType::kGeneric};
    int n = 0;
    for (JointType t : types) {
      Joint j;
      j.name = "j" + std::to_string(n++);
      j.type = t;
      j.i = body_marker();
      j.j = other_marker(j.i);
      j.locks = t == JointType::kGeneric ? 1u + rng() % 63u : JointTypeLocks(t);
      m.joints.push_back(j);
    }
    // one more, with marker i on ground
    Joint j;
    j.name = "jg";
    j.type = JointType::kRevolute;
    j.i = pick(opt.ground_markers + 1);
    j.j = body_marker();
    j.locks = JointTypeLocks(JointType::kRevolute);
    m.joints.push_back(j);
  }
  if (opt.forces) {
    int n = 0;
    auto add = [&](Force f) {
      f.name = "f" + std::to_string(n++);
      m.forces.push_back(f);
    };
    for (int k = 0; k < 2; ++k) {  // springs: body-body and body-ground
      Force f;
      f.type = ForceType::kSpringDamper;
      f.i = body_marker();
      f.j = k == 0 ? other_marker(f.i) : pick(opt.ground_markers + 1);
      f.stiffness = C(uniform(10, 100));
      f.damping = C(uniform(0.5, 5));
      f.free_length = C(uniform(0.1, 1));
      f.preload = C(uniform(-2, 2));
      add(f);
    }
    for (ForceType t : {ForceType::kForce, ForceType::kTorque})
      for (ForceFrame fr : {ForceFrame::kWorld, ForceFrame::kI, ForceFrame::kJ})
        for (int k = 0; k < 2; ++k) {  // reaction on a body, and on ground
          Force f;
          f.type = t;
          f.frame = fr;
          f.i = body_marker();
          f.j = k == 0 ? other_marker(f.i) : pick(opt.ground_markers + 1);
          for (int c = 0; c < 3; ++c) f.value[c] = C(uniform(-5, 5));
          add(f);
        }
  }
  if (opt.bushings) {
    for (int k = 0; k < 3; ++k) {
      Force f;
      f.name = "b" + std::to_string(k);
      f.type = ForceType::kBushing;
      if (k == 2) {
        f.i = pick(opt.ground_markers + 1);
        f.j = body_marker();
      } else {
        f.i = body_marker();
        f.j = k == 0 ? other_marker(f.i) : pick(opt.ground_markers + 1);
      }
      for (int c = 0; c < 6; ++c) {
        f.bushing_stiffness[c] = C(c == k ? 0.0 : uniform(10, 100));
        f.bushing_damping[c] = C(c == 5 - k ? 0.0 : uniform(0.5, 5));
      }
      m.forces.push_back(f);
    }
  }
  if (opt.measures) {
    int n = 0;
    for (Quantity qt : {Quantity::kPosition, Quantity::kVelocity, Quantity::kAcceleration}) {
      for (Component c : {Component::kX, Component::kY, Component::kZ, Component::kDistance})
        for (MeasureFrame fr : {MeasureFrame::kJ, MeasureFrame::kWorld}) {
          Measure me;
          me.name = "m" + std::to_string(n++);
          me.type = MeasureType::kTranslational;
          me.i = body_marker();
          me.j = (n % 3 == 0) ? 0 : other_marker(me.i);
          me.component = c;
          me.frame = fr;
          me.quantity = qt;
          m.measures.push_back(me);
        }
      for (Component c : {Component::kX, Component::kY, Component::kZ}) {
        Measure me;
        me.name = "m" + std::to_string(n++);
        me.type = MeasureType::kRotational;
        me.i = body_marker();
        me.j = (n % 2 == 0) ? pick(opt.ground_markers + 1) : other_marker(me.i);
        me.component = c;
        me.quantity = qt;
        m.measures.push_back(me);
      }
    }
    if (opt.expression_forces) AddExpressionForces(m, rng, first_body_marker);
    if (opt.motion_gear) AddMotionAndGear(m);
  }
  return m;
}

// A random state: q with unit Euler parameters, v, a, w (nc entries).
struct RandomState {
  std::vector<double> q, v, a, w;
};

inline RandomState MakeRandomState(std::mt19937& rng, const mbs::Model& m, int nc,
                                   bool tangent_rates = false) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  RandomState s;
  const int nq = m.num_coordinates();
  s.q.resize(nq);
  s.v.resize(nq);
  s.a.resize(nq);
  s.w.resize(nc);
  for (size_t b = 0; b < m.bodies.size(); ++b) {
    const int o = 7 * static_cast<int>(b);
    const mbs::Quat e = RandomUnitQuaternion(rng);
    for (int k = 0; k < 3; ++k) s.q[o + k] = 2 * u(rng);
    for (int k = 0; k < 4; ++k) s.q[o + 3 + k] = e[k];
  }
  for (auto& x : s.v) x = u(rng);
  for (auto& x : s.a) x = u(rng);
  for (auto& x : s.w) x = u(rng);
  if (tangent_rates) {  // e . e' = 0
    for (size_t b = 0; b < m.bodies.size(); ++b) {
      const int o = 7 * static_cast<int>(b) + 3;
      Eigen::Map<mbs::Quat> e(s.q.data() + o), ed(s.v.data() + o);
      ed -= e.dot(ed) * e;
    }
  }
  return s;
}

}  // namespace mbdae::testing
