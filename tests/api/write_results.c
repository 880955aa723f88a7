/* Writes the results file of a model through the C API, for compare_results.py:
 *
 *   api_write_results MODEL OUT.h5 [--steps] [KEY=VALUE ...]
 *
 * KEY=VALUE are mbdae_set_option calls. With --steps the run is stepped with one
 * mbdae_solve_to per output time instead of one mbdae_solve. Exit code 0 on success, 1
 * with the library's message otherwise. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mbdae.h"

static int Fail(const char* what) {
  fprintf(stderr, "%s: %s\n", what, mbdae_last_error());
  return 1;
}

int main(int argc, char** argv) {
  mbdae_model* m = NULL;
  int i, steps = 0, code = 0;
  if (argc < 3) {
    fprintf(stderr, "usage: %s MODEL OUT.h5 [--steps] [KEY=VALUE ...]\n", argv[0]);
    return 2;
  }
  if (mbdae_model_from_file(argv[1], &m) != MBDAE_OK) return Fail(argv[1]);
  for (i = 3; i < argc; ++i) {
    char key[64];
    const char* eq = strchr(argv[i], '=');
    if (strcmp(argv[i], "--steps") == 0) {
      steps = 1;
      continue;
    }
    if (!eq || (size_t)(eq - argv[i]) >= sizeof key) {
      fprintf(stderr, "bad argument '%s'\n", argv[i]);
      code = 2;
      goto done;
    }
    memcpy(key, argv[i], (size_t)(eq - argv[i]));
    key[eq - argv[i]] = '\0';
    if (mbdae_set_option(m, key, eq + 1) != MBDAE_OK) {
      code = Fail(argv[i]);
      goto done;
    }
  }
  if (steps) {
    char buf[64];
    double t_end, h;
    long k;
    if (mbdae_get_option(m, "t_end", buf, sizeof buf) != MBDAE_OK) goto failed;
    t_end = atof(buf);
    if (mbdae_get_option(m, "output_step", buf, sizeof buf) != MBDAE_OK) goto failed;
    h = atof(buf);
    for (k = 1; k * h < t_end - 1e-9 * h; ++k) /* as driver::OutputTimes */
      if (mbdae_solve_to(m, k * h) != MBDAE_OK) goto failed;
    if (mbdae_solve_to(m, t_end) != MBDAE_OK) goto failed;
  } else if (mbdae_solve(m) != MBDAE_OK) {
    goto failed;
  }
  if (mbdae_write_results(m, argv[2]) != MBDAE_OK) goto failed;
  goto done;
failed:
  code = Fail("mbdae");
done:
  mbdae_model_free(m);
  return code;
}
