// Sensitivity parameters by name and the chain of dependent parameters (see
// sensitivity_parameters.h).
#include "mbs/sensitivity_parameters.h"

#include <algorithm>
#include <cctype>
#include <functional>
#include <stdexcept>

namespace mbdae::mbs {
namespace {

int EditDistance(const std::string& a, const std::string& b) {
  std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

// " (did you mean 'x', 'y'?)" for names within edit distance 2 (or a third of the length).
std::string Suggest(const std::string& name, const std::vector<std::string>& candidates) {
  std::string out;
  for (const std::string& c : candidates) {
    const int limit = std::max(2, static_cast<int>(name.size()) / 3);
    if (EditDistance(name, c) <= limit) out += (out.empty() ? "" : ", ") + ("'" + c + "'");
  }
  return out.empty() ? "" : " (did you mean " + out + "?)";
}

std::string KnownNames(const Model& model) {
  std::string out;
  for (const Parameter& p : model.parameters) out += (out.empty() ? "" : ", ") + p.name;
  for (const SplineDef& s : model.splines) out += (out.empty() ? "" : ", ") + (s.name + "[i]");
  return out.empty() ? "none" : out;
}

}  // namespace

std::vector<SensitivityParameter> ResolveSensitivityParameters(const Model& model,
                                                               const std::vector<std::string>& names) {
  std::vector<SensitivityParameter> out;
  for (const std::string& name : names) {
    SensitivityParameter p;
    p.name = name;
    const size_t open = name.find('[');
    if (open == std::string::npos) {
      p.parameter = model.find_parameter(name);
      if (p.parameter < 0) {
        const int s = model.find_spline(name);
        if (s >= 0) {
          throw std::invalid_argument("'" + name + "' is a spline: name one of its ordinates as " + name +
                                      "[i], 0 <= i < " + std::to_string(model.splines[s].spline.x().size()));
        }
        std::vector<std::string> candidates;
        for (const Parameter& q : model.parameters) candidates.push_back(q.name);
        for (const SplineDef& q : model.splines) candidates.push_back(q.name);
        throw std::invalid_argument("unknown sensitivity parameter '" + name + "'" + Suggest(name, candidates) +
                                    " (parameters and spline ordinates: " + KnownNames(model) + ")");
      }
    } else {
      const std::string spline = name.substr(0, open);
      const std::string rest = name.substr(open + 1);
      const bool digits = rest.size() >= 2 && rest.back() == ']' &&
                          std::all_of(rest.begin(), rest.end() - 1,
                                      [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; });
      if (spline.empty() || !digits || rest.size() > 11) {
        throw std::invalid_argument("malformed spline ordinate '" + name +
                                    "': write SPLINE[i] with a 0-based point index, e.g. u1[3]");
      }
      p.spline = model.find_spline(spline);
      if (p.spline < 0) {
        std::vector<std::string> candidates;
        for (const SplineDef& q : model.splines) candidates.push_back(q.name);
        throw std::invalid_argument("'" + name + "': unknown spline '" + spline + "'" + Suggest(spline, candidates) +
                                    " (splines: " + (candidates.empty() ? std::string("none") : [&] {
                                      std::string s;
                                      for (const std::string& c : candidates) s += (s.empty() ? "" : ", ") + c;
                                      return s;
                                    }()) + ")");
      }
      const long index = std::stol(rest.substr(0, rest.size() - 1));
      const long n = static_cast<long>(model.splines[p.spline].spline.x().size());
      if (index >= n) {
        throw std::invalid_argument("'" + name + "': point index " + std::to_string(index) + " out of range: spline '" +
                                    spline + "' has " + std::to_string(n) + " points (0 .. " + std::to_string(n - 1) +
                                    ")");
      }
      p.point = static_cast<int>(index);
    }
    out.push_back(p);
  }
  return out;
}

std::vector<SensitivityParameter> AllSensitivityParameters(const Model& model, bool with_splines) {
  std::vector<SensitivityParameter> out;
  for (size_t k = 0; k < model.parameters.size(); ++k) {
    SensitivityParameter p;
    p.name = model.parameters[k].name;
    p.parameter = static_cast<int>(k);
    out.push_back(p);
  }
  if (!with_splines) return out;
  for (size_t s = 0; s < model.splines.size(); ++s) {
    for (size_t i = 0; i < model.splines[s].spline.x().size(); ++i) {
      SensitivityParameter p;
      p.name = model.splines[s].name + "[" + std::to_string(i) + "]";
      p.spline = static_cast<int>(s);
      p.point = static_cast<int>(i);
      out.push_back(p);
    }
  }
  return out;
}

std::vector<std::vector<double>> ParameterChain(const Model& model,
                                                const std::vector<SensitivityParameter>& params) {
  const int n = static_cast<int>(model.parameters.size());
  const std::vector<double> values = model.parameter_values();
  std::vector<std::vector<double>> chain;
  for (const SensitivityParameter& p : params) {
    std::vector<double> column(n, 0.0);
    if (p.parameter < 0) {
      chain.push_back(column);
      continue;
    }
    std::vector<int> state(n, 0);  // 0 not yet, 1 in progress, 2 done
    std::function<void(int)> visit = [&](int j) {
      if (state[j] == 2) return;
      if (state[j] == 1) throw std::logic_error("ParameterChain: parameters depend on each other in a cycle");
      state[j] = 1;
      const Parameter& par = model.parameters[j];
      if (j == p.parameter) {
        column[j] = 1;
      } else if (!par.overridden && !par.formula.parameters_used().empty()) {
        ExpressionInputs in;
        in.parameters = values.data();
        ExpressionGradient g;
        par.formula.EvaluateGradient(in, &g);
        double d = 0;
        const std::vector<int>& used = par.formula.parameters_used();
        for (size_t u = 0; u < used.size(); ++u) {
          visit(used[u]);
          if (column[used[u]] != 0) d += g.d_parameters[u] * column[used[u]];
        }
        column[j] = d;
      }
      state[j] = 2;
    };
    for (int j = 0; j < n; ++j) visit(j);
    chain.push_back(std::move(column));
  }
  return chain;
}

std::vector<double> SplineOrdinateDirection(const Model& model, const SensitivityParameter& param,
                                            const std::vector<double>& chain_column, int spline) {
  const SplineDef& def = model.splines.at(spline);
  std::vector<double> dy(def.spline.x().size(), 0.0);
  if (param.parameter < 0) {
    if (param.spline == spline) dy.at(param.point) = 1;
    return dy;
  }
  if (def.y_expressions.size() != dy.size()) return dy;
  const std::vector<double> values = model.parameter_values();
  ExpressionInputs in;
  in.parameters = values.data();
  for (size_t i = 0; i < dy.size(); ++i) {
    const Expression& e = def.y_expressions[i];
    if (e.parameters_used().empty()) continue;
    ExpressionGradient g;
    e.EvaluateGradient(in, &g);
    for (size_t u = 0; u < e.parameters_used().size(); ++u) dy[i] += g.d_parameters[u] * chain_column[e.parameters_used()[u]];
  }
  return dy;
}

}  // namespace mbdae::mbs
