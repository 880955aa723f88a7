#include "sensitivities/system_matrices.h"

namespace mbdae::sens {

SystemMatrices::SystemMatrices(dae::MechanicalSystem& system) : system_(system) {
  const int nq = system.num_coordinates(), nc = system.num_constraints();
  for (int m = 0; m < dae::kNumMatrices; ++m)
    mat_[m].assign(system.pattern(static_cast<dae::Matrix>(m)).nnz(), 0.0);
  for (int m = 0; m < dae::kNumParameterMatrices; ++m)
    par_[m].assign(system.parameter_pattern(static_cast<dae::ParameterMatrix>(m)).nnz(), 0.0);
  force_.assign(nq, 0.0);
  constraint_.assign(nc, 0.0);
  constraint_dt_.assign(nc, 0.0);
  acc_rhs_.assign(nc, 0.0);
}

int SystemMatrices::Evaluate(const Request& r, double t, const double* q, const double* v,
                             const double* a, const double* w, std::string* error) {
  dae::EvalInput in;
  in.t = t;
  in.q = q;
  in.v = v;
  in.a = a;
  in.w = w;
  dae::EvalOutput out;
  if (r.force) out.force = force_.data();
  if (r.constraint) out.constraint = constraint_.data();
  if (r.constraint_dt) out.constraint_dt = constraint_dt_.data();
  if (r.acc_rhs) out.acc_rhs = acc_rhs_.data();
  for (int m = 0; m < dae::kNumMatrices; ++m)
    if (r.matrices[m]) out.matrix[m] = mat_[m].data();
  if (system_.num_parameters() > 0)
    for (int m = 0; m < dae::kNumParameterMatrices; ++m)
      if (r.parameters[m]) out.parameter_matrix[m] = par_[m].data();
  const int code = system_.Evaluate(in, out);
  if (code != 0 && error) *error = system_.last_error();
  return code;
}

void SystemMatrices::AddColumn(dae::ParameterMatrix m, int k, double s, double* y) const {
  const dae::CscPattern& p = system_.parameter_pattern(m);
  const std::vector<double>& val = par_[static_cast<int>(m)];
  for (int i = p.col_start[k]; i < p.col_start[k + 1]; ++i) y[p.row_index[i]] += s * val[i];
}

}  // namespace mbdae::sens
