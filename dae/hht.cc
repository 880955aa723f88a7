// HHT-alpha for the index-3 mechanical DAE (see dae/hht.h and docs/hht.md).
//
// Unknowns of each step: a_{n+1}, lambda_{n+1}; F = C_q^T lambda - Q.
// Form kNegrut (Negrut, Rampalli, Ottarsson, Sajdak, J. Comput. Nonlinear Dynam. 2
// (2007) 73-85), Newmark's formulas on a:
//   r_q = (M a)_{n+1} / (1 + alpha) + F_{n+1} - alpha / (1 + alpha) F_n
//   r_c = C(q_{n+1}, t_{n+1}) / (beta h^2)
//   Newton matrix [ M/(1+alpha) + beta h^2 (K_Ma/(1+alpha) + K_C - Q_q) - gamma h Q_v , C_q^T ]
//                 [ C_q                                                               , 0     ]
// Form kEquilibrium (generalized-alpha, Arnold & Bruls, Multibody Syst. Dyn. 18 (2007)
// 185-202, alpha_m = 0, alpha_f = -alpha), Newmark's formulas on the acceleration-like
// abar_{n+1} = (1 + alpha) a_{n+1} - alpha a_n (abar_0 = a_0):
//   r_q = ((M a)_{n+1} + F_{n+1}) / (1 + alpha)
//   r_c = C(q_{n+1}, t_{n+1}) / ((1 + alpha) beta h^2)
//   Newton matrix [ M/(1+alpha) + beta h^2 (K_Ma + K_C - Q_q) - gamma h Q_v , C_q^T/(1+alpha) ]
//                 [ C_q                                                    , 0               ]
//   (dq_{n+1}/da_{n+1} = (1 + alpha) beta h^2, dv_{n+1}/da_{n+1} = (1 + alpha) gamma h).
//
// Quaternion groups, `modified = true`: OUR modification (not the formulas of Sherif et
// al. 2019, which the material available to us did not reveal). For each group of Euler
// parameters e (scalar first) the Newmark formulas act on the body angular velocity
// omega = 2 G(e) e' and acceleration omega' = 2 G(e) e'' instead of on e', e'':
//   omega'_n = 2 G(e_n) a_n,  omega'_{n+1} = 2 G(e_{n+1}) a_{n+1}
//   theta   = h omega_n + h^2 [(1/2 - beta) omega'_n + beta omega'_{n+1}]
//   omega_{n+1} = omega_n + h [(1 - gamma) omega'_n + gamma omega'_{n+1}]
//   e_{n+1} = (1 + rho) e_n (x) exp(theta / 2),   e'_{n+1} = G(e_{n+1})^T omega_{n+1} / 2
//             + gamma h s e_{n+1}
//   rho = beta h^2 s,  s = e_{n+1}^T a_{n+1} + |e'_{n+1}|^2   (acceleration-level
//   normalisation defect; it is zero at convergence because the normalisation
//   constraint then forces rho = 0).
// Here G(e) is Nikravesh's 3x4 body matrix, (x) the quaternion product and
// exp(theta/2) = (cos|theta|/2, sin(|theta|/2) theta/|theta|). For a rotation about a
// fixed principal axis omega, omega' keep their direction, so the update is exactly
// Newmark's for the rotation angle: with alpha = 0 a constant moment gives
// omega_{n+1} = omega_n + h M / J exactly (trapezoidal rule on a constant). The
// dependence of e_{n+1} on G(e_{n+1}) is resolved inside the Newton iteration (G is
// taken at the previous iterate). The Newton matrix is either the classical one, the
// first-order approximation of the modified map (dq/da = beta h^2 I, dv/da = gamma h I),
// or, with HhtOptions::rotation_jacobian exact, the map's own 4 x 4 blocks per group
// (dae/hht_rotation.h; the tree elimination's default).
// In the kEquilibrium form omega' is replaced by the acceleration-like body quantity
// omegabar'_{n+1} = (1 + alpha) 2 G(e_{n+1}) a_{n+1} - alpha 2 G(e_n) a_n (stored per
// group; omegabar'_0 = 2 G(e_0) a_0), and rho = (1 + alpha) beta h^2 s, the radial
// velocity term (1 + alpha) gamma h s e_{n+1}: s stays the defect of the true a_{n+1}
// (so its normalisation part holds at t_{n+1}), and the Newton matrix is again the
// first-order approximation of the map (dq/da = (1 + alpha) beta h^2 I, ...).
#include "dae/hht.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <utility>

#include "dae/block_tree_lu.h"
#include "dae/consistent.h"
#include "dae/format.h"
#include "dae/hht_rotation.h"
#include "dae/klu_solver.h"
#include "dae/tree_kkt.h"

namespace mbdae::dae {

bool HhtOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = "HhtOptions: " + why;
    return false;
  };
  if (!(alpha >= -1.0 / 3.0 && alpha <= 0.0))
    return fail("alpha = " + std::to_string(alpha) + " is outside [-1/3, 0]");
  if (!(step > 0) || !std::isfinite(step)) return fail("step must be positive and finite");
  if (!(min_step > 0)) return fail("min_step must be positive");
  if (min_step > step) return fail("min_step is larger than step");
  if (max_step < 0) return fail("max_step must be >= 0 (0: no limit)");
  if (max_step > 0 && max_step < min_step) return fail("max_step is smaller than min_step");
  if (adaptive && !(tolerance > 0)) return fail("tolerance must be positive");
  if (!(newton_tolerance > 0 && newton_tolerance < 1))
    return fail("newton_tolerance must be in (0, 1)");
  if (!(adaptive_newton_factor > 0 && adaptive_newton_factor <= 1))
    return fail("adaptive_newton_factor must be in (0, 1]");
  if (max_newton_iterations < 1) return fail("max_newton_iterations must be >= 1");
  if (max_steps_per_call < 0) return fail("max_steps_per_call must be >= 0 (0: no limit)");
  if (!(newton_noise_factor >= 1)) return fail("newton_noise_factor must be >= 1");
  if (!(jacobian_reuse_rate > 0 && jacobian_reuse_rate < 1))
    return fail("jacobian_reuse_rate must be in (0, 1)");
  if (!std::isfinite(jacobian_cost)) return fail("jacobian_cost must be finite");
  if (max_steps_same_jacobian < 1) return fail("max_steps_same_jacobian must be >= 1");
  for (double h : replay_steps)
    if (!(h > 0) || !std::isfinite(h)) return fail("replay_steps must be positive and finite");
  if (dense_output && !replay_steps.empty())
    return fail("dense_output and replay_steps exclude each other (a replay lands on its targets)");
  if (std::isnan(stop_time)) return fail("stop_time must not be NaN");
  return true;
}

namespace {

// The names of an option's values: the first pair's value is the fallback of NameOf.
template <class E>
using NameTable = std::initializer_list<std::pair<const char*, E>>;

template <class E>
const char* NameOf(E value, NameTable<E> table) {
  for (const auto& entry : table)
    if (entry.second == value) return entry.first;
  return table.begin()->first;
}

template <class E>
bool ParseName(const std::string& name, NameTable<E> table, E* value) {
  for (const auto& entry : table)
    if (name == entry.first) {
      *value = entry.second;
      return true;
    }
  return false;
}

constexpr NameTable<HhtOptions::Form> kFormNames = {
    {"equilibrium", HhtOptions::Form::kEquilibrium}, {"negrut", HhtOptions::Form::kNegrut}};
constexpr NameTable<HhtOptions::Start> kStartNames = {
    {"consistent", HhtOptions::Start::kConsistent}, {"perturbed", HhtOptions::Start::kPerturbed}};
constexpr NameTable<HhtOptions::Predictor> kPredictorNames = {
    {"auto", HhtOptions::Predictor::kAuto},
    {"constant", HhtOptions::Predictor::kConstant},
    {"linear", HhtOptions::Predictor::kLinear}};
constexpr NameTable<HhtOptions::RotationJacobian> kRotationJacobianNames = {
    {"auto", HhtOptions::RotationJacobian::kAuto},
    {"first-order", HhtOptions::RotationJacobian::kFirstOrder},
    {"exact", HhtOptions::RotationJacobian::kExact}};
constexpr NameTable<HhtOptions::LinearSolver> kLinearSolverNames = {
    {"klu", HhtOptions::LinearSolver::kKlu}, {"tree", HhtOptions::LinearSolver::kTree}};

// The names of table, built once per option (each enum has one table).
template <class E>
const std::vector<std::string>& NamesOf(NameTable<E> table) {
  static const std::vector<std::string> names = [&] {
    std::vector<std::string> v;
    for (const auto& entry : table) v.emplace_back(entry.first);
    return v;
  }();
  return names;
}

}  // namespace

const std::vector<std::string>& HhtFormNames() { return NamesOf(kFormNames); }
const std::vector<std::string>& HhtStartNames() { return NamesOf(kStartNames); }
const std::vector<std::string>& HhtPredictorNames() { return NamesOf(kPredictorNames); }
const std::vector<std::string>& HhtRotationJacobianNames() {
  return NamesOf(kRotationJacobianNames);
}
const std::vector<std::string>& HhtLinearSolverNames() { return NamesOf(kLinearSolverNames); }

const char* HhtFormName(HhtOptions::Form form) { return NameOf(form, kFormNames); }
bool ParseHhtForm(const std::string& name, HhtOptions::Form* form) {
  return ParseName(name, kFormNames, form);
}
const char* HhtStartName(HhtOptions::Start start) { return NameOf(start, kStartNames); }
bool ParseHhtStart(const std::string& name, HhtOptions::Start* start) {
  return ParseName(name, kStartNames, start);
}
const char* HhtPredictorName(HhtOptions::Predictor predictor) {
  return NameOf(predictor, kPredictorNames);
}
bool ParseHhtPredictor(const std::string& name, HhtOptions::Predictor* predictor) {
  return ParseName(name, kPredictorNames, predictor);
}
const char* HhtRotationJacobianName(HhtOptions::RotationJacobian jacobian) {
  return NameOf(jacobian, kRotationJacobianNames);
}
bool ParseHhtRotationJacobian(const std::string& name, HhtOptions::RotationJacobian* jacobian) {
  return ParseName(name, kRotationJacobianNames, jacobian);
}
const char* HhtLinearSolverName(HhtOptions::LinearSolver solver) {
  return NameOf(solver, kLinearSolverNames);
}
bool ParseHhtLinearSolver(const std::string& name, HhtOptions::LinearSolver* solver) {
  return ParseName(name, kLinearSolverNames, solver);
}

HhtNewtonMatrix::HhtNewtonMatrix(MechanicalSystem& system, const HhtOptions& options,
                                 bool rotation_blocks)
    : system_(system) {
  const int nq = system_.num_coordinates(), nc = system_.num_constraints();
  alpha_ = options.alpha;
  beta_ = (1 - alpha_) * (1 - alpha_) / 4;
  gamma_ = 0.5 - alpha_;
  equilibrium_ = options.form == HhtOptions::Form::kEquilibrium;
  std::string err;
  for (int m = 0; m < kNumMatrices; ++m) {
    const CscPattern& p = system_.pattern(static_cast<Matrix>(m));
    if (!p.IsValid(&err))
      throw std::invalid_argument("HHT: pattern of matrix " + std::to_string(m) + ": " + err);
    if (m != static_cast<int>(Matrix::kConstraintVelDq)) mat_[m].assign(p.nnz(), 0.0);
  }
  auto check_dims = [&](Matrix m, int rows, const char* name) {
    const CscPattern& p = system_.pattern(m);
    if (p.rows != rows || p.cols != nq)
      throw std::invalid_argument(std::string("HHT: pattern of ") + name + " is " +
                                  std::to_string(p.rows) + " x " + std::to_string(p.cols) +
                                  ", expected " + std::to_string(rows) + " x " +
                                  std::to_string(nq));
  };
  check_dims(Matrix::kMass, nq, "M");
  check_dims(Matrix::kMassTimesAccDq, nq, "d(Ma)/dq");
  check_dims(Matrix::kForceDq, nq, "dQ/dq");
  check_dims(Matrix::kForceDv, nq, "dQ/dv");
  check_dims(Matrix::kConstraintDq, nc, "C_q");
  check_dims(Matrix::kConstraintTDq, nq, "d(C_q^T w)/dq");
  b_mass_ = assembler_.AddBlock(system_.pattern(Matrix::kMass), 0, 0);
  b_kma_ = assembler_.AddBlock(system_.pattern(Matrix::kMassTimesAccDq), 0, 0);
  b_kc_ = assembler_.AddBlock(system_.pattern(Matrix::kConstraintTDq), 0, 0);
  b_qq_ = assembler_.AddBlock(system_.pattern(Matrix::kForceDq), 0, 0);
  b_qv_ = assembler_.AddBlock(system_.pattern(Matrix::kForceDv), 0, 0);
  b_cqt_ = assembler_.AddBlock(system_.pattern(Matrix::kConstraintDq), 0, nq, /*transpose=*/true);
  b_cq_ = assembler_.AddBlock(system_.pattern(Matrix::kConstraintDq), nq, 0);
  std::vector<std::pair<int, int>> diag;
  for (int i = 0; i < nq + nc; ++i) diag.push_back({i, i});
  assembler_.AddEntries(diag);
  // The matrices whose columns meet dq/da or dv/da, and the row of their block.
  const std::pair<Matrix, int> rotated[] = {
      {Matrix::kMassTimesAccDq, 0}, {Matrix::kConstraintTDq, 0}, {Matrix::kForceDq, 0},
      {Matrix::kForceDv, 0},        {Matrix::kConstraintDq, nq}};
  const std::vector<int>& groups = system_.quaternion_offsets();
  rotation_blocks_ = rotation_blocks && options.modified && !groups.empty();
  // Per rotated matrix, each row it has in a group's four columns (its entries there, -1
  // where it has none); the pattern gets that row in all four columns.
  std::vector<std::pair<int, int>> fill;
  std::vector<std::vector<int>> rows(kNumMatrices);  // each RotationRow's row
  for (const auto& [m, row0] : rotated) {
    if (!rotation_blocks_) break;
    const CscPattern& p = system_.pattern(m);
    auto& list = rot_rows_[static_cast<int>(m)];
    std::vector<int> slot(p.rows, -1);  // the row's entry in list for this group
    for (size_t grp = 0; grp < groups.size(); ++grp) {
      const size_t first = list.size();
      for (int c = 0; c < 4; ++c)
        for (int k = p.col_start[groups[grp] + c]; k < p.col_start[groups[grp] + c + 1]; ++k) {
          const int row = p.row_index[k];
          if (slot[row] < 0) {
            slot[row] = static_cast<int>(list.size());
            list.push_back(RotationRow{static_cast<int>(grp), {-1, -1, -1, -1}, {}});
            rows[static_cast<int>(m)].push_back(row0 + row);
            for (int j = 0; j < 4; ++j) fill.push_back({row0 + row, groups[grp] + j});
          }
          list[slot[row]].k[c] = k;
        }
      for (size_t i = first; i < list.size(); ++i) slot[rows[static_cast<int>(m)][i] - row0] = -1;
    }
  }
  if (rotation_blocks_) assembler_.AddEntries(fill);
  assembler_.Finalize(nq + nc, nq + nc);
  for (int m = 0; m < kNumMatrices; ++m)
    for (size_t i = 0; i < rot_rows_[m].size(); ++i)
      for (int j = 0; j < 4; ++j)
        rot_rows_[m][i].pos[j] =
            assembler_.pattern().find(rows[m][i], groups[rot_rows_[m][i].group] + j);
}

int HhtNewtonMatrix::Assemble(double t, double h, const double* q, const double* v,
                              const double* a, const double* lambda, double* values,
                              double* force, double* constraint, const double* rotation) {
  EvalInput in;
  in.t = t;
  in.q = q;
  in.v = v;
  in.a = a;
  in.w = lambda;
  EvalOutput out;
  out.force = force;
  out.constraint = constraint;
  for (int m = 0; m < kNumMatrices; ++m)
    if (m != static_cast<int>(Matrix::kConstraintVelDq)) out.matrix[m] = mat_[m].data();
  const int rc = system_.Evaluate(in, out);
  if (rc != 0) return rc;
  AssembleFrom(h, mat_, values, rotation);
  return 0;
}

void HhtNewtonMatrix::AssembleFrom(double h, const std::vector<double>* mats, double* values,
                                   const double* rotation) const {
  auto M = [&](Matrix m) { return mats[static_cast<int>(m)].data(); };
  const double s = 1 / (1 + alpha_), bh2 = beta_ * h * h;
  // The blocks whose columns carry dq/da or dv/da, with their scales (the first-order
  // factors of dq/da and dv/da included). The blocks of the top left overlap and are
  // summed in this order; C_q^T and C_q overlap nothing.
  struct Term {
    int block;
    Matrix m;
    double scale;
  };
  const Term terms[] = {{b_kma_, Matrix::kMassTimesAccDq, equilibrium_ ? bh2 : bh2 * s},
                        {b_kc_, Matrix::kConstraintTDq, bh2},
                        {b_qq_, Matrix::kForceDq, -bh2},
                        {b_qv_, Matrix::kForceDv, -gamma_ * h},
                        {b_cq_, Matrix::kConstraintDq, 1.0}};
  assembler_.SetZero(values);
  assembler_.Accumulate(b_mass_, M(Matrix::kMass), s, values);
  for (const Term& t : terms) assembler_.Accumulate(t.block, M(t.m), t.scale, values);
  assembler_.Accumulate(b_cqt_, M(Matrix::kConstraintDq), equilibrium_ ? s : 1.0, values);
  if (!rotation) return;
  if (!has_rotation_blocks())
    throw std::logic_error("HhtNewtonMatrix: rotation blocks given, but its pattern has no room for them");
  // Column j of a group: the sum over the group's columns c of B[:, c] (R - I)[c][j], B
  // with its scale, R = dq/da / (mix beta h^2) (dv/da / (mix gamma h) for Q_v); row by
  // row, each of the row's four results loaded and stored once (c in increasing order).
  for (const Term& t : terms) {
    const double* b = M(t.m);
    const int off = t.m == Matrix::kForceDv ? 16 : 0;
    for (const RotationRow& rr : rot_rows_[static_cast<int>(t.m)]) {
      const double* r = rotation + 32 * rr.group + off;
      double x[4];
      for (int c = 0; c < 4; ++c) x[c] = rr.k[c] >= 0 ? t.scale * b[rr.k[c]] : 0.0;
      for (int j = 0; j < 4; ++j) {
        double v = values[rr.pos[j]];
        for (int c = 0; c < 4; ++c)
          if (rr.k[c] >= 0) v += x[c] * r[4 * c + j];
        values[rr.pos[j]] = v;
      }
    }
  }
}

namespace {

// A number for messages: %.6g (std::to_string prints 1e-12 as 0.000000).
std::string Num(double x) { return FormatG(x, 6); }

// Whether the Newton matrix may take the exact rotation blocks (HhtOptions::
// rotation_jacobian): room for them in its pattern.
bool WantsRotationBlocks(const HhtOptions& o) {
  using R = HhtOptions::RotationJacobian;
  return o.modified && (o.rotation_jacobian == R::kExact ||
                        (o.rotation_jacobian == R::kAuto &&
                         o.linear_solver == HhtOptions::LinearSolver::kTree));
}

class HhtIntegrator final : public Integrator {
 public:
  HhtIntegrator(MechanicalSystem& system, const HhtOptions& options)
      : sys_(system),
        opt_(options),
        newton_(std::make_unique<HhtNewtonMatrix>(system, options, WantsRotationBlocks(options))) {
    std::string err;
    if (!opt_.IsValid(&err)) throw std::invalid_argument(err);
    nq_ = sys_.num_coordinates();
    nc_ = sys_.num_constraints();
    if (nq_ <= 0) throw std::invalid_argument("HHT: the system has no coordinates");
    alpha_ = opt_.alpha;
    beta_ = (1 - alpha_) * (1 - alpha_) / 4;
    gamma_ = 0.5 - alpha_;
    equilibrium_ = opt_.form == HhtOptions::Form::kEquilibrium;
    // dq_{n+1}/da_{n+1} = mix_ beta h^2, dv_{n+1}/da_{n+1} = mix_ gamma h.
    mix_ = equilibrium_ ? 1 + alpha_ : 1.0;
    scheme_ = HhtRotationScheme::Of(alpha_, equilibrium_);
    for (int g : sys_.quaternion_offsets())
      if (g < 0 || g + 4 > nq_)
        throw std::invalid_argument("HHT: quaternion offset " + std::to_string(g) +
                                    " outside the coordinates");

    // Buffers of the matrices the residual needs (the patterns were checked by newton_),
    // and the Newton matrix with its factorisation.
    for (Matrix m : {Matrix::kMass, Matrix::kConstraintDq})
      mat_[static_cast<int>(m)].assign(sys_.pattern(m).nnz(), 0.0);
    // C_q^T lambda of F without C_q where the system gives it (the same numbers).
    cqtw_product_ = sys_.provides_constraint_transpose_w();
    jac_.assign(newton_->pattern().nnz(), 0.0);
    if (opt_.linear_solver == HhtOptions::LinearSolver::kTree)
      tree_ = BlockTreeLu::ForMechanicalSystem(newton_->pattern(), sys_.pattern(Matrix::kMass),
                                               sys_.pattern(Matrix::kConstraintDq),
                                               kMaxTreeNode, &tree_refusal_);
    if (!tree_) {
      DropRotationRoom(0);
      klu_ = std::make_unique<KluSolver>(newton_->pattern());
    }
    ResolveSolverDefaults();

    const int n = nq_ + nc_;
    for (auto* v : {&qn_, &vn_, &an_, &fn_, &f_, &force_, &cqtw_, &e_iter_, &abar_, &abar_new_,
                    &a_prev_, &start_q_, &start_qa_, &start_va_, &start_aa_, &norm_terms_})
      v->assign(nq_, 0.0);
    const size_t ng = sys_.quaternion_offsets().size();
    wbar_.assign(3 * ng, 0.0);
    wbar_new_.assign(3 * ng, 0.0);
    rotation_.assign(32 * ng, 0.0);
    rotation_start_.assign(ng, HhtRotationStart{});
    for (auto* v : {&lamn_, &con_, &lam_prev_}) v->assign(nc_, 0.0);
    res_.assign(n, 0.0);
    x_.assign(n, 0.0);
    state_.Resize(nq_, nc_);
    dense_ = opt_.dense_output;
    if (dense_) {
      prev_.Resize(nq_, nc_);
      out_.Resize(nq_, nc_);
    }
  }

  void Initialize(const State& x0) override {
    if (static_cast<int>(x0.q.size()) != nq_ || static_cast<int>(x0.v.size()) != nq_ ||
        static_cast<int>(x0.a.size()) != nq_ || static_cast<int>(x0.lambda.size()) != nc_)
      throw std::invalid_argument("HHT::Initialize: state sizes do not match the system (q " + std::to_string(x0.q.size()) + ", lambda " + std::to_string(x0.lambda.size()) + "; nq = " +
                                  std::to_string(nq_) + ", nc = " + std::to_string(nc_) + ")");
    state_ = x0;
    summary_ = Summary();
    SolverSummary();
    summary_.status = Summary::Status::kRunning;
    summary_.t_reached = x0.t;
    h_prev_ = 0;
    replay_next_ = 0;
    step_index_ = 0;
    h_ = opt_.step;
    if (opt_.max_step > 0) h_ = std::min(h_, opt_.max_step);
    jacobian_fresh_ = false;
    jacobian_valid_ = false;
    jacobian_h_ = 0;
    steps_with_jacobian_ = 0;
    // Acceleration-like variables of the equilibrium form: abar_0 = a_0.
    abar_ = state_.a;
    {
      const std::vector<int>& groups = sys_.quaternion_offsets();
      for (size_t k = 0; k < groups.size(); ++k) {
        const int g = groups[k];
        HhtRotationG(&state_.q[g], &state_.a[g], &wbar_[3 * k]);
        for (int i = 0; i < 3; ++i) wbar_[3 * k + i] *= 2;
      }
    }
    if (equilibrium_ && opt_.start == HhtOptions::Start::kPerturbed && alpha_ != 0) PerturbStart();
    // F_0 = C_q^T lambda_0 - Q(q_0, v_0, t_0).
    initialized_ = EvaluateF(state_.t, state_.q.data(), state_.v.data(), state_.lambda.data(),
                             fn_.data()) == 0;
    if (!initialized_) {
      summary_.status = Summary::Status::kFailed;
      summary_.message = std::string("evaluation at the initial state failed: ") + sys_.last_error();
      return;
    }
    std::fill(quad_.begin(), quad_.end(), 0.0);
    if (quad_spec_.size > 0 && !EvaluateIntegrand(quad_g_.data())) {
      initialized_ = false;
      summary_.status = Summary::Status::kFailed;
      summary_.message = "quadrature integrand failed at the initial state";
      return;
    }
    if (dense_) {
      prev_ = state_;
      out_ = state_;
      quad_prev_ = quad_;
      quad_out_ = quad_;
    }
    if (observer_) observer_(state_, 0.0);
  }

  void SaveSnapshot(IntegratorSnapshot* out) const override {
    if (dense_)
      throw std::logic_error("HHT with dense output cannot save its state (SaveSnapshot): the "
                             "state it reports is interpolated, not a step's");
    out->state = state_;
    const int ng = static_cast<int>(wbar_.size() / 3);
    out->history.resize(HhtHistory::Size(nq_, nc_, ng));
    double* hist = out->history.data();
    hist[HhtHistory::kForm] = equilibrium_ ? 1 : 2;
    hist[HhtHistory::kModified] = opt_.modified ? 1 : 0;
    hist[HhtHistory::kAlpha] = alpha_;
    hist[HhtHistory::kHPrev] = h_prev_;
    hist[HhtHistory::kHNext] = h_;
    hist[HhtHistory::kStep] = static_cast<double>(step_index_);
    const std::vector<double>& carried = equilibrium_ ? abar_ : fn_;
    std::copy(carried.begin(), carried.end(), hist + HhtHistory::kVectors);
    std::copy(wbar_.begin(), wbar_.end(), hist + HhtHistory::kVectors + nq_);
    double* prev = hist + HhtHistory::kVectors + nq_ + 3 * ng;
    std::copy(a_prev_.begin(), a_prev_.end(), prev);
    std::copy(lam_prev_.begin(), lam_prev_.end(), prev + nq_);
  }

  void RestoreSnapshot(const IntegratorSnapshot& x) override {
    if (dense_)
      throw std::logic_error("HHT with dense output cannot restore a state (RestoreSnapshot)");
    const int ng = static_cast<int>(wbar_.size() / 3);
    const State& s = x.state;
    if (static_cast<int>(s.q.size()) != nq_ || static_cast<int>(s.v.size()) != nq_ ||
        static_cast<int>(s.a.size()) != nq_ || static_cast<int>(s.lambda.size()) != nc_ ||
        static_cast<int>(x.history.size()) != HhtHistory::Size(nq_, nc_, ng))
      throw std::invalid_argument(
          "HHT::RestoreSnapshot: the snapshot's sizes (q " + std::to_string(s.q.size()) +
          ", lambda " + std::to_string(s.lambda.size()) + ", history " +
          std::to_string(x.history.size()) + ") do not match the system (nq = " +
          std::to_string(nq_) + ", nc = " + std::to_string(nc_) + ", history " +
          std::to_string(HhtHistory::Size(nq_, nc_, ng)) + ")");
    const double* hist = x.history.data();
    if (hist[HhtHistory::kForm] != (equilibrium_ ? 1 : 2) ||
        hist[HhtHistory::kModified] != (opt_.modified ? 1 : 0) || hist[HhtHistory::kAlpha] != alpha_)
      throw std::invalid_argument(
          std::string("HHT::RestoreSnapshot: the snapshot's scheme (form ") +
          (hist[HhtHistory::kForm] == 1 ? "equilibrium" : "negrut") +
          (hist[HhtHistory::kModified] == 1 ? ", modified" : ", classical") +
          ", alpha = " + Num(hist[HhtHistory::kAlpha]) + ") is not this integrator's (form " +
          HhtFormName(opt_.form) + (opt_.modified ? ", modified" : ", classical") +
          ", alpha = " + Num(alpha_) + "): other options");
    const double step = hist[HhtHistory::kStep];
    if (!(hist[HhtHistory::kHPrev] >= 0) || !(hist[HhtHistory::kHNext] > 0) || !(step >= 0) ||
        step != std::floor(step))
      throw std::invalid_argument("HHT::RestoreSnapshot: the snapshot's step sizes or step count are invalid");
    state_ = s;
    summary_ = Summary();
    SolverSummary();
    summary_.status = Summary::Status::kRunning;
    summary_.t_reached = s.t;
    h_prev_ = hist[HhtHistory::kHPrev];
    h_ = hist[HhtHistory::kHNext];
    step_index_ = static_cast<long>(step);
    replay_next_ = static_cast<size_t>(step_index_);
    jacobian_fresh_ = false;
    jacobian_valid_ = false;
    jacobian_h_ = 0;
    steps_with_jacobian_ = 0;
    std::vector<double>& carried = equilibrium_ ? abar_ : fn_;
    std::copy(hist + HhtHistory::kVectors, hist + HhtHistory::kVectors + nq_, carried.begin());
    std::copy(hist + HhtHistory::kVectors + nq_, hist + HhtHistory::kVectors + nq_ + 3 * ng,
              wbar_.begin());
    const double* prev = hist + HhtHistory::kVectors + nq_ + 3 * ng;
    std::copy(prev, prev + nq_, a_prev_.begin());
    std::copy(prev + nq_, prev + nq_ + nc_, lam_prev_.begin());
    initialized_ = true;
    std::fill(quad_.begin(), quad_.end(), 0.0);
    if (quad_spec_.size > 0 && !EvaluateIntegrand(quad_g_.data())) {
      initialized_ = false;
      summary_.status = Summary::Status::kFailed;
      summary_.message = "quadrature integrand failed at the restored state";
    }
  }

  void SetQuadrature(Quadrature quadrature) override {
    if (quadrature.size < 0 || (quadrature.size > 0 && !quadrature.integrand))
      throw std::invalid_argument("HHT::SetQuadrature: a positive size needs an integrand");
    quad_spec_ = std::move(quadrature);
    quad_.assign(quad_spec_.size, 0.0);
    quad_g_.assign(quad_spec_.size, 0.0);
    quad_g_new_.assign(quad_spec_.size, 0.0);
    quad_prev_.assign(quad_spec_.size, 0.0);
    quad_out_.assign(quad_spec_.size, 0.0);
    initialized_ = false;
  }
  const std::vector<double>& quadrature() const override { return dense_ ? quad_out_ : quad_; }
  void SetStepObserver(StepObserver observer) override { observer_ = std::move(observer); }

  bool AdvanceTo(double t_target) override {
    if (!initialized_) {
      if (summary_.status != Summary::Status::kFailed) {
        summary_.status = Summary::Status::kFailed;
        summary_.message = "AdvanceTo called before Initialize";
      }
      return false;
    }
    const double t_now = dense_ ? out_.t : state_.t;
    if (!(t_target > t_now)) {
      if (t_target == t_now) return true;
      summary_.status = Summary::Status::kFailed;
      summary_.message = "AdvanceTo: target " + Num(t_target) + " is before the current time " +
                         Num(t_now);
      return false;
    }
    if (dense_ && t_target > opt_.stop_time)
      return Fail("AdvanceTo: target " + Num(t_target) + " is beyond the stop time " +
                  Num(opt_.stop_time) + " (dense output)");
    summary_.status = Summary::Status::kRunning;
    const double h_nominal_fixed = opt_.max_step > 0 ? std::min(opt_.step, opt_.max_step) : opt_.step;
    // Step budget of this call (max_steps_per_call, plus the steps the nominal step needs).
    const double budget = opt_.max_steps_per_call > 0
                              ? opt_.max_steps_per_call + (t_target - state_.t) / h_nominal_fixed
                              : std::numeric_limits<double>::infinity();
    double attempts = 0;
    if (!opt_.replay_steps.empty()) return Replay(t_target);
    // The time the steps land on: the target, or with dense output the stop time.
    const double t_land = dense_ ? opt_.stop_time : t_target;
    while (state_.t < t_target) {
      if (++attempts > budget)
        return Fail("more than " + Num(budget) + " step attempts between t = " + Num(state_.t) +
                    " and the next output time " + Num(t_target) + " (step size now " + Num(h_) +
                    "): the step size collapsed; the multipliers or forces may be growing "
                    "without bound (HHT with alpha = 0 on constrained systems, a singular "
                    "configuration), or the problem needs a smaller tolerance or output step");
      const double remaining = t_land - state_.t;
      double h = h_;
      bool last = false;
      if (remaining <= h * (1 + 1e-3)) {
        h = remaining;  // hit the target, stretching by at most 0.1 %
        last = true;
      } else if (remaining < 2 * h && remaining - h < 0.25 * h) {
        h = remaining / 2;  // avoid a tiny leftover step: split evenly
      }
      if (h < opt_.min_step && !last) h = opt_.min_step;
      const StepResult r = TryStep(h);
      if (r == StepResult::kFatal) return Fail(message_);
      if (r == StepResult::kNewtonFailure) {
        ++summary_.steps_rejected;
        h_ = h / 2;
        if (h_ < opt_.min_step)
          return Fail("Newton iteration failed at t = " + Num(state_.t) +
                      " with the step reduced below min_step = " + Num(opt_.min_step) +
                      (message_.empty() ? "" : " (" + message_ + ")"));
        continue;
      }
      // Converged: error test in adaptive mode.
      double h_next = h;
      if (opt_.adaptive) {
        const double err = ErrorNorm(h);
        // Local error O(h^3): exponent 1/3; safety 0.9, growth in [0.2, 2].
        const double factor =
            err > 0 ? std::clamp(0.9 * std::pow(err, -1.0 / 3.0), 0.2, 2.0) : 2.0;
        if (err > 1.0) {
          ++summary_.steps_rejected;
          h_ = h * std::min(factor, 0.9);
          if (h_ < opt_.min_step)
            return Fail("error test failed at t = " + Num(state_.t) +
                        " with the step at min_step = " + Num(opt_.min_step));
          continue;
        }
        h_next = h * factor;
        if (h < h_) h_next = std::max(h_next, h_);  // a step shortened to hit the target
        if (opt_.max_step > 0) h_next = std::min(h_next, opt_.max_step);
      } else {
        // Fixed step: come back to the nominal step after temporary reductions.
        h_next = std::min(h_nominal_fixed, 2 * h_);
      }
      h_ = std::max(h_next, opt_.min_step);
      if (!Accepted(h, last ? t_land : state_.t + h)) return false;
    }
    if (dense_) Interpolate(t_target);
    summary_.status = Summary::Status::kDone;
    summary_.message.clear();
    return true;
  }

  const State& state() const override { return dense_ ? out_ : state_; }
  const Summary& summary() const override { return summary_; }
  std::string name() const override {
    return std::string(opt_.modified ? "HHT (modified for Euler parameters)" : "HHT") +
           ", alpha = " + Num(alpha_) + ", form " + HhtFormName(opt_.form) +
           (dense_ ? ", dense output" : "");
  }

 private:
  enum class StepResult { kOk, kNewtonFailure, kFatal };

  // HhtOptions::Start::kPerturbed (dae/hht.h): the starting values of the smooth
  // solution of the equilibrium form. With j = (a_p - a_0)/h ~ q'''(t_0), a_p the
  // acceleration-level solution at the Taylor-predicted state at t_0 + h:
  //   abar_0 = a_0 + alpha h j               (abar_n = a(t_n + alpha h) + O(h^2)),
  //   omegabar'_0 likewise from w = 2 G(e) a at both states,
  //   v_0 += dv, [M C_q^T; C_q 0] [dv; mu] = [0; -c h^2 C_q j],  c = 1/12 + alpha^2/4:
  // along the position-level constraints Newmark's update with exact positions leaves
  // v_n = q'(t_n) - c h^2 q'''(t_n) + O(h^3) (the h^3 terms of the position update with
  // beta = (1 - alpha)^2 / 4, gamma = 1/2 - alpha); an exact v_0 is off by that much and
  // excites the parasitic root -rho_inf, a double root along the constraints: the
  // multipliers then alternate in sign with an envelope n rho_inf^n. Leaves the
  // kConsistent values (set before) if the acceleration-level system cannot be solved.
  void PerturbStart() {
    const double h = h_;
    std::vector<double> qp(nq_), vp(nq_), ap(nq_), lp(nc_), jerk(nq_), rhs(nq_ + nc_, 0.0);
    for (int i = 0; i < nq_; ++i) {
      qp[i] = state_.q[i] + h * state_.v[i] + 0.5 * h * h * state_.a[i];
      vp[i] = state_.v[i] + h * state_.a[i];
    }
    AccelerationSolver solver(sys_);
    if (solver.Solve(state_.t + h, qp.data(), vp.data(), ap.data(), lp.data()) != 0 ||
        solver.Solve(state_.t, state_.q.data(), state_.v.data(), vp.data(), lp.data()) != 0) {
      summary_.message = "HHT perturbed start not possible (" + solver.last_error() +
                         "): started with abar_0 = a_0";
      return;
    }
    for (int i = 0; i < nq_; ++i) jerk[i] = (ap[i] - state_.a[i]) / h;
    solver.MultiplyConstraintJacobian(jerk.data(), rhs.data() + nq_);
    const double c = 1.0 / 12.0 + 0.25 * alpha_ * alpha_;
    for (int k = 0; k < nc_; ++k) rhs[nq_ + k] *= -c * h * h;
    solver.SolveAgain(rhs.data());
    for (int i = 0; i < nq_; ++i) {
      state_.v[i] += rhs[i];
      abar_[i] = state_.a[i] + alpha_ * h * jerk[i];
    }
    const std::vector<int>& groups = sys_.quaternion_offsets();
    for (size_t k = 0; k < groups.size(); ++k) {
      const int g = groups[k];
      double wp[3];
      HhtRotationG(&qp[g], &ap[g], wp);
      for (int i = 0; i < 3; ++i) {
        double& w = wbar_[3 * k + i];  // 2 G(e_0) a_0
        w += alpha_ * (2 * wp[i] - w);
      }
    }
  }

  bool Fail(const std::string& why) {
    summary_.status = Summary::Status::kFailed;
    summary_.message = why;
    summary_.t_reached = state_.t;
    if (dense_ && initialized_) {  // the last state reached is the last step's
      out_ = state_;
      quad_out_ = quad_;
    }
    return false;
  }

  // Dense output: out_ (and quad_out_) at t in [prev_.t, state_.t] (HhtOptions::dense_output).
  void Interpolate(double t) {
    if (t >= state_.t || state_.t == prev_.t) {
      out_ = state_;  // no allocation: same sizes
      quad_out_ = quad_;
      out_.t = t;
      return;
    }
    const double h = state_.t - prev_.t;
    const double s = std::max(0.0, (t - prev_.t) / h), s2 = s * s, s3 = s2 * s;
    // Cubic Hermite basis on [0, 1].
    const double h00 = 2 * s3 - 3 * s2 + 1, h10 = (s3 - 2 * s2 + s) * h;
    const double h01 = 3 * s2 - 2 * s3, h11 = (s3 - s2) * h;
    out_.t = t;
    for (int i = 0; i < nq_; ++i) {
      out_.q[i] = h00 * prev_.q[i] + h10 * prev_.v[i] + h01 * state_.q[i] + h11 * state_.v[i];
      out_.v[i] = h00 * prev_.v[i] + h10 * prev_.a[i] + h01 * state_.v[i] + h11 * state_.a[i];
      out_.a[i] = (1 - s) * prev_.a[i] + s * state_.a[i];
    }
    for (int j = 0; j < nc_; ++j) out_.lambda[j] = (1 - s) * prev_.lambda[j] + s * state_.lambda[j];
    // Euler parameters: unit length, and their rate orthogonal to them.
    for (int g : sys_.quaternion_offsets()) {
      double* e = &out_.q[g];
      double* ed = &out_.v[g];
      const double n = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3]);
      if (!(n > 0)) continue;
      double dot = 0;
      for (int k = 0; k < 4; ++k) {
        e[k] /= n;
        dot += e[k] * ed[k];
      }
      for (int k = 0; k < 4; ++k) ed[k] -= dot * e[k];
    }
    // The integral of the integrand's linear interpolant (g_n in quad_g_new_ after the
    // swap of Accepted, g_{n+1} in quad_g_).
    for (int k = 0; k < quad_spec_.size; ++k)
      quad_out_[k] = quad_prev_[k] +
                     h * s * (quad_g_new_[k] + 0.5 * s * (quad_g_[k] - quad_g_new_[k]));
  }

  // AdvanceTo with the steps of opt_.replay_steps.
  bool Replay(double t_target) {
    while (state_.t < t_target) {
      if (replay_next_ >= opt_.replay_steps.size())
        return Fail("replay: the " + std::to_string(opt_.replay_steps.size()) +
                    " steps end at t = " + Num(state_.t) + " before " + Num(t_target));
      const double h = opt_.replay_steps[replay_next_++];
      const double end = state_.t + h;
      const bool last = end >= t_target - 1e-9 * h;
      if (end > t_target + 1e-9 * h)
        return Fail("replay: step " + std::to_string(replay_next_) + " of size " + Num(h) +
                    " from t = " + Num(state_.t) + " passes the target " + Num(t_target));
      const StepResult r = TryStep(h);
      if (r != StepResult::kOk)
        return Fail("replay: step " + std::to_string(replay_next_) + " at t = " +
                    Num(state_.t) + " failed" + (message_.empty() ? "" : ": " + message_));
      if (!Accepted(h, last ? t_target : end)) return false;
    }
    summary_.status = Summary::Status::kDone;
    summary_.message.clear();
    return true;
  }

  // Accept, then the quadrature and the observer.
  bool Accepted(double h, double t1) {
    Accept(h, t1);
    if (quad_spec_.size > 0) {
      if (dense_) quad_prev_ = quad_;  // no allocation: same size
      // Trapezoidal rule over the accepted step.
      if (!EvaluateIntegrand(quad_g_new_.data()))
        return Fail("quadrature integrand failed at t = " + Num(state_.t));
      for (int i = 0; i < quad_spec_.size; ++i)
        quad_[i] += 0.5 * h * (quad_g_[i] + quad_g_new_[i]);
      quad_g_.swap(quad_g_new_);
    }
    if (observer_) observer_(state_, h);
    return true;
  }

  bool EvaluateIntegrand(double* g) {
    return quad_spec_.integrand(state_.t, state_.q.data(), state_.v.data(), state_.a.data(),
                                state_.lambda.data(), g) == 0;
  }

  // f = C_q^T lambda - Q(q, v, t). Uses the C_q buffer (or cqtw_).
  int EvaluateF(double t, const double* q, const double* v, const double* lam, double* f) {
    EvalInput in;
    in.t = t;
    in.q = q;
    in.v = v;
    EvalOutput out;
    out.force = force_.data();
    const bool product = RequestConstraintForce(lam, in, out);
    const int rc = sys_.Evaluate(in, out);
    ++summary_.residual_evaluations;
    if (rc != 0) return rc;
    for (int i = 0; i < nq_; ++i) f[i] = -force_[i];
    AddConstraintForce(product, mat_[static_cast<int>(Matrix::kConstraintDq)].data(), lam, f);
    return 0;
  }

  // C_q^T lambda of F: asked of the system as a product where it gives one (cqtw_product_;
  // returns true), else as C_q. AddConstraintForce adds it to f: from cqtw_ (product) or
  // from C_q's values cq, the same sums to the last bit.
  bool RequestConstraintForce(const double* lam, EvalInput& in, EvalOutput& out) {
    if (cqtw_product_) {
      in.w = lam;
      out.constraint_transpose_w = cqtw_.data();
    } else {
      out[Matrix::kConstraintDq] = mat_[static_cast<int>(Matrix::kConstraintDq)].data();
    }
    return cqtw_product_;
  }
  void AddConstraintForce(bool product, const double* cq, const double* lam, double* f) const {
    if (product)
      for (int i = 0; i < nq_; ++i) f[i] += cqtw_[i];
    else
      MultiplyTransposeAdd(sys_.pattern(Matrix::kConstraintDq), cq, 1.0, lam, f);
  }

  // q_{n+1}, v_{n+1} from a_{n+1} (Newmark, and the modified map for quaternions).
  // Newmark acts on a (kNegrut) or on abar (kEquilibrium); abar_new_ and wbar_new_
  // receive abar_{n+1} and the groups' omegabar'_{n+1}.
  void Kinematics(double h) {
    evaluated_ = false;  // qn_, vn_ change
    assert(start_h_ == h);
    const std::vector<double>& q0 = state_.q;
    const std::vector<double>& v0 = state_.v;
    for (int i = 0; i < nq_; ++i)
      abar_new_[i] = equilibrium_ ? (1 + alpha_) * an_[i] - start_aa_[i] : an_[i];
    const std::vector<double>& a1 = abar_new_;
    for (int i = 0; i < nq_; ++i) {
      qn_[i] = start_q_[i] + h * h * (start_qa_[i] + beta_ * a1[i]);
      vn_[i] = v0[i] + h * (start_va_[i] + gamma_ * a1[i]);
    }
    if (!opt_.modified) return;
    // Each group by the rotation update (dae/hht_rotation.h), with G(e_{n+1}) at the
    // previous iterate of e_{n+1} (stored in e_iter_), or e_n at the start; the step's
    // part of it from StepStart.
    using L = HhtRotationLayout;
    const std::vector<int>& groups = sys_.quaternion_offsets();
    for (size_t grp = 0; grp < groups.size(); ++grp) {
      const int g = groups[grp];
      double y[L::kOutputs];
      HhtRotationIterate(scheme_, h, rotation_start_[grp], &q0[g], &an_[g], &e_iter_[g], y);
      for (int k = 0; k < 4; ++k) {
        qn_[g + k] = y[L::kE1 + k];
        vn_[g + k] = y[L::kEd1 + k];
      }
      for (int k = 0; k < 3; ++k) wbar_new_[3 * grp + k] = y[L::kWbar1 + k];
    }
  }

  // Residual at the current iterate (an_, lamn_); fills res_, f_ (F_{n+1}). Right after a
  // refresh of the Newton matrix at this iterate (evaluated_) the refresh's evaluation
  // gives Q, C, M and C_q (the same values: the system computes each output alike whatever
  // else is asked), else the system is evaluated here.
  int Residual(double t1, double h) {
    const double* mass = mat_[static_cast<int>(Matrix::kMass)].data();
    const double* cq = mat_[static_cast<int>(Matrix::kConstraintDq)].data();
    bool product = false;  // C_q^T lambda from cqtw_
    ++summary_.residual_evaluations;
    if (evaluated_) {
      evaluated_ = false;
      mass = newton_->matrix(Matrix::kMass).data();
      cq = newton_->matrix(Matrix::kConstraintDq).data();
    } else {
      EvalInput in;
      in.t = t1;
      in.q = qn_.data();
      in.v = vn_.data();
      EvalOutput out;
      out.force = force_.data();
      out.constraint = con_.data();
      out[Matrix::kMass] = mat_[static_cast<int>(Matrix::kMass)].data();
      product = RequestConstraintForce(lamn_.data(), in, out);
      const int rc = sys_.Evaluate(in, out);
      if (rc != 0) return rc;
    }
    const double s = 1 / (1 + alpha_);
    for (int i = 0; i < nq_; ++i) f_[i] = -force_[i];
    AddConstraintForce(product, cq, lamn_.data(), f_.data());
    if (equilibrium_) {
      for (int i = 0; i < nq_; ++i) res_[i] = s * f_[i];
    } else {
      for (int i = 0; i < nq_; ++i) res_[i] = f_[i] - alpha_ * s * fn_[i];
    }
    MultiplyAdd(sys_.pattern(Matrix::kMass), mass, s, an_.data(), res_.data());
    const double sc = 1 / (mix_ * beta_ * h * h);
    for (int j = 0; j < nc_; ++j) res_[nq_ + j] = sc * con_[j];
    for (double r : res_)
      if (!std::isfinite(r)) return 1;
    return 0;
  }

  // Evaluates the Jacobians at the current iterate and factorises the Newton matrix. The
  // same evaluation gives the next residual's Q and C (evaluated_); where it fails, the
  // Jacobians alone are evaluated again, so that a failure takes the path it took when
  // the residual had its own evaluation.
  int NewtonMatrix(double t1, double h, std::string* error) {
    evaluated_ = false;
    const double* rotation = nullptr;
    if (ExactRotation()) {
      RotationBlocks(h);
      rotation = rotation_.data();
    }
    int rc = newton_->Assemble(t1, h, qn_.data(), vn_.data(), an_.data(), lamn_.data(),
                              jac_.data(), force_.data(), con_.data(), rotation);
    if (rc == 0)
      evaluated_ = true;
    else
      rc = newton_->Assemble(t1, h, qn_.data(), vn_.data(), an_.data(), lamn_.data(), jac_.data(),
                            nullptr, nullptr, rotation);
    ++summary_.jacobian_evaluations;
    if (rc != 0) {
      *error = sys_.last_error();
      return rc;
    }
    ++summary_.factorizations;
    if (!FactorNewtonMatrix(h, error)) return 1;
    jacobian_valid_ = true;
    jacobian_fresh_ = true;
    jacobian_h_ = h;
    steps_with_jacobian_ = 0;
    cycle_steps_ = 0;
    cycle_iterations_ = 0;
    return 0;
  }

  // The exact rotation blocks of the Newton matrix at the current iterate (HhtNewtonMatrix::
  // Assemble): per group dq/da / (mix beta h^2) - I and dv/da / (mix gamma h) - I, with
  // G(e_{n+1}) at the iterate's e_{n+1} (the fixed point, dae/hht_rotation.h).
  void RotationBlocks(double h) {
    using L = HhtRotationLayout;
    const double r = HistoryRatio(h);
    const std::vector<int>& groups = sys_.quaternion_offsets();
    for (size_t grp = 0; grp < groups.size(); ++grp) {
      const int g = groups[grp];
      double x[L::kInputs];
      GroupStepInputs(grp, x);
      for (int k = 0; k < 4; ++k) {
        x[L::kA1 + k] = an_[g + k];
        x[L::kEIter + k] = qn_[g + k];
      }
      double de[16], ded[16];
      HhtRotationDerivative(scheme_, h, r, x, de, ded);
      HhtRotationBlock(scheme_, h, de, ded, &rotation_[32 * grp]);
    }
  }

  // Factorises jac_: by the block tree elimination when it was set up and its pivots are
  // usable (TreePivotRule, as AccelerationSolver for dae/tree_kkt.h), else by KLU, which
  // takes over for good when the very first tree factorisation fails (e.g. a loop
  // closed through the ground, which the forest does not see).
  bool FactorNewtonMatrix(double h, std::string* error) {
    use_tree_ = false;
    if (tree_) {
      if (tree_->Factor(jac_.data()) && tree_rule_.Accept(tree_->rcond())) {
        use_tree_ = true;
        return true;
      }
      ++summary_.klu_fallbacks;
      if (!tree_rule_.seen_usable()) {
        tree_.reset();
        DropRotationRoom(h);
        tree_refusal_ = "the first factorisation's pivots were unusable";
        ResolveSolverDefaults();  // KLU's refresh rules and predictor from here on
        SolverSummary();
      }
    }
    if (!klu_) klu_ = std::make_unique<KluSolver>(newton_->pattern());
    return klu_->Factor(jac_.data(), error);
  }
  // KLU for good while the Newton matrix has room for rotation blocks that only the tree's
  // default (auto) asked for: a matrix without that room, so that the run is KLU's own
  // (pattern, first-order matrix and all). With h > 0 (a refresh of step h under way)
  // the new matrix is assembled from the old one's evaluation, and the residual makes its
  // own.
  void DropRotationRoom(double h) {
    if (!newton_->has_rotation_blocks() ||
        opt_.rotation_jacobian == HhtOptions::RotationJacobian::kExact)
      return;
    auto plain = std::make_unique<HhtNewtonMatrix>(sys_, opt_, false);
    jac_.assign(plain->pattern().nnz(), 0.0);
    if (h > 0) plain->AssembleFrom(h, newton_->matrices(), jac_.data());
    newton_ = std::move(plain);
    evaluated_ = false;
  }
  void SolveNewton(double* x) const {
    if (use_tree_)
      tree_->Solve(x);
    else
      klu_->Solve(x);
  }
  std::string LinearSolverReport() const {
    if (tree_) return "tree";
    if (opt_.linear_solver == HhtOptions::LinearSolver::kTree)
      return "klu (no tree: " + tree_refusal_ + ")";
    return "klu";
  }
  static constexpr int kMaxTreeNode = 48;

  // Weighted RMS norm of the position- and velocity-level Newton correction. The terms
  // first (a loop without a carried sum, so that the divisions run in vector registers),
  // then their sum in order: the same number as one loop.
  double CorrectionNorm(double h) {
    const double cq = mix_ * beta_ * h * h, cv = mix_ * gamma_ * h;
    double* term = norm_terms_.data();
    for (int i = 0; i < nq_; ++i) {
      const double dq = cq * x_[i] / (1 + std::abs(qn_[i]));
      const double dv = cv * x_[i] / (1 + std::abs(vn_[i]));
      term[i] = dq * dq + dv * dv;
    }
    double sum = 0;
    for (int i = 0; i < nq_; ++i) sum += term[i];
    return std::sqrt(sum / (2 * nq_));
  }

  double NewtonThreshold() const {
    return opt_.adaptive ? std::max(opt_.newton_tolerance, opt_.adaptive_newton_factor * opt_.tolerance)
                         : opt_.newton_tolerance;
  }

  // The round-off floor of the correction (see TryStep): newton_noise_factor times the
  // threshold, and for fixed steps at most newton_noise_factor * 1e-12, the floor the
  // rule was made for: with a loose newton_tolerance a slowly contracting iteration is
  // not noise (the default threshold 1e-12 gives the same floor as before).
  double NoiseFloor() const {
    const double tau = NewtonThreshold();
    return opt_.newton_noise_factor * (opt_.adaptive ? tau : std::min(tau, kNoiseScale));
  }
  static constexpr double kNoiseScale = 1e-12;

  // One step of size h from state_; on success an_, lamn_, qn_, vn_, f_ hold the new state.
  StepResult TryStep(double h) {
    const double t1 = state_.t + h;
    message_.clear();
    // The Newton matrix depends on h: refresh when h changed by more than 20 % (a
    // smaller change only slows the convergence a little) or when it is old.
    const bool stale = !jacobian_valid_ || std::abs(h / jacobian_h_ - 1) > 0.2 ||
                       steps_with_jacobian_ >= opt_.max_steps_same_jacobian;
    bool retried = false;
    for (int attempt = 0; attempt < 2; ++attempt) {
      Predict(h);
      jacobian_fresh_ = false;
      if ((attempt == 0 && stale) || attempt == 1) {
        std::string err;
        const int rc = NewtonMatrix(t1, h, &err);
        if (rc < 0) {
          message_ = "Jacobian evaluation failed: " + err;
          return StepResult::kFatal;
        }
        if (rc > 0) {
          message_ = err;
          jacobian_valid_ = false;
          return StepResult::kNewtonFailure;
        }
      }
      double prev_norm = 0, prev_prev_norm = 0;
      bool converged = false, diverged = false;
      int iterations = 0;
      for (int it = 0; it < opt_.max_newton_iterations; ++it) {
        const int rc = Residual(t1, h);
        if (rc < 0) {
          message_ = std::string("residual evaluation failed: ") + sys_.last_error();
          return StepResult::kFatal;
        }
        if (rc > 0) {
          diverged = true;
          break;
        }
        ++summary_.newton_iterations;
        ++iterations;
        for (int i = 0; i < nq_ + nc_; ++i) x_[i] = -res_[i];
        SolveNewton(x_.data());
        for (int i = 0; i < nq_; ++i) an_[i] += x_[i];
        for (int j = 0; j < nc_; ++j) lamn_[j] += x_[nq_ + j];
        const double norm = CorrectionNorm(h);
        if (!std::isfinite(norm)) {
          diverged = true;
          break;
        }
        if (opt_.modified)
          for (int g : sys_.quaternion_offsets())
            for (int k = 0; k < 4; ++k) e_iter_[g + k] = qn_[g + k];
        Kinematics(h);
        if (norm <= NewtonThreshold()) {
          converged = true;
          break;
        }
        if (it > 0) {
          const double step_rate = norm / prev_norm;
          // With the exact rotation blocks the stopping, round-off and divergence tests
          // measure the contraction over two iterations, sqrt(|D_k| / |D_{k-2}|) (RADAU5's
          // theta, Hairer & Wanner, Solving ODEs II, IV.8): G(e_{n+1}) lags one iterate,
          // so a correction carries part of the one two before it, and on a fast top the
          // third correction is about the second (heavy top, h = 2.5e-4: 3.3e-4, 2.2e-8,
          // 3.1e-8, then 1e-12), which the one-step rate reads as divergence. The refresh
          // test below keeps the one-step rate (with the two-iteration one an old matrix
          // is kept too long: KLU's rules took 40 % more iterations).
          const double rate = ExactRotation() && it > 1 ? std::sqrt(norm / prev_prev_norm)
                                                        : step_rate;
          // Contracting iteration: the distance to the solution is about
          // rate / (1 - rate) * norm (Hairer & Wanner, Solving ODEs II, IV.8, the
          // stopping rule of RADAU5); stop once that estimate meets the threshold.
          if (rate < 1.0 && rate / (1.0 - rate) * norm <= NewtonThreshold()) {
            converged = true;
            break;
          }
          // Round-off floor: corrections that stop contracting while already tiny are
          // noise of the linear solve (the 1/(beta h^2) scaling of C amplifies the
          // rounding of C); accept the iterate instead of failing the step.
          if (rate > 0.5 && norm <= NoiseFloor()) {
            ++summary_.newton_noise_stops;
            converged = true;
            break;
          }
          if (rate > 1.0) {
            diverged = true;
            break;
          }
          // Slow convergence: use a fresh matrix from the next step on.
          if (step_rate > opt_.jacobian_reuse_rate) jacobian_valid_ = false;
        }
        prev_prev_norm = prev_norm;
        prev_norm = norm;
      }
      if (converged) {
        RenewalRule(iterations);
        if (equilibrium_) return StepResult::kOk;
        // F_{n+1} at the converged state for the next step's HHT term.
        const int rc = EvaluateF(t1, qn_.data(), vn_.data(), lamn_.data(), f_.data());
        if (rc < 0) {
          message_ = std::string("evaluation failed: ") + sys_.last_error();
          return StepResult::kFatal;
        }
        if (rc > 0) return StepResult::kNewtonFailure;
        return StepResult::kOk;
      }
      (void)diverged;
      // Failure with an old matrix: refresh it and retry once with the same h.
      if (jacobian_fresh_ || retried) break;
      retried = true;
    }
    jacobian_valid_ = false;
    message_ = "no convergence in " + std::to_string(opt_.max_newton_iterations) +
               " Newton iterations";
    return StepResult::kNewtonFailure;
  }

  // The first iterate of a step of size h (HhtOptions::predictor): an_, lamn_, and qn_,
  // vn_ from them. Constant: a_n, lambda_n. Linear (after an accepted step): a_n + r (a_n -
  // a_{n-1}), lambda likewise, r = h / h_prev; the modified scheme's G(e_{n+1}) of the
  // kinematic update is then taken at the Euler parameters of a first pass with G(e_n)
  // (e_iter_), as a Newton iteration does after its correction.
  void Predict(double h) {
    StepStart(h);
    std::copy(state_.a.begin(), state_.a.end(), an_.begin());
    std::copy(state_.lambda.begin(), state_.lambda.end(), lamn_.begin());
    const bool extrapolate = linear_predictor_ && h_prev_ > 0;
    if (extrapolate) {
      const double r = h / h_prev_;
      for (int i = 0; i < nq_; ++i) an_[i] += r * (state_.a[i] - a_prev_[i]);
      for (int j = 0; j < nc_; ++j) lamn_[j] += r * (state_.lambda[j] - lam_prev_[j]);
    }
    e_iter_ = state_.q;  // no allocation: same size
    Kinematics(h);
    if (extrapolate && opt_.modified && !sys_.quaternion_offsets().empty()) {
      for (int g : sys_.quaternion_offsets())
        for (int k = 0; k < 4; ++k) e_iter_[g + k] = qn_[g + k];
      Kinematics(h);
    }
  }

  // The terms of Kinematics that a step of size h from state_ fixes: Newmark's
  // q_n + h v_n, (1/2 - beta) a_n and (1 - gamma) a_n (abar-scaled in the equilibrium
  // form) and alpha a_n, and each group's part of the rotation update (HhtRotationStartOf).
  // The same operations as computing them at every iterate: the same numbers.
  void StepStart(double h) {
    start_h_ = h;
    const double r = HistoryRatio(h);
    for (int i = 0; i < nq_; ++i) {
      const double a0 = equilibrium_ ? state_.a[i] + r * (abar_[i] - state_.a[i]) : state_.a[i];
      start_q_[i] = state_.q[i] + h * state_.v[i];
      start_qa_[i] = (0.5 - beta_) * a0;
      start_va_[i] = (1 - gamma_) * a0;
      start_aa_[i] = alpha_ * state_.a[i];
    }
    if (!opt_.modified) return;
    using L = HhtRotationLayout;
    const std::vector<int>& groups = sys_.quaternion_offsets();
    for (size_t grp = 0; grp < groups.size(); ++grp) {
      double x[L::kInputs];
      GroupStepInputs(grp, x);
      HhtRotationStartOf(scheme_, h, r, x, &rotation_start_[grp]);
    }
  }

  // abar_n - a_n = -alpha (a_n - a_{n-1}) is proportional to the step that made it; a step
  // of size h after one of h_prev needs it scaled by r = h / h_prev (equilibrium form; 1
  // else), or every change of the step (to land on an output time, or by the step-size
  // control) costs an O(h^2) local error and the method drops to first order.
  double HistoryRatio(double h) const { return equilibrium_ && h_prev_ > 0 ? h / h_prev_ : 1.0; }

  // The inputs of group grp's rotation update that the step fixes (e_n, e'_n, a_n, wbar_n;
  // HhtRotationLayout) from state_.
  void GroupStepInputs(size_t grp, double* x) const {
    using L = HhtRotationLayout;
    const int g = sys_.quaternion_offsets()[grp];
    for (int k = 0; k < 4; ++k) {
      x[L::kE0 + k] = state_.q[g + k];
      x[L::kEd0 + k] = state_.v[g + k];
      x[L::kA0 + k] = state_.a[g + k];
    }
    for (int k = 0; k < 3; ++k) x[L::kWbar0 + k] = wbar_[3 * grp + k];
  }

  // The options whose `auto` depends on the linear solver (jacobian_cost, predictor),
  // resolved for the one that factorises now: the tree's defaults while tree_ is set,
  // KLU's once it is not (from the start, or when KLU takes over for good).
  void ResolveSolverDefaults() {
    jacobian_cost_ = opt_.jacobian_cost >= 0 ? opt_.jacobian_cost
                     : tree_                 ? HhtOptions::kTreeJacobianCost
                                             : 0.0;
    linear_predictor_ = opt_.predictor == HhtOptions::Predictor::kAuto
                            ? tree_ != nullptr
                            : opt_.predictor == HhtOptions::Predictor::kLinear;
  }

  // HhtOptions::rotation_jacobian resolved: the exact blocks are used.
  bool ExactRotation() const { return newton_->has_rotation_blocks(); }

  // The summary's account of the linear solver and the options resolved for it.
  void SolverSummary() {
    summary_.linear_solver = LinearSolverReport();
    summary_.jacobian_cost = jacobian_cost_;
    summary_.predictor = HhtPredictorName(linear_predictor_ ? HhtOptions::Predictor::kLinear
                                                            : HhtOptions::Predictor::kConstant);
    summary_.rotation_jacobian =
        HhtRotationJacobianName(ExactRotation() ? HhtOptions::RotationJacobian::kExact
                                                : HhtOptions::RotationJacobian::kFirstOrder);
  }

  // The matrix's refresh by cost (HhtOptions::jacobian_cost, c > 0): the k-th step on a
  // matrix (counting from 1) took n_k iterations; the average cost per step of the matrix
  // so far is (c + n_1 + ... + n_k) / k, and once n_k reaches it the next steps on the old
  // matrix would raise it (its convergence only gets slower), so the next step refreshes
  // the matrix. A renewal argument: the refresh interval that minimises the average cost
  // ends where the marginal cost meets the average.
  void RenewalRule(int iterations) {
    if (!(jacobian_cost_ > 0)) return;
    ++cycle_steps_;
    cycle_iterations_ += iterations;
    if (cycle_steps_ > 1 &&
        static_cast<double>(iterations) * cycle_steps_ >= jacobian_cost_ + cycle_iterations_)
      jacobian_valid_ = false;
  }

  // Weighted RMS of the local position error estimate (beta - 1/6) h^2 (a_{n+1} - a_n)
  // (abar in the equilibrium form, the variable Newmark's formulas act on)
  // (Zienkiewicz & Xie, Earthquake Eng. Struct. Dyn. 20 (1991) 871-887; the same
  // leading Newmark term is the basis of the estimate in Negrut et al. 2007).
  double ErrorNorm(double h) const {
    const double tol = opt_.tolerance;
    double sum = 0;
    for (int i = 0; i < nq_; ++i) {
      const double e = equilibrium_ ? (beta_ - 1.0 / 6.0) * h * h * (abar_new_[i] - abar_[i])
                                    : (beta_ - 1.0 / 6.0) * h * h * (an_[i] - state_.a[i]);
      const double w = tol + tol * std::max(std::abs(qn_[i]), std::abs(state_.q[i]));
      sum += (e / w) * (e / w);
    }
    return std::sqrt(sum / nq_);
  }

  void Accept(double h, double t1) {
    // a_n and lambda_n become the linear predictor's a_{n-1}, lambda_{n-1}.
    std::copy(state_.a.begin(), state_.a.end(), a_prev_.begin());
    std::copy(state_.lambda.begin(), state_.lambda.end(), lam_prev_.begin());
    if (dense_) {  // the step's start, for the interpolation (no allocation: same sizes)
      prev_.t = state_.t;
      prev_.q.swap(state_.q);
      prev_.v.swap(state_.v);
      prev_.a.swap(state_.a);
      prev_.lambda.swap(state_.lambda);
    }
    state_.t = t1;
    std::copy(qn_.begin(), qn_.end(), state_.q.begin());
    std::copy(vn_.begin(), vn_.end(), state_.v.begin());
    std::copy(an_.begin(), an_.end(), state_.a.begin());
    std::copy(lamn_.begin(), lamn_.end(), state_.lambda.begin());
    if (equilibrium_) {
      abar_.swap(abar_new_);
      wbar_.swap(wbar_new_);
    } else {
      std::copy(f_.begin(), f_.end(), fn_.begin());
    }
    ++summary_.steps_accepted;
    ++steps_with_jacobian_;
    summary_.t_reached = t1;
    summary_.h_last = h;
    h_prev_ = h;
    ++step_index_;
  }

  MechanicalSystem& sys_;
  HhtOptions opt_;
  int nq_ = 0, nc_ = 0;
  double alpha_ = 0, beta_ = 0, gamma_ = 0;
  bool equilibrium_ = true;  // opt_.form == kEquilibrium
  double mix_ = 1;           // 1 + alpha (equilibrium form) or 1
  HhtRotationScheme scheme_;  // the same constants for the rotation update
  // Its room for rotation blocks is HhtOptions::rotation_jacobian resolved: made where
  // they may be used (WantsRotationBlocks) and dropped where KLU's auto does not use them
  // (DropRotationRoom), so ExactRotation() needs no flag of its own.
  std::unique_ptr<HhtNewtonMatrix> newton_;
  std::vector<double> mat_[kNumMatrices];  // M and C_q of the residual
  std::vector<double> jac_;
  std::unique_ptr<KluSolver> klu_;  // null until needed when tree_ is set
  std::unique_ptr<BlockTreeLu> tree_;
  std::string tree_refusal_;
  bool use_tree_ = false;  // the last factorisation is tree_'s
  TreePivotRule tree_rule_;
  // Work vectors (sized in the constructor; no allocation while stepping).
  std::vector<double> qn_, vn_, an_, lamn_, fn_, f_, force_, con_, res_, x_;
  // C_q^T lambda from the system (EvalOutput::constraint_transpose_w) where it gives it.
  std::vector<double> cqtw_;
  std::vector<double> norm_terms_;  // CorrectionNorm's
  bool cqtw_product_ = false;
  std::vector<double> e_iter_;  // previous Newton iterate of q_{n+1} (modified scheme)
  // Equilibrium form: abar_n and abar_{n+1}; per quaternion group omegabar'_n, _{n+1}.
  std::vector<double> abar_, abar_new_, wbar_, wbar_new_;
  // a_{n-1} and lambda_{n-1}, the linear predictor's (valid when h_prev_ > 0).
  std::vector<double> a_prev_, lam_prev_;
  bool linear_predictor_ = false;  // HhtOptions::predictor resolved
  std::vector<double> rotation_;   // RotationBlocks: 32 per group
  // What a step of size start_h_ fixes in Kinematics (StepStart): per coordinate and
  // per group.
  std::vector<double> start_q_, start_qa_, start_va_, start_aa_;
  std::vector<HhtRotationStart> rotation_start_;
  double start_h_ = 0;
  State state_;
  Summary summary_;
  std::string message_;
  Quadrature quad_spec_;
  std::vector<double> quad_, quad_g_, quad_g_new_;  // integrals; integrand at t_n, t_{n+1}
  // Dense output (HhtOptions::dense_output): the state before the last accepted step, the
  // reported (interpolated) state, and the integrals at prev_ and at out_.
  bool dense_ = false;
  State prev_, out_;
  std::vector<double> quad_prev_, quad_out_;
  StepObserver observer_;
  size_t replay_next_ = 0;  // next entry of opt_.replay_steps
  long step_index_ = 0;     // accepted steps since Initialize (carried by snapshots)
  double h_ = 0;
  double h_prev_ = 0;  // the last accepted step (0 before the first)
  double jacobian_h_ = 0;
  bool jacobian_valid_ = false, jacobian_fresh_ = false, initialized_ = false;
  int steps_with_jacobian_ = 0;
  // The refresh by cost: HhtOptions::jacobian_cost resolved (0: off); the converged steps
  // on the current matrix and their Newton iterations.
  double jacobian_cost_ = 0;
  int cycle_steps_ = 0;
  long cycle_iterations_ = 0;
  // force_, con_ and newton_.matrix() hold the evaluation at the current qn_, vn_ (made by
  // NewtonMatrix, used by the next Residual).
  bool evaluated_ = false;
};

}  // namespace

std::unique_ptr<Integrator> MakeHhtIntegrator(MechanicalSystem& system, const HhtOptions& options) {
  return std::make_unique<HhtIntegrator>(system, options);
}

}  // namespace mbdae::dae
