/* mbdae user-force C ABI, version 1.
 *
 * A `user` force element (model format: `type: user`, `library:`, `function:`,
 * `parameters:`) is computed by a function in a shared library that mbdae loads at run
 * time (dlopen with RTLD_NOW | RTLD_LOCAL). This header is the whole contract between
 * mbdae and such a library. It is plain C (C89 types only) and may be copied into the
 * library's own sources.
 *
 * What a library exports (all with C linkage, `extern "C"` when compiled as C++):
 *
 *   int mbdae_user_force_abi_version(void);          required, once per library:
 *       returns MBDAE_USER_FORCE_ABI_VERSION as seen by the library when compiled.
 *       mbdae refuses a library whose value differs from its own.
 *
 *   int NAME(const mbdae_user_force_input* in,        required, one per force law;
 *            mbdae_user_force_output* out);            NAME is the model's `function:`.
 *       Type: mbdae_user_force_function.
 *
 *   int NAME_init(const double* parameters, int num_parameters,      optional
 *                 void** user_data, char* message, size_t message_size);
 *   void NAME_free(void* user_data);                                 optional
 *       Per-element state. If NAME_init exists it is called once per element, before the
 *       first evaluation, with the element's parameters; whatever it stores in
 *       *user_data (initially NULL) is passed back as in->user_data in every call and
 *       to NAME_free (if it exists) when the element is destroyed. NAME_init returns 0
 *       on success, non-zero on error (then it writes a message as described below and
 *       NAME_free is not called).
 *
 * Units: SI (m, rad, s, N, N m). Axes: every vector and matrix is in WORLD axes.
 *
 * Inputs: the absolute kinematics of the two markers i and j of the element (the
 * relative kinematics follow: r = p_i - p_j, R = R_j^T R_i, ...), the time and the
 * element's parameters, in mbdae_user_force_input.
 *   R_i, R_j: rotation matrices from the marker's axes to world, COLUMN-major:
 *     R_i[3*k + r] is world component r of marker i's k-th axis (k = 0,1,2 = x,y,z), so
 *     R_i + 0, R_i + 3, R_i + 6 are the marker's x, y, z axes as world vectors.
 *   v_i, w_i: velocity of marker i's origin and angular velocity of its axes.
 *
 * Outputs: the force and the torque acting ON MARKER i, world axes, force applied at
 * marker i's origin. The reaction on marker j is implied by Newton's third law with
 * moment balance: force_j = -force, torque_j = -torque - (p_i - p_j) x force (so the
 * pair is in equilibrium as a whole). An attracting spring has force along -(p_i - p_j).
 *
 * Derivatives (optional): if out->jacobian is not NULL, mbdae requests the 6 x 24
 * Jacobian of y = (force, torque) with respect to the 24 inputs
 *     x = (p_i, phi_i, p_j, phi_j, v_i, w_i, v_j, w_j),
 * stored ROW-major: jacobian[24 * r + c] = d y_r / d x_c, r = 0..2 force x,y,z,
 * r = 3..5 torque x,y,z; column offsets are the MBDAE_UF_* constants below. phi_i is a
 * small rotation of marker i in world axes: R_i -> exp(skew(phi_i)) R_i (the velocities
 * and the other marker held fixed). All 24 inputs are treated as independent (e.g. the
 * velocity v_i is not changed when p_i is perturbed). A library that fills the
 * Jacobian sets out->jacobian_written = 1 (mbdae sets it to 0 before each call); a
 * library that leaves it 0 (or ignores the pointer) makes mbdae use central finite
 * differences instead. A library must never write through a NULL jacobian.
 *
 * Return value: 0 on success. Non-zero on error: then the function writes a
 * NUL-terminated message of at most out->message_size bytes (including the NUL) into
 * out->message (always non-NULL, message_size >= 1), and mbdae stops the computation
 * with an error naming the element, the library, the function, the code and the message.
 *
 * Thread safety: mbdae never calls one element's function from two threads at once, but
 * distinct elements (distinct user_data, possibly the same NAME) may be evaluated from
 * distinct threads at the same time: a function must not modify global state without
 * its own synchronisation. The function must not throw (C++), longjmp out, or keep the
 * input or output pointers after it returns.
 */
#ifndef MBDAE_USER_FORCE_H_
#define MBDAE_USER_FORCE_H_

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MBDAE_USER_FORCE_ABI_VERSION 1

/* Column offsets of the inputs in the 6 x 24 Jacobian. */
#define MBDAE_UF_P_I 0     /* position of marker i */
#define MBDAE_UF_PHI_I 3   /* small rotation of marker i, world axes */
#define MBDAE_UF_P_J 6     /* position of marker j */
#define MBDAE_UF_PHI_J 9   /* small rotation of marker j, world axes */
#define MBDAE_UF_V_I 12    /* velocity of marker i */
#define MBDAE_UF_W_I 15    /* angular velocity of marker i */
#define MBDAE_UF_V_J 18    /* velocity of marker j */
#define MBDAE_UF_W_J 21    /* angular velocity of marker j */
#define MBDAE_UF_NUM_INPUTS 24
#define MBDAE_UF_NUM_OUTPUTS 6

typedef struct mbdae_user_force_input {
  double t;          /* time, s */
  double p_i[3];     /* position of marker i's origin, m */
  double p_j[3];
  double R_i[9];     /* marker axes -> world, column-major (see above) */
  double R_j[9];
  double v_i[3];     /* velocity of marker i's origin, m/s */
  double v_j[3];
  double w_i[3];     /* angular velocity of marker i, rad/s */
  double w_j[3];
  const double* parameters; /* the element's `parameters:` (NULL if none) */
  int num_parameters;
  void* user_data;   /* what NAME_init stored, or NULL */
} mbdae_user_force_input;

typedef struct mbdae_user_force_output {
  double force[3];   /* on marker i, N, world axes */
  double torque[3];  /* on marker i, N m, world axes */
  double* jacobian;  /* 6 x 24 row-major, or NULL: not requested */
  int jacobian_written; /* set to 1 by the library if it filled jacobian */
  char* message;     /* error message buffer (never NULL) */
  size_t message_size;
} mbdae_user_force_output;

typedef int (*mbdae_user_force_function)(const mbdae_user_force_input* in,
                                         mbdae_user_force_output* out);
typedef int (*mbdae_user_force_init_function)(const double* parameters, int num_parameters,
                                              void** user_data, char* message,
                                              size_t message_size);
typedef void (*mbdae_user_force_free_function)(void* user_data);
typedef int (*mbdae_user_force_abi_version_function)(void);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* MBDAE_USER_FORCE_H_ */
