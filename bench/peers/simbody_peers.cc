// Simbody's side of the side-by-side benchmark (bench/peers/README.md, bench/README.md
// "Peers: mbdae against Simbody"). One run per invocation, one JSON line on stdout:
//
//   simbody_peers chain N INTEGRATOR ACCURACY [--step H]
//   simbody_peers fourbar INTEGRATOR ACCURACY [--step H]
//
// INTEGRATOR: rkmerson | rk3 | rkfehlberg | cpodes | verlet | euler | semieuler2.
// ACCURACY: Integrator::setAccuracy (error-controlled integrators); with --step H the
// integrator takes fixed steps H (setFixedStepSize) instead.
//
// Scenes (the same as mbdae's model files):
//  chain N: an open chain of N rods, 0.1 m, 1 kg, box inertia 0.1 x 0.01 x 0.01 m, each a
//    MobilizedBody::Ball (quaternions) on the far end of the previous one, the first on
//    the ground origin; at rest straight along +x; gravity 9.81 m/s^2 in -y; 1 s. Output:
//    the tip (far end of the last rod) at t = 1 s.
//  fourbar: the parallelogram four-bar of verification/singular/fourbar.yaml: two cranks
//    (1 m, 1 kg uniform rods) on MobilizedBody::Pin to the ground 1 m apart, the coupler
//    (1 m, 1 kg) on a Pin at crank 0's top, the loop closed by a Constraint::Ball between
//    the coupler's far end and crank 1's top (its z equation is redundant: Simbody's
//    projection handles rank-deficient constraints). Cranks vertical at t = 0, their tops
//    moving at 1 m/s in +x; 10 s. Output: the crank angle phi (from the upward vertical,
//    clockwise) at 10 s (and at 0.5 s, before the first singular position), and the branch: the largest |crank 1 angle - crank 0 angle| and
//    the largest coupler rotation over rows every 0.01 s (both 0 on the parallelogram
//    branch).
//
// Times: "build" = building the system and realizing the topology and the initial
// state; "solve" = the integration; each as process CPU time and wall time.
#include <time.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "Simbody.h"

namespace {

using namespace SimTK;

double CpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

double WallSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::unique_ptr<Integrator> MakeIntegrator(const std::string& name, MultibodySystem& system) {
  if (name == "rkmerson") return std::make_unique<RungeKuttaMersonIntegrator>(system);
  if (name == "rk3") return std::make_unique<RungeKutta3Integrator>(system);
  if (name == "rkfehlberg") return std::make_unique<RungeKuttaFeldbergIntegrator>(system);
  if (name == "cpodes")
    return std::make_unique<CPodesIntegrator>(system, CPodes::BDF, CPodes::Newton);
  if (name == "verlet") return std::make_unique<VerletIntegrator>(system);
  if (name == "euler") return std::make_unique<ExplicitEulerIntegrator>(system);
  if (name == "semieuler2") return std::make_unique<SemiExplicitEuler2Integrator>(system);
  return nullptr;
}

struct Times {
  double cpu0 = CpuSeconds(), wall0 = WallSeconds();
  double build_cpu = 0, build_wall = 0, solve_cpu = 0, solve_wall = 0;
  void EndBuild() {
    build_cpu = CpuSeconds() - cpu0;
    build_wall = WallSeconds() - wall0;
    cpu0 = CpuSeconds();
    wall0 = WallSeconds();
  }
  void EndSolve() {
    solve_cpu = CpuSeconds() - cpu0;
    solve_wall = WallSeconds() - wall0;
  }
};

void Configure(Integrator& integ, double accuracy, double step) {
  if (step > 0) {
    integ.setFixedStepSize(step);
  } else {
    integ.setAccuracy(accuracy);
  }
}

void PrintCommon(const std::string& scene, const std::string& integrator, double accuracy,
                 double step, const Times& t, const Integrator& integ, bool ok,
                 const std::string& message) {
  std::printf(
      "{\"solver\": \"simbody\", \"scene\": \"%s\", \"integrator\": \"%s\", \"accuracy\": %.3e, "
      "\"step\": %.6e, \"status\": \"%s\", \"message\": \"%s\", \"build_cpu\": %.6f, "
      "\"build_wall\": %.6f, \"solve_cpu\": %.6f, \"solve_wall\": %.6f, \"steps\": %d, "
      "\"attempts\": %d, \"realizations\": %d, \"projections\": %d",
      scene.c_str(), integrator.c_str(), accuracy, step, ok ? "done" : "failed",
      message.c_str(), t.build_cpu, t.build_wall, t.solve_cpu, t.solve_wall,
      integ.getNumStepsTaken(), integ.getNumStepsAttempted(), integ.getNumRealizations(),
      integ.getNumProjections());
}

int RunChain(int n, const std::string& name, double accuracy, double step) {
  const double length = 0.1, mass = 1.0, width = 0.01, t_end = 1.0;
  Times times;
  MultibodySystem system;
  SimbodyMatterSubsystem matter(system);
  GeneralForceSubsystem forces(system);
  Force::UniformGravity gravity(forces, matter, Vec3(0, -9.81, 0));
  const double ixx = mass * (width * width + width * width) / 12;
  const double iyy = mass * (length * length + width * width) / 12;
  // Body frame at the rod's centre, x along the rod.
  Body::Rigid rod(MassProperties(mass, Vec3(0), Inertia(ixx, iyy, iyy)));
  const Vec3 near_end(-length / 2, 0, 0), far_end(length / 2, 0, 0);
  std::vector<MobilizedBody::Ball> bodies;
  bodies.reserve(n);
  bodies.emplace_back(matter.Ground(), Transform(Vec3(0)), rod, Transform(near_end));
  for (int k = 1; k < n; ++k)
    bodies.emplace_back(bodies.back(), Transform(far_end), rod, Transform(near_end));
  State state = system.realizeTopology();  // all balls at the identity: straight along +x
  system.realizeModel(state);
  system.realize(state, Stage::Acceleration);
  auto integ = MakeIntegrator(name, system);
  if (!integ) {
    std::fprintf(stderr, "simbody_peers: unknown integrator '%s'\n", name.c_str());
    return 2;
  }
  Configure(*integ, accuracy, step);
  integ->setFinalTime(t_end);
  integ->initialize(state);
  times.EndBuild();
  bool ok = true;
  std::string message;
  try {
    while (true) {
      const Integrator::SuccessfulStepStatus status = integ->stepTo(t_end, t_end);
      if (status == Integrator::EndOfSimulation || integ->getTime() >= t_end) break;
    }
  } catch (const std::exception& e) {
    ok = false;
    message = "exception (on stderr)";
    std::fprintf(stderr, "simbody_peers: %s\n", e.what());
  }
  if (integ->getTime() < t_end - 1e-12) ok = false;
  times.EndSolve();
  const State& sf = integ->getState();
  system.realize(sf, Stage::Position);
  const Vec3 tip = bodies.back().findStationLocationInGround(sf, far_end);
  PrintCommon("chain" + std::to_string(n), name, accuracy, step, times, *integ, ok, message);
  std::printf(", \"n\": %d, \"t\": %.17g, \"tip\": [%.17g, %.17g, %.17g]}\n", n,
              integ->getTime(), tip[0], tip[1], tip[2]);
  return ok ? 0 : 3;
}

int RunFourbar(const std::string& name, double accuracy, double step) {
  const double L = 1.0, m = 1.0, g = 9.81, v0 = 1.0, t_end = 10.0, row = 0.01;
  Times times;
  MultibodySystem system;
  SimbodyMatterSubsystem matter(system);
  GeneralForceSubsystem forces(system);
  Force::UniformGravity gravity(forces, matter, Vec3(0, -g, 0));
  // Crank: body frame at its pin, the rod along body +y; a uniform slender rod
  // (no moment about its own axis, m L^2 / 12 about the others through its centre).
  const Inertia crank_centre(m * L * L / 12, 0, m * L * L / 12);
  Body::Rigid crank(MassProperties(m, Vec3(0, L / 2, 0),
                                   crank_centre.shiftFromMassCenter(Vec3(0, L / 2, 0), m)));
  // Coupler: body frame at its end A, the rod along body +x.
  const Inertia coupler_centre(0, m * L * L / 12, m * L * L / 12);
  Body::Rigid coupler(MassProperties(m, Vec3(L / 2, 0, 0),
                                     coupler_centre.shiftFromMassCenter(Vec3(L / 2, 0, 0), m)));
  // Pins turn about the z axis of their frames.
  MobilizedBody::Pin crank0(matter.Ground(), Transform(Vec3(0, 0, 0)), crank, Transform());
  MobilizedBody::Pin crank1(matter.Ground(), Transform(Vec3(L, 0, 0)), crank, Transform());
  MobilizedBody::Pin link(crank0, Transform(Vec3(0, L, 0)), coupler, Transform());
  Constraint::Ball loop(crank1, Vec3(0, L, 0), link, Vec3(L, 0, 0));
  State state = system.realizeTopology();
  system.realizeModel(state);
  // At q = 0 the cranks are vertical and the coupler horizontal; u = -v0 / L turns the
  // cranks clockwise (tops moving in +x), the coupler translates (relative rate v0 / L).
  crank0.setOneU(state, 0, -v0 / L);
  crank1.setOneU(state, 0, -v0 / L);
  link.setOneU(state, 0, v0 / L);
  system.realize(state, Stage::Acceleration);
  auto integ = MakeIntegrator(name, system);
  if (!integ) {
    std::fprintf(stderr, "simbody_peers: unknown integrator '%s'\n", name.c_str());
    return 2;
  }
  Configure(*integ, accuracy, step);
  integ->setFinalTime(t_end);
  integ->initialize(state);
  times.EndBuild();
  bool ok = true;
  std::string message;
  double crank_gap = 0, coupler_turn = 0, phi_half = 0;  // phi_half: phi at 0.5 s
  const int rows = static_cast<int>(std::lround(t_end / row));
  try {
    for (int k = 1; k <= rows; ++k) {
      const double tr = k * row;
      while (integ->getTime() < tr - 1e-12) {
        const Integrator::SuccessfulStepStatus status = integ->stepTo(tr, t_end);
        if (status == Integrator::EndOfSimulation) break;
      }
      const State& s = integ->getState();
      const double q0 = crank0.getOneQ(s, 0), q1 = crank1.getOneQ(s, 0),
                   qc = link.getOneQ(s, 0);
      crank_gap = std::max(crank_gap, std::fabs(std::remainder(q1 - q0, 2 * Pi)));
      coupler_turn = std::max(coupler_turn, std::fabs(std::remainder(q0 + qc, 2 * Pi)));
      if (k == rows / 20) phi_half = -q0;
      if (integ->getTime() >= t_end) break;
    }
  } catch (const std::exception& e) {
    ok = false;
    message = "exception (on stderr)";
    std::fprintf(stderr, "simbody_peers: %s\n", e.what());
  }
  if (integ->getTime() < t_end - 1e-12) ok = false;
  times.EndSolve();
  const State& sf = integ->getState();
  const double phi = -crank0.getOneQ(sf, 0);
  PrintCommon("fourbar", name, accuracy, step, times, *integ, ok, message);
  std::printf(
      ", \"t\": %.17g, \"phi\": %.17g, \"phi_0_5\": %.17g, \"max_crank_gap\": %.6e, \"max_coupler_turn\": %.6e, "
      "\"branch\": \"%s\"}\n",
      integ->getTime(), phi, phi_half, crank_gap, coupler_turn,
      (crank_gap < 1e-2 && coupler_turn < 1e-2) ? "parallelogram" : "left");
  return ok ? 0 : 3;
}

int Usage() {
  std::fprintf(stderr,
               "usage: simbody_peers chain N INTEGRATOR ACCURACY [--step H]\n"
               "       simbody_peers fourbar INTEGRATOR ACCURACY [--step H]\n"
               "INTEGRATOR: rkmerson rk3 rkfehlberg cpodes verlet euler semieuler2\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  double step = 0;
  for (size_t i = 0; i < args.size(); ++i)
    if (args[i] == "--step" && i + 1 < args.size()) {
      step = std::atof(args[i + 1].c_str());
      args.erase(args.begin() + i, args.begin() + i + 2);
      break;
    }
  try {
    if (args.size() == 4 && args[0] == "chain") {
      const int n = std::atoi(args[1].c_str());
      if (n < 1) return Usage();
      return RunChain(n, args[2], std::atof(args[3].c_str()), step);
    }
    if (args.size() == 3 && args[0] == "fourbar")
      return RunFourbar(args[1], std::atof(args[2].c_str()), step);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "simbody_peers: %s\n", e.what());
    return 3;
  }
  return Usage();
}
