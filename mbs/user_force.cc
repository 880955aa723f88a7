#include "mbs/user_force.h"

#include <dlfcn.h>

#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace mbdae::mbs {
namespace {

std::string Quoted(const std::string& s) { return "'" + s + "'"; }

void CopyIn(const MarkerPairKinematics& k, double t, mbdae_user_force_input* in) {
  in->t = t;
  for (int r = 0; r < 3; ++r) {
    in->p_i[r] = k.p_i[r];
    in->p_j[r] = k.p_j[r];
    in->v_i[r] = k.v_i[r];
    in->v_j[r] = k.v_j[r];
    in->w_i[r] = k.w_i[r];
    in->w_j[r] = k.w_j[r];
    for (int c = 0; c < 3; ++c) {  // column-major: in->R[3*c + r] = R(r, c)
      in->R_i[3 * c + r] = k.R_i(r, c);
      in->R_j[3 * c + r] = k.R_j(r, c);
    }
  }
}

}  // namespace

// --- UserForceLibrary ---------------------------------------------------------------

UserForceLibrary::UserForceLibrary(std::string path) : path_(std::move(path)) {
  // dlopen searches the system's library path for a name without '/': a file name alone
  // means the file in the current folder.
  if (path_.find('/') == std::string::npos) path_ = "./" + path_;
  dlerror();  // clear
  handle_ = dlopen(path_.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle_) {
    const char* why = dlerror();
    throw std::runtime_error("user force library " + Quoted(path_) +
                             ": cannot be loaded: " + (why ? why : "unknown reason"));
  }
  try {
    auto version = reinterpret_cast<mbdae_user_force_abi_version_function>(
        Symbol("mbdae_user_force_abi_version", true));
    abi_version_ = version();
    if (abi_version_ != MBDAE_USER_FORCE_ABI_VERSION) {
      std::ostringstream msg;
      msg << "user force library " << Quoted(path_) << ": ABI version " << abi_version_
          << " (mbdae_user_force_abi_version), this mbdae supports version "
          << MBDAE_USER_FORCE_ABI_VERSION << "; rebuild the library against this "
          << "api/mbdae_user_force.h";
      throw std::runtime_error(msg.str());
    }
  } catch (...) {
    dlclose(handle_);
    handle_ = nullptr;
    throw;
  }
}

UserForceLibrary::~UserForceLibrary() {
  if (handle_) dlclose(handle_);
}

void* UserForceLibrary::Symbol(const std::string& name, bool required) const {
  dlerror();
  void* p = dlsym(handle_, name.c_str());
  const char* why = dlerror();
  if ((why || !p) && required)
    throw std::runtime_error("user force library " + Quoted(path_) + ": symbol " +
                             Quoted(name) + " not found" +
                             (why ? std::string(" (") + why + ")" : std::string()));
  return why ? nullptr : p;
}

// --- UserForce ------------------------------------------------------------------------

bool UserForceOptions::IsValid(std::string* error) const {
  if (!(fd_relative_step > 0 && fd_relative_step <= 1e-2)) {
    if (error) *error = "UserForceOptions: fd_relative_step must be in (0, 1e-2]";
    return false;
  }
  return true;
}

UserForce::UserForce(std::shared_ptr<const UserForceLibrary> library, std::string function,
                     std::vector<double> parameters, const Options& options)
    : library_(std::move(library)),
      function_(std::move(function)),
      parameters_(std::move(parameters)),
      options_(options) {
  if (!library_) throw std::invalid_argument("user force " + Quoted(function_) + ": no library");
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument(error);
  fn_ = reinterpret_cast<mbdae_user_force_function>(library_->Symbol(function_, true));
  auto init = reinterpret_cast<mbdae_user_force_init_function>(
      library_->Symbol(function_ + "_init", false));
  free_ = reinterpret_cast<mbdae_user_force_free_function>(
      library_->Symbol(function_ + "_free", false));
  if (init) {
    std::array<char, 512> message{};
    void* data = nullptr;
    const int rc = init(parameters_.empty() ? nullptr : parameters_.data(),
                        static_cast<int>(parameters_.size()), &data, message.data(),
                        message.size());
    if (rc != 0) {
      message.back() = '\0';
      std::ostringstream msg;
      msg << "user force " << Quoted(function_) << " in " << Quoted(library_->path())
          << ": " << function_ << "_init returned " << rc << ": " << message.data();
      throw std::runtime_error(msg.str());
    }
    user_data_ = data;
  }
}

void UserForce::Release() noexcept {
  if (free_ && user_data_) free_(user_data_);
  user_data_ = nullptr;
}

UserForce::~UserForce() { Release(); }

UserForce::UserForce(UserForce&& o) noexcept
    : library_(std::move(o.library_)),
      function_(std::move(o.function_)),
      parameters_(std::move(o.parameters_)),
      options_(o.options_),
      fn_(o.fn_),
      free_(o.free_),
      user_data_(std::exchange(o.user_data_, nullptr)),
      library_jacobian_(o.library_jacobian_),
      asked_jacobian_(o.asked_jacobian_) {}

UserForce& UserForce::operator=(UserForce&& o) noexcept {
  if (this != &o) {
    Release();
    library_ = std::move(o.library_);
    function_ = std::move(o.function_);
    parameters_ = std::move(o.parameters_);
    options_ = o.options_;
    fn_ = o.fn_;
    free_ = o.free_;
    user_data_ = std::exchange(o.user_data_, nullptr);
    library_jacobian_ = o.library_jacobian_;
    asked_jacobian_ = o.asked_jacobian_;
  }
  return *this;
}

ForceTorque UserForce::Call(double t, const MarkerPairKinematics& k, double* jacobian,
                            bool* written) const {
  mbdae_user_force_input in{};
  CopyIn(k, t, &in);
  in.parameters = parameters_.empty() ? nullptr : parameters_.data();
  in.num_parameters = static_cast<int>(parameters_.size());
  in.user_data = user_data_;
  std::array<char, 512> message{};
  mbdae_user_force_output out{};
  out.jacobian = jacobian;
  out.jacobian_written = 0;
  out.message = message.data();
  out.message_size = message.size();
  const int rc = fn_(&in, &out);
  if (rc != 0) {
    message.back() = '\0';
    std::ostringstream msg;
    msg << "user force " << Quoted(function_) << " in " << Quoted(library_->path())
        << " returned " << rc << " at t = " << t << ": " << message.data();
    throw std::runtime_error(msg.str());
  }
  if (written) *written = jacobian && out.jacobian_written != 0;
  ForceTorque y;
  for (int r = 0; r < 3; ++r) {
    y.force[r] = out.force[r];
    y.torque[r] = out.torque[r];
  }
  if (!y.force.allFinite() || !y.torque.allFinite()) {
    std::ostringstream msg;
    msg << "user force " << Quoted(function_) << " in " << Quoted(library_->path())
        << " returned a non-finite force or torque at t = " << t;
    throw std::runtime_error(msg.str());
  }
  return y;
}

ForceTorque UserForce::Evaluate(double t, const MarkerPairKinematics& k,
                                ForceJacobian* jacobian) const {
  if (!jacobian) return Call(t, k, nullptr, nullptr);
  // Ask the library for the Jacobian until it has once declined (a library either
  // provides it for a function or not).
  if (!asked_jacobian_ || library_jacobian_) {
    Eigen::Matrix<double, 6, 24, Eigen::RowMajor> rm;
    bool written = false;
    const ForceTorque y = Call(t, k, rm.data(), &written);
    asked_jacobian_ = true;
    library_jacobian_ = written;
    if (written) {
      *jacobian = rm;
      return y;
    }
  }
  const ForceTorque y = Call(t, k, nullptr, nullptr);
  *jacobian = FiniteDifferenceJacobian(
      [&](const MarkerPairKinematics& kk) { return Call(t, kk, nullptr, nullptr); }, k,
      options_.fd_relative_step);
  return y;
}

}  // namespace mbdae::mbs
