// The DAE interface the integrators see: a constrained second-order mechanical
// system in index-3 form
//
//   M(q) a + C_q(q, t)^T lambda = Q(q, v, t),     C(q, t) = 0,      v = q', a = q''.
//
// The integrators know nothing else of what the system models. Every matrix has a
// sparsity pattern fixed for the lifetime of the object and is filled in place.
#pragma once

#include <vector>

#include "dae/sparse.h"

namespace mbdae::dae {

// The matrices a system emits, each with its own fixed pattern.
enum class Matrix {
  kMass,            // M(q)                               nq x nq
  kMassTimesAccDq,  // d(M(q) a)/dq at fixed a             nq x nq
  kForceDq,         // dQ/dq                               nq x nq
  kForceDv,         // dQ/dv                               nq x nq
  kConstraintDq,    // C_q                                 nc x nq
  kConstraintTDq,   // d(C_q^T w)/dq at fixed w            nq x nq
  kConstraintVelDq  // d(C_q v + C_t)/dq at fixed v        nc x nq
};
constexpr int kNumMatrices = 7;

// Partial derivatives with respect to the system's parameters p (num_parameters() of
// them, fixed for the lifetime of the object: e.g. model parameters and spline
// ordinates chosen when the system was built), for sensitivity analysis. Each is a
// sparse matrix with a fixed pattern (parameter_pattern), filled in place like Matrix.
enum class ParameterMatrix {
  kMassTimesAccDp,   // d(M(q) a)/dp at fixed q, a               nq x np
  kForceDp,          // dQ(q, v, t)/dp at fixed q, v             nq x np
  kConstraintTDp,    // d(C_q^T w)/dp at fixed q, w              nq x np
  kConstraintDp,     // dC(q, t)/dp at fixed q                   nc x np
  kConstraintVelDp,  // d(C_q v + C_t)/dp at fixed q, v          nc x np
  kAccRhsDp          // d gamma/dp at fixed q, v (acc_rhs)       nc x np
};
constexpr int kNumParameterMatrices = 6;

// Where to evaluate. Pointers may be null when nothing requested needs them.
struct EvalInput {
  double t = 0;
  const double* q = nullptr;  // nq
  const double* v = nullptr;  // nq
  const double* a = nullptr;  // nq, for kMassTimesAccDq
  const double* w = nullptr;  // nc, weights for kConstraintTDq and constraint_transpose_w
};

// What to evaluate: every non-null pointer is filled (vectors by size, matrices by
// the nnz of their pattern, in pattern order).
struct EvalOutput {
  double* force = nullptr;           // Q(q, v, t), nq
  double* constraint = nullptr;      // C(q, t), nc
  double* constraint_dt = nullptr;   // C_t(q, t), nc   (velocity level: C_q v + C_t = 0)
  double* acc_rhs = nullptr;         // gamma, nc: acceleration level C_q a = gamma, i.e.
                                     // gamma = -(C_q v)_q v - 2 C_qt v - C_tt
  // The next two: optional outputs for callers that inspect the equations (the C API);
  // the integrators do not request them, and a system that does not provide one leaves
  // it untouched (callers must check that the system documents it).
  double* force_quadratic_velocity = nullptr;  // Q_v, nq: the part of Q that is the
                                     // velocity-quadratic inertia terms (gyroscopic,
                                     // centripetal); Q - Q_v are the applied forces
  double* constraint_dtt = nullptr;  // C_tt(q, t), nc: the second partial time derivative
  // C_q(q)^T w (nq, w = EvalInput::w) without the matrix C_q: for the integrators'
  // residuals, requested only from a system whose provides_constraint_transpose_w() says
  // it fills it; then it equals MultiplyTransposeAdd(pattern(kConstraintDq), C_q, 1.0, w,
  // zeros) to the last bit (each column's products summed in the same order), so that a
  // run gives the same numbers with or without it.
  double* constraint_transpose_w = nullptr;
  double* matrix[kNumMatrices] = {nullptr, nullptr, nullptr, nullptr,
                                  nullptr, nullptr, nullptr};
  // Parameter derivatives (only for a system with num_parameters() > 0), each by the
  // nnz of its parameter_pattern, in pattern order.
  double* parameter_matrix[kNumParameterMatrices] = {nullptr, nullptr, nullptr,
                                                     nullptr, nullptr, nullptr};
  double*& operator[](Matrix m) { return matrix[static_cast<int>(m)]; }
  double*& operator[](ParameterMatrix m) { return parameter_matrix[static_cast<int>(m)]; }
};

// Return codes of Evaluate, as in SUNDIALS: 0 success, > 0 recoverable (the
// integrator may retry with a smaller step), < 0 unrecoverable.
class MechanicalSystem {
 public:
  virtual ~MechanicalSystem() = default;

  virtual int num_coordinates() const = 0;  // nq
  virtual int num_constraints() const = 0;  // nc
  virtual const CscPattern& pattern(Matrix m) const = 0;

  // First indices of groups of four coordinates that are unit quaternions (Euler
  // parameters, scalar first) whose normalisation is one of the constraints; used by
  // integrators that treat rotations specially (modified HHT). Empty by default.
  virtual const std::vector<int>& quaternion_offsets() const { return no_quaternions_; }

  virtual int Evaluate(const EvalInput& in, EvalOutput& out) = 0;

  // Whether Evaluate fills EvalOutput::constraint_transpose_w (see there). No by default.
  virtual bool provides_constraint_transpose_w() const { return false; }

  // Parameters of the sensitivity analysis: their number (0: the system offers no
  // parameter derivatives, and Evaluate ignores parameter_matrix), names for messages,
  // and the fixed patterns of the ParameterMatrix outputs (nq x np or nc x np).
  virtual int num_parameters() const { return 0; }
  virtual const CscPattern& parameter_pattern(ParameterMatrix m) const;

  // A human-readable reason for the last non-zero return of Evaluate.
  virtual const char* last_error() const { return ""; }

 private:
  std::vector<int> no_quaternions_;
  mutable CscPattern no_parameters_[kNumParameterMatrices];
};

}  // namespace mbdae::dae
