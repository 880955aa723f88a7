// ModelObjectives (sensitivities/model_objectives.h): values against the measures
// computed independently (MultibodySystem::EvaluateMeasures, ReactionMeasures), and every
// gradient (q, v, a, kept lambda, parameters, spline ordinates) against central
// differences at random states.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "mbs/loader.h"
#include "mbs/reaction.h"
#include "mbs/sensitivity_parameters.h"
#include "mbs/system.h"
#include "sensitivities/model_objectives.h"

namespace mbdae::sens {
namespace {

// A pendulum (revolute to ground) with objectives over every kind of measure.
const std::string kPendulum = R"Y(format: 1
gravity: [0, -9.81, 0]
parameters: {L: 1.0, m: 1.5, k: 0.7}
splines:
  u: {x: [0, 0.5, 1, 1.5], y: [0, 1, 0.5, 2]}
bodies:
  - name: bob
    mass: m
    inertia: [0.01, 0.02, 0.03]
    position: [L, 0, 0]
    markers:
      pivot: {position: ["-L", 0, 0]}
measures:
  - {name: x, type: translational, i: bob.cm, component: x}
  - {name: drop, type: translational, i: bob.cm, component: y, offset_initial: true}
  - {name: angle, type: rotational, i: bob.pivot, j: ground.O, axis: z}
  - {name: rate, type: rotational, i: bob.pivot, j: ground.O, axis: z, quantity: angular_velocity}
  - {name: acc, type: translational, i: bob.cm, component: distance, quantity: acceleration}
  - {name: wdot, type: rotational, i: bob.pivot, j: ground.O, axis: z, quantity: angular_acceleration}
  - {name: tension, type: reaction, joint: pivot, component: x, frame: j}
  - {name: moment, type: reaction, joint: pivot, component: rx, frame: world}
joints:
  - {name: pivot, type: revolute, i: bob.pivot, j: ground.O}
objectives:
  - {name: G, integral: "0.5*(k*x^2 + rate^2) + spline(u, t)*drop", terminal: "sin(angle) + k*acc"}
  - {name: E, integral: "tension^2 + moment*wdot + m*t"}
  - {name: F, terminal: "x*tension + spline(u, 0.7)"}
)Y";

// Two bodies (a double pendulum, second link on a spherical joint), objectives over
// measures between the bodies.
const std::string kTwoBodies = R"Y(format: 1
gravity: [0, -9.81, 0]
parameters: {c: 2.0}
bodies:
  - name: a
    mass: 2
    inertia: [0.1, 0.2, 0.3]
    position: [0.5, 0, 0]
    markers:
      p: {position: [-0.5, 0, 0]}
      q: {position: [0.5, 0, 0], orientation: {axis: [0, 0.2, 1], angle: 0.7}}
  - name: b
    mass: 1
    inertia: [0.05, 0.06, 0.07]
    position: [1.3, 0.1, 0]
    markers:
      s: {position: [-0.3, -0.1, 0.05], orientation: {axis: [1, 0, 0.3], angle: 1.1}}
measures:
  - {name: gap, type: translational, i: b.cm, j: a.q, component: distance}
  - {name: side, type: translational, i: b.cm, j: a.q, component: y, quantity: velocity}
  - {name: twist, type: rotational, i: b.s, j: a.q, axis: x, quantity: angular_acceleration}
  - {name: ball_z, type: reaction, joint: ball, component: rz, frame: j}
  - {name: ball_f, type: reaction, joint: ball, component: y, frame: world}
joints:
  - {name: hinge, type: revolute, i: a.p, j: ground.O}
  - {name: ball, type: spherical, i: b.s, j: a.q}
objectives:
  - {name: A, integral: "c*gap^2 + side*twist + ball_f^2", terminal: "ball_z*c + exp(0.1*side)"}
)Y";

// A rotor driven by a motion joint: the energy-like objective of the drive torque.
const std::string kMotion = R"Y(format: 1
gravity: [0, -9.81, 0]
parameters: {alpha: 3.0}
bodies:
  - name: rotor
    mass: 2
    inertia: [0.2, 0.2, 0.4]
    position: [0.1, 0, 0]
    markers:
      o: {position: [-0.1, 0, 0]}
measures:
  - {name: angle, type: rotational, i: rotor.o, j: ground.O, axis: z}
  - {name: drive, type: reaction, joint: spin, component: rz, frame: world}
joints:
  - {name: axle, type: revolute, i: rotor.o, j: ground.O}
  - {name: spin, type: motion, measure: angle, value: "0.5*alpha*t^2"}
objectives:
  - {name: W, integral: "drive^2", terminal: "alpha*drive*angle"}
)Y";

struct Point {
  double t = 0.4;
  std::vector<double> q, v, a, lambda;
  ObjectivePoint view() const { return ObjectivePoint{t, q.data(), v.data(), a.data(), lambda.data()}; }
};

Point RandomPoint(int nq, int nc, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  Point p;
  for (auto* x : {&p.q, &p.v, &p.a}) {
    x->resize(nq);
    for (double& y : *x) y = u(rng);
  }
  for (int b = 0; b < nq / 7; ++b) p.q[7 * b + 3] += 1.5;
  p.lambda.resize(nc);
  for (double& y : p.lambda) y = 5 * u(rng);
  return p;
}

// Central differences of sum_i w_i f_i along one input entry (step h).
double Fd(ModelObjectives& obj, bool terminal, Point p, std::vector<double> Point::*field, int k,
          const std::vector<double>& w, double h) {
  const int n = obj.num_objectives();
  std::vector<double> fp(n), fm(n);
  const double x = (p.*field)[k];
  (p.*field)[k] = x + h;
  terminal ? obj.Terminal(p.view(), fp.data()) : obj.Integrand(p.view(), fp.data());
  (p.*field)[k] = x - h;
  terminal ? obj.Terminal(p.view(), fm.data()) : obj.Integrand(p.view(), fm.data());
  double s = 0;
  for (int i = 0; i < n; ++i) s += w[i] * (fp[i] - fm[i]) / (2 * h);
  return s;
}

// Checks every gradient of a model's objectives at random states with `drop` equations
// dropped from the end of the joint equations (the kept lambda is mapped to the full set).
// Tolerance: 2e-6 relative to the largest entry (central differences, step 1e-5 for q
// (the acceleration measures' q-derivative itself uses central differences of the exact
// Hessian), 1e-6 for v, a, lambda; the objective is smooth, so the error is O(h^2)).
void CheckGradients(const std::string& yaml, bool with_splines) {
  mbs::Model model = mbs::LoadModelFromString(yaml, "m.yaml");
  mbs::MultibodySystem sys(model);
  const int nq = sys.num_coordinates(), nc_full = sys.num_constraints();
  std::vector<int> kept;
  for (int r = 0; r < nc_full; ++r)
    if (r != 1) kept.push_back(r);  // drop one joint equation
  const int nc = static_cast<int>(kept.size());
  const auto params = mbs::AllSensitivityParameters(model, with_splines);
  ModelObjectives obj(model, sys, kept, params);
  const int n = obj.num_objectives();
  const int np = static_cast<int>(params.size());
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.5, 1.5);
  for (int trial = 0; trial < 2; ++trial) {
    Point p = RandomPoint(nq, nc, rng);
    std::vector<double> w(n);
    for (double& x : w) x = u(rng);
    for (bool terminal : {false, true}) {
      SCOPED_TRACE(terminal ? "terminal" : "integrand");
      std::vector<double> dq(nq, 0.0), dv(nq, 0.0), da(nq, 0.0), dl(nc, 0.0), dp(np, 0.0);
      ObjectiveGradient g{dq.data(), dv.data(), da.data(), dl.data(), dp.data()};
      ASSERT_EQ(terminal ? obj.TerminalGradient(p.view(), w.data(), &g)
                         : obj.IntegrandGradient(p.view(), w.data(), &g),
                0)
          << obj.last_error();
      double scale = 1e-2;
      for (auto* x : {&dq, &dv, &da, &dl, &dp})
        for (double y : *x) scale = std::max(scale, std::abs(y));
      const double tol = 2e-6 * scale;
      for (int k = 0; k < nq; ++k) {
        EXPECT_NEAR(dq[k], Fd(obj, terminal, p, &Point::q, k, w, 1e-5), tol) << "q " << k;
        EXPECT_NEAR(dv[k], Fd(obj, terminal, p, &Point::v, k, w, 1e-6), tol) << "v " << k;
        EXPECT_NEAR(da[k], Fd(obj, terminal, p, &Point::a, k, w, 1e-6), tol) << "a " << k;
      }
      for (int k = 0; k < nc; ++k)
        EXPECT_NEAR(dl[k], Fd(obj, terminal, p, &Point::lambda, k, w, 1e-6), tol) << "lambda " << k;
      for (int k = 0; k < np; ++k) {
        const mbs::SensitivityParameter& sp = params[k];
        std::vector<double> fp(n), fm(n);
        const double h = 1e-6;
        const std::vector<double> p0 = sys.parameters();
        const std::vector<double> y0 = sp.parameter >= 0 ? std::vector<double>() : model.splines[sp.spline].spline.y();
        auto eval = [&](double delta, std::vector<double>* f) {
          if (sp.parameter >= 0) {
            sys.parameters()[sp.parameter] = p0[sp.parameter] + delta;
          } else {
            mbs::Spline& s = model.splines[sp.spline].spline;
            std::vector<double> y = y0;
            y[sp.point] += delta;
            s.SetPoints(s.x(), y);
          }
          if (f) terminal ? obj.Terminal(p.view(), f->data()) : obj.Integrand(p.view(), f->data());
        };
        eval(h, &fp);
        eval(-h, &fm);
        eval(0, nullptr);  // restore exactly
        double fd = 0;
        for (int i = 0; i < n; ++i) fd += w[i] * (fp[i] - fm[i]) / (2 * h);
        EXPECT_NEAR(dp[k], fd, tol) << "p " << sp.name;
      }
      // Called twice: the same gradient (nothing left over from the first call).
      std::vector<double> dq2(nq, 0.0);
      ObjectiveGradient g2{dq2.data(), nullptr, nullptr, nullptr, nullptr};
      terminal ? obj.TerminalGradient(p.view(), w.data(), &g2) : obj.IntegrandGradient(p.view(), w.data(), &g2);
      for (int k = 0; k < nq; ++k) EXPECT_EQ(dq2[k], dq[k]);
    }
  }
}

TEST(ModelObjectives, PendulumGradientsMatchCentralDifferences) { CheckGradients(kPendulum, true); }
TEST(ModelObjectives, TwoBodyGradientsMatchCentralDifferences) { CheckGradients(kTwoBodies, false); }
TEST(ModelObjectives, MotionReactionTorqueGradientsMatchCentralDifferences) { CheckGradients(kMotion, false); }

// Values: the expressions over the measures as computed independently.
TEST(ModelObjectives, ValuesAreTheExpressionsOverTheMeasures) {
  const mbs::Model model = mbs::LoadModelFromString(kPendulum, "m.yaml");
  mbs::MultibodySystem sys(model);
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  std::vector<int> kept;
  for (int r = 0; r < nc; ++r) kept.push_back(r);
  ModelObjectives obj(model, sys, kept);
  ASSERT_EQ(obj.num_objectives(), 3);
  EXPECT_EQ(obj.names()[1], "E");
  EXPECT_TRUE(obj.has_integral(0) && obj.has_terminal(0));
  EXPECT_TRUE(obj.has_integral(1) && !obj.has_terminal(1));
  EXPECT_TRUE(!obj.has_integral(2) && obj.has_terminal(2));
  EXPECT_TRUE(obj.depends_on_acceleration());
  EXPECT_TRUE(obj.depends_on_multipliers());
  std::mt19937 rng(5);
  // A state near the initial one, so that the angle is away from +-pi.
  Point p = RandomPoint(nq, nc, rng);
  std::vector<double> m(model.measures.size());
  sys.EvaluateMeasures(p.t, p.q.data(), p.v.data(), p.a.data(), m.data());
  mbs::ReactionMeasures r(model);
  r.Evaluate(p.t, p.q.data(), p.lambda.data(), m.data());
  std::vector<double> q0, v0;
  sys.InitialState(q0, v0);
  std::vector<double> m0(model.measures.size());
  sys.EvaluateMeasures(0, q0.data(), v0.data(), nullptr, m0.data());
  const double drop = m[1] - m0[1];
  const double ut = model.splines[0].spline.Evaluate(p.t);
  std::vector<double> g(3), phi(3);
  ASSERT_EQ(obj.Integrand(p.view(), g.data()), 0);
  ASSERT_EQ(obj.Terminal(p.view(), phi.data()), 0);
  EXPECT_NEAR(g[0], 0.5 * (0.7 * m[0] * m[0] + m[3] * m[3]) + ut * drop, 1e-12);
  EXPECT_NEAR(g[1], m[6] * m[6] + m[7] * m[5] + 1.5 * p.t, 1e-10);
  EXPECT_EQ(g[2], 0.0);
  EXPECT_NEAR(phi[0], std::sin(m[2]) + 0.7 * m[4], 1e-12);
  EXPECT_EQ(phi[1], 0.0);
  EXPECT_NEAR(phi[2], m[0] * m[6] + model.splines[0].spline.Evaluate(0.7), 1e-12);
}

}  // namespace
}  // namespace mbdae::sens
