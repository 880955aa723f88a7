// Measures, vectors and sparse matrices at the current state (api/mbdae.h, "Measures at the
// current state" to "Sparse matrices at the current state"). Placeholder bodies until the
// implementation lands: every call reports MBDAE_ERROR_INTERNAL.
#include "api/session.h"

namespace mbdae::api {

void MeasureValues(mbdae_model&, double*, int) {
  throw ApiError(MBDAE_ERROR_INTERNAL, "not implemented yet");
}

void MeasureGradient(mbdae_model&, int, double*, int) {
  throw ApiError(MBDAE_ERROR_INTERNAL, "not implemented yet");
}

void GetVector(mbdae_model&, mbdae_vector, double*, int) {
  throw ApiError(MBDAE_ERROR_INTERNAL, "not implemented yet");
}

void GetMatrix(mbdae_model&, const mbdae_block*, int, int, int, mbdae_sparse_format, int*, int*,
               int*, double*) {
  throw ApiError(MBDAE_ERROR_INTERNAL, "not implemented yet");
}

}  // namespace mbdae::api
