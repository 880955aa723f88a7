#include "dae/integrator.h"

#include <cstdio>
#include <stdexcept>

namespace mbdae::dae {

namespace {
const char* StatusName(Summary::Status s) {
  switch (s) {
    case Summary::Status::kNotStarted: return "not started";
    case Summary::Status::kRunning: return "running";
    case Summary::Status::kDone: return "done";
    case Summary::Status::kFailed: return "FAILED";
  }
  return "?";
}
}  // namespace

void Integrator::SetQuadrature(Quadrature) {
  throw std::logic_error(name() + ": quadratures are not supported");
}

void Integrator::SetStepObserver(StepObserver) {
  throw std::logic_error(name() + ": step observers are not supported");
}

const CscPattern& MechanicalSystem::parameter_pattern(ParameterMatrix m) const {
  // No parameters: nq x 0 or nc x 0.
  CscPattern& p = no_parameters_[static_cast<int>(m)];
  const bool constraint_rows = m == ParameterMatrix::kConstraintDp ||
                               m == ParameterMatrix::kConstraintVelDp ||
                               m == ParameterMatrix::kAccRhsDp;
  p.rows = constraint_rows ? num_constraints() : num_coordinates();
  p.cols = 0;
  return p;
}

std::string Summary::BriefReport() const {
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "%s at t = %.9g: %ld steps accepted, %ld rejected, %ld Newton iterations, "
                "%ld Jacobians, %ld factorisations, %ld residuals, last h = %.3g",
                StatusName(status), t_reached, steps_accepted, steps_rejected, newton_iterations,
                jacobian_evaluations, factorizations, residual_evaluations, h_last);
  std::string s = buf;
  if (!message.empty()) s += " (" + message + ")";
  return s;
}

}  // namespace mbdae::dae
