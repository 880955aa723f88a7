/* mbdae C API, version 1: drive models from code, step by step, with every internal vector
 * and matrix.
 *
 * Conventions
 * - Opaque handles: any number of models at once, independent of each other; no global
 *   "active model". A handle may be used by one thread at a time; different handles from
 *   different threads at once.
 * - Every call returns an mbdae_status (MBDAE_OK = 0). On an error, nothing is half-done
 *   (outputs are left unchanged) and mbdae_last_error() returns the message of this
 *   thread's last failed call ("" after a successful one). No C++ exception crosses this
 *   interface.
 * - Indices are zero-based. Sizes: "n" arguments give the length of the caller's array;
 *   a wrong length is MBDAE_ERROR_SIZE with the expected length in the message.
 * - Units SI; vectors in world axes unless said otherwise.
 * - Coordinates q: per body the centre-of-mass position (3) and the Euler parameters (4);
 *   v = q', a = q''. Multipliers lambda: the independent constraint equations (redundant
 *   ones are found when the model is assembled and set aside; their names are listed by
 *   MBDAE_REDUNDANT).
 *
 * Life of a model
 *   mbdae_model_from_file / mbdae_model_from_string -> (set parameters, spline points,
 *   options) -> mbdae_assemble (consistent initial state at t = 0; also done by the first
 *   solve call) -> mbdae_solve (to t_end) or mbdae_solve_to (any number of calls) ->
 *   read stored outputs, the state, vectors and matrices -> mbdae_model_free.
 *   Changing a parameter or spline points marks the model for re-assembly: the next
 *   solve call starts again from t = 0 (stored outputs are cleared then).
 *   Gradients of the model's objectives (mbdae_gradient) run their own simulations at
 *   any point of this life and leave the stored outputs and the state alone.
 */
#ifndef MBDAE_H_
#define MBDAE_H_

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MBDAE_API_VERSION 1

typedef enum {
  MBDAE_OK = 0,
  MBDAE_ERROR_INPUT = 1,     /* a model file or string with a mistake, a bad option value */
  MBDAE_ERROR_ARGUMENT = 2,  /* a null handle or pointer, an index or name that does not exist */
  MBDAE_ERROR_SIZE = 3,      /* an array length that does not match */
  MBDAE_ERROR_ORDER = 4,     /* a call that needs an earlier one (e.g. outputs before a solve) */
  MBDAE_ERROR_SOLVER = 5,    /* the integrator or the assembly failed (outputs so far kept) */
  MBDAE_ERROR_IO = 6,        /* a file could not be read or written */
  MBDAE_ERROR_INTERNAL = 7   /* a bug: please report the message */
} mbdae_status;

typedef struct mbdae_model mbdae_model;

/* The message of this thread's last failed call, "" if the last call succeeded. Valid until
 * the next call from this thread. */
const char* mbdae_last_error(void);
/* "0.1.0"; and MBDAE_API_VERSION as compiled into the library. */
const char* mbdae_version(void);
int mbdae_api_version(void);

/* ---- Creating and freeing ------------------------------------------------------------ */

/* A model file in the project's format (.yaml) or a FreeDyn file (.fds). */
mbdae_status mbdae_model_from_file(const char* path, mbdae_model** model);
/* Model text in the project's format; `name` is used in messages and relative paths
 * (spline data files, meshes) are resolved against its folder ("" = the working folder). */
mbdae_status mbdae_model_from_string(const char* text, const char* name, mbdae_model** model);
/* Frees the model (NULL is allowed). */
void mbdae_model_free(mbdae_model* model);

/* ---- Sizes and names ------------------------------------------------------------------- */

typedef enum {
  MBDAE_COORDINATES = 0,  /* q: "body.x" ... "body.e3" */
  MBDAE_MULTIPLIERS = 1,  /* lambda: the independent constraint equations ("joint.x", ...) */
  MBDAE_REDUNDANT = 2,    /* the constraint equations set aside as redundant */
  MBDAE_BODIES = 3,
  MBDAE_JOINTS = 4,
  MBDAE_FORCES = 5,
  MBDAE_MEASURES = 6,
  MBDAE_PARAMETERS = 7,
  MBDAE_SPLINES = 8,
  MBDAE_OUTPUTS = 9,      /* stored output rows (no names) */
  MBDAE_OBJECTIVES = 10,  /* the model's objectives (`objectives:` of the model file) */
  MBDAE_GRADIENT_OBJECTIVES = 11, /* the rows of the stored gradient (mbdae_gradient): the
                                     objectives it was computed for; 0 before the first */
  MBDAE_GRADIENT_WRT = 12 /* the columns of the stored gradient: what it was taken with
                             respect to, "k" or "SPLINE[i]"; 0 before the first */
} mbdae_kind;

/* MULTIPLIERS and REDUNDANT assemble the model if needed. */
mbdae_status mbdae_count(mbdae_model* model, mbdae_kind kind, int* count);
/* The name of item `index` (the pointer stays valid until the model is freed or
 * re-assembled, or a parameter is set). */
mbdae_status mbdae_name(mbdae_model* model, mbdae_kind kind, int index, const char** name);
/* The index of the item called `name`; MBDAE_ERROR_ARGUMENT if there is none. */
mbdae_status mbdae_find(mbdae_model* model, mbdae_kind kind, const char* name, int* index);

/* ---- Parameters, splines and options ------------------------------------------------- */

mbdae_status mbdae_get_parameter(mbdae_model* model, int index, double* value);
/* Sets a parameter as `--set NAME=VALUE` does: parameters, masses, positions and spline
 * points that depend on it are recomputed; the model is re-assembled at the next solve.
 * A value that makes the model invalid is MBDAE_ERROR_INPUT (the old value stays). */
mbdae_status mbdae_set_parameter(mbdae_model* model, int index, double value);

mbdae_status mbdae_spline_size(mbdae_model* model, int index, int* num_points);
mbdae_status mbdae_get_spline_points(mbdae_model* model, int index, double* x, double* y, int n);
/* New points (x strictly increasing, at least 2; the spline's interpolation kept). */
mbdae_status mbdae_set_spline_points(mbdae_model* model, int index, const double* x,
                                     const double* y, int n);

/* Simulation settings, with the names and value syntax of the model file's `simulation:`
 * block: "t_end", "output_step", "integrator" (hht|ida|kinematic|erk; kinematic:
 * kinematic analysis, for models without degrees of freedom; erk: explicit Runge-Kutta
 * on the index-1 form), "hht.alpha", "hht.step",
 * "hht.adaptive" (true|false), "hht.tolerance", "hht.modified", "hht.form"
 * (equilibrium|negrut), "ida.rtol", "ida.atol", "ida.max_steps" (a whole number >= 1),
 * "ida.min_step" (>= 0; 0: no limit), "erk.rtol", "erk.atol", "erk.max_steps",
 * "erk.min_step", "erk.max_step" (>= 0; 0: automatic / no limit). Numbers are plain numbers (no
 * expressions). Validated as the program validates its options: an unknown key is
 * MBDAE_ERROR_ARGUMENT, a bad value MBDAE_ERROR_INPUT (the old value stays). Takes
 * effect at the next assembly (set before solving): like a parameter, it marks the
 * model for re-assembly.
 * The settings of mbdae_gradient (they do not mark the model for re-assembly):
 * "gradient.fd_step" (fd: the step of p is fd_step * max(|p|, 1); default 1e-5),
 * "gradient.newton_factor" (HHT, exact methods: the adaptive Newton threshold of the
 * forward run is max(newton tolerance, newton_factor * hht.tolerance); default 1e-6),
 * "gradient.trajectory_memory" (HHT adjoint: bytes the stored run may take before only
 * checkpoints are kept; 0 = store every step; default 536870912),
 * "gradient.ida_checkpoint_steps" (IDA adjoint: forward steps between two checkpoints,
 * an integer >= 1; default 200). */
mbdae_status mbdae_set_option(mbdae_model* model, const char* key, const char* value);
/* The current value as text into buf (size bytes, NUL-terminated). */
mbdae_status mbdae_get_option(mbdae_model* model, const char* key, char* buf, size_t size);

/* ---- Solving --------------------------------------------------------------------------- */

/* Consistent initial conditions at t = 0 (positions, velocities, accelerations,
 * multipliers; redundant equations found and set aside); clears stored outputs, stores the
 * row at t = 0 and makes that the current state. */
mbdae_status mbdae_assemble(mbdae_model* model);
/* Integrates from the current state to t_end (assembling first if needed), storing a row
 * at every output time (0, output_step, 2 output_step, ..., t_end). Nothing to do (MBDAE_OK)
 * when the current time is t_end or later. A solver failure is MBDAE_ERROR_SOLVER with
 * the reason; the rows so far stay and the current state is the last one reached (the
 * next solve call restarts the integrator from it). */
mbdae_status mbdae_solve(mbdae_model* model);
/* Integrates from the current state to t (> current time, <= t_end is not required),
 * storing a row at every output time passed on the way (and none at t unless t is one).
 * Calling it for each output time gives bitwise the same rows as one mbdae_solve. A t
 * within 1e-9 output_step of an output time is that output time. After t_end the output
 * times go on every output_step (t_end + output_step, ...). */
mbdae_status mbdae_solve_to(mbdae_model* model, double t);

/* The current state: time, q, v, a (each nq = MBDAE_COORDINATES), lambda (nm =
 * MBDAE_MULTIPLIERS). Any pointer may be NULL (its size is then not checked). Assembles
 * the model if needed. */
mbdae_status mbdae_get_state(mbdae_model* model, double* t, double* q, double* v, double* a,
                             double* lambda, int nq, int nm);
/* Sets the current state and restarts the integrator from it (a co-simulation host's
 * correction). a and lambda may be NULL: they are then computed from the equations of
 * motion at (t, q, v). q and v are used as given (not projected). Stored rows after t are
 * dropped (they belong to the history replaced); the next row is stored at the first
 * output time after t, with measure angles unwrapped from the last row kept. The restart
 * resets the integrator's history (IDA's order and step, HHT's acceleration-like
 * variables): a continuation from a saved state agrees with the uninterrupted run to the
 * integrator's accuracy, not bitwise. */
mbdae_status mbdae_set_state(mbdae_model* model, double t, const double* q, const double* v,
                             const double* a, const double* lambda, int nq, int nm);

/* ---- Stored outputs -------------------------------------------------------------------- */

typedef enum {
  MBDAE_OUT_TIME = 0,       /* 1 value */
  MBDAE_OUT_Q = 1,          /* nq */
  MBDAE_OUT_V = 2,          /* nq */
  MBDAE_OUT_A = 3,          /* nq */
  MBDAE_OUT_LAMBDA = 4,     /* nm */
  MBDAE_OUT_MEASURES = 5,   /* number of measures, as in the results file (unwrapped angles) */
  MBDAE_OUT_BODY_POSES = 6  /* 12 per body: centre-of-mass position (3), then the rotation
                               matrix body -> world, row-major (9) */
} mbdae_output;

/* Row `row` (0 .. MBDAE_OUTPUTS - 1) of quantity `what` into out (n values). */
mbdae_status mbdae_get_output(mbdae_model* model, int row, mbdae_output what, double* out, int n);
/* Writes the stored rows as a results file (docs/results-file.md), with the datasets and
 * attributes `mbdae simulate` writes (a model solved with mbdae_solve gives the program's
 * file, run times aside). `status` is "done" once t_end is stored, "failed" after a solver
 * failure, else "running" (a run a host is still stepping); the counters add up every
 * integrator of the run (set_state and failures restart it). As `mbdae simulate`, the file
 * is written as PATH.PID.tmp beside `path` and renamed over it when complete (an earlier
 * file stays whole if writing fails); a path that is the model file (by any spelling or
 * link), an empty path or one the system refuses (its reason) is MBDAE_ERROR_IO. */
mbdae_status mbdae_write_results(mbdae_model* model, const char* path);

/* ---- Measures at the current state ----------------------------------------------------- */

/* Values of all measures (n = MBDAE_MEASURES), as the model defines them (no unwrapping). */
mbdae_status mbdae_measure_values(mbdae_model* model, double* values, int n);
/* d(measure)/dq at the current state (n = nq). */
mbdae_status mbdae_measure_gradient(mbdae_model* model, int measure, double* dq, int n);

/* ---- Vectors at the current state ------------------------------------------------------ */

typedef enum {
  MBDAE_VEC_MASS_TIMES_ACC = 0,       /* M(q) a                                     nq */
  MBDAE_VEC_CONSTRAINT_FORCES = 1,    /* C_q^T lambda                               nq */
  MBDAE_VEC_QUADRATIC_VELOCITY = 2,   /* Q_v: the velocity-quadratic inertia terms  nq */
  MBDAE_VEC_EXTERNAL_FORCES = 3,      /* gravity, force elements                    nq */
  MBDAE_VEC_SUM_OF_FORCES = 4,        /* Q = Q_v + external                          nq */
  MBDAE_VEC_CONSTRAINTS = 5,          /* C(q, t)                                     nm */
  MBDAE_VEC_CONSTRAINTS_DT = 6,       /* dC/dt (partial)                             nm */
  MBDAE_VEC_CONSTRAINTS_QDOT = 7,     /* d(C_q)/dt q' (total derivative of C_q)      nm */
  MBDAE_VEC_CONSTRAINTS_DTT = 8       /* d2C/dt2 (partial)                           nm */
} mbdae_vector;

mbdae_status mbdae_get_vector(mbdae_model* model, mbdae_vector which, double* out, int n);

/* ---- Sparse matrices at the current state ---------------------------------------------- */

typedef enum {
  MBDAE_MAT_MASS = 0,          /* M                       nq x nq */
  MBDAE_MAT_CONSTRAINT_DQ = 1, /* C_q                     nm x nq */
  MBDAE_MAT_MASS_ACC_DQ = 2,   /* d(M a)/dq at fixed a    nq x nq */
  MBDAE_MAT_FORCE_DQ = 3,      /* dQ/dq                   nq x nq */
  MBDAE_MAT_FORCE_DV = 4,      /* dQ/dq'                  nq x nq */
  MBDAE_MAT_CONSTRAINT_T_DQ = 5, /* d(C_q^T lambda)/dq    nq x nq */
  MBDAE_MAT_NEWTON_HHT = 6,    /* the HHT Newton matrix (docs/hht.md) with the model's HHT
                                  settings and the Newton step h   (nq + nm) square */
  MBDAE_MAT_NEWTON_IDA = 7     /* IDA's Newton matrix dF/dy + c_j dF/dy' of the stabilised
                                  index-2 (GGL) form, y = (q, v, lambda, mu), with
                                  c_j = 1 / h (IDA's value for a BDF1 step of size h)
                                  (2 nq + 2 nm) square */
} mbdae_matrix;

/* The step h of the Newton matrices (default: the option hht.step). */
mbdae_status mbdae_set_newton_step(mbdae_model* model, double h);

/* A block of a composed matrix: `scale` times matrix `which` (transposed if `transpose`),
 * its top-left corner at (row, col). */
typedef struct {
  mbdae_matrix which;
  double scale;
  int row, col;
  int transpose;
} mbdae_block;

typedef enum { MBDAE_CSC = 0, MBDAE_CSR = 1 } mbdae_sparse_format;

/* The sum of the blocks as a rows x cols sparse matrix (entries of overlapping blocks are
 * added; a block outside rows x cols is MBDAE_ERROR_ARGUMENT). Two calls: first with
 * ptr = idx = val = NULL to get *nnz, then with arrays of sizes (cols + 1 for CSC,
 * rows + 1 for CSR), nnz and nnz. The pattern is the structural one (entries that are
 * zero at this state are included). */
mbdae_status mbdae_get_matrix(mbdae_model* model, const mbdae_block* blocks, int num_blocks,
                              int rows, int cols, mbdae_sparse_format format, int* nnz,
                              int* ptr, int* idx, double* val);

/* ---- Objectives and their gradients ------------------------------------------------- */

/* Values G_i of the model's objectives (MBDAE_OBJECTIVES; `objectives:` of the model file,
 * G = integral over [0, t_end] + terminal value at t_end) and their gradients dG_i/dp_k
 * with respect to parameters ("k") and spline ordinates ("SPLINE[i]", 0-based point
 * index), with the model's current parameters, spline points and options: the pipeline
 * of `mbdae gradient` (docs/sensitivities.md).
 *
 * method: "adjoint" (NULL = "adjoint"; HHT: the discrete adjoint of the run, IDA: IDAS
 *   adjoint sensitivities), "forward" (HHT: direct differentiation, IDA: IDAS forward
 *   sensitivities) or "fd" (central differences of whole runs; the step of each entry is
 *   read back with MBDAE_GRAD_FD_STEPS; option "gradient.fd_step").
 * objectives: num_objectives names (NULL or num_objectives = 0: every objective, in the
 *   model's order). The rows of the result are in the model's order whatever the order
 *   given.
 * wrt: num_wrt names, parameters and "SPLINE[i]" (NULL or num_wrt = 0: every parameter);
 *   wrt_splines != 0 adds every ordinate of every spline after them (skipping ones
 *   listed). The columns of the result are in this order.
 * results_path: NULL or "": no file; else the results file of the forward run plus, per
 *   objective, the group /objectives/NAME (attributes value, integral, terminal,
 *   gradient_names; dataset gradient), as `mbdae gradient -o` writes it: as PATH.PID.tmp
 *   beside it, renamed over PATH when the driver is through (an earlier file stays whole
 *   until then and is kept by a call that fails with an error); the model file itself
 *   (by any spelling or link) is refused with MBDAE_ERROR_IO.
 *
 * The result is stored in the handle and read with mbdae_count / mbdae_name
 * (MBDAE_GRADIENT_OBJECTIVES: rows, MBDAE_GRADIENT_WRT: columns), mbdae_get_gradient and
 * mbdae_gradient_report; it stays until the next successful mbdae_gradient or the model
 * is freed (setting a parameter does not clear it). The call runs its own simulations:
 * the stored output rows, the current state and the assembly are left as they were.
 * Parameters set with mbdae_set_parameter are fixed numbers as with `--set` (a parameter
 * computed from others follows them unless it was set itself).
 *
 * Errors (nothing stored, the previous result kept): an unknown method, objective or wrt
 * name (or an ordinate outside its spline, a name listed twice) is MBDAE_ERROR_ARGUMENT
 * (the message names it); a model without objectives, a parameter the exact methods
 * cannot differentiate (the element and line are named), a method the integrator cannot
 * provide for these objectives (the IDAS adjoint with objectives over accelerations or
 * reactions), a model that cannot be assembled (as `mbdae gradient` exits 2) is
 * MBDAE_ERROR_INPUT; a run that fails (the forward run, a perturbed run of fd or its
 * assembly, the sweep) is MBDAE_ERROR_SOLVER with the reason (a results file asked for
 * is written with status "failed"); a results file that cannot be written
 * MBDAE_ERROR_IO. */
mbdae_status mbdae_gradient(mbdae_model* model, const char* method,
                            const char* const* objectives, int num_objectives,
                            const char* const* wrt, int num_wrt, int wrt_splines,
                            const char* results_path);

typedef enum {
  MBDAE_GRAD_VALUES = 0,    /* G_i of the forward run                     num_objectives */
  MBDAE_GRAD_GRADIENT = 1,  /* dG_i/dp_k at [i * num_wrt + k] (row-major) num_objectives * num_wrt */
  MBDAE_GRAD_FD_STEPS = 2,  /* fd: the absolute step of each p_k          num_wrt (other
                               methods: MBDAE_ERROR_ARGUMENT) */
  MBDAE_GRAD_TIMES = 3,     /* process CPU seconds of the forward run, CPU seconds of the
                               gradient beyond it (fd: every perturbed run), wall seconds
                               of everything                              3 */
  MBDAE_GRAD_COUNTERS = 4   /* accepted steps of the forward run, whole runs done (fd:
                               1 + 2 per wrt entry), linear solves of the HHT sweep, bytes
                               of the stored HHT run                      4 */
} mbdae_gradient_output;

/* Quantity `what` of the stored gradient into out (n values). MBDAE_ERROR_ORDER before a
 * successful mbdae_gradient. Sizes: num_objectives = count of MBDAE_GRADIENT_OBJECTIVES,
 * num_wrt = count of MBDAE_GRADIENT_WRT. */
mbdae_status mbdae_get_gradient(mbdae_model* model, mbdae_gradient_output what, double* out,
                                int n);
/* The stored gradient as text, NUL-terminated: json = 0 the report `mbdae gradient`
 * prints (values, the table of dG/dp, method, times), json != 0 its `--json` object.
 * buf = NULL with size = 0 asks for the length: *length (not NULL) is then the number of
 * bytes needed, the NUL included; a buffer shorter than that is MBDAE_ERROR_SIZE. */
mbdae_status mbdae_gradient_report(mbdae_model* model, int json, char* buf, size_t size,
                                   size_t* length);

/* ---- Optimal control and identification ------------------------------------------- */

/* The result of an optimisation (mbdae_optimize); freed with mbdae_optimization_free. */
typedef struct mbdae_optimization mbdae_optimization;

/* Called after every Ipopt iteration (iteration 0: the starting point) with the objective
 * and the constraint violation (Ipopt's inf_pr) of the iterate. Return 0 to go on; a
 * positive value stops the optimisation (Ipopt: User_Requested_Stop; the result is then
 * "failed", with the last iterate run and written as usual); a negative value stops it
 * and abandons the results file (nothing is written: an earlier file of that name stays
 * as it was; the result has no results path). Runs on the calling thread, inside
 * mbdae_optimize: it must not call mbdae_optimize itself. */
typedef int (*mbdae_progress_callback)(int iteration, double objective,
                                       double constraint_violation, void* user_data);

/* Solves the problem file `problem_path` as `mbdae optimize` does (docs/sensitivities.md,
 * "Optimal control: mbdae optimize"): single shooting with Ipopt over the parameters and
 * spline ordinates of its `variables:`, minimising an objective of the model subject to
 * bounds on other objectives, with exact gradients (`method:`) and a limited-memory
 * Hessian. The problem's `model:` is resolved against the problem file's folder.
 * results_path: NULL or "": no file; else the run at the final point plus the group
 *   /optimization (variables, history, ...), as `mbdae optimize -o` writes it.
 *   It is written as PATH.PID.tmp beside it and renamed over PATH at the end (an earlier
 *   file stays whole until then; a call that fails, or a final run that could not start,
 *   leaves it as it was); a path that is the problem file or the problem's model file
 *   (by any spelling or link) is refused with MBDAE_ERROR_IO.
 * progress: NULL or a function called after every iteration with user_data.
 * *result (not NULL): a new result on MBDAE_OK, also when Ipopt did not converge (read
 *   its status with mbdae_optimization_report); left unchanged on an error.
 *
 * Errors (no result): a mistake in the problem file (unknown keys or names, bounds, a
 * start outside the bounds, a bad Ipopt option; the message names the problem file, line
 * and column) or in its model file (named), or a variable the gradient method cannot
 * differentiate, is MBDAE_ERROR_INPUT; a problem file that cannot be read, or a results
 * path that cannot be written (its folder does not exist, ...: the system's reason) or
 * is an input file, MBDAE_ERROR_IO; NULL problem_path or result
 * MBDAE_ERROR_ARGUMENT. Nothing is written then. */
mbdae_status mbdae_optimize(const char* problem_path, const char* results_path,
                            mbdae_progress_callback progress, void* user_data,
                            mbdae_optimization** result);
/* The same with the problem as YAML text: `name` is used in messages and `model:` is
 * resolved against its folder (as mbdae_model_from_string; NULL or "" = the working
 * folder, messages say "<string>"). */
mbdae_status mbdae_optimize_string(const char* text, const char* name, const char* results_path,
                                   mbdae_progress_callback progress, void* user_data,
                                   mbdae_optimization** result);
/* Frees a result (NULL is allowed). */
void mbdae_optimization_free(mbdae_optimization* result);

/* The result as text, NUL-terminated: json = 0 the report `mbdae optimize` prints (status,
 * objective, constraints, variables, iterations, times), json != 0 its `--json` object
 * {"status": "solved" | "failed", "objective": ..., "iterations": ..., "variables":
 * {"NAME": ...}, "constraint_violation": ..., "ipopt_status": ..., "objective_name": ...,
 * "constraints": {"OBJECTIVE": value}, "gradient_evaluations": ..., "failed_evaluations":
 * ..., "hessian_evaluations": ..., "runs": ..., "gradient_cpu_time": ..., "cpu_time": ...,
 * "wall_time": ..., "shooting_intervals": ..., "shooting_defect": ...}
 * (numbers with 17 significant digits, non-finite as null). buf = NULL with size = 0 asks
 * for the length: *length (not NULL) is then the number of bytes needed, the NUL
 * included; a buffer shorter than that is MBDAE_ERROR_SIZE. */
mbdae_status mbdae_optimization_report(const mbdae_optimization* result, int json, char* buf,
                                       size_t size, size_t* length);

/* Columns of the iteration history: iteration, objective, constraint violation (Ipopt's
 * inf_pr), dual infeasibility (inf_du), barrier parameter mu, step (alpha_pr), line-search
 * trials, gradient evaluations so far. */
#define MBDAE_OPTIMIZATION_HISTORY_COLUMNS 8
/* The history, one row per iteration (row 0: the starting point), row-major into out
 * (n = rows * MBDAE_OPTIMIZATION_HISTORY_COLUMNS values). out = NULL with n = 0 asks for
 * the number of rows (*rows, not NULL). */
mbdae_status mbdae_optimization_history(const mbdae_optimization* result, double* out, int n,
                                        int* rows);

/* ---- Joint space (api/joint_space.cc; docs/urdf.md, "Joint space") ---------------------- */

/* For a model whose joints form a tree of revolute, prismatic and fixed joints from the
 * ground (one joint per body: a URDF import, a serial arm): its n joint coordinates, one
 * per revolute joint (the angle of marker i about marker j's z axis, any real number) and
 * prismatic joint (the displacement along it), in the order of the model's joints. Every
 * function is exact, from the redundant-coordinate equations M x'' + C_x^T lambda = Q:
 * the absolute coordinates x, x' = J q', x'' = J q'' + J' q' follow from the joint state
 * by forward kinematics, and J^T C_x^T = 0 removes the multipliers. A model that is not
 * such a tree (a motion or gear joint, a loop, a free body) is MBDAE_ERROR_INPUT naming
 * the element. The model's current parameters are used; the stored state is not. */

/* n, the number of joint coordinates. */
mbdae_status mbdae_joint_count(mbdae_model* model, int* n);
/* The name of joint coordinate k (the joint's name) into buf (size bytes, NUL-terminated;
 * too short: MBDAE_ERROR_SIZE); *is_angle (if not NULL) 1 for a revolute joint, 0 for a
 * prismatic one. */
mbdae_status mbdae_joint_name(mbdae_model* model, int k, char* buf, size_t size, int* is_angle);
/* The joint-space mass matrix M_q(q) = J^T M J: n x n, column-major (symmetric). */
mbdae_status mbdae_joint_mass_matrix(mbdae_model* model, const double* q, int n, double* M);
/* Inverse dynamics tau = J^T (M x'' - Q(x, x', t)): the generalized force each joint must
 * transmit about (along) its axis for the joint accelerations qdd, with every force of the
 * model (gravity, force elements) acting. qd and qdd may be NULL (zero). */
mbdae_status mbdae_inverse_dynamics(mbdae_model* model, double t, const double* q, const double* qd,
                                    const double* qdd, int n, double* tau);
/* Bias forces b(q, qd) = tau(q, qd, 0) = C(q, qd) qd + g(q), and the gravity (applied
 * force) vector g(q) = tau(q, 0, 0). */
mbdae_status mbdae_joint_bias(mbdae_model* model, double t, const double* q, const double* qd, int n,
                              double* b);
mbdae_status mbdae_joint_gravity(mbdae_model* model, double t, const double* q, int n, double* g);
/* The absolute coordinates and velocities of a joint state (nq = MBDAE_COORDINATES each;
 * x and xd may be NULL, qd may be NULL): for mbdae_set_state. */
mbdae_status mbdae_joint_to_absolute(mbdae_model* model, const double* q, const double* qd, int n, double* x,
                                     double* xd, int nq);
/* The joint state of absolute coordinates that satisfy the joints (e.g. mbdae_get_state's):
 * q (angles in (-pi, pi]), qd = J^+ xd and qdd = J^+ (xdd - J' qd) (exact when x' and x''
 * are rates the joints allow). xd, xdd, qd, qdd may be NULL. */
mbdae_status mbdae_joint_from_absolute(mbdae_model* model, const double* x, const double* xd, const double* xdd,
                                       int nq, double* q, double* qd, double* qdd, int n);

#ifdef __cplusplus
}
#endif

#endif /* MBDAE_H_ */
