// Measures, vectors and sparse matrices at the current state (api/mbdae.h, "Measures at
// the current state" to "Sparse matrices at the current state").
//
// Everything is evaluated on the kept system (the independent constraint equations) at
// m.state = (t, q, v, a, lambda):
// - vectors: M a, C_q^T lambda, Q_v, Q - Q_v, Q, C, C_t, d(C_q)/dt q' and C_tt. The total
//   derivative d(C_q)/dt q' = (C_q q')_q q' + C_qt q' is the matrix d(C_q v + C_t)/dq
//   (dae::Matrix::kConstraintVelDq) times v, with no assumption on C_qt;
// - matrices: the system's own (M, C_q, d(M a)/dq at a, dQ/dq, dQ/dv, d(C_q^T lambda)/dq
//   at lambda), the HHT Newton matrix (dae::HhtNewtonMatrix, the integrator's assembly)
//   and IDA's (dae::internal::GglResidual::Jacobian at y = (q, v, lambda, 0),
//   y' = (v, a, 0, 0), c_j = 1/h), composed into one CSC or CSR matrix by a
//   dae::BlockAssembler;
// - measures: values as the results file defines them (offset_initial subtracts the value
//   at the assembled state, the file's first row) without unwrapping; gradients with
//   respect to q at fixed v and a from mbs/measure_kinematics.h: position g, velocity
//   H v (exact); acceleration H a + d/ds (H(q + s v) v) at s = 0, whose second term (a
//   third derivative of the measure) is a central difference along v.
// Results go to the caller's arrays only when everything succeeded.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "api/session.h"
#include "dae/hht.h"
#include "dae/ida_internal.h"
#include "dae/sparse.h"
#include "mbs/measure_kinematics.h"

namespace mbdae::api {
namespace {

using dae::Matrix;

void CheckLength(int n, int expected, const std::string& what) {
  if (n != expected)
    throw ApiError(MBDAE_ERROR_SIZE, what + ": the array length is " + std::to_string(n) +
                                         ", expected " + std::to_string(expected));
}

void CheckPointer(const void* p, const std::string& what) {
  if (!p) throw ApiError(MBDAE_ERROR_ARGUMENT, what + " is NULL");
}

dae::MechanicalSystem& Kept(mbdae_model& m) { return *m.assembly->kept_system; }

// Evaluates the kept system at the current state; throws MBDAE_ERROR_SOLVER on failure.
void EvaluateAtState(mbdae_model& m, dae::EvalOutput& out) {
  dae::EvalInput in;
  in.t = m.state.t;
  in.q = m.state.q.data();
  in.v = m.state.v.data();
  in.a = m.state.a.data();
  in.w = m.state.lambda.data();
  const int rc = Kept(m).Evaluate(in, out);
  if (rc != 0)
    throw ApiError(MBDAE_ERROR_SOLVER, "the model could not be evaluated at the current state "
                                       "(t = " + std::to_string(m.state.t) + "): " +
                                           Kept(m).last_error());
}

double NewtonStep(const mbdae_model& m) {
  return m.newton_step > 0 ? m.newton_step : m.settings.hht_step;
}

const char* MatrixName(mbdae_matrix which) {
  switch (which) {
    case MBDAE_MAT_MASS: return "MBDAE_MAT_MASS";
    case MBDAE_MAT_CONSTRAINT_DQ: return "MBDAE_MAT_CONSTRAINT_DQ";
    case MBDAE_MAT_MASS_ACC_DQ: return "MBDAE_MAT_MASS_ACC_DQ";
    case MBDAE_MAT_FORCE_DQ: return "MBDAE_MAT_FORCE_DQ";
    case MBDAE_MAT_FORCE_DV: return "MBDAE_MAT_FORCE_DV";
    case MBDAE_MAT_CONSTRAINT_T_DQ: return "MBDAE_MAT_CONSTRAINT_T_DQ";
    case MBDAE_MAT_NEWTON_HHT: return "MBDAE_MAT_NEWTON_HHT";
    case MBDAE_MAT_NEWTON_IDA: return "MBDAE_MAT_NEWTON_IDA";
  }
  return "?";
}
constexpr int kNumApiMatrices = 8;

// The system matrix behind an API matrix (the first six).
Matrix SystemMatrix(mbdae_matrix which) {
  switch (which) {
    case MBDAE_MAT_MASS: return Matrix::kMass;
    case MBDAE_MAT_CONSTRAINT_DQ: return Matrix::kConstraintDq;
    case MBDAE_MAT_MASS_ACC_DQ: return Matrix::kMassTimesAccDq;
    case MBDAE_MAT_FORCE_DQ: return Matrix::kForceDq;
    case MBDAE_MAT_FORCE_DV: return Matrix::kForceDv;
    default: return Matrix::kConstraintTDq;
  }
}

// One matrix at the current state: its pattern and (if evaluated) values. The Newton
// matrices own their assemblers, kept alive here for the pattern's lifetime.
struct StateMatrix {
  const dae::CscPattern* pattern = nullptr;
  std::vector<double> values;
  std::unique_ptr<dae::HhtNewtonMatrix> hht;
  std::unique_ptr<dae::internal::GglResidual> ggl;
};

dae::HhtOptions HhtOptionsOf(const mbdae_model& m) {
  dae::HhtOptions o;
  o.alpha = m.settings.hht_alpha;
  if (!dae::ParseHhtForm(m.settings.hht_form, &o.form))
    throw ApiError(MBDAE_ERROR_INPUT,
                   "option hht.form must be equilibrium or negrut, got '" + m.settings.hht_form + "'");
  return o;
}

// Sets up matrix `which`: the pattern always, the values if `evaluate`.
void PrepareMatrix(mbdae_model& m, mbdae_matrix which, bool evaluate, StateMatrix* out) {
  dae::MechanicalSystem& sys = Kept(m);
  const double h = NewtonStep(m);
  if (which == MBDAE_MAT_NEWTON_HHT) {
    out->hht = std::make_unique<dae::HhtNewtonMatrix>(sys, HhtOptionsOf(m));
    out->pattern = &out->hht->pattern();
    if (!evaluate) return;
    out->values.assign(out->pattern->nnz(), 0.0);
    const int rc = out->hht->Assemble(m.state.t, h, m.state.q.data(), m.state.v.data(),
                                      m.state.a.data(), m.state.lambda.data(),
                                      out->values.data());
    if (rc != 0)
      throw ApiError(MBDAE_ERROR_SOLVER, std::string("the HHT Newton matrix could not be "
                                                     "evaluated at the current state: ") +
                                             sys.last_error());
    return;
  }
  if (which == MBDAE_MAT_NEWTON_IDA) {
    out->ggl = std::make_unique<dae::internal::GglResidual>(sys);
    out->pattern = &out->ggl->jacobian_pattern();
    if (!evaluate) return;
    const int nq = sys.num_coordinates(), nc = sys.num_constraints();
    std::vector<double> y(2 * nq + 2 * nc, 0.0), yp(2 * nq + 2 * nc, 0.0);
    std::copy(m.state.q.begin(), m.state.q.end(), y.begin());
    std::copy(m.state.v.begin(), m.state.v.end(), y.begin() + nq);
    std::copy(m.state.lambda.begin(), m.state.lambda.end(), y.begin() + 2 * nq);
    std::copy(m.state.v.begin(), m.state.v.end(), yp.begin());
    std::copy(m.state.a.begin(), m.state.a.end(), yp.begin() + nq);
    out->values.assign(out->pattern->nnz(), 0.0);
    const int rc = out->ggl->Jacobian(m.state.t, 1 / h, y.data(), yp.data(), out->values.data());
    if (rc != 0)
      throw ApiError(MBDAE_ERROR_SOLVER, std::string("IDA's Newton matrix could not be "
                                                     "evaluated at the current state: ") +
                                             sys.last_error());
    return;
  }
  const Matrix sm = SystemMatrix(which);
  out->pattern = &sys.pattern(sm);
  if (!evaluate) return;
  out->values.assign(out->pattern->nnz(), 0.0);
  dae::EvalOutput eo;
  eo[sm] = out->values.data();
  EvaluateAtState(m, eo);
}

// Rows and columns of matrix `which` (before a transpose).
std::array<int, 2> MatrixSize(const mbdae_model& m, mbdae_matrix which) {
  const int nq = m.assembly->kept_system->num_coordinates();
  const int nc = m.assembly->kept_system->num_constraints();
  switch (which) {
    case MBDAE_MAT_CONSTRAINT_DQ: return {nc, nq};
    case MBDAE_MAT_NEWTON_HHT: return {nq + nc, nq + nc};
    case MBDAE_MAT_NEWTON_IDA: return {2 * nq + 2 * nc, 2 * nq + 2 * nc};
    default: return {nq, nq};
  }
}

}  // namespace

void MeasureValues(mbdae_model& m, double* values, int n) {
  EnsureAssembled(m);
  const mbs::Model& model = *m.model;
  const int nm = static_cast<int>(model.measures.size());
  CheckLength(n, nm, "mbdae_measure_values (one value per measure)");
  if (nm == 0) return;
  CheckPointer(values, "mbdae_measure_values: values");
  const mbs::MultibodySystem& sys = *m.assembly->system;
  std::vector<double> out(nm), initial(nm);
  sys.EvaluateMeasures(m.state.t, m.state.q.data(), m.state.v.data(), m.state.a.data(),
                       out.data());
  const dae::State& x0 = m.assembly->x0;
  sys.EvaluateMeasures(x0.t, x0.q.data(), x0.v.data(), x0.a.data(), initial.data());
  for (int k = 0; k < nm; ++k)
    if (model.measures[k].offset_initial) out[k] -= initial[k];
  std::copy(out.begin(), out.end(), values);
}

void MeasureGradient(mbdae_model& m, int measure, double* dq, int n) {
  EnsureAssembled(m);
  const mbs::Model& model = *m.model;
  const int nm = static_cast<int>(model.measures.size());
  if (measure < 0 || measure >= nm)
    throw ApiError(MBDAE_ERROR_ARGUMENT, "mbdae_measure_gradient: measure index " +
                                             std::to_string(measure) + " is outside [0, " +
                                             std::to_string(nm) + ")");
  const int nq = Kept(m).num_coordinates();
  CheckLength(n, nq, "mbdae_measure_gradient (one value per coordinate)");
  CheckPointer(dq, "mbdae_measure_gradient: dq");
  const mbs::MeasureDef def = mbs::ResolveMeasure(model, measure);
  const double* q = m.state.q.data();
  const double* v = m.state.v.data();
  mbs::Vec14 g = mbs::Vec14::Zero();
  switch (def.quantity) {
    case mbs::Quantity::kPosition: {
      mbs::MeasureJacobian j;
      mbs::EvaluateMeasurePosition(def, q, false, &j);
      g = j.gradient;
      break;
    }
    case mbs::Quantity::kVelocity: {
      mbs::MeasureStateJacobian j;
      mbs::EvaluateMeasureState(def, q, v, &j);
      g = j.dq;
      break;
    }
    case mbs::Quantity::kAcceleration: {
      // m_a = g(q) . a + v^T H(q) v: d/dq = H a + D_v(H v), the directional derivative of
      // H v along v (the third derivative is symmetric), by central differences with a
      // step of cbrt(eps) relative to the coordinates.
      mbs::MeasureJacobian j;
      mbs::EvaluateMeasurePosition(def, q, true, &j);
      const mbs::Vec14 vl = mbs::GatherLocal(def.offset, v);
      const mbs::Vec14 ql = mbs::GatherLocal(def.offset, q);
      g = j.hessian * mbs::GatherLocal(def.offset, m.state.a.data());
      const double vn = vl.norm();
      if (vn > 0) {
        const double step = std::cbrt(std::numeric_limits<double>::epsilon()) *
                            std::max(1.0, ql.norm()) / vn;
        std::vector<double> qs(m.state.q);
        mbs::MeasureJacobian jp, jm;
        for (int i = 0; i < nq; ++i) qs[i] = q[i] + step * v[i];
        mbs::EvaluateMeasurePosition(def, qs.data(), true, &jp);
        for (int i = 0; i < nq; ++i) qs[i] = q[i] - step * v[i];
        mbs::EvaluateMeasurePosition(def, qs.data(), true, &jm);
        g += (jp.hessian * vl - jm.hessian * vl) / (2 * step);
      }
      break;
    }
  }
  std::vector<double> out(nq, 0.0);
  for (int r = 0; r < 14; ++r)
    if (def.offset[r / 7] >= 0) out[def.offset[r / 7] + r % 7] += g[r];
  std::copy(out.begin(), out.end(), dq);
}

void GetVector(mbdae_model& m, mbdae_vector which, double* out, int n) {
  EnsureAssembled(m);
  dae::MechanicalSystem& sys = Kept(m);
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  const int w = EnumInt(which);
  const bool q_sized = w >= MBDAE_VEC_MASS_TIMES_ACC && w <= MBDAE_VEC_SUM_OF_FORCES;
  const bool c_sized = w >= MBDAE_VEC_CONSTRAINTS && w <= MBDAE_VEC_CONSTRAINTS_DTT;
  if (!q_sized && !c_sized)
    throw ApiError(MBDAE_ERROR_ARGUMENT, "mbdae_get_vector: " + std::to_string(w) + " is not an mbdae_vector (0 .. 8)");
  CheckLength(n, q_sized ? nq : nc,
              std::string("mbdae_get_vector (") +
                  (q_sized ? "one value per coordinate)" : "one value per multiplier)"));
  if (n == 0) return;
  CheckPointer(out, "mbdae_get_vector: out");
  std::vector<double> r(n, 0.0);
  dae::EvalOutput eo;
  switch (which) {
    case MBDAE_VEC_MASS_TIMES_ACC:
    case MBDAE_VEC_CONSTRAINT_FORCES:
    case MBDAE_VEC_CONSTRAINTS_QDOT: {
      const Matrix sm = which == MBDAE_VEC_MASS_TIMES_ACC      ? Matrix::kMass
                        : which == MBDAE_VEC_CONSTRAINT_FORCES ? Matrix::kConstraintDq
                                                               : Matrix::kConstraintVelDq;
      std::vector<double> val(sys.pattern(sm).nnz());
      eo[sm] = val.data();
      EvaluateAtState(m, eo);
      if (which == MBDAE_VEC_MASS_TIMES_ACC)
        dae::MultiplyAdd(sys.pattern(sm), val.data(), 1.0, m.state.a.data(), r.data());
      else if (which == MBDAE_VEC_CONSTRAINT_FORCES)
        dae::MultiplyTransposeAdd(sys.pattern(sm), val.data(), 1.0, m.state.lambda.data(),
                                  r.data());
      else  // d(C_q v + C_t)/dq v = (C_q v)_q v + C_qt v = d(C_q)/dt v
        dae::MultiplyAdd(sys.pattern(sm), val.data(), 1.0, m.state.v.data(), r.data());
      break;
    }
    case MBDAE_VEC_QUADRATIC_VELOCITY:
      eo.force_quadratic_velocity = r.data();
      EvaluateAtState(m, eo);
      break;
    case MBDAE_VEC_EXTERNAL_FORCES: {
      std::vector<double> qv(nq, 0.0);
      eo.force = r.data();
      eo.force_quadratic_velocity = qv.data();
      EvaluateAtState(m, eo);
      for (int i = 0; i < nq; ++i) r[i] -= qv[i];
      break;
    }
    case MBDAE_VEC_SUM_OF_FORCES:
      eo.force = r.data();
      EvaluateAtState(m, eo);
      break;
    case MBDAE_VEC_CONSTRAINTS:
      eo.constraint = r.data();
      EvaluateAtState(m, eo);
      break;
    case MBDAE_VEC_CONSTRAINTS_DT:
      eo.constraint_dt = r.data();
      EvaluateAtState(m, eo);
      break;
    case MBDAE_VEC_CONSTRAINTS_DTT:
      eo.constraint_dtt = r.data();
      EvaluateAtState(m, eo);
      break;
  }
  std::copy(r.begin(), r.end(), out);
}

void GetMatrix(mbdae_model& m, const mbdae_block* blocks, int num_blocks, int rows, int cols,
               mbdae_sparse_format format, int* nnz, int* ptr, int* idx, double* val) {
  EnsureAssembled(m);
  CheckPointer(nnz, "mbdae_get_matrix: nnz");
  if (num_blocks < 0)
    throw ApiError(MBDAE_ERROR_ARGUMENT,
                   "mbdae_get_matrix: num_blocks = " + std::to_string(num_blocks) + " is negative");
  if (num_blocks > 0) CheckPointer(blocks, "mbdae_get_matrix: blocks");
  if (rows < 0 || cols < 0)
    throw ApiError(MBDAE_ERROR_ARGUMENT, "mbdae_get_matrix: the size " + std::to_string(rows) +
                                             " x " + std::to_string(cols) + " is negative");
  // ptr has rows + 1 (CSR) or cols + 1 (CSC) entries, counted by an int.
  if (rows == std::numeric_limits<int>::max() || cols == std::numeric_limits<int>::max())
    throw ApiError(MBDAE_ERROR_ARGUMENT, "mbdae_get_matrix: the size " + std::to_string(rows) + " x " +
                                             std::to_string(cols) + " is too large (ptr needs " +
                                             "rows + 1 or cols + 1 entries)");
  if (EnumInt(format) != MBDAE_CSC && EnumInt(format) != MBDAE_CSR)
    throw ApiError(MBDAE_ERROR_ARGUMENT, "mbdae_get_matrix: format " + std::to_string(EnumInt(format)) +
                                             " is neither MBDAE_CSC (0) nor MBDAE_CSR (1)");
  const bool query = !ptr && !idx && !val;
  if (!query && !(ptr && idx && val))
    throw ApiError(MBDAE_ERROR_ARGUMENT,
                   "mbdae_get_matrix: ptr, idx and val must be all NULL (to query nnz) or all "
                   "given");

  // Check every block before evaluating anything.
  for (int b = 0; b < num_blocks; ++b) {
    const mbdae_block& blk = blocks[b];
    const int w = EnumInt(blk.which);
    if (w < 0 || w >= kNumApiMatrices)
      throw ApiError(MBDAE_ERROR_ARGUMENT, "mbdae_get_matrix: block " + std::to_string(b) +
                                               ": " + std::to_string(w) +
                                               " is not an mbdae_matrix (0 .. 7)");
    if (!std::isfinite(blk.scale))
      throw ApiError(MBDAE_ERROR_ARGUMENT,
                     "mbdae_get_matrix: block " + std::to_string(b) + ": the scale is not finite");
    std::array<int, 2> size = MatrixSize(m, blk.which);
    if (blk.transpose) std::swap(size[0], size[1]);
    if (blk.row < 0 || blk.col < 0 || blk.row > rows - size[0] || blk.col > cols - size[1])
      throw ApiError(MBDAE_ERROR_ARGUMENT,
                     "mbdae_get_matrix: block " + std::to_string(b) + " (" +
                         MatrixName(blk.which) + (blk.transpose ? ", transposed" : "") +
                         ", " + std::to_string(size[0]) + " x " + std::to_string(size[1]) +
                         ") at row " + std::to_string(blk.row) + ", column " +
                         std::to_string(blk.col) + " does not fit in the " +
                         std::to_string(rows) + " x " + std::to_string(cols) + " matrix");
  }

  // Each distinct matrix once; then the union pattern.
  StateMatrix mats[kNumApiMatrices];
  for (int b = 0; b < num_blocks; ++b) {
    StateMatrix& sm = mats[blocks[b].which];
    if (!sm.pattern) PrepareMatrix(m, blocks[b].which, !query, &sm);
  }
  dae::BlockAssembler assembler;
  std::vector<int> ids(num_blocks);
  for (int b = 0; b < num_blocks; ++b)
    ids[b] = assembler.AddBlock(*mats[blocks[b].which].pattern, blocks[b].row, blocks[b].col,
                                blocks[b].transpose != 0);
  assembler.Finalize(rows, cols);
  const dae::CscPattern& p = assembler.pattern();
  if (query) {
    *nnz = p.nnz();
    return;
  }
  CheckLength(*nnz, p.nnz(), "mbdae_get_matrix (*nnz, the length of idx and val: the number "
                             "of entries)");
  std::vector<double> values(p.nnz(), 0.0);
  for (int b = 0; b < num_blocks; ++b)
    assembler.Accumulate(ids[b], mats[blocks[b].which].values.data(), blocks[b].scale,
                         values.data());
  if (format == MBDAE_CSC) {
    std::copy(p.col_start.begin(), p.col_start.end(), ptr);
    std::copy(p.row_index.begin(), p.row_index.end(), idx);
    std::copy(values.begin(), values.end(), val);
    return;
  }
  // CSR: count the entries of each row, then walk the columns in order (so the column
  // indices of every row come out sorted).
  std::vector<int> row_start(rows + 1, 0);
  for (int r : p.row_index) ++row_start[r + 1];
  for (int r = 0; r < rows; ++r) row_start[r + 1] += row_start[r];
  std::vector<int> next(row_start.begin(), row_start.end() - 1);
  std::vector<int> col_index(p.nnz());
  std::vector<double> csr_values(p.nnz());
  for (int c = 0; c < cols; ++c)
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) {
      const int pos = next[p.row_index[k]]++;
      col_index[pos] = c;
      csr_values[pos] = values[k];
    }
  std::copy(row_start.begin(), row_start.end(), ptr);
  std::copy(col_index.begin(), col_index.end(), idx);
  std::copy(csr_values.begin(), csr_values.end(), val);
}

}  // namespace mbdae::api
