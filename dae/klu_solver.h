// KLU for a square sparse matrix with a fixed pattern: symbolic analysis once,
// numeric factorisation and refactorisation, solves in place.
#pragma once

#include <memory>
#include <string>

#include "dae/sparse.h"

namespace mbdae::dae {

class KluSolver {
 public:
  explicit KluSolver(const CscPattern& pattern);  // analyses the pattern
  // growth_check_interval: the pivot growth of a refactorisation (klu_rgrowth, about as
  // costly as a tenth to a third of the refactorisation itself) is checked after every
  // growth_check_interval-th refactorisation only (1: after each; the condition estimate
  // is checked after each in any case). For callers that refactor at many nearby values
  // (the explicit integrator's stages) and accept that pivots gone poor are found a few
  // refactorisations late.
  KluSolver(const CscPattern& pattern, int growth_check_interval);
  ~KluSolver();
  KluSolver(const KluSolver&) = delete;
  KluSolver& operator=(const KluSolver&) = delete;

  // Factorises the matrix with these values (pattern order). The first call does a
  // full factorisation; later calls refactor with the same pivots when possible.
  // Returns false with a reason when the matrix is singular.
  bool Factor(const double* values, std::string* error = nullptr);
  // Solves A x = b in place (b has `rows` entries).
  void Solve(double* b) const;
  // Solves A^T x = b in place (klu_tsolve), for adjoint sweeps.
  void SolveTransposed(double* b) const;
  // Reciprocal condition estimate of the last factorisation (klu_rcond).
  double rcond() const;
  long factorizations() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mbdae::dae
