/* The C API with integers outside its enums, as a C caller (or ctypes) may pass them:
 * every function answers MBDAE_ERROR_ARGUMENT naming the value, and nothing reads the
 * value as the enum before checking it (run under -fsanitize=undefined by
 * scripts/sanitize.sh, where such a read is an error). Then one valid call of each kind.
 *
 * Usage: api_enum_range MODEL (exit code 0 when every check holds). */
#include <limits.h>
#include <stdio.h>
#include <string.h>

#include "mbdae.h"

static int failures = 0;

#define CHECK(cond, ...)                                                          \
  do {                                                                            \
    if (!(cond)) {                                                                \
      fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__, #cond);    \
      fprintf(stderr, __VA_ARGS__);                                               \
      fprintf(stderr, "\n");                                                      \
      ++failures;                                                                 \
    }                                                                             \
  } while (0)

/* The call failed with MBDAE_ERROR_ARGUMENT and the message names `value`. */
static void ExpectRefused(mbdae_status status, int value, const char* call) {
  char number[32];
  snprintf(number, sizeof number, "%d", value);
  CHECK(status == MBDAE_ERROR_ARGUMENT, "%s with %d: status %d (%s)", call, value, (int)status,
        mbdae_last_error());
  CHECK(strstr(mbdae_last_error(), number) != NULL, "%s with %d: message '%s'", call, value,
        mbdae_last_error());
}

int main(int argc, char** argv) {
  static const int kBad[] = {-1, 7, 9, 16, 1000, INT_MIN, INT_MAX};
  mbdae_model* model = NULL;
  double out[64];
  int count = 0, index = 0, nnz = 0, k;
  const char* name = NULL;
  if (argc != 2) {
    fprintf(stderr, "usage: api_enum_range MODEL\n");
    return 2;
  }
  if (mbdae_model_from_file(argv[1], &model) != MBDAE_OK) {
    fprintf(stderr, "cannot load %s: %s\n", argv[1], mbdae_last_error());
    return 1;
  }
  if (mbdae_assemble(model) != MBDAE_OK) {
    fprintf(stderr, "cannot assemble %s: %s\n", argv[1], mbdae_last_error());
    mbdae_model_free(model);
    return 1;
  }

  for (k = 0; k < (int)(sizeof kBad / sizeof kBad[0]); ++k) {
    const int v = kBad[k];
    mbdae_block block;
    if (v < 0 || v > MBDAE_GRADIENT_WRT) {
      ExpectRefused(mbdae_count(model, (mbdae_kind)v, &count), v, "mbdae_count");
      ExpectRefused(mbdae_name(model, (mbdae_kind)v, 0, &name), v, "mbdae_name");
      ExpectRefused(mbdae_find(model, (mbdae_kind)v, "bob", &index), v, "mbdae_find");
    }
    if (v < 0 || v > MBDAE_OUT_BODY_POSES)
      ExpectRefused(mbdae_get_output(model, 0, (mbdae_output)v, out, 1), v, "mbdae_get_output");
    if (v < 0 || v > MBDAE_VEC_CONSTRAINTS_DTT)
      ExpectRefused(mbdae_get_vector(model, (mbdae_vector)v, out, 2), v, "mbdae_get_vector");
    if (v < 0 || v > MBDAE_GRAD_COUNTERS)
      ExpectRefused(mbdae_get_gradient(model, (mbdae_gradient_output)v, out, 1), v,
                    "mbdae_get_gradient");
    ExpectRefused(mbdae_get_matrix(model, NULL, 0, 2, 2, (mbdae_sparse_format)v, &nnz, NULL, NULL,
                                   NULL),
                  v, "mbdae_get_matrix (format)");
    if (v < 0 || v > MBDAE_MAT_NEWTON_IDA) {
      memset(&block, 0, sizeof block);
      block.which = (mbdae_matrix)v;
      block.scale = 1;
      ExpectRefused(mbdae_get_matrix(model, &block, 1, 2, 2, MBDAE_CSC, &nnz, NULL, NULL, NULL), v,
                    "mbdae_get_matrix (block)");
    }
  }

  /* A size of INT_MAX would need INT_MAX + 1 pointers (it overflowed int). */
  ExpectRefused(mbdae_get_matrix(model, NULL, 0, INT_MAX, 2, MBDAE_CSR, &nnz, NULL, NULL, NULL), INT_MAX,
                "mbdae_get_matrix (rows)");
  ExpectRefused(mbdae_get_matrix(model, NULL, 0, 2, INT_MAX, MBDAE_CSC, &nnz, NULL, NULL, NULL), INT_MAX,
                "mbdae_get_matrix (cols)");

  /* The enumerators themselves still work. */
  CHECK(mbdae_count(model, MBDAE_BODIES, &count) == MBDAE_OK && count == 1, "bodies: %d (%s)", count,
        mbdae_last_error());
  CHECK(mbdae_get_output(model, 0, MBDAE_OUT_TIME, out, 1) == MBDAE_OK && out[0] == 0.0,
        "time of row 0: %s", mbdae_last_error());
  {
    mbdae_block block;
    memset(&block, 0, sizeof block);
    block.which = MBDAE_MAT_MASS;
    block.scale = 1;
    CHECK(mbdae_count(model, MBDAE_COORDINATES, &count) == MBDAE_OK, "%s", mbdae_last_error());
    CHECK(mbdae_get_matrix(model, &block, 1, count, count, MBDAE_CSR, &nnz, NULL, NULL, NULL) ==
              MBDAE_OK && nnz > 0,
          "mass matrix nnz %d: %s", nnz, mbdae_last_error());
  }
  mbdae_model_free(model);
  if (failures) fprintf(stderr, "%d checks failed\n", failures);
  return failures ? 1 : 0;
}
