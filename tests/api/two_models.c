/* Acceptance 1 of the C API (issue 5), in C through api/mbdae.h only: two models at once,
 * one stepped with mbdae_solve_to in 100 calls, the other solved with one mbdae_solve; the
 * stored rows must be bitwise identical (memcmp), for HHT and for IDA, for the pendulum
 * and for a spatial four-bar with redundant constraints.
 *
 * Usage: api_two_models MODEL... (exit code 0 when every comparison holds). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mbdae.h"

static int failures = 0;

#define CHECK(cond, ...)                                  \
  do {                                                    \
    if (!(cond)) {                                        \
      fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__, #cond); \
      fprintf(stderr, __VA_ARGS__);                       \
      fprintf(stderr, "\n");                              \
      ++failures;                                         \
    }                                                     \
  } while (0)

#define CALL(expr)                                                                    \
  do {                                                                                \
    mbdae_status status_ = (expr);                                                    \
    if (status_ != MBDAE_OK) {                                                        \
      fprintf(stderr, "%s:%d: %s returned %d: %s\n", __FILE__, __LINE__, #expr,       \
              (int)status_, mbdae_last_error());                                      \
      ++failures;                                                                     \
      goto cleanup;                                                                   \
    }                                                                                 \
  } while (0)

/* Compares every stored quantity of every row of a and b bitwise. Returns the number of
 * rows compared, -1 on a difference. */
static int CompareRows(mbdae_model* a, mbdae_model* b) {
  int rows_a = 0, rows_b = 0, nq = 0, nm = 0, nmeas = 0, nb = 0, row, w;
  double *buf_a = NULL, *buf_b = NULL;
  int result = -1;
  const mbdae_output what[] = {MBDAE_OUT_TIME, MBDAE_OUT_Q, MBDAE_OUT_V, MBDAE_OUT_A,
                               MBDAE_OUT_LAMBDA, MBDAE_OUT_MEASURES, MBDAE_OUT_BODY_POSES};
  int size[7];
  CALL(mbdae_count(a, MBDAE_OUTPUTS, &rows_a));
  CALL(mbdae_count(b, MBDAE_OUTPUTS, &rows_b));
  CHECK(rows_a == rows_b, "rows %d vs %d", rows_a, rows_b);
  if (rows_a != rows_b) goto cleanup;
  CALL(mbdae_count(a, MBDAE_COORDINATES, &nq));
  CALL(mbdae_count(a, MBDAE_MULTIPLIERS, &nm));
  CALL(mbdae_count(a, MBDAE_MEASURES, &nmeas));
  CALL(mbdae_count(a, MBDAE_BODIES, &nb));
  size[0] = 1;
  size[1] = size[2] = size[3] = nq;
  size[4] = nm;
  size[5] = nmeas;
  size[6] = 12 * nb;
  buf_a = (double*)malloc(sizeof(double) * (size_t)(12 * nb + nq + nm + nmeas + 1));
  buf_b = (double*)malloc(sizeof(double) * (size_t)(12 * nb + nq + nm + nmeas + 1));
  for (row = 0; row < rows_a; ++row) {
    for (w = 0; w < 7; ++w) {
      if (size[w] == 0) continue;
      CALL(mbdae_get_output(a, row, what[w], buf_a, size[w]));
      CALL(mbdae_get_output(b, row, what[w], buf_b, size[w]));
      if (memcmp(buf_a, buf_b, sizeof(double) * (size_t)size[w]) != 0) {
        CHECK(0, "row %d, output %d differs", row, (int)what[w]);
        goto cleanup;
      }
    }
  }
  result = rows_a;
cleanup:
  free(buf_a);
  free(buf_b);
  return result;
}

/* Runs the comparison for one model file and integrator. */
static void StepVersusSolve(const char* path, const char* integrator) {
  mbdae_model *stepped = NULL, *whole = NULL;
  char buf[64];
  double t_end = 0, t0 = 0, t1 = 0;
  int k, rows, calls = 100;
  CALL(mbdae_model_from_file(path, &stepped));
  CALL(mbdae_model_from_file(path, &whole));
  CALL(mbdae_set_option(stepped, "integrator", integrator));
  CALL(mbdae_set_option(whole, "integrator", integrator));
  /* 100 output steps over the run. */
  CALL(mbdae_get_option(whole, "t_end", buf, sizeof buf));
  t_end = atof(buf);
  snprintf(buf, sizeof buf, "%.17g", t_end / calls);
  CALL(mbdae_set_option(stepped, "output_step", buf));
  CALL(mbdae_set_option(whole, "output_step", buf));

  /* Interleaved: the two handles are independent. */
  CALL(mbdae_assemble(stepped));
  CALL(mbdae_assemble(whole));
  for (k = 1; k <= calls; ++k) {
    /* The output times as the library computes them: k * output_step, the last t_end. */
    const double t = k == calls ? t_end : k * (t_end / calls);
    CALL(mbdae_solve_to(stepped, t));
    if (k == calls / 2) CALL(mbdae_solve(whole)); /* in the middle of the other's steps */
  }
  CALL(mbdae_get_state(stepped, &t0, NULL, NULL, NULL, NULL, 0, 0));
  CALL(mbdae_get_state(whole, &t1, NULL, NULL, NULL, NULL, 0, 0));
  CHECK(t0 == t_end && t1 == t_end, "final times %.17g %.17g, t_end %.17g", t0, t1, t_end);
  rows = CompareRows(stepped, whole);
  CHECK(rows == calls + 1, "%d rows compared, expected %d", rows, calls + 1);
  if (rows == calls + 1)
    printf("%s, %s: %d rows bitwise identical (100 solve_to calls vs one solve)\n", path,
           integrator, rows);
cleanup:
  mbdae_model_free(stepped);
  mbdae_model_free(whole);
}

int main(int argc, char** argv) {
  int i;
  if (argc < 2) {
    fprintf(stderr, "usage: %s MODEL...\n", argv[0]);
    return 2;
  }
  for (i = 1; i < argc; ++i) {
    StepVersusSolve(argv[i], "hht");
    StepVersusSolve(argv[i], "ida");
  }
  if (failures) fprintf(stderr, "%d check(s) failed\n", failures);
  return failures ? 1 : 0;
}
