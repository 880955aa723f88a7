#include "sensitivities/hht_sensitivity.h"

namespace mbdae::sens {

dae::StepObserver HhtTrajectory::Recorder() {
  return [this](const dae::State& x, double h) {
    t_.push_back(x.t);
    h_.push_back(h);
    q_.insert(q_.end(), x.q.begin(), x.q.end());
    v_.insert(v_.end(), x.v.begin(), x.v.end());
    a_.insert(a_.end(), x.a.begin(), x.a.end());
    lambda_.insert(lambda_.end(), x.lambda.begin(), x.lambda.end());
  };
}

void HhtTrajectory::Clear() {
  for (auto* v : {&t_, &h_, &q_, &v_, &a_, &lambda_}) v->clear();
}

size_t HhtTrajectory::memory() const {
  size_t n = 0;
  for (auto* v : {&t_, &h_, &q_, &v_, &a_, &lambda_}) n += v->capacity() * sizeof(double);
  return n;
}

}  // namespace mbdae::sens
