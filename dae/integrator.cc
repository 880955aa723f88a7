#include "dae/integrator.h"

#include <cstdio>

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
