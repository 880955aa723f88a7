#include "mbs/model.h"

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

std::vector<double> Model::parameter_values() const {
  std::vector<double> values;
  values.reserve(parameters.size());
  for (const Parameter& p : parameters) values.push_back(p.value);
  return values;
}

}  // namespace mbdae::mbs
