// The matrices of a dae::MechanicalSystem at one point, with the buffers to hold them:
// what the sensitivity sweeps evaluate at every stored step. Allocated once.
#pragma once

#include <string>
#include <vector>

#include "dae/mechanical_system.h"
#include "dae/sparse.h"

namespace mbdae::sens {

class SystemMatrices {
 public:
  explicit SystemMatrices(dae::MechanicalSystem& system);

  // Which outputs the next Evaluate fills.
  struct Request {
    bool force = false, constraint = false, constraint_dt = false, acc_rhs = false;
    bool matrices[dae::kNumMatrices] = {false, false, false, false, false, false, false};
    bool parameters[dae::kNumParameterMatrices] = {false, false, false, false, false, false};
    void All() {
      force = constraint = constraint_dt = acc_rhs = true;
      for (bool& b : matrices) b = true;
      for (bool& b : parameters) b = true;
    }
  };
  // Returns the system's code (0 success); *error gets its message on failure.
  int Evaluate(const Request& request, double t, const double* q, const double* v,
               const double* a, const double* w, std::string* error);

  // y += s * A x and y += s * A^T x for the last evaluated matrices.
  void Mul(dae::Matrix m, double s, const double* x, double* y) const {
    dae::MultiplyAdd(system_.pattern(m), mat_[static_cast<int>(m)].data(), s, x, y);
  }
  void MulT(dae::Matrix m, double s, const double* x, double* y) const {
    dae::MultiplyTransposeAdd(system_.pattern(m), mat_[static_cast<int>(m)].data(), s, x, y);
  }
  void Mul(dae::ParameterMatrix m, double s, const double* x, double* y) const {
    dae::MultiplyAdd(system_.parameter_pattern(m), par_[static_cast<int>(m)].data(), s, x, y);
  }
  void MulT(dae::ParameterMatrix m, double s, const double* x, double* y) const {
    dae::MultiplyTransposeAdd(system_.parameter_pattern(m), par_[static_cast<int>(m)].data(), s,
                              x, y);
  }
  // Column k of a parameter matrix, added into y with scale s.
  void AddColumn(dae::ParameterMatrix m, int k, double s, double* y) const;

  const std::vector<double>& values(dae::Matrix m) const { return mat_[static_cast<int>(m)]; }
  const std::vector<double>* all_values() const { return mat_; }  // by dae::Matrix index
  const std::vector<double>& force() const { return force_; }
  const std::vector<double>& constraint() const { return constraint_; }
  const std::vector<double>& constraint_dt() const { return constraint_dt_; }
  const std::vector<double>& acc_rhs() const { return acc_rhs_; }

 private:
  dae::MechanicalSystem& system_;
  std::vector<double> mat_[dae::kNumMatrices];
  std::vector<double> par_[dae::kNumParameterMatrices];
  std::vector<double> force_, constraint_, constraint_dt_, acc_rhs_;
};

}  // namespace mbdae::sens
