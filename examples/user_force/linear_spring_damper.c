/* Example user-force library for mbdae (C ABI: api/mbdae_user_force.h).
 *
 * A linear spring-damper between markers i and j along their connecting line, the same
 * law as mbdae's built-in `spring_damper`:
 *   r = p_i - p_j,  l = |r|,  n = r / l,  l' = n . (v_i - v_j),
 *   s = -k (l - l0) - c l' + preload,     force on i = s n,  torque = 0.
 * Parameters: [k, c, l0, preload] (N/m, N s/m, m, N); preload > 0 pushes the markers
 * apart.
 *
 * Exports:
 *   mbdae_spring_damper         value and analytic 6 x 24 Jacobian;
 *   mbdae_spring_damper_nojac   the same value, no Jacobian (mbdae then uses finite
 *                               differences);
 *   mbdae_spring_damper_init / _free  check the parameter count and keep a copy of the
 *                               parameters as per-element state (an example of user_data).
 * It is reentrant: no global mutable state.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api/mbdae_user_force.h"

#if defined(_WIN32)
#define EXPORT __declspec(dllexport)
#else
#define EXPORT __attribute__((visibility("default")))
#endif

EXPORT int mbdae_user_force_abi_version(void) { return MBDAE_USER_FORCE_ABI_VERSION; }

typedef struct {
  double k, c, l0, preload;
} spring_params;

static int read_params(const double* p, int n, spring_params* s, char* message,
                       size_t size) {
  if (n != 4 || !p) {
    snprintf(message, size, "expected 4 parameters [k, c, l0, preload], got %d", n);
    return 1;
  }
  s->k = p[0];
  s->c = p[1];
  s->l0 = p[2];
  s->preload = p[3];
  return 0;
}

/* The common evaluation; jacobian may be NULL. */
static int evaluate(const spring_params* sp, const mbdae_user_force_input* in,
                    mbdae_user_force_output* out, double* jacobian) {
  double r[3], dv[3], n[3];
  double l = 0, ld = 0, s;
  int a, b;
  for (a = 0; a < 3; ++a) {
    r[a] = in->p_i[a] - in->p_j[a];
    dv[a] = in->v_i[a] - in->v_j[a];
    l += r[a] * r[a];
  }
  l = sqrt(l);
  if (!(l > 1e-12)) {
    snprintf(out->message, out->message_size, "spring length zero (%g m)", l);
    return 2;
  }
  for (a = 0; a < 3; ++a) n[a] = r[a] / l;
  for (a = 0; a < 3; ++a) ld += n[a] * dv[a];
  s = -sp->k * (l - sp->l0) - sp->c * ld + sp->preload;
  for (a = 0; a < 3; ++a) {
    out->force[a] = s * n[a];
    out->torque[a] = 0;
  }
  if (jacobian) {
    /* P = (I - n n^T) / l = dn/dr;  dl/dr = n^T;  dl'/dr = dv^T P;  dl'/d(dv) = n^T
       ds/dr = -k n^T - c dv^T P;  ds/d(dv) = -c n^T
       dF/dr = n ds/dr + s P;      dF/d(dv) = n ds/d(dv);  r = p_i - p_j, dv = v_i - v_j */
    double P[3][3], dsdr[3];
    memset(jacobian, 0, sizeof(double) * MBDAE_UF_NUM_OUTPUTS * MBDAE_UF_NUM_INPUTS);
    for (a = 0; a < 3; ++a)
      for (b = 0; b < 3; ++b) P[a][b] = ((a == b ? 1.0 : 0.0) - n[a] * n[b]) / l;
    for (b = 0; b < 3; ++b) {
      double t = 0;
      for (a = 0; a < 3; ++a) t += dv[a] * P[a][b];
      dsdr[b] = -sp->k * n[b] - sp->c * t;
    }
    for (a = 0; a < 3; ++a) {
      double* row = jacobian + MBDAE_UF_NUM_INPUTS * a;
      for (b = 0; b < 3; ++b) {
        const double dfdr = n[a] * dsdr[b] + s * P[a][b];
        const double dfdv = -sp->c * n[a] * n[b];
        row[MBDAE_UF_P_I + b] = dfdr;
        row[MBDAE_UF_P_J + b] = -dfdr;
        row[MBDAE_UF_V_I + b] = dfdv;
        row[MBDAE_UF_V_J + b] = -dfdv;
      }
    }
    out->jacobian_written = 1;
  }
  return 0;
}

EXPORT int mbdae_spring_damper_init(const double* parameters, int num_parameters,
                                    void** user_data, char* message, size_t message_size) {
  spring_params* sp;
  spring_params tmp;
  if (read_params(parameters, num_parameters, &tmp, message, message_size)) return 1;
  sp = (spring_params*)malloc(sizeof(spring_params));
  if (!sp) {
    snprintf(message, message_size, "out of memory");
    return 1;
  }
  *sp = tmp;
  *user_data = sp;
  return 0;
}

EXPORT void mbdae_spring_damper_free(void* user_data) { free(user_data); }

EXPORT int mbdae_spring_damper(const mbdae_user_force_input* in,
                               mbdae_user_force_output* out) {
  const spring_params* sp = (const spring_params*)in->user_data;
  if (!sp) {
    snprintf(out->message, out->message_size, "mbdae_spring_damper_init was not called");
    return 1;
  }
  return evaluate(sp, in, out, out->jacobian);
}

/* No init: the parameters are read on every call; no Jacobian. */
EXPORT int mbdae_spring_damper_nojac(const mbdae_user_force_input* in,
                                     mbdae_user_force_output* out) {
  spring_params sp;
  if (read_params(in->parameters, in->num_parameters, &sp, out->message,
                  out->message_size))
    return 1;
  return evaluate(&sp, in, out, NULL);
}
