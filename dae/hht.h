// Hilber-Hughes-Taylor integrator for the index-3 form, after Negrut, Rampalli,
// Ottarsson, Sajdak, J. Comput. Nonlinear Dynam. 2 (2007) 73-85, with the
// modification for Euler parameters of Sherif, Nachbagauer, Steiner, Lauss,
// Multibody Syst. Dyn. 46 (2019) 181-202.
#pragma once

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "dae/integrator.h"
#include "dae/sparse.h"

namespace mbdae::dae {

struct HhtOptions {
  // Which residual the step solves (docs/hht.md, "Forms"):
  //  kEquilibrium (default): the equations of motion hold exactly at t_{n+1},
  //    M(q_{n+1}) a_{n+1} + F_{n+1} = 0, and Newmark's formulas use the acceleration-like
  //    variable abar_{n+1} = (1 + alpha) a_{n+1} - alpha a_n: the generalized-alpha scheme
  //    of Arnold & Bruls, Multibody Syst. Dyn. 18 (2007) 185-202, with alpha_m = 0,
  //    alpha_f = -alpha (HHT's parameters). Second order in q and v also when M depends
  //    on q.
  //  kNegrut: the residual of Negrut et al. 2007, (M a)_{n+1}/(1+alpha) + F_{n+1}
  //    - alpha/(1+alpha) F_n = 0 (forces mixed at t_n and t_{n+1}); identical to the above
  //    for a constant M and linear forces, first order for alpha < 0 when M depends on q.
  enum class Form { kEquilibrium, kNegrut };
  Form form = Form::kEquilibrium;
  // The acceleration-like starting value of the equilibrium form (docs/hht.md, "Start";
  // the negrut form ignores it):
  //  kConsistent: abar_0 = a_0 (per quaternion group omegabar'_0 = 2 G(e_0) a_0) and the
  //    consistent v_0. The generalized-alpha variable approximates a(t_n + alpha h)
  //    (Arnold & Bruls 2007), and v_n is off q'(t_n) by O(h^2) along the constraints (see
  //    kPerturbed), so this start is off the smooth solution: when q'''(t_0) != 0 (a
  //    driven motion, a jerk) the multipliers carry a transient that alternates in sign
  //    from step to step (1.3e-2 N m at t = 0.005 s on tests/app/models/arm_motion.yaml).
  //  kPerturbed: the starting values of the smooth solution. With j = (a_p - a_0)/h, a_p
  //    the solution of the acceleration-level equations [M C_q^T; C_q 0] [a; lambda] =
  //    [Q; gamma] at t_0 + h, q_0 + h v_0 + h^2/2 a_0, v_0 + h a_0 (h: the first step):
  //    abar_0 = a_0 + alpha h j = a(t_0 + alpha h) + O(h^2) (as the perturbed starting
  //    values of Arnold, Bruls, Cardona, Numer. Math. 129 (2015) 149-179; per quaternion
  //    group omegabar'_0 likewise), and v_0 moved along the constraints by dv with
  //    [M C_q^T; C_q 0] [dv; mu] = [0; -(1/12 + alpha^2/4) h^2 C_q j]: Newmark's update
  //    with exact positions keeps v_n = q'(t_n) - (1/12 + alpha^2/4) h^2 q'''(t_n) + O(h^3)
  //    along the position-level constraints, and an exact v_0 excites the parasitic root
  //    -rho_inf (double along the constraints: the multipliers then alternate in sign with
  //    an envelope n rho_inf^n; correcting abar_0 alone does not remove it). state().v at
  //    t_0 is that v_0 (C_q v + C_t = O(h^2)). Two more factorisations at Initialize. When
  //    the acceleration-level system cannot be solved, the start falls back to
  //    kConsistent (Summary::message says so). The discrete sensitivities
  //    (sensitivities/) differentiate the kConsistent start: gradient runs use it.
  enum class Start { kConsistent, kPerturbed };
  Start start = Start::kConsistent;
  // Numerical damping, in [-1/3, 0]; beta = (1 - alpha)^2 / 4, gamma = 1/2 - alpha.
  double alpha = -0.1;
  // Step size: the fixed step, or the initial step when adaptive.
  double step = 1e-3;
  // Adaptive step size control on the local error estimate.
  bool adaptive = false;
  // Tolerance of the local error estimate (weighted RMS norm, relative and absolute
  // parts both equal to this value) when adaptive.
  double tolerance = 1e-6;
  double min_step = 1e-12;
  double max_step = 0;  // 0: no limit
  // true: the modified scheme for Euler parameters (Sherif et al. 2019); false: classical.
  bool modified = true;
  // Newton: stop when the weighted norm of the correction is below
  // max(newton_tolerance, adaptive_newton_factor * tolerance) (adaptive) or below
  // newton_tolerance (fixed step). Gradients of a run (sensitivities/) are exact to this
  // threshold: their forward runs lower adaptive_newton_factor.
  double newton_tolerance = 1e-12;
  double adaptive_newton_factor = 1e-3;
  // An iteration whose correction stops contracting (rate > 0.5) while its norm is below
  // newton_noise_factor * the Newton threshold has reached the round-off floor of the
  // linear solve and is accepted as converged (counted in Summary::newton_noise_stops).
  double newton_noise_factor = 1e4;
  int max_newton_iterations = 10;
  // The linear solver of the Newton matrix (docs/hht.md, "Linear solver"): kKlu (default)
  // sparse LU by KLU; kTree the block elimination along the tree of bodies, each with the
  // joint to its parent (dae/block_tree_lu.h): no fill and dense small blocks, for systems
  // whose bodies, joints and forces form a tree. Where the system is no such tree, kTree
  // uses KLU (Summary::linear_solver says which ran), and a factorisation whose pivot ratio
  // is tiny or has dropped is redone by KLU (counted in Summary::klu_fallbacks).
  using LinearSolver = LinearSolverKind;
  LinearSolver linear_solver = LinearSolver::kKlu;
  // One AdvanceTo call fails (with a message) after this many step attempts beyond the
  // number the nominal step needs to reach its target: the step size has collapsed
  // (as SUNDIALS' mxstep). 0: no limit.
  int max_steps_per_call = 100000;
  // Reuse the factorised Newton matrix across iterations and steps while the
  // convergence rate stays below this value.
  double jacobian_reuse_rate = 0.2;
  int max_steps_same_jacobian = 20;
  // The cost of a fresh Newton matrix (the Jacobians' evaluation and the factorisation) in
  // Newton iterations (each a residual and a solve); docs/hht.md, "Newton matrix". When
  // positive, the matrix is also refreshed once it no longer pays: after a step whose
  // iterations reach the average cost per step since the last refresh (that cost counted
  // in), a renewal rule. 0: only the rules above. Negative (default): kTreeJacobianCost
  // when the tree elimination factorises the matrix, 0 with KLU (whose results are those
  // of the rules above).
  double jacobian_cost = -1;
  // The first iterate of each step's Newton iteration (docs/hht.md, "Newton iteration"):
  //  kConstant: a_{n+1} = a_n, lambda_{n+1} = lambda_n.
  //  kLinear: extrapolated from the last two accepted steps, a_{n+1} = a_n + r (a_n -
  //    a_{n-1}) and lambda likewise, r = h / h_prev (constant in the first step after
  //    Initialize); in the modified scheme the iterate's G(e_{n+1}) is also taken at the
  //    Euler parameters this prediction gives instead of at e_n (one more pass of the
  //    kinematic update). The converged step is the same to the Newton threshold.
  //  kAuto (default): kLinear when the tree elimination factorises the matrix, kConstant
  //    with KLU (whose results stay those of the constant predictor).
  enum class Predictor { kAuto, kConstant, kLinear };
  Predictor predictor = Predictor::kAuto;
  // The Newton matrix's columns of the Euler-parameter groups in the modified scheme
  // (docs/hht.md, "Newton matrix"; unused by the classical scheme, whose matrix is exact):
  //  kFirstOrder: dq/da = mix beta h^2 I, dv/da = mix gamma h I, the classical scheme's,
  //    a first-order approximation of the rotation update (mix = 1 + alpha in the
  //    equilibrium form, 1 in the negrut form).
  //  kExact: each group's exact 4 x 4 dq/da and dv/da (dae/hht_rotation.h) at the iterate
  //    of the refresh. The converged step is the same to the Newton threshold.
  //  kAuto (default): kExact when the tree elimination factorises the matrix,
  //    kFirstOrder with KLU (whose results stay those of the first-order matrix).
  enum class RotationJacobian { kAuto, kFirstOrder, kExact };
  RotationJacobian rotation_jacobian = RotationJacobian::kAuto;
  // Replay: when not empty, the steps taken are exactly these sizes in order (e.g. the
  // accepted steps of an earlier adaptive run), with no error control and no step
  // changes: a Newton failure or a sequence that does not meet an AdvanceTo target (to
  // 1e-9 of a step) fails the run. For finite-difference references of adaptive runs
  // (the discrete objective of a frozen step sequence).
  std::vector<double> replay_steps;
  // Dense output (docs/hht.md, "Dense output"): false (default): every AdvanceTo target
  // is a step end (the step is shortened to land on it, as before). true: the steps do
  // not depend on the targets; AdvanceTo steps until it reaches or passes the target and
  // state() is interpolated there: q and v cubic Hermite from (q, v) and (v, a) at the
  // step's two ends, a and lambda linear, each Euler-parameter group normalised (and its
  // rate made orthogonal to it); quadrature() is the integral of the integrand's linear
  // interpolant over the part of the step. Not with replay_steps, SaveSnapshot or
  // RestoreSnapshot (the interpolated state is not a step's state).
  bool dense_output = false;
  // With dense_output, no step passes this time (the step reaching it is shortened to
  // land on it, as an AdvanceTo target is without dense output) and AdvanceTo beyond it
  // fails. Infinity: no limit (the last step may pass the last target). Unused without
  // dense_output.
  double stop_time = std::numeric_limits<double>::infinity();

  bool IsValid(std::string* error) const;

  // jacobian_cost's value for the tree elimination: on the ball chains of 100 and 1000
  // rods a fresh matrix costs about 3 iterations of HHT with the tree (docs/hht.md,
  // "Newton matrix"; bench_step_flops' BM_HhtRefresh fits it).
  static constexpr double kTreeJacobianCost = 3.0;
};

// "klu" | "tree"; and the inverse (false for an unknown name).
const char* HhtLinearSolverName(HhtOptions::LinearSolver solver);
bool ParseHhtLinearSolver(const std::string& name, HhtOptions::LinearSolver* solver);

// "auto" | "constant" | "linear"; and the inverse (false for an unknown name).
const char* HhtPredictorName(HhtOptions::Predictor predictor);
bool ParseHhtPredictor(const std::string& name, HhtOptions::Predictor* predictor);

// "auto" | "first-order" | "exact"; and the inverse (false for an unknown name).
const char* HhtRotationJacobianName(HhtOptions::RotationJacobian jacobian);
bool ParseHhtRotationJacobian(const std::string& name, HhtOptions::RotationJacobian* jacobian);

// The names of each choice option, in the order messages list them: what the model file,
// the command line and the C API accept (HhtFormNames: equilibrium, negrut; HhtStartNames:
// consistent, perturbed; HhtPredictorNames: auto, constant, linear;
// HhtRotationJacobianNames: auto, first-order, exact; HhtLinearSolverNames: klu, tree).
const std::vector<std::string>& HhtFormNames();
const std::vector<std::string>& HhtStartNames();
const std::vector<std::string>& HhtPredictorNames();
const std::vector<std::string>& HhtRotationJacobianNames();
const std::vector<std::string>& HhtLinearSolverNames();

// "equilibrium" | "negrut"; and the inverse (false for an unknown name).
const char* HhtFormName(HhtOptions::Form form);
bool ParseHhtForm(const std::string& name, HhtOptions::Form* form);
// "consistent" | "perturbed"; and the inverse (false for an unknown name).
const char* HhtStartName(HhtOptions::Start start);
bool ParseHhtStart(const std::string& name, HhtOptions::Start* start);

std::unique_ptr<Integrator> MakeHhtIntegrator(MechanicalSystem& system, const HhtOptions& options);

// The history of an HHT snapshot (IntegratorSnapshot::history; Integrator::SaveSnapshot,
// RestoreSnapshot): Size(nq, nc, ng) numbers for ng Euler-parameter groups
// (MechanicalSystem::quaternion_offsets), in this order:
//   kForm     1 (equilibrium form) or 2 (negrut)
//   kModified 1 (the modified scheme) or 0
//   kAlpha    alpha; a restore into an integrator of another form, scheme or alpha throws
//   kHPrev    the last accepted step (0 before the first): scales abar's history term
//   kHNext    the step the integrator tries next (the step-size control's state)
//   kStep     accepted steps since Initialize; a restored integrator replays
//             HhtOptions::replay_steps from this entry on, so a snapshot of step n of a
//             run continues, with the run's steps as replay_steps, with step n + 1
//   kVectors  nq numbers: abar_n (equilibrium form) or F_n = C_q^T lambda_n - Q_n
//             (negrut), then 3 ng: each group's omegabar'_n (equilibrium form; kept
//             but unused by negrut), then nq: a_{n-1} and nc: lambda_{n-1} (the
//             linear predictor's; unused when kHPrev is 0)
struct HhtHistory {
  enum : int { kForm = 0, kModified, kAlpha, kHPrev, kHNext, kStep, kVectors };
  static int Size(int nq, int nc, int ng) { return kVectors + 2 * nq + 3 * ng + nc; }
};

// The Newton matrix of an HHT step of size h (docs/hht.md), the one the integrator
// factorises, at the iterate (t_{n+1}, q_{n+1}, v_{n+1}, a_{n+1}, lambda_{n+1}):
//   kEquilibrium: [ M/(1+alpha) + beta h^2 (K_Ma + K_C - Q_q) - gamma h Q_v , C_q^T/(1+alpha) ]
//                 [ C_q                                                    , 0               ]
//   kNegrut:      [ M/(1+alpha) + beta h^2 (K_Ma/(1+alpha) + K_C - Q_q) - gamma h Q_v , C_q^T ]
//                 [ C_q                                                               , 0     ]
// with beta = (1 - alpha)^2 / 4, gamma = 1/2 - alpha, K_Ma = d(M a)/dq, K_C =
// d(C_q^T lambda)/dq, Q_q = dQ/dq, Q_v = dQ/dv. It is the derivative of the step's
// residual (r_q, r_c) with respect to (a_{n+1}, lambda_{n+1}) through Newmark's formulas
// (dq_{n+1}/da_{n+1} = (1 + alpha) beta h^2 I in the equilibrium form, beta h^2 I in the
// negrut form; dv/da likewise with gamma h), exact for the classical scheme and its
// first-order approximation for the modified one. With rotation blocks (the modified
// scheme's exact derivative, HhtOptions::rotation_jacobian) the columns of each
// Euler-parameter group take the group's 4 x 4 dq/da and dv/da instead (the pattern then
// holds, in each block row, the union of the group's four columns). The pattern, (nq +
// nc) square, is fixed at construction and holds the whole diagonal (zeros included, for
// the factorisation). Uses only options.alpha and options.form.
class HhtNewtonMatrix {
 public:
  // Throws std::invalid_argument if the system's patterns are invalid or of the wrong size.
  // rotation_blocks: room in the pattern for the groups' exact blocks (the system's
  // quaternion_offsets).
  HhtNewtonMatrix(MechanicalSystem& system, const HhtOptions& options,
                  bool rotation_blocks = false);

  const CscPattern& pattern() const { return assembler_.pattern(); }
  // Evaluates the system's matrices at (t, q, v, a, lambda) and writes the matrix for
  // step h into values (pattern().nnz(), pattern order). Returns the system's Evaluate
  // code (0 success; values are then complete). With force and constraint (nq and nc
  // values) the same evaluation also writes Q and C there, and matrix() keeps M and C_q:
  // a residual at that iterate needs no evaluation of its own.
  // rotation: nullptr (the first-order matrix) or, with rotation blocks, 32 numbers per
  // group: dq/da / (mix beta h^2) - I and dv/da / (mix gamma h) - I (4 x 4, row-major;
  // mix = 1 + alpha in the equilibrium form, 1 in the negrut form).
  int Assemble(double t, double h, const double* q, const double* v, const double* a,
               const double* lambda, double* values, double* force = nullptr,
               double* constraint = nullptr, const double* rotation = nullptr);
  // The system's matrix m of the last Assemble (not kConstraintVelDq).
  const std::vector<double>& matrix(Matrix m) const { return mat_[static_cast<int>(m)]; }
  // All of them, indexed by Matrix (AssembleFrom's mats).
  const std::vector<double>* matrices() const { return mat_; }
  // The same from matrices the caller evaluated at that iterate: mats[m] holds the values
  // of Matrix m (all but kConstraintVelDq are read; K_Ma with a = a_{n+1}, K_C with
  // w = lambda_{n+1}).
  void AssembleFrom(double h, const std::vector<double>* mats, double* values,
                    const double* rotation = nullptr) const;
  bool has_rotation_blocks() const { return rotation_blocks_; }

 private:
  MechanicalSystem& system_;
  double alpha_ = 0, beta_ = 0, gamma_ = 0;
  bool equilibrium_ = true;
  BlockAssembler assembler_;
  int b_mass_ = 0, b_kma_ = 0, b_kc_ = 0, b_qq_ = 0, b_qv_ = 0, b_cqt_ = 0, b_cq_ = 0;
  std::vector<double> mat_[kNumMatrices];  // the system's matrices (all but kConstraintVelDq)
  // Rotation blocks: per system matrix, each row it has in a group's four columns (the
  // group, the row's entries in those columns, -1 where it has none, and the result's
  // positions of that row in the four columns).
  struct RotationRow {
    int group, k[4], pos[4];
  };
  std::vector<RotationRow> rot_rows_[kNumMatrices];
  bool rotation_blocks_ = false;
};

}  // namespace mbdae::dae
