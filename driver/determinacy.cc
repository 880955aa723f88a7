// Determinacy of the accelerations (driver/determinacy.h): a structural pre-pass over the
// bodies, then a numeric rank test only on the groups of bodies without a positive mass
// and a positive definite inertia.
#include "driver/determinacy.h"

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <SuiteSparseQR.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>
#include <stdexcept>

#include "dae/consistent.h"
#include "mbs/system.h"

namespace mbdae::driver {
namespace {

struct Matrices {
  std::vector<double> mass, cq;
};

Matrices Evaluate(dae::MechanicalSystem& system, const dae::State& x) {
  const dae::CscPattern& pm = system.pattern(dae::Matrix::kMass);
  const dae::CscPattern& pc = system.pattern(dae::Matrix::kConstraintDq);
  Matrices m;
  m.mass.assign(pm.nnz(), 0.0);
  m.cq.assign(pc.nnz(), 0.0);
  dae::EvalInput in;
  in.t = x.t;
  in.q = x.q.data();
  in.v = x.v.data();
  in.a = x.a.data();
  dae::EvalOutput out;
  out[dae::Matrix::kMass] = m.mass.data();
  out[dae::Matrix::kConstraintDq] = m.cq.data();
  if (system.Evaluate(in, out) != 0)
    throw std::runtime_error(std::string("cannot evaluate the model at the assembled state: ") +
                             system.last_error());
  return m;
}

// Positive mass and a positive definite inertia (relative to its largest moment).
bool IsRegular(const mbs::Body& body, double ratio) {
  if (!(body.mass > 0)) return false;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(body.inertia);
  const double largest = eig.eigenvalues().maxCoeff();
  return largest > 0 && eig.eigenvalues().minCoeff() > ratio * largest;
}

bool IsSemiDefinite(const mbs::Body& body) {
  if (!(body.mass >= 0)) return false;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(body.inertia);
  return eig.eigenvalues().minCoeff() >= -1e-12 * std::max(1.0, eig.eigenvalues().cwiseAbs().maxCoeff());
}

// Ruiz equilibration of a dense matrix: rows and columns scaled by 1/sqrt(max |a_ij|)
// until the maxima are near 1 (10 sweeps); returns the column scaling.
Eigen::VectorXd Equilibrate(Eigen::MatrixXd& a) {
  Eigen::VectorXd col = Eigen::VectorXd::Ones(a.cols());
  for (int it = 0; it < 10; ++it) {
    for (int i = 0; i < a.rows(); ++i) {
      const double r = a.row(i).cwiseAbs().maxCoeff();
      if (r > 0) a.row(i) /= std::sqrt(r);
    }
    for (int j = 0; j < a.cols(); ++j) {
      const double c = a.col(j).cwiseAbs().maxCoeff();
      const double s = c > 0 ? 1.0 / std::sqrt(c) : 1.0;
      a.col(j) *= s;
      col[j] *= s;
    }
  }
  return col;
}

// Bodies of the coordinates in the null space of the kernel vectors (columns of z, in
// unscaled coordinates), each vector thresholded at 1e-6 of its largest entry.
void BodiesOfKernel(const Eigen::MatrixXd& z, const std::vector<int>& coordinate,
                    std::set<int>* bodies) {
  for (int c = 0; c < z.cols(); ++c) {
    const double zmax = z.col(c).cwiseAbs().maxCoeff();
    if (zmax == 0) continue;
    for (int i = 0; i < z.rows(); ++i)
      if (std::abs(z(i, c)) > 1e-6 * zmax) bodies->insert(coordinate[i] / 7);
  }
}

// Rank of a sparse matrix (triplets, m x n) by SPQR with its default fill-reducing
// ordering; tol absolute on the column norms of the triangular factor.
long SparseRank(int m, int n, const std::vector<Eigen::Triplet<double>>& entries, double tol) {
  cholmod_common cc;
  cholmod_l_start(&cc);
  cholmod_triplet* t = cholmod_l_allocate_triplet(m, n, std::max<size_t>(1, entries.size()), 0,
                                                  CHOLMOD_REAL, &cc);
  auto* ti = static_cast<SuiteSparse_long*>(t->i);
  auto* tj = static_cast<SuiteSparse_long*>(t->j);
  auto* tx = static_cast<double*>(t->x);
  for (size_t k = 0; k < entries.size(); ++k) {
    ti[k] = entries[k].row();
    tj[k] = entries[k].col();
    tx[k] = entries[k].value();
  }
  t->nnz = entries.size();
  cholmod_sparse* a = cholmod_l_triplet_to_sparse(t, entries.size(), &cc);
  cholmod_l_free_triplet(&t, &cc);
  cholmod_sparse* r = nullptr;
  SuiteSparse_long* e = nullptr;
  const long rank = SuiteSparseQR<double>(SPQR_ORDERING_DEFAULT, tol, 0, a, &r, &e, &cc);
  cholmod_l_free_sparse(&a, &cc);
  if (r) cholmod_l_free_sparse(&r, &cc);
  if (e) cholmod_l_free(n, sizeof(SuiteSparse_long), e, &cc);
  cholmod_l_finish(&cc);
  if (rank < 0) throw std::runtime_error("determinacy: SuiteSparseQR failed");
  return rank;
}

int Find(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

std::vector<std::string> Names(const mbs::Model& model, const std::set<int>& bodies) {
  std::vector<std::string> names;
  for (int b : bodies)
    if (b < static_cast<int>(model.bodies.size())) names.push_back(model.bodies[b].name);
  return names;
}

}  // namespace

DeterminacyResult DenseDeterminacy(const mbs::Model& model, dae::MechanicalSystem& system,
                                   const dae::State& x, double tolerance) {
  const int nq = system.num_coordinates();
  const int nc = system.num_constraints();
  const int n = nq + nc;
  const Matrices v = Evaluate(system, x);
  const dae::CscPattern& pm = system.pattern(dae::Matrix::kMass);
  const dae::CscPattern& pc = system.pattern(dae::Matrix::kConstraintDq);
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(n, n);
  for (int c = 0; c < pm.cols; ++c)
    for (int e = pm.col_start[c]; e < pm.col_start[c + 1]; ++e) k(pm.row_index[e], c) += v.mass[e];
  for (int c = 0; c < pc.cols; ++c)
    for (int e = pc.col_start[c]; e < pc.col_start[c + 1]; ++e) {
      k(nq + pc.row_index[e], c) += v.cq[e];
      k(c, nq + pc.row_index[e]) += v.cq[e];
    }
  // Symmetric equilibration (Ruiz), as the rank decision must not depend on units.
  Eigen::VectorXd d = Eigen::VectorXd::Ones(n);
  for (int it = 0; it < 10; ++it) {
    Eigen::VectorXd s(n);
    for (int i = 0; i < n; ++i) {
      const double r = k.row(i).cwiseAbs().maxCoeff();
      s[i] = r > 0 ? 1.0 / std::sqrt(r) : 1.0;
    }
    k = s.asDiagonal() * k * s.asDiagonal();
    d = d.cwiseProduct(s);
  }
  DeterminacyResult result;
  Eigen::FullPivLU<Eigen::MatrixXd> lu(k);
  lu.setThreshold(tolerance);
  if (lu.rank() == n) return result;
  result.singular = true;
  const Eigen::MatrixXd kernel = lu.kernel();
  Eigen::MatrixXd z = (d.asDiagonal() * kernel).topRows(nq);
  std::vector<int> coordinate(nq);
  std::iota(coordinate.begin(), coordinate.end(), 0);
  std::set<int> bodies;
  BodiesOfKernel(z, coordinate, &bodies);
  result.bodies = Names(model, bodies);
  return result;
}

DeterminacyResult AnalyseDeterminacy(const mbs::Model& model, dae::MechanicalSystem& system,
                                     const dae::State& x, const DeterminacyOptions& options) {
  const int nq = system.num_coordinates();
  const int nc = system.num_constraints();
  const int nb = static_cast<int>(model.bodies.size());
  bool semi_definite = nq == 7 * nb;
  for (int b = 0; semi_definite && b < nb; ++b) semi_definite = IsSemiDefinite(model.bodies[b]);
  // Outside what the structural argument covers: the whole matrix.
  if (!semi_definite) return DenseDeterminacy(model, system, x, options.tolerance);

  DeterminacyResult result;
  if (options.check_constraint_rank && nc > 0) {
    std::vector<int> order;  // normalisations first: the order of least fill (chains)
    if (auto* mb = dynamic_cast<mbs::MultibodySystem*>(&system)) {
      for (int e = 0; e < nc; ++e)
        if (mb->constraint_joint()[e] < 0) order.push_back(e);
      for (int e = 0; e < nc; ++e)
        if (mb->constraint_joint()[e] >= 0) order.push_back(e);
    }
    if (!dae::FindRedundantConstraints(system, x.t, x.q.data(), 1e-9, order).empty())
      result.singular = true;
  }

  std::vector<char> irregular(nb, 0);
  for (int b = 0; b < nb; ++b) {
    irregular[b] = !IsRegular(model.bodies[b], options.regular_inertia_ratio);
    result.irregular_bodies += irregular[b];
  }
  if (result.irregular_bodies == 0) return result;

  const Matrices v = Evaluate(system, x);
  const dae::CscPattern& pm = system.pattern(dae::Matrix::kMass);
  const dae::CscPattern& pc = system.pattern(dae::Matrix::kConstraintDq);
  // Groups: irregular bodies joined by a constraint equation that touches both.
  std::vector<int> parent(nb);
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<int> row_body(nc, -1);  // an irregular body the equation touches
  for (int c = 0; c < nq; ++c) {
    const int b = c / 7;
    if (!irregular[b]) continue;
    for (int e = pc.col_start[c]; e < pc.col_start[c + 1]; ++e) {
      const int r = pc.row_index[e];
      if (row_body[r] < 0) row_body[r] = b;
      else parent[Find(parent, b)] = Find(parent, row_body[r]);
    }
  }
  std::vector<std::vector<int>> group_bodies(nb), group_rows(nb);
  for (int b = 0; b < nb; ++b)
    if (irregular[b]) group_bodies[Find(parent, b)].push_back(b);
  for (int r = 0; r < nc; ++r)
    if (row_body[r] >= 0) group_rows[Find(parent, row_body[r])].push_back(r);

  std::set<int> bodies;
  std::vector<int> local(nq, -1), local_row(nc, -1);
  for (int g = 0; g < nb; ++g) {
    if (group_bodies[g].empty()) continue;
    // Columns: the group's coordinates; rows: M's rows of them, then the equations.
    std::vector<int> coordinate;
    for (int b : group_bodies[g])
      for (int i = 0; i < 7; ++i) coordinate.push_back(7 * b + i);
    const int cols = static_cast<int>(coordinate.size());
    const int rows = cols + static_cast<int>(group_rows[g].size());
    result.largest_group = std::max(result.largest_group, cols);
    for (int i = 0; i < cols; ++i) local[coordinate[i]] = i;
    for (size_t k = 0; k < group_rows[g].size(); ++k) local_row[group_rows[g][k]] = cols + static_cast<int>(k);
    std::vector<Eigen::Triplet<double>> entries;
    for (int i = 0; i < cols; ++i) {
      const int c = coordinate[i];
      for (int e = pm.col_start[c]; e < pm.col_start[c + 1]; ++e)
        if (local[pm.row_index[e]] >= 0) entries.emplace_back(local[pm.row_index[e]], i, v.mass[e]);
      for (int e = pc.col_start[c]; e < pc.col_start[c + 1]; ++e)
        entries.emplace_back(local_row[pc.row_index[e]], i, v.cq[e]);
    }
    if (cols <= options.max_dense_columns) {
      Eigen::MatrixXd a = Eigen::MatrixXd::Zero(rows, cols);
      for (const auto& t : entries) a(t.row(), t.col()) += t.value();
      const Eigen::VectorXd scale = Equilibrate(a);
      Eigen::FullPivLU<Eigen::MatrixXd> lu(a);
      lu.setThreshold(options.tolerance);
      if (lu.rank() < cols) {
        result.singular = true;
        const Eigen::MatrixXd z = scale.asDiagonal() * lu.kernel();
        BodiesOfKernel(z, coordinate, &bodies);
      }
    } else {
      // Rank only, on the matrix scaled by its largest entry per column.
      std::vector<double> colmax(cols, 0.0);
      for (const auto& t : entries) colmax[t.col()] = std::max(colmax[t.col()], std::abs(t.value()));
      for (auto& t : entries)
        t = Eigen::Triplet<double>(t.row(), t.col(), colmax[t.col()] > 0 ? t.value() / colmax[t.col()] : 0.0);
      if (SparseRank(rows, cols, entries, options.tolerance * std::sqrt(double(rows))) < cols) {
        result.singular = true;
        for (int b : group_bodies[g]) {
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(model.bodies[b].inertia);
          if (model.bodies[b].mass <= 0 || eig.eigenvalues().minCoeff() <= 0) bodies.insert(b);
        }
      }
    }
    for (int c : coordinate) local[c] = -1;
    for (int r : group_rows[g]) local_row[r] = -1;
  }
  result.bodies = Names(model, bodies);
  return result;
}

}  // namespace mbdae::driver
