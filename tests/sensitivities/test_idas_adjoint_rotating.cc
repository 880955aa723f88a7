// The IDAS adjoint (sensitivities/idas_sensitivity.h) on multibody models whose bodies
// have Euler parameters, through driver::ComputeGradient: the adjoint against the IDAS
// forward method at several tolerances, for terminal objectives over the positions and
// velocities of rotating bodies. The mass matrix of such a body is singular
// (4 G^T J G e = 0), which made the adjoint's terminal values NaN or inconsistent and
// the backward run fail with IDA_CONV_FAIL; and at rtol 1e-11 the replay of a
// checkpoint interval overran IDAS's storage (a segfault).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "driver/gradient.h"
#include "driver/simulation.h"
#include "mbs/loader.h"

namespace mbdae {
namespace {

// tests/app/models/gradient_demo.yaml with objectives over the pendulum bob (a body
// rotating about z) and the block on its rail.
const std::string kDemo = R"Y(format: 1
gravity: [0, -9.81, 0]
parameters: {k: 40.0, c: 0.8, m: 1.5, phi0: 0.3, k2: "2*k"}
splines:
  u: {x: [0, 0.5, 1.0, 1.5, 2.0], y: [0, 1, -0.5, 0.2, 0]}
ground:
  markers:
    wall: {position: [-1, 0, 0]}
    rail: {orientation: {axis: [0, 1, 0], angle: pi/2}}
bodies:
  - name: block
    mass: m
    inertia: [0.1, 0.1, 0.1]
    position: [0.2, 0, 0]
    markers:
      rail: {orientation: {axis: [0, 1, 0], angle: pi/2}}
  - name: bob
    mass: 1
    inertia: [0.01, 0.01, 0.01]
    position: ["sin(phi0)", "-cos(phi0)", 0]
    orientation: {axis: [0, 0, 1], angle: phi0}
    markers:
      pivot: {position: [0, 1, 0]}
measures:
  - {name: x, type: translational, i: block.cm, component: x}
  - {name: bx, type: translational, i: bob.cm, component: x}
  - {name: bvx, type: translational, i: bob.cm, component: x, quantity: velocity}
  - {name: bvy, type: translational, i: bob.cm, component: y, quantity: velocity}
joints:
  - {name: slide, type: prismatic, i: block.rail, j: ground.rail}
  - {name: pivot, type: revolute, i: bob.pivot, j: ground.O}
forces:
  - {name: spring, type: spring_damper, i: block.cm, j: ground.wall, stiffness: k2, damping: c, free_length: 1.1}
  - {name: push, type: force, i: block.cm, frame: world, value: ["3*spline(u, t)", 0, 0]}
objectives:
  - {name: X, terminal: "x + bx", integral: "0.1*x^2"}
  - {name: BX, terminal: "bx"}
  - {name: BV, terminal: "bvx + 0.3*bvy + bx"}
simulation: {t_end: 1.0, output_step: 0.01, integrator: ida}
)Y";

// A heavy top: a body on a spherical joint spinning about its tilted symmetry axis (spin
// w0) and precessing under gravity: all four Euler parameters move, gyroscopic terms.
const std::string kTop = R"Y(format: 1
gravity: [0, 0, -9.81]
parameters: {m: 2.0, w0: 12.0, tilt: 0.4}
bodies:
  - name: top
    mass: m
    inertia: [0.05, 0.05, 0.02]
    position: ["0.3*sin(tilt)", 0, "0.3*cos(tilt)"]
    orientation: {axis: [0, 1, 0], angle: tilt}
    angular_velocity: ["w0*sin(tilt)", 0, "w0*cos(tilt)"]
    markers:
      tip: {position: [0, 0, -0.3]}
measures:
  - {name: tx, type: translational, i: top.cm, component: x}
  - {name: ty, type: translational, i: top.cm, component: y}
  - {name: tz, type: translational, i: top.cm, component: z}
  - {name: tvy, type: translational, i: top.cm, component: y, quantity: velocity}
joints:
  - {name: ball, type: spherical, i: top.tip, j: ground.O}
objectives:
  - {name: P, terminal: "tx + 2*ty - tz"}
  - {name: PV, terminal: "ty + 0.1*tvy", integral: "tx^2"}
simulation: {t_end: 0.5, output_step: 0.01, integrator: ida}
)Y";

driver::GradientResult Gradient(const mbs::Model& model, const std::vector<std::string>& wrt,
                                driver::GradientMethod method, double rtol) {
  driver::SettingsOverrides o;
  o.ida_rtol = rtol;
  o.ida_atol = rtol * 1e-2;
  const mbs::SimulationSettings s = driver::ResolveSettings(model.simulation, o);
  driver::GradientRequest request;
  request.wrt = wrt;
  request.method = method;
  return driver::ComputeGradient(model, s, request, {});
}

// Per objective, max_k |adjoint - forward| / max_k |forward|; the largest over the
// objectives.
double AdjointForwardDifference(const std::string& text, const std::vector<std::string>& wrt,
                                double rtol) {
  const mbs::Model model = mbs::LoadModelFromString(text, "test.yaml");
  const driver::GradientResult adj = Gradient(model, wrt, driver::GradientMethod::kAdjoint, rtol);
  const driver::GradientResult fwd = Gradient(model, wrt, driver::GradientMethod::kForward, rtol);
  EXPECT_EQ(adj.status, driver::GradientResult::Status::kDone) << "rtol " << rtol << ": " << adj.failure_reason;
  EXPECT_EQ(fwd.status, driver::GradientResult::Status::kDone) << "rtol " << rtol << ": " << fwd.failure_reason;
  if (adj.status != driver::GradientResult::Status::kDone ||
      fwd.status != driver::GradientResult::Status::kDone)
    return INFINITY;
  double worst = 0;
  const int np = static_cast<int>(wrt.size());
  for (size_t i = 0; i < adj.objectives.size(); ++i) {
    double scale = 0, diff = 0;
    for (int k = 0; k < np; ++k) {
      scale = std::max(scale, std::abs(fwd.Gradient(static_cast<int>(i), k)));
      diff = std::max(diff, std::abs(adj.Gradient(static_cast<int>(i), k) - fwd.Gradient(static_cast<int>(i), k)));
      std::printf("rtol %.0e %s d/d%s: adjoint %.12g forward %.12g\n", rtol, adj.objectives[i].c_str(),
                  wrt[k].c_str(), adj.Gradient(static_cast<int>(i), k), fwd.Gradient(static_cast<int>(i), k));
    }
    EXPECT_GT(scale, 0) << adj.objectives[i];
    worst = std::max(worst, diff / scale);
  }
  return worst;
}

// The bound of max|adjoint - forward| / max|forward| at a tolerance: both carry the
// runs' error (the adjoint's forward run also stops only at t_end), which is a few
// hundred rtol here at most (measured below).
double Bound(double rtol) { return 1e3 * rtol; }

TEST(IdasAdjointRotating, PendulumBobTerminalObjectives) {
  // Measured max relative differences: 5.6e-6 (1e-6), 4.7e-7 (1e-8), 1.7e-9 (1e-10),
  // 2.8e-10 (1e-11). Before the fix every one of these failed (IDA_CONV_FAIL), and
  // without fresh KLU factorisations the run at 1e-11 segfaults in IDASolveB.
  for (double rtol : {1e-6, 1e-8, 1e-10, 1e-11}) {
    const double e = AdjointForwardDifference(kDemo, {"k", "c", "phi0"}, rtol);
    std::printf("gradient demo, rtol %.0e: max relative adjoint-forward %.2e\n", rtol, e);
    EXPECT_LT(e, Bound(rtol)) << "rtol " << rtol;
  }
}

TEST(IdasAdjointRotating, SpinningTopTerminalObjectives) {
  // Measured: 1.8e-5 (1e-6), 5.4e-7 (1e-8), 2.2e-8 (1e-10); IDA_CONV_FAIL before the fix.
  for (double rtol : {1e-6, 1e-8, 1e-10}) {
    const double e = AdjointForwardDifference(kTop, {"m", "w0", "tilt"}, rtol);
    std::printf("spinning top, rtol %.0e: max relative adjoint-forward %.2e\n", rtol, e);
    EXPECT_LT(e, Bound(rtol)) << "rtol " << rtol;
  }
}

}  // namespace
}  // namespace mbdae
