// User force elements: force laws computed in a shared library loaded at run time,
// through the C ABI of api/mbdae_user_force.h.
//
//   auto lib = std::make_shared<const UserForceLibrary>("/abs/path/libmyforce.so");
//   UserForce f(lib, "my_force", {1.0, 2.0});
//   ForceJacobian J;
//   ForceTorque y = f.Evaluate(t, kinematics, &J);
//
// Errors (library not found or not loadable, missing symbol, ABI version mismatch, the
// library's init or force function returning non-zero) throw std::runtime_error with a
// message naming the library path, the function and, for returned errors, the code and
// the library's message. The caller (the system) catches them at its C-callback edge.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "api/mbdae_user_force.h"
#include "mbs/force_law.h"

namespace mbdae::mbs {

// A shared library opened with dlopen(path, RTLD_NOW | RTLD_LOCAL), closed on
// destruction. `path` is a file: a path without '/' is taken in the current folder
// ("./" is prepended, path() returns it so), never searched on the system's library path
// (the loader resolves a model's `library:` against the model file's folder first).
// Opening runs the library's initialisers. The library must export
// mbdae_user_force_abi_version() returning MBDAE_USER_FORCE_ABI_VERSION.
class UserForceLibrary {
 public:
  explicit UserForceLibrary(std::string path);
  ~UserForceLibrary();
  UserForceLibrary(const UserForceLibrary&) = delete;
  UserForceLibrary& operator=(const UserForceLibrary&) = delete;

  // The address of `name`; nullptr if absent and !required; throws if absent and required.
  void* Symbol(const std::string& name, bool required) const;
  const std::string& path() const { return path_; }
  int abi_version() const { return abi_version_; }

 private:
  std::string path_;
  void* handle_ = nullptr;
  int abi_version_ = 0;
};

struct UserForceOptions {
  // Relative step of the central finite differences used when the library does not
  // provide the Jacobian (rule in force_law.h). Must be in (0, 1e-2].
  double fd_relative_step = kDefaultFdRelativeStep;
  bool IsValid(std::string* error) const;
};

// One force element bound to a function of a library and its parameters. Calls
// NAME_init on construction and NAME_free on destruction when the library has them.
// Not copyable (it owns the library's per-element state); movable.
// Evaluate is const but not safe to call concurrently on the same object (the library's
// user_data may be mutated by the function); distinct objects may be used concurrently.
class UserForce {
 public:
  using Options = UserForceOptions;

  UserForce(std::shared_ptr<const UserForceLibrary> library, std::string function,
            std::vector<double> parameters, const Options& options = Options());
  ~UserForce();
  UserForce(UserForce&& other) noexcept;
  UserForce& operator=(UserForce&& other) noexcept;
  UserForce(const UserForce&) = delete;
  UserForce& operator=(const UserForce&) = delete;

  // Force and torque on marker i (world axes) at time t. If jacobian is not null it
  // receives the 6 x 24 Jacobian (force_law.h layout): the library's when it writes it,
  // central finite differences of the library's values otherwise.
  ForceTorque Evaluate(double t, const MarkerPairKinematics& k,
                       ForceJacobian* jacobian = nullptr) const;

  // Whether the library filled the Jacobian the last time it was asked (false before).
  bool library_provides_jacobian() const { return library_jacobian_; }
  const std::string& function() const { return function_; }
  const std::vector<double>& parameters() const { return parameters_; }
  const UserForceLibrary& library() const { return *library_; }

 private:
  // One call of the library function; throws on a non-zero return.
  ForceTorque Call(double t, const MarkerPairKinematics& k, double* jacobian,
                   bool* written) const;
  void Release() noexcept;

  std::shared_ptr<const UserForceLibrary> library_;
  std::string function_;
  std::vector<double> parameters_;
  Options options_;
  mbdae_user_force_function fn_ = nullptr;
  mbdae_user_force_free_function free_ = nullptr;
  void* user_data_ = nullptr;
  mutable bool library_jacobian_ = false;
  mutable bool asked_jacobian_ = false;
};

}  // namespace mbdae::mbs
