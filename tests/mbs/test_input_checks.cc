// Input checks of the loaders and of the multibody system (issue 11, part 4): inertias
// no rigid body can have, rotation axes of extreme length, force values that are not
// finite (at the initial state: a ModelError with the force's file and line; during a
// run: a fatal evaluation error naming the element, the value and the time), simulation
// settings the integrators cannot use, and user-force library paths.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "mbs/freedyn.h"
#include "mbs/kinematics.h"
#include "mbs/loader.h"
#include "tests/support/load_error.h"
#include "mbs/system.h"
#include "mbs/user_force.h"

namespace mbdae::mbs {
namespace {

using testing::LoadError;

std::string FreeDynError(const std::string& text) {
  try {
    LoadFreeDynModelFromString(text, "m.fds");
  } catch (const ModelError& e) {
    return e.what();
  }
  return "";
}

std::string Body(const std::string& inertia) {
  return "format: 1\nbodies:\n  - name: b\n    mass: 1\n    inertia: " + inertia + "\n";
}

TEST(InertiaCheck, TriangleInequalityOnPrincipalMoments) {
  std::string why;
  EXPECT_TRUE(IsPhysicalInertia(Vec3(1, 2, 3).asDiagonal(), &why)) << why;  // 3 = 1 + 2: a flat plate
  EXPECT_TRUE(IsPhysicalInertia(Mat3::Zero(), &why)) << why;                 // a point mass
  EXPECT_TRUE(IsPhysicalInertia(Vec3(0, 0.0075, 0.0075).asDiagonal(), &why)) << why;  // a thin rod
  EXPECT_FALSE(IsPhysicalInertia(Vec3(1, 1, 3).asDiagonal(), &why));
  EXPECT_EQ(why,
            "inertia violates the triangle inequality: principal moments 1, 1, 3; the largest exceeds the sum "
            "of the other two (2) by 1, and no rigid body has such an inertia (allowed: 1e-3 of the largest + "
            "1e-12 kg m^2)");
  // The largest moment need not be the last one.
  EXPECT_FALSE(IsPhysicalInertia(Vec3(3, 1, 1).asDiagonal(), nullptr));
  EXPECT_FALSE(IsPhysicalInertia(Vec3(1, 5, 1).asDiagonal(), nullptr));
  // Not positive semi-definite: the earlier message.
  EXPECT_FALSE(IsPhysicalInertia(Vec3(1, 1, -1e-5).asDiagonal(), &why));
  EXPECT_EQ(why, "inertia is not positive semi-definite (smallest eigenvalue -1e-05)");
  // Not finite.
  EXPECT_FALSE(IsPhysicalInertia(Vec3(1, NAN, 1).asDiagonal(), &why));
  EXPECT_EQ(why, "inertia is not finite");
}

TEST(InertiaCheck, Tolerance) {
  // A flat plate or a rod written with rounded values: excess up to 1e-3 of the largest.
  EXPECT_TRUE(IsPhysicalInertia(Vec3(0.0833, 0.0833, 0.1667).asDiagonal(), nullptr));  // excess 6e-4 I3
  EXPECT_TRUE(IsPhysicalInertia(Vec3(0, 0.0075, 0.0075075).asDiagonal(), nullptr));     // excess 1e-3 I3 - 0
  EXPECT_FALSE(IsPhysicalInertia(Vec3(0, 0.0075, 0.00751).asDiagonal(), nullptr));      // excess 1.3e-3 I3
  // The absolute part: moments at the round-off level of a point mass.
  EXPECT_TRUE(IsPhysicalInertia(Vec3(0, 0, 1e-12).asDiagonal(), nullptr));
  EXPECT_FALSE(IsPhysicalInertia(Vec3(0, 0, 3e-12).asDiagonal(), nullptr));
  // Just inside and just outside the bound I3 - (I1 + I2) = 1e-3 I3 + 1e-12.
  const double i3 = 1.0, bound = 1e-3 * i3 + 1e-12;
  EXPECT_TRUE(IsPhysicalInertia(Vec3(0.3, i3 - 0.3 - 0.99 * bound, i3).asDiagonal(), nullptr));
  EXPECT_FALSE(IsPhysicalInertia(Vec3(0.3, i3 - 0.3 - 1.01 * bound, i3).asDiagonal(), nullptr));
}

TEST(InertiaCheck, FullTensorByEigenvalues) {
  // The diagonal [2, 2, 2] is fine, but Ixy = 1.9 gives the principal moments 0.1, 2, 3.9.
  Mat3 J = Vec3(2, 2, 2).asDiagonal();
  J(0, 1) = J(1, 0) = 1.9;
  std::string why;
  EXPECT_FALSE(IsPhysicalInertia(J, &why));
  EXPECT_NE(why.find("principal moments 0.1, 2, 3.9"), std::string::npos) << why;
  // A rotated valid tensor stays valid.
  const Mat3 R = RotationMatrix(QuaternionFromAxisAngle(Vec3(1, 2, 3), 0.7));
  EXPECT_TRUE(IsPhysicalInertia(R * Vec3(1, 2, 2.9).asDiagonal() * R.transpose(), &why)) << why;
}

TEST(InertiaCheck, LoadersRefuseWithFileAndLine) {
  EXPECT_EQ(LoadError(Body("[1, 1, 3]")),
            "m.yaml:5:14: body 'b': inertia violates the triangle inequality: principal moments 1, 1, 3; the "
            "largest exceeds the sum of the other two (2) by 1, and no rigid body has such an inertia (allowed: "
            "1e-3 of the largest + 1e-12 kg m^2)");
  EXPECT_NE(LoadError(Body("[2, 2, 2, 1.9, 0, 0]")).find("m.yaml:5:14: body 'b': inertia violates"), std::string::npos);
  EXPECT_EQ(LoadError(Body("[0, 0.0075, 0.0075]")), "");  // a rod
  EXPECT_EQ(LoadError(Body("[0, 0, 0]")), "");            // a point mass
  // A geometry with a density gives a valid inertia; an explicit one replaces it and is checked.
  EXPECT_EQ(LoadError("format: 1\nbodies:\n  - name: b\n    geometry: {shape: box, size: [1, 0.01, 0.01], density: 1}\n"),
            "");
  EXPECT_NE(LoadError("format: 1\nbodies:\n  - name: b\n    geometry: {shape: box, size: [1, 1, 1], density: 1}\n"
                      "    inertia: [1, 1, 3]\n")
                .find("m.yaml:5:14: body 'b': inertia violates the triangle inequality"),
            std::string::npos);

  const std::string fds =
      "Header freeDynHeader\nEndHeader\n%\nBody Rigid_EulerParameter_PAI\n\tID = 7f000001\n\tName = plate\n"
      "\tMass = 1.0\n\tLocationCenterMass = 0,0,0\n\tInertia = 1.0,1.0,3.0\n\tOrientationPAI = 1,0,0,0,1,0,0,0,1\n"
      "EndBody\n%\n";
  EXPECT_EQ(FreeDynError(fds),
            "m.fds:9:12: Body 'plate': 'Inertia': inertia violates the triangle inequality: principal moments 1, "
            "1, 3; the largest exceeds the sum of the other two (2) by 1, and no rigid body has such an inertia "
            "(allowed: 1e-3 of the largest + 1e-12 kg m^2)");
}

TEST(AxisAngle, ExtremeAxisLengths) {
  // [1e200, 1e200, 0]: |axis| overflows when computed directly; the rotation is the one
  // about [1, 1, 0].
  const Quat big = QuaternionFromAxisAngle(Vec3(1e200, 1e200, 0), 1.0);
  const Quat ref = QuaternionFromAxisAngle(Vec3(1, 1, 0), 1.0);
  EXPECT_LT((big - ref).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_NEAR(ref[0], std::cos(0.5), 1e-15);
  EXPECT_NEAR(ref[1], std::sin(0.5) / std::sqrt(2.0), 1e-15);
  // [1e-200, 0, 0]: |axis|^2 underflows to 0; it is the x axis.
  const Quat tiny = QuaternionFromAxisAngle(Vec3(1e-200, 0, 0), 1.0);
  EXPECT_LT((tiny - Quat(std::cos(0.5), std::sin(0.5), 0, 0)).cwiseAbs().maxCoeff(), 1e-15);
  const Quat denormal = QuaternionFromAxisAngle(Vec3(0, -5e-324, 0), 1.0);
  EXPECT_LT((denormal - Quat(std::cos(0.5), 0, -std::sin(0.5), 0)).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_THROW(QuaternionFromAxisAngle(Vec3::Zero(), 1.0), std::invalid_argument);
  EXPECT_THROW(QuaternionFromAxisAngle(Vec3(INFINITY, 0, 0), 1.0), std::invalid_argument);
  EXPECT_THROW(QuaternionFromAxisAngle(Vec3(NAN, 0, 0), 1.0), std::invalid_argument);

  // Through the loader.
  const Model m = LoadModelFromString(
      "format: 1\nbodies:\n  - {name: a, mass: 1, inertia: [1, 1, 1], orientation: {axis: [1e200, 1e200, 0], angle: 1}}\n"
      "  - {name: b, mass: 1, inertia: [1, 1, 1], orientation: {axis: [1e-200, 0, 0], angle: 1}}\n",
      "m.yaml");
  EXPECT_LT((m.bodies[0].orientation - ref).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((m.bodies[1].orientation - tiny).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(LoadError("format: 1\nbodies:\n  - {name: a, mass: 1, orientation: {axis: [0, 0, 0], angle: 1}}\n"),
            "m.yaml:3:44: body 'a': 'orientation': the rotation axis must not be zero");
}

TEST(SimulationSettings, RefusedWithFileAndLine) {
  const std::string head = "format: 1\nbodies:\n  - {name: b, mass: 1, inertia: [1, 1, 1]}\nsimulation:\n";
  EXPECT_EQ(LoadError(head + "  t_end: 1\n  output_step: 1e-12\n"),
            "m.yaml:6:16: simulation: t_end 1 with output_step 1e-12 gives 1e+12 output rows; at most 1e+08 "
            "(make output_step larger)");
  // The default output step (0.01) with a long t_end: the line of t_end.
  EXPECT_EQ(LoadError(head + "  t_end: 1e9\n"),
            "m.yaml:5:10: simulation: t_end 1000000000 with output_step 0.01 gives 1e+11 output rows; at most "
            "1e+08 (make output_step larger)");
  EXPECT_EQ(LoadError(head + "  t_end: 1\n  output_step: 1e-8\n"), "");  // exactly 1e8 rows
  EXPECT_EQ(LoadError(head + "  hht: {step: 1e-13}\n"),
            "m.yaml:5:15: simulation: hht step 1e-13 is smaller than the smallest step of the HHT integrator, "
            "1e-12");
  EXPECT_EQ(LoadError(head + "  hht: {step: 1e-12}\n"), "");

  const std::string fds =
      "Header freeDynHeader\nEndHeader\n%\nBody Rigid_EulerParameter_PAI\n\tID = 7f000001\n\tName = ball\n"
      "\tMass = 1.0\n\tLocationCenterMass = 0,0,0\n\tInertia = 1,1,1\n\tOrientationPAI = 1,0,0,0,1,0,0,0,1\n"
      "EndBody\n%\nSimulation Dynamic\n\tSimulationTimeEnd = 1.0\n\tOutputTimeStepSize = ";
  EXPECT_EQ(FreeDynError(fds + "1e-12\nEndSimulation\n%\n"),
            "m.fds:15:23: Simulation Dynamic: 'OutputTimeStepSize': SimulationTimeEnd 1 with OutputTimeStepSize 1e-12 "
            "gives 1e+12 output rows; at most 1e+08 (make OutputTimeStepSize larger)");
  EXPECT_EQ(FreeDynError(fds + "0.01\nEndSimulation\n%\nSolver HHT\n\tSolverMaxTimeStep = 1e-13\nEndSolver\n%\n"),
            "m.fds:19:22: Solver HHT: 'SolverMaxTimeStep': the HHT step 1e-13 (the smaller of SolverMaxTimeStep and "
            "OutputTimeStepSize) is smaller than the smallest step of the HHT integrator, 1e-12");
}

// A free body pushed by a force whose value is given; gravity-free.
Model PushedBody(const std::string& value, const std::string& extra = "") {
  return LoadModelFromString("format: 1\nbodies:\n  - {name: s, mass: 1, inertia: [1, 1, 1], position: [1, 0, 0]}\n"
                             "measures:\n  - {name: x, type: translational, i: s.cm, component: x, frame: world}\n"
                             "forces:\n  - {name: push, type: force, i: s.cm, value: [\"" + value + "\", 0, 0]}\n" +
                                 extra,
                             "m.yaml");
}

std::string SystemError(const Model& model) {
  try {
    MultibodySystem sys(model);
  } catch (const ModelError& e) {
    return e.what();
  }
  return "";
}

TEST(ForceValues, NotFiniteAtTheInitialStateIsAModelError) {
  // Values without measures: refused by the loader where they are written.
  const std::string head = "format: 1\nbodies:\n  - {name: s, mass: 1, inertia: [1, 1, 1], position: [1, 0, 0]}\n"
                           "forces:\n  - {name: push, type: force, i: s.cm, value: [";
  EXPECT_EQ(LoadError(head + "\"sqrt(-1)\", 0, 0]}\n"),
            "m.yaml:5:48: force 'push': 'value' entry 1 ('sqrt(-1)') is nan at the initial state of the model file "
            "(t = 0); a force value must be finite");
  EXPECT_EQ(LoadError(head + "0, \"-1/t\", 0]}\n"),
            "m.yaml:5:51: force 'push': 'value' entry 2 ('-1/t') is -inf at the initial state of the model file "
            "(t = 0); a force value must be finite");
  EXPECT_EQ(LoadError(head + "0, 0, \"sqrt(1 - t)\"]}\n"), "");
  EXPECT_EQ(LoadError("format: 1\nbodies:\n  - {name: s, mass: 1, inertia: [1, 1, 1], position: [1, 0, 0]}\n"
                      "forces:\n  - {name: k, type: spring_damper, i: s.cm, stiffness: 1, free_length: 0, damping: log(0)}\n"),
            "m.yaml:5:84: force 'k': 'damping' ('log(0)') is -inf at the initial state of the model file (t = 0); "
            "a force value must be finite");
  // Values over measures: refused when the system is built, at the force.
  EXPECT_EQ(SystemError(PushedBody("1/(x - 1)")),
            "m.yaml:7:5: force 'push': 'value' entry 1 ('1/(x - 1)') is inf at the initial state of the model "
            "file (t = 0); a force value must be finite");
  EXPECT_EQ(SystemError(PushedBody("sqrt(x - 1.5)")),
            "m.yaml:7:5: force 'push': 'value' entry 1 ('sqrt(x - 1.5)') is nan at the initial state of the model "
            "file (t = 0); a force value must be finite");
  EXPECT_EQ(SystemError(PushedBody("1/x")), "");
  const Model spring = LoadModelFromString(
      "format: 1\nbodies:\n  - {name: s, mass: 1, inertia: [1, 1, 1], position: [1, 0, 0]}\n"
      "measures:\n  - {name: x, type: translational, i: s.cm, component: x, frame: world}\n"
      "forces:\n  - {name: k, type: spring_damper, i: s.cm, stiffness: 1, free_length: 0, damping: log(x - 1)}\n",
      "m.yaml");
  EXPECT_EQ(SystemError(spring),
            "m.yaml:7:5: force 'k': 'damping' ('log(x - 1)') is -inf at the initial state of the model file (t = 0); "
            "a force value must be finite");
}

TEST(ForceValues, NotFiniteDuringTheRunIsFatalAndNamed) {
  const Model model = PushedBody("sqrt(0.5 - t)");
  MultibodySystem sys(model);
  std::vector<double> q, v;
  sys.InitialState(q, v);
  std::vector<double> f(sys.num_coordinates());
  dae::EvalInput in;
  in.q = q.data();
  in.v = v.data();
  dae::EvalOutput out;
  out.force = f.data();
  in.t = 0.25;
  ASSERT_EQ(sys.Evaluate(in, out), 0) << sys.last_error();
  EXPECT_NEAR(f[0], std::sqrt(0.25), 1e-15);
  in.t = 0.625;
  EXPECT_LT(sys.Evaluate(in, out), 0);
  EXPECT_EQ(std::string(sys.last_error()), "force 'push': 'value' entry 1 ('sqrt(0.5 - t)') is nan at t = 0.625");
  // Called twice: the same answer, and a good state afterwards evaluates again.
  EXPECT_LT(sys.Evaluate(in, out), 0);
  EXPECT_EQ(std::string(sys.last_error()), "force 'push': 'value' entry 1 ('sqrt(0.5 - t)') is nan at t = 0.625");
  in.t = 0.5;
  EXPECT_EQ(sys.Evaluate(in, out), 0) << sys.last_error();
  EXPECT_EQ(f[0], 0.0);
}

TEST(UserForceLibrary, FileNameAloneIsNotSearchedOnTheLibraryPath) {
  // "libm.so.6" exists on the system's library path; as a file name alone it means the
  // file in the current folder, which does not exist here.
  try {
    UserForceLibrary lib("libm.so.6");
    FAIL() << "loaded " << lib.path();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("user force library './libm.so.6': cannot be loaded"), std::string::npos)
        << e.what();
  }
  // Through the loader, a model in the current folder: './libm.so.6'.
  const std::string model =
      "format: 1\nbodies:\n  - {name: s, mass: 1, inertia: [1, 1, 1]}\n"
      "forces:\n  - {name: u, type: user, library: libm.so.6, function: f, i: s.cm}\n";
  const std::string error = LoadError(model);
  EXPECT_NE(error.find("m.yaml:5:36: force 'u': cannot use the library (relative paths are relative to the model "
                       "file): user force library './libm.so.6': cannot be loaded"),
            std::string::npos)
      << error;
  // In another folder: beside that model.
  EXPECT_NE(LoadError(model, "models/m.yaml").find("user force library 'models/libm.so.6': cannot be loaded"),
            std::string::npos);
}

TEST(UserForceLibrary, LoadedOnlyAfterTheFileIsChecked) {
  // The library does not exist: a model with a mistake after the forces reports that
  // mistake, not the library (which is not opened).
  const std::string model =
      "format: 1\nbodies:\n  - {name: s, mass: 1, inertia: [1, 1, 1]}\n"
      "forces:\n  - {name: u, type: user, library: ./no_such_library.so, function: f, i: s.cm}\n"
      "simulation: {t_end: -1}\n";
  EXPECT_EQ(LoadError(model), "m.yaml:6:21: simulation: t_end must be > 0, got -1");
  EXPECT_NE(LoadError(model.substr(0, model.find("simulation"))).find("no_such_library.so"), std::string::npos);
}

}  // namespace
}  // namespace mbdae::mbs
