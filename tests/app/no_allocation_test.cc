// The step loops of both integrators allocate nothing: after the first output interval
// (which sizes every work array), advancing further performs no heap allocation through
// operator new, neither in the integrators nor in the multibody system they evaluate.
// Andrews' squeezer exercises every part: redundant equations (KeepConstraints), a
// spring, a torque, revolute joints, Euler parameters.
#include <gtest/gtest.h>

#include <cstdlib>
#include <new>

#include "dae/hht.h"
#include "dae/ida.h"
#include "driver/simulation.h"
#include "mbs/loader.h"

#include "tests/support/count_allocations.h"

namespace mbdae {
namespace {

driver::Assembly AndrewsAssembly(mbs::Model* model) {
  *model = mbs::LoadModel(std::string(MBDAE_SOURCE_DIR) + "/verification/andrews/andrews.yaml");
  return driver::Assemble(*model);
}

long AllocationsWhileAdvancing(dae::Integrator& integ, double t1, double t2) {
  EXPECT_TRUE(integ.AdvanceTo(t1)) << integ.summary().BriefReport();
  const long before = g_allocations;
  EXPECT_TRUE(integ.AdvanceTo(t2)) << integ.summary().BriefReport();
  return g_allocations - before;
}

TEST(NoAllocation, HhtFixedStep) {
  mbs::Model model;
  driver::Assembly a = AndrewsAssembly(&model);
  dae::HhtOptions opt;
  opt.step = 1e-5;
  auto integ = dae::MakeHhtIntegrator(*a.kept_system, opt);
  integ->Initialize(a.x0);
  EXPECT_EQ(AllocationsWhileAdvancing(*integ, 1e-3, 3e-3), 0);
  EXPECT_GT(integ->summary().steps_accepted, 250);
}

TEST(NoAllocation, HhtAdaptive) {
  mbs::Model model;
  driver::Assembly a = AndrewsAssembly(&model);
  dae::HhtOptions opt;
  opt.step = 1e-6;
  opt.adaptive = true;
  opt.tolerance = 1e-6;
  auto integ = dae::MakeHhtIntegrator(*a.kept_system, opt);
  integ->Initialize(a.x0);
  EXPECT_EQ(AllocationsWhileAdvancing(*integ, 1e-3, 3e-3), 0);
}

TEST(NoAllocation, IdaCallbacks) {
  mbs::Model model;
  driver::Assembly a = AndrewsAssembly(&model);
  dae::IdaOptions opt;
  opt.rtol = opt.atol = 1e-8;
  auto integ = dae::MakeIdaIntegrator(*a.kept_system, opt);
  integ->Initialize(a.x0);
  EXPECT_EQ(AllocationsWhileAdvancing(*integ, 1e-3, 3e-3), 0);
  EXPECT_GT(integ->summary().steps_accepted, 10);
}

}  // namespace
}  // namespace mbdae
