/* A user-force library that leaves a trace when it is loaded: its initialiser writes
 * library_was_loaded.txt into the current folder. The tests of tests/bad_input/ check
 * that a refused model runs none of a library's code, and that a library named by a
 * file name alone is the file beside the model. marker_spring: a linear spring from
 * marker j to marker i, force -k (p_i - p_j), parameters [k]. */
#include <stdio.h>

#include "api/mbdae_user_force.h"

__attribute__((constructor)) static void leave_a_trace(void) {
  FILE* f = fopen("library_was_loaded.txt", "w");
  if (f) {
    fputs("loaded\n", f);
    fclose(f);
  }
}

__attribute__((visibility("default"))) int mbdae_user_force_abi_version(void) {
  return MBDAE_USER_FORCE_ABI_VERSION;
}

__attribute__((visibility("default"))) int marker_spring(const mbdae_user_force_input* in,
                                                        mbdae_user_force_output* out) {
  int a;
  if (in->num_parameters != 1) {
    snprintf(out->message, out->message_size, "expected 1 parameter [k], got %d", in->num_parameters);
    return 1;
  }
  for (a = 0; a < 3; ++a) {
    out->force[a] = -in->parameters[0] * (in->p_i[a] - in->p_j[a]);
    out->torque[a] = 0;
  }
  return 0;
}
