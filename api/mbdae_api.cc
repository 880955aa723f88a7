// The C API (api/mbdae.h): handles, errors, names, parameters, splines, options, assembly,
// solving, stored outputs and the results file. Work in progress: only the error and
// version calls so far.
#pragma GCC visibility push(default)
#include "api/mbdae.h"
#pragma GCC visibility pop

#include <string>

#include "api/session.h"

namespace mbdae::api {
namespace {
thread_local std::string last_error;
}  // namespace

void EnsureAssembled(mbdae_model&) {
  throw ApiError(MBDAE_ERROR_INTERNAL, "not implemented yet");
}

}  // namespace mbdae::api

extern "C" {

const char* mbdae_last_error(void) { return mbdae::api::last_error.c_str(); }
const char* mbdae_version(void) { return MBDAE_VERSION; }
int mbdae_api_version(void) { return MBDAE_API_VERSION; }

}  // extern "C"
