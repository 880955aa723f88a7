// RAII owners of SUNDIALS objects (context, vectors, matrices, linear solvers, IDA(S)
// memory), shared by the IDA integrator (dae/ida.cc) and the IDAS sensitivities
// (sensitivities/idas_sensitivity.cc). Internal: include only where SUNDIALS is used.
#pragma once

#include <idas/idas.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_linearsolver.h>
#include <sundials/sundials_matrix.h>
#include <sundials/sundials_nvector.h>

#include <memory>
#include <type_traits>

namespace mbdae::dae::sundials {

struct ContextDeleter {
  void operator()(SUNContext c) const { SUNContext_Free(&c); }
};
struct VectorDeleter {
  void operator()(N_Vector v) const { N_VDestroy(v); }
};
struct MatrixDeleter {
  void operator()(SUNMatrix m) const { SUNMatDestroy(m); }
};
struct LinearSolverDeleter {
  void operator()(SUNLinearSolver s) const { SUNLinSolFree(s); }
};
struct IdaMemDeleter {
  void operator()(void* mem) const { IDAFree(&mem); }
};
using ContextPtr = std::unique_ptr<std::remove_pointer_t<SUNContext>, ContextDeleter>;
using VectorPtr = std::unique_ptr<std::remove_pointer_t<N_Vector>, VectorDeleter>;
using MatrixPtr = std::unique_ptr<std::remove_pointer_t<SUNMatrix>, MatrixDeleter>;
using LinearSolverPtr = std::unique_ptr<std::remove_pointer_t<SUNLinearSolver>, LinearSolverDeleter>;
using IdaMemPtr = std::unique_ptr<void, IdaMemDeleter>;

}  // namespace mbdae::dae::sundials
