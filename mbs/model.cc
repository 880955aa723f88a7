#include "mbs/model.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace mbdae::mbs {

namespace {

template <typename T>
int FindByName(const std::vector<T>& items, const std::string& name) {
  for (size_t k = 0; k < items.size(); ++k)
    if (items[k].name == name) return static_cast<int>(k);
  return -1;
}

}  // namespace

int Model::find_parameter(const std::string& name) const { return FindByName(parameters, name); }
int Model::find_marker(const std::string& full_name) const { return FindByName(markers, full_name); }
int Model::find_body(const std::string& name) const { return FindByName(bodies, name); }
int Model::find_measure(const std::string& name) const { return FindByName(measures, name); }
int Model::find_spline(const std::string& name) const { return FindByName(splines, name); }
int Model::find_objective(const std::string& name) const { return FindByName(objectives, name); }

std::vector<double> Model::parameter_values() const {
  std::vector<double> values;
  values.reserve(parameters.size());
  for (const Parameter& p : parameters) values.push_back(p.value);
  return values;
}

bool SplineDef::depends_on_parameters() const {
  for (const std::vector<Expression>* list : {&x_expressions, &y_expressions})
    for (const Expression& e : *list)
      if (!e.parameters_used().empty()) return true;
  return false;
}

bool IsPhysicalInertia(const Mat3& J, std::string* error) {
  auto fail = [error](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  auto num = [](double v) {
    std::ostringstream s;
    s << std::setprecision(10) << v;
    return s.str();
  };
  if (!J.allFinite()) return fail("inertia is not finite");
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(J, Eigen::EigenvaluesOnly);
  const Vec3 I = eig.eigenvalues();  // ascending
  if (I[0] < -1e-12 * std::max(1.0, std::abs(I[2]))) {
    return fail("inertia is not positive semi-definite (smallest eigenvalue " + num(I[0]) + ")");
  }
  // Clamp round-off negatives of a positive semi-definite tensor to zero.
  const double i1 = std::max(I[0], 0.0), i2 = std::max(I[1], 0.0), i3 = std::max(I[2], 0.0);
  const double excess = i3 - (i1 + i2);
  if (excess > kInertiaTriangleRelativeTolerance * i3 + kInertiaTriangleAbsoluteTolerance) {
    return fail("inertia violates the triangle inequality: principal moments " + num(i1) + ", " +
                num(i2) + ", " + num(i3) + "; the largest exceeds the sum of the other two (" +
                num(i1 + i2) + ") by " + num(excess) +
                ", and no rigid body has such an inertia (allowed: 1e-3 of the largest + 1e-12 kg m^2)");
  }
  return true;
}

void ReevaluateSplinePoints(Model* model) {
  assert(model);
  const std::vector<double> values = model->parameter_values();
  for (SplineDef& def : model->splines) {
    if (!def.depends_on_parameters()) continue;
    std::vector<double> x, y;
    for (const Expression& e : def.x_expressions) x.push_back(e.Evaluate(values.data()));
    for (const Expression& e : def.y_expressions) y.push_back(e.Evaluate(values.data()));
    try {
      def.spline.SetPoints(std::move(x), std::move(y));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("spline '" + def.name + "': " + e.what());
    }
  }
}

}  // namespace mbdae::mbs
