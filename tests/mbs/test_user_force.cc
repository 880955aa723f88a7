// Tests of mbs/user_force: the example library (examples/user_force) through the C ABI
// against the same spring-damper in C++, its analytic Jacobian against finite
// differences, the finite-difference path against the analytic Jacobian, and every
// error (missing library, missing symbol, ABI version, init and evaluation errors).
#include "mbs/user_force.h"

#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <string>

namespace mbdae::mbs {
namespace {

using Vec3 = Eigen::Vector3d;

MarkerPairKinematics RandomKinematics(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&] { return Vec3(u(rng), u(rng), u(rng)); };
  auto rot = [&] {
    return Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng)).normalized())
        .toRotationMatrix();
  };
  MarkerPairKinematics k;
  k.p_i = vec() + Vec3(1.5, 0, 0);  // keeps |p_i - p_j| away from zero
  k.p_j = vec();
  k.R_i = rot();
  k.R_j = rot();
  k.v_i = 2 * vec();
  k.v_j = 2 * vec();
  k.w_i = 3 * vec();
  k.w_j = 3 * vec();
  return k;
}

// The built-in spring_damper law, written independently in C++.
ForceTorque SpringDamper(double k, double c, double l0, double preload,
                         const MarkerPairKinematics& m) {
  const Vec3 r = m.p_i - m.p_j;
  const double l = r.norm();
  const Vec3 n = r / l;
  const double ld = n.dot(m.v_i - m.v_j);
  ForceTorque y;
  y.force = (-k * (l - l0) - c * ld + preload) * n;
  return y;
}

const std::vector<double> kParams = {4530.0, 12.5, 0.07785, 30.0};

std::shared_ptr<const UserForceLibrary> Example() {
  static auto lib = std::make_shared<const UserForceLibrary>(MBDAE_EXAMPLE_USER_FORCE_LIBRARY);
  return lib;
}

std::string MessageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST(UserForce, ExampleLibraryReproducesSpringDamper) {
  std::mt19937 rng(11);
  UserForce with_jac(Example(), "mbdae_spring_damper", kParams);
  UserForce without_jac(Example(), "mbdae_spring_damper_nojac", kParams);
  EXPECT_EQ(Example()->abi_version(), MBDAE_USER_FORCE_ABI_VERSION);
  double worst = 0;
  for (int trial = 0; trial < 50; ++trial) {
    const MarkerPairKinematics m = RandomKinematics(rng);
    const double t = 0.1 * trial;
    const ForceTorque ref = SpringDamper(kParams[0], kParams[1], kParams[2], kParams[3], m);
    for (const UserForce* f : {&with_jac, &without_jac}) {
      const ForceTorque a = f->Evaluate(t, m);
      const ForceTorque b = f->Evaluate(t, m);  // a second call gives the same
      EXPECT_EQ(a.force, b.force);
      const double err = (a.force - ref.force).norm() / ref.force.norm();
      worst = std::max(worst, err);
      EXPECT_LT(err, 1e-12) << "trial " << trial << " " << f->function();
      EXPECT_EQ(a.torque.norm(), 0.0);
    }
  }
  std::printf("spring-damper through the C ABI vs C++: worst relative difference %.3g\n",
              worst);
}

TEST(UserForce, AnalyticJacobianMatchesFiniteDifferences) {
  std::mt19937 rng(12);
  UserForce f(Example(), "mbdae_spring_damper", kParams);
  double worst = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const MarkerPairKinematics m = RandomKinematics(rng);
    ForceJacobian J;
    const ForceTorque y = f.Evaluate(0.3, m, &J);
    EXPECT_TRUE(f.library_provides_jacobian());
    EXPECT_EQ(y.force, f.Evaluate(0.3, m).force);
    const ForceJacobian fd = FiniteDifferenceJacobian(
        [&](const MarkerPairKinematics& k) { return f.Evaluate(0.3, k); }, m);
    const double err = (J - fd).cwiseAbs().maxCoeff() / J.cwiseAbs().maxCoeff();
    worst = std::max(worst, err);
    EXPECT_LT(err, 1e-8) << "trial " << trial;
    // The law does not depend on the orientations and angular velocities.
    EXPECT_EQ(J.middleCols<3>(kPhiI).norm() + J.middleCols<3>(kWj).norm(), 0.0);
  }
  std::printf("analytic vs central FD: worst relative difference %.3g\n", worst);
}

TEST(UserForce, FiniteDifferencePathMatchesAnalyticJacobian) {
  std::mt19937 rng(13);
  UserForce analytic(Example(), "mbdae_spring_damper", kParams);
  UserForce fd(Example(), "mbdae_spring_damper_nojac", kParams);
  double worst = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const MarkerPairKinematics m = RandomKinematics(rng);
    ForceJacobian Ja, Jf;
    const ForceTorque ya = analytic.Evaluate(1.0, m, &Ja);
    const ForceTorque yf = fd.Evaluate(1.0, m, &Jf);
    EXPECT_FALSE(fd.library_provides_jacobian());
    EXPECT_LT((ya.force - yf.force).norm(), 1e-12 * ya.force.norm());
    const double err = (Ja - Jf).cwiseAbs().maxCoeff() / Ja.cwiseAbs().maxCoeff();
    worst = std::max(worst, err);
    EXPECT_LT(err, 1e-6) << "trial " << trial;
  }
  std::printf("FD path vs analytic: worst relative difference %.3g\n", worst);
}

TEST(UserForce, MovedElementKeepsItsState) {
  std::mt19937 rng(14);
  const MarkerPairKinematics m = RandomKinematics(rng);
  UserForce a(Example(), "mbdae_spring_damper", kParams);
  const ForceTorque y = a.Evaluate(0, m);
  UserForce b(std::move(a));
  EXPECT_EQ(b.Evaluate(0, m).force, y.force);
  UserForce c(Example(), "mbdae_spring_damper", {1, 0, 0, 0});
  c = std::move(b);
  EXPECT_EQ(c.Evaluate(0, m).force, y.force);
}

TEST(UserForce, MissingLibrary) {
  const std::string msg = MessageOf([] { UserForceLibrary lib("no/such/libforce.so"); });
  EXPECT_NE(msg.find("user force library 'no/such/libforce.so'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cannot be loaded"), std::string::npos) << msg;
}

TEST(UserForce, MissingSymbol) {
  const std::string msg = MessageOf([] { UserForce f(Example(), "no_such_force", {}); });
  EXPECT_NE(msg.find("symbol 'no_such_force' not found"), std::string::npos) << msg;
  EXPECT_NE(msg.find(MBDAE_EXAMPLE_USER_FORCE_LIBRARY), std::string::npos) << msg;
}

TEST(UserForce, WrongAbiVersion) {
  const std::string msg = MessageOf([] { UserForceLibrary lib(MBDAE_BAD_ABI_LIBRARY); });
  EXPECT_NE(msg.find("ABI version 999"), std::string::npos) << msg;
  EXPECT_NE(msg.find("supports version 1"), std::string::npos) << msg;
  EXPECT_NE(msg.find(MBDAE_BAD_ABI_LIBRARY), std::string::npos) << msg;
}

TEST(UserForce, NoVersionFunction) {
  const std::string msg = MessageOf([] { UserForceLibrary lib(MBDAE_NO_VERSION_LIBRARY); });
  EXPECT_NE(msg.find("symbol 'mbdae_user_force_abi_version' not found"), std::string::npos)
      << msg;
}

TEST(UserForce, InitErrorWithMessage) {
  const std::string msg =
      MessageOf([] { UserForce f(Example(), "mbdae_spring_damper", {1.0, 2.0}); });
  EXPECT_NE(msg.find("user force 'mbdae_spring_damper'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("mbdae_spring_damper_init returned 1"), std::string::npos) << msg;
  EXPECT_NE(msg.find("expected 4 parameters [k, c, l0, preload], got 2"), std::string::npos)
      << msg;
}

TEST(UserForce, EvaluationErrorWithMessage) {
  MarkerPairKinematics m;  // both markers at the origin: zero spring length
  for (const char* name : {"mbdae_spring_damper", "mbdae_spring_damper_nojac"}) {
    UserForce f(Example(), name, kParams);
    const std::string msg = MessageOf([&] { f.Evaluate(2.5, m); });
    EXPECT_NE(msg.find(std::string("user force '") + name + "'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("returned 2 at t = 2.5: spring length zero"), std::string::npos)
        << msg;
  }
  // Wrong parameter count seen at evaluation (no init for the _nojac export).
  UserForce g(Example(), "mbdae_spring_damper_nojac", {1.0});
  std::mt19937 rng(15);
  const std::string msg = MessageOf([&] { g.Evaluate(0, RandomKinematics(rng)); });
  EXPECT_NE(msg.find("returned 1"), std::string::npos) << msg;
  EXPECT_NE(msg.find("got 1"), std::string::npos) << msg;
}

TEST(UserForce, OptionsValidation) {
  UserForce::Options o;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error));
  o.fd_relative_step = 0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("fd_relative_step"), std::string::npos);
  EXPECT_THROW(UserForce(Example(), "mbdae_spring_damper", kParams, o), std::invalid_argument);
}

}  // namespace
}  // namespace mbdae::mbs
