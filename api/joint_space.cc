// Joint space of a tree through the C API (api/mbdae.h, "Joint space"): mbs::JointSpace on
// the handle's model, with a MultibodySystem of the whole model at its current parameters.
// The declarations of the header get default visibility (the library is compiled with
// hidden visibility, and only these functions are exported).
#pragma GCC visibility push(default)
#include "api/mbdae.h"
#pragma GCC visibility pop

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "api/session.h"
#include "mbs/joint_space.h"
#include "mbs/system.h"

namespace {

using mbdae::api::ApiError;

mbdae_model& Handle(mbdae_model* model) {
  if (!model) throw ApiError(MBDAE_ERROR_ARGUMENT, "the model handle is NULL");
  return *model;
}

mbdae::mbs::JointSpace Space(mbdae_model& m) {
  try {
    return mbdae::mbs::JointSpace(*m.model);
  } catch (const std::invalid_argument& e) {
    throw ApiError(MBDAE_ERROR_INPUT, std::string("joint space: ") + e.what());
  }
}

void CheckN(const mbdae::mbs::JointSpace& js, int n) {
  if (n != js.size())
    throw ApiError(MBDAE_ERROR_SIZE, "n (joint coordinates) is " + std::to_string(n) + ", expected " +
                                         std::to_string(js.size()));
}

void NotNull(const void* p, const char* what) {
  if (!p) throw ApiError(MBDAE_ERROR_ARGUMENT, std::string(what) + " is NULL");
}

// Runs `f` with a system of the model; evaluation failures are MBDAE_ERROR_SOLVER.
template <typename F>
void WithSystem(mbdae_model& m, F f) {
  mbdae::mbs::MultibodySystem system(*m.model, m.model->parameter_values());
  try {
    f(system);
  } catch (const std::runtime_error& e) {
    throw ApiError(MBDAE_ERROR_SOLVER, e.what());
  }
}

}  // namespace

extern "C" {

mbdae_status mbdae_joint_count(mbdae_model* model, int* n) {
  return mbdae::api::CallApi([&] {
    NotNull(n, "n");
    *n = Space(Handle(model)).size();
  });
}

mbdae_status mbdae_joint_name(mbdae_model* model, int k, char* buf, size_t size, int* is_angle) {
  return mbdae::api::CallApi([&] {
    const mbdae::mbs::JointSpace js = Space(Handle(model));
    if (k < 0 || k >= js.size())
      throw ApiError(MBDAE_ERROR_ARGUMENT, "joint coordinate " + std::to_string(k) + " does not exist (0 .. " +
                                               std::to_string(js.size() - 1) + ")");
    NotNull(buf, "buf");
    const std::string& name = js.names()[k];
    if (name.size() + 1 > size)
      throw ApiError(MBDAE_ERROR_SIZE, "buf: " + std::to_string(size) + " bytes, the name needs " +
                                           std::to_string(name.size() + 1));
    std::memcpy(buf, name.c_str(), name.size() + 1);
    if (is_angle) *is_angle = js.is_angle(k) ? 1 : 0;
  });
}

mbdae_status mbdae_joint_mass_matrix(mbdae_model* model, const double* q, int n, double* M) {
  return mbdae::api::CallApi([&] {
    mbdae_model& m = Handle(model);
    const mbdae::mbs::JointSpace js = Space(m);
    CheckN(js, n);
    NotNull(q, "q");
    NotNull(M, "M");
    std::vector<double> out(static_cast<size_t>(n) * n);
    WithSystem(m, [&](mbdae::mbs::MultibodySystem& s) { js.MassMatrix(s, q, out.data()); });
    std::copy(out.begin(), out.end(), M);
  });
}

mbdae_status mbdae_inverse_dynamics(mbdae_model* model, double t, const double* q, const double* qd,
                                    const double* qdd, int n, double* tau) {
  return mbdae::api::CallApi([&] {
    mbdae_model& m = Handle(model);
    const mbdae::mbs::JointSpace js = Space(m);
    CheckN(js, n);
    NotNull(q, "q");
    NotNull(tau, "tau");
    std::vector<double> out(n);
    WithSystem(m, [&](mbdae::mbs::MultibodySystem& s) { js.InverseDynamics(s, t, q, qd, qdd, out.data()); });
    std::copy(out.begin(), out.end(), tau);
  });
}

mbdae_status mbdae_joint_bias(mbdae_model* model, double t, const double* q, const double* qd, int n, double* b) {
  return mbdae_inverse_dynamics(model, t, q, qd, nullptr, n, b);
}

mbdae_status mbdae_joint_gravity(mbdae_model* model, double t, const double* q, int n, double* g) {
  return mbdae_inverse_dynamics(model, t, q, nullptr, nullptr, n, g);
}

mbdae_status mbdae_joint_to_absolute(mbdae_model* model, const double* q, const double* qd, int n, double* x,
                                     double* xd, int nq) {
  return mbdae::api::CallApi([&] {
    mbdae_model& m = Handle(model);
    const mbdae::mbs::JointSpace js = Space(m);
    CheckN(js, n);
    NotNull(q, "q");
    const int expected = m.model->num_coordinates();
    if ((x || xd) && nq != expected)
      throw ApiError(MBDAE_ERROR_SIZE, "nq (coordinates) is " + std::to_string(nq) + ", expected " +
                                           std::to_string(expected));
    std::vector<double> a(expected), b(expected);
    js.Absolute(q, qd, nullptr, a.data(), b.data(), nullptr, nullptr);
    if (x) std::copy(a.begin(), a.end(), x);
    if (xd) std::copy(b.begin(), b.end(), xd);
  });
}

mbdae_status mbdae_joint_from_absolute(mbdae_model* model, const double* x, const double* xd, const double* xdd,
                                       int nq, double* q, double* qd, double* qdd, int n) {
  return mbdae::api::CallApi([&] {
    mbdae_model& m = Handle(model);
    const mbdae::mbs::JointSpace js = Space(m);
    CheckN(js, n);
    NotNull(x, "x");
    NotNull(q, "q");
    const int expected = m.model->num_coordinates();
    if (nq != expected)
      throw ApiError(MBDAE_ERROR_SIZE, "nq (coordinates) is " + std::to_string(nq) + ", expected " +
                                           std::to_string(expected));
    std::vector<double> a(n), b(n), c(n);
    js.JointState(x, xd, xdd, nullptr, a.data(), qd ? b.data() : nullptr, qdd ? c.data() : nullptr);
    std::copy(a.begin(), a.end(), q);
    if (qd) std::copy(b.begin(), b.end(), qd);
    if (qdd) std::copy(c.begin(), c.end(), qdd);
  });
}

}  // extern "C"
