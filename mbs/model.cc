#include "mbs/model.h"

#include <cassert>
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
