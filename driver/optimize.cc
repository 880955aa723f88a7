#include "driver/optimize.h"

#include <IpIpoptApplication.hpp>
#include <IpSolveStatistics.hpp>
#include <IpTNLP.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "dae/format.h"
#include "io/results_file.h"
#include "mbs/freedyn.h"
#include "mbs/loader.h"
#include "mbs/measure_kinematics.h"
#include "mbs/model_writer.h"

namespace mbdae::driver {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double CpuSeconds() { return double(std::clock()) / CLOCKS_PER_SEC; }

std::string Num(double x) { return FormatG(x, 10); }

std::string JsonNumber(double x) {
  if (!std::isfinite(x)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

// JSON strings: quoted and escaped as the model writer does.
std::string JsonString(const std::string& s) { return mbs::DoubleQuoted(s); }

std::string Join(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i];
  return out;
}

// ---- the problem file ------------------------------------------------------------

class ProblemReader {
 public:
  explicit ProblemReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void Fail(const YAML::Mark& mark, const std::string& element, const std::string& what) const {
    std::ostringstream s;
    s << file_ << ":";
    if (mark.line >= 0) s << mark.line + 1 << ":" << mark.column + 1 << ":";
    s << " " << element << ": " << what;
    throw InputError(s.str());
  }
  [[noreturn]] void Fail(const YAML::Node& node, const std::string& element, const std::string& what) const {
    Fail(node.Mark(), element, what);
  }

  static std::string Kind(const YAML::Node& n) {
    switch (n.Type()) {
      case YAML::NodeType::Scalar: return "'" + n.Scalar() + "'";
      case YAML::NodeType::Sequence: return "a list";
      case YAML::NodeType::Map: return "a mapping";
      default: return "nothing";
    }
  }

  void CheckKeys(const YAML::Node& node, const std::string& element, const std::vector<std::string>& allowed) const {
    if (!node.IsMap()) Fail(node, element, "expected a mapping (key: value), got " + Kind(node));
    for (auto it = node.begin(); it != node.end(); ++it) {
      const std::string key = it->first.as<std::string>();
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
        Fail(it->first, element, "unknown key '" + key + "' (expected one of: " + Join(allowed) + ")");
    }
  }

  double Number(const YAML::Node& n, const std::string& element, const std::string& key) const {
    if (!n.IsScalar()) Fail(n, element, key + " must be a number, got " + Kind(n));
    double x = 0;
    if (!YAML::convert<double>::decode(n, x) || std::isnan(x))
      Fail(n, element, key + " must be a number, got " + Kind(n));
    return x;
  }

  std::string Name(const YAML::Node& n, const std::string& element, const std::string& key) const {
    if (!n.IsScalar() || n.Scalar().empty()) Fail(n, element, key + " must be a name, got " + Kind(n));
    return n.Scalar();
  }

  bool Bool(const YAML::Node& n, const std::string& element, const std::string& key) const {
    bool b = false;
    if (!n.IsScalar() || !YAML::convert<bool>::decode(n, b))
      Fail(n, element, key + " must be true or false, got " + Kind(n));
    return b;
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

// The objective names of the model.
std::vector<std::string> ObjectiveNames(const mbs::Model& model) {
  std::vector<std::string> names;
  for (const auto& o : model.objectives) names.push_back(o.name);
  return names;
}

void ReadSimulation(const ProblemReader& r, const YAML::Node& node, SettingsOverrides* o) {
  const std::string element = "simulation";
  r.CheckKeys(node, element, {"t_end", "output_step", "integrator", "hht", "ida", "output_accelerations"});
  if (const YAML::Node n = node["t_end"]) o->t_end = r.Number(n, element, "t_end");
  if (const YAML::Node n = node["output_step"]) o->output_step = r.Number(n, element, "output_step");
  if (const YAML::Node n = node["integrator"]) {
    const std::string v = r.Name(n, element, "integrator");
    if (v == "hht")
      o->integrator = mbs::IntegratorKind::kHht;
    else if (v == "ida")
      o->integrator = mbs::IntegratorKind::kIda;
    else
      r.Fail(n, element, "integrator must be hht or ida, got '" + v + "'");
  }
  if (const YAML::Node h = node["hht"]) {
    r.CheckKeys(h, element + " hht", {"alpha", "step", "adaptive", "tolerance", "modified", "form", "start"});
    if (const YAML::Node n = h["alpha"]) o->hht_alpha = r.Number(n, element, "hht alpha");
    if (const YAML::Node n = h["step"]) o->hht_step = r.Number(n, element, "hht step");
    if (const YAML::Node n = h["adaptive"]) o->hht_adaptive = r.Bool(n, element, "hht adaptive");
    if (const YAML::Node n = h["tolerance"]) o->hht_tolerance = r.Number(n, element, "hht tolerance");
    if (const YAML::Node n = h["modified"]) o->hht_modified = r.Bool(n, element, "hht modified");
    if (const YAML::Node n = h["form"]) {
      const std::string v = r.Name(n, element, "hht form");
      if (v != "equilibrium" && v != "negrut")
        r.Fail(n, element, "hht form must be equilibrium or negrut, got '" + v + "'");
      o->hht_form = v;
    }
    if (const YAML::Node n = h["start"]) {
      const std::string v = r.Name(n, element, "hht start");
      if (v != "consistent" && v != "perturbed")
        r.Fail(n, element, "hht start must be consistent or perturbed, got '" + v + "'");
      o->hht_start = v;
    }
  }
  if (const YAML::Node n = node["output_accelerations"]) {
    const std::string v = r.Name(n, element, "output_accelerations");
    if (v != "solved" && v != "integrator")
      r.Fail(n, element, "output_accelerations must be solved or integrator, got '" + v + "'");
    o->output_accelerations = v;
  }
  if (const YAML::Node i = node["ida"]) {
    r.CheckKeys(i, element + " ida", {"rtol", "atol", "max_steps", "min_step"});
    if (const YAML::Node n = i["rtol"]) o->ida_rtol = r.Number(n, element, "ida rtol");
    if (const YAML::Node n = i["atol"]) o->ida_atol = r.Number(n, element, "ida atol");
    if (const YAML::Node n = i["max_steps"]) {
      long long k = 0;
      if (!n.IsScalar() || !YAML::convert<long long>::decode(n, k) || k < 1)
        r.Fail(n, element, "ida max_steps must be a whole number of at least 1, got " + r.Kind(n));
      o->ida_max_steps = static_cast<long>(k);
    }
    if (const YAML::Node n = i["min_step"]) {
      const double h = r.Number(n, element, "ida min_step");
      if (!(h > 0) || !std::isfinite(h)) r.Fail(n, element, "ida min_step must be a positive number, got " + Num(h));
      o->ida_min_step = h;
    }
  }
}

// Checks each option against Ipopt's registry (name, type, range) on a scratch
// application, so that a bad option is named with its line before anything runs.
void ReadIpoptOptions(const ProblemReader& r, const YAML::Node& node, std::vector<IpoptOption>* out) {
  const std::string element = "ipopt";
  if (!node.IsMap()) r.Fail(node, element, "expected a mapping of Ipopt options, got " + r.Kind(node));
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = new Ipopt::IpoptApplication(false);
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string name = it->first.as<std::string>();
    const YAML::Node v = it->second;  // a copy: it->second lives only in this statement
    const std::string what = "option '" + name + "'";
    Ipopt::SmartPtr<const Ipopt::RegisteredOption> reg = app->RegOptions()->GetOption(name);
    if (!Ipopt::IsValid(reg)) r.Fail(it->first, element, "unknown Ipopt option '" + name + "'");
    if (!v.IsScalar()) r.Fail(v, element, what + " must be a number or a string, got " + r.Kind(v));
    // A quoted scalar (tag "!") is a string whatever it looks like.
    const bool quoted = v.Tag() == "!";
    IpoptOption o;
    o.name = name;
    bool accepted = false;
    switch (reg->Type()) {
      case Ipopt::OT_Number: {
        double x = 0;
        if (quoted || !YAML::convert<double>::decode(v, x) || !std::isfinite(x))
          r.Fail(v, element, what + " takes a number, got " + r.Kind(v));
        o.kind = IpoptOption::Kind::kNumber;
        o.number = x;
        accepted = app->Options()->SetNumericValue(name, x);
        break;
      }
      case Ipopt::OT_Integer: {
        long long k = 0;
        if (quoted || !YAML::convert<long long>::decode(v, k) || k < std::numeric_limits<int>::min() ||
            k > std::numeric_limits<int>::max())
          r.Fail(v, element, what + " takes an integer, got " + r.Kind(v));
        o.kind = IpoptOption::Kind::kInteger;
        o.integer = static_cast<int>(k);
        accepted = app->Options()->SetIntegerValue(name, o.integer);
        break;
      }
      default:
        o.kind = IpoptOption::Kind::kString;
        o.text = v.Scalar();
        accepted = app->Options()->SetStringValue(name, o.text);
        break;
    }
    if (!accepted) {
      r.Fail(v, element, what + ": Ipopt does not accept " + r.Kind(v) + " (its range or list of values)");
    }
    out->push_back(o);
  }
}

}  // namespace

namespace {

// `shooting:` (after the variables): checks the names against the model and the
// variables, then appends the node variables.
void ReadShooting(const ProblemReader& r, const YAML::Node& node, const std::map<std::string, YAML::Node>& fixed,
                  OptimizationProblem* p) {
  const std::string el = "shooting";
  const mbs::Model& m = p->model;
  if (!node.IsMap()) r.Fail(node, el, "expected a mapping {intervals: N, time: PARAMETER, state: [...]}, got " + r.Kind(node));
  r.CheckKeys(node, el, {"intervals", "time", "state"});
  std::vector<std::string> known;
  for (const auto& q : m.parameters) known.push_back(q.name);
  std::set<std::string> taken, used;  // variables; parameters named here
  for (const auto& v : p->variables)
    if (v.parameter >= 0) taken.insert(v.name);
  // A model parameter that is neither a variable nor fixed nor used twice here.
  auto parameter = [&](const YAML::Node& n, const std::string& element, const std::string& key) {
    const std::string name = r.Name(n, element, key);
    if (m.find_parameter(name) < 0)
      r.Fail(n, element, "unknown parameter '" + name + "' of model " + p->model_path +
                             (known.empty() ? std::string(" (it has no parameters)") : "; its parameters: " + Join(known)));
    if (taken.count(name)) r.Fail(n, element, "parameter '" + name + "' is a variable: the shooting sets it");
    if (fixed.count(name))
      r.Fail(n, element, "parameter '" + name + "' is fixed in `parameters:` (line " +
                             std::to_string(fixed.at(name).Mark().line + 1) + "): the shooting sets it");
    if (!used.insert(name).second) r.Fail(n, element, "parameter '" + name + "' is used twice in `shooting:`");
    return name;
  };
  Shooting& sh = p->shooting;
  const YAML::Node in = node["intervals"];
  if (!in) r.Fail(node, el, "missing key 'intervals'");
  long long count = 0;
  if (!in.IsScalar() || !YAML::convert<long long>::decode(in, count) || count < 1 || count > 1000)
    r.Fail(in, el, "intervals must be an integer from 1 to 1000, got " + r.Kind(in));
  sh.intervals = static_cast<int>(count);
  if (!node["time"]) r.Fail(node, el, "missing key 'time' (the model parameter of the interval's start time)");
  sh.time = parameter(node["time"], el, "time");
  const YAML::Node st = node["state"];
  if (!st || !st.IsSequence() || st.size() == 0)
    r.Fail(st ? st : node, el, "expected 'state': a non-empty list of {parameter: NAME, measure: NAME}");
  std::vector<std::string> measures;
  for (const auto& q : m.measures) measures.push_back(q.name);
  for (size_t k = 0; k < st.size(); ++k) {
    const YAML::Node s = st[k];
    const std::string e = "shooting.state[" + std::to_string(k) + "]";
    r.CheckKeys(s, e, {"parameter", "measure", "lower", "upper", "start"});
    if (!s["parameter"]) r.Fail(s, e, "missing key 'parameter'");
    if (!s["measure"]) r.Fail(s, e, "missing key 'measure'");
    ShootingState ss;
    ss.parameter = parameter(s["parameter"], e, "parameter");
    ss.measure = r.Name(s["measure"], e, "measure");
    for (size_t i = 0; i < m.measures.size(); ++i)
      if (m.measures[i].name == ss.measure) ss.measure_index = static_cast<int>(i);
    if (ss.measure_index < 0)
      r.Fail(s["measure"], e, "unknown measure '" + ss.measure + "' of model " + p->model_path +
                                  (measures.empty() ? std::string(" (it has no measures)") : "; its measures: " + Join(measures)));
    for (const ShootingState& other : sh.states)
      if (other.measure == ss.measure) r.Fail(s["measure"], e, "measure '" + ss.measure + "' is used twice in `shooting:`");
    ss.angle = mbs::IsAngleMeasure(m.measures[ss.measure_index]);
    if (s["lower"]) ss.lower = r.Number(s["lower"], e, "lower");
    if (s["upper"]) ss.upper = r.Number(s["upper"], e, "upper");
    if (ss.lower >= ss.upper)
      r.Fail(s["lower"], e, "lower bound " + Num(ss.lower) + " is not below upper bound " + Num(ss.upper));
    if (const YAML::Node v = s["start"]) {  // the node variables' starts, nodes 1 .. intervals - 1
      if (!v.IsSequence() || v.size() != static_cast<size_t>(sh.intervals - 1))
        r.Fail(v, e, "expected 'start': a list of " + std::to_string(sh.intervals - 1) +
                         " values (one per node, intervals - 1), got " + r.Kind(v));
      for (size_t i = 0; i < v.size(); ++i) {
        const double x = r.Number(v[i], e, "start[" + std::to_string(i) + "]");
        if (x < ss.lower || x > ss.upper)
          r.Fail(v[i], e, "start " + Num(x) + " is outside the bounds [" + Num(ss.lower) + ", " + Num(ss.upper) + "]");
        ss.start.push_back(x);
      }
    }
    sh.states.push_back(ss);
  }
  for (int k = 1; k < sh.intervals; ++k)
    for (size_t s = 0; s < sh.states.size(); ++s) {
      OptimizationVariable ov;
      ov.name = sh.states[s].parameter + "@" + std::to_string(k);
      ov.node = k;
      ov.state = static_cast<int>(s);
      ov.lower = sh.states[s].lower;
      ov.upper = sh.states[s].upper;
      ov.start = m.parameters[m.find_parameter(sh.states[s].parameter)].value;
      if (!sh.states[s].start.empty()) {
        ov.start = sh.states[s].start[k - 1];
        ov.start_given = true;
      }
      p->variables.push_back(ov);
    }
}

// The problem from its parsed YAML; `path` names it in messages and its folder is where
// `model:` is resolved.
OptimizationProblem ReadProblem(const YAML::Node& root, const std::string& path) {
  ProblemReader r(path);
  OptimizationProblem p;
  p.file = path;
  const std::string element = "problem";
  if (!root.IsMap()) r.Fail(root, element, "expected a mapping (format, model, variables, minimize, ...), got " + r.Kind(root));
  r.CheckKeys(root, element,
              {"format", "model", "parameters", "variables", "minimize", "constraints", "simulation", "ipopt", "method",
               "shooting"});
  auto required = [&](const char* key) {
    const YAML::Node n = root[key];
    if (!n) r.Fail(root, element, std::string("missing key '") + key + "'");
    return n;
  };
  if (const YAML::Node f = root["format"]) {
    if (!f.IsScalar() || f.Scalar() != "1") r.Fail(f, element, "format must be 1, got " + r.Kind(f));
  }

  // The model, relative to the problem file.
  const YAML::Node model_node = required("model");
  const std::string model_name = r.Name(model_node, "model", "model");
  std::filesystem::path model_path(model_name);
  if (model_path.is_relative()) model_path = std::filesystem::path(path).parent_path() / model_path;
  p.model_path = model_path.lexically_normal().string();
  {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(p.model_path, ec))
      r.Fail(model_node, "model", "the model file '" + p.model_path + "' does not exist" +
                                       (std::filesystem::exists(p.model_path, ec) ? " as a file" : ""));
  }
  p.model = mbs::LoadAnyModel(p.model_path);

  // Fixed parameters: names checked against the model, then the model loaded with them.
  std::map<std::string, YAML::Node> fixed_nodes;
  if (const YAML::Node ps = root["parameters"]) {
    if (!ps.IsMap()) r.Fail(ps, "parameters", "expected a mapping {NAME: VALUE, ...}, got " + r.Kind(ps));
    std::vector<std::string> known;
    for (const auto& q : p.model.parameters) known.push_back(q.name);
    for (auto it = ps.begin(); it != ps.end(); ++it) {
      const std::string name = r.Name(it->first, "parameters", "a parameter");
      if (p.model.find_parameter(name) < 0)
        r.Fail(it->first, "parameters", "unknown parameter '" + name + "' of model " + p.model_path +
                                            (known.empty() ? std::string(" (it has no parameters)")
                                                           : "; its parameters: " + Join(known)));
      const double value = r.Number(it->second, "parameters", name);
      if (!std::isfinite(value)) r.Fail(it->second, "parameters", name + " must be finite");
      p.parameters[name] = value;
      fixed_nodes[name] = it->first;
    }
    if (!p.parameters.empty()) {
      mbs::LoadOptions lo;
      lo.parameter_overrides = p.parameters;
      try {
        p.model = mbs::LoadAnyModel(p.model_path, lo);
      } catch (const mbs::ModelError& e) {
        r.Fail(ps, "parameters", std::string("the model refuses these values: ") + e.what());
      }
    }
  }
  const mbs::Model& m = p.model;
  const std::vector<std::string> objectives = ObjectiveNames(m);

  // Variables.
  const YAML::Node vars = required("variables");
  if (!vars.IsSequence() || vars.size() == 0)
    r.Fail(vars, "variables", "expected a non-empty list of {parameter: NAME} or {spline: NAME}, got " + r.Kind(vars));
  std::set<std::string> seen;
  for (size_t k = 0; k < vars.size(); ++k) {
    const YAML::Node v = vars[k];
    const std::string el = "variables[" + std::to_string(k) + "]";
    r.CheckKeys(v, el, {"parameter", "spline", "points", "lower", "upper", "start"});
    double lower = -kInf, upper = kInf;
    if (v["lower"]) lower = r.Number(v["lower"], el, "lower");
    if (v["upper"]) upper = r.Number(v["upper"], el, "upper");
    if (lower > upper) r.Fail(v["lower"], el, "lower bound " + Num(lower) + " is greater than upper bound " + Num(upper));
    if (lower == upper) r.Fail(v["lower"], el, "lower and upper bound are equal (" + Num(lower) + "): that is not a variable");
    std::vector<OptimizationVariable> add;
    if (v["parameter"] && v["spline"]) r.Fail(v, el, "give either parameter or spline, not both");
    if (const YAML::Node n = v["parameter"]) {
      if (v["points"]) r.Fail(v["points"], el, "points are for splines");
      const std::string name = r.Name(n, el, "parameter");
      int index = -1;
      std::vector<std::string> known;
      for (size_t i = 0; i < m.parameters.size(); ++i) {
        known.push_back(m.parameters[i].name);
        if (m.parameters[i].name == name) index = static_cast<int>(i);
      }
      if (index < 0)
        r.Fail(n, el, "unknown parameter '" + name + "' of model " + p.model_path +
                          (known.empty() ? std::string(" (it has no parameters)") : "; its parameters: " + Join(known)));
      if (p.parameters.count(name))
        r.Fail(n, el, "parameter '" + name + "' is fixed in `parameters:` (line " +
                          std::to_string(fixed_nodes[name].Mark().line + 1) + "): it cannot also be a variable");
      OptimizationVariable ov;
      ov.name = name;
      ov.parameter = index;
      ov.start = m.parameters[index].value;
      add.push_back(ov);
    } else if (const YAML::Node n = v["spline"]) {
      const std::string name = r.Name(n, el, "spline");
      int index = -1;
      std::vector<std::string> known;
      for (size_t i = 0; i < m.splines.size(); ++i) {
        known.push_back(m.splines[i].name);
        if (m.splines[i].name == name) index = static_cast<int>(i);
      }
      if (index < 0)
        r.Fail(n, el, "unknown spline '" + name + "' of model " + p.model_path +
                          (known.empty() ? std::string(" (it has no splines)") : "; its splines: " + Join(known)));
      const mbs::SplineDef& s = m.splines[index];
      // Ordinates written as expressions of parameters are computed, not free; abscissae
      // that depend on parameters are fine (the ordinates are set after a reload).
      for (const mbs::Expression& e : s.y_expressions)
        if (!e.parameters_used().empty())
          r.Fail(n, el, "the ordinates of spline '" + name + "' are computed from parameters: they cannot be variables");
      const int count = static_cast<int>(s.spline.y().size());
      std::vector<int> points;
      if (const YAML::Node pts = v["points"]) {
        if (!pts.IsSequence() || pts.size() == 0) r.Fail(pts, el, "points must be a non-empty list of point indices, got " + r.Kind(pts));
        for (const YAML::Node& q : pts) {
          long long i = -1;
          if (!q.IsScalar() || !YAML::convert<long long>::decode(q, i) || i < 0 || i >= count)
            r.Fail(q, el, "point " + r.Kind(q) + " is not an index of spline '" + name + "' (0 to " +
                              std::to_string(count - 1) + ")");
          points.push_back(static_cast<int>(i));
        }
      } else {
        for (int i = 0; i < count; ++i) points.push_back(i);
      }
      for (int i : points) {
        OptimizationVariable ov;
        ov.name = name + "[" + std::to_string(i) + "]";
        ov.spline = index;
        ov.point = i;
        ov.start = s.spline.y()[i];
        add.push_back(ov);
      }
    } else {
      r.Fail(v, el, "expected {parameter: NAME} or {spline: NAME}");
    }
    if (const YAML::Node s = v["start"]) {
      // One number for every ordinate, or (splines) one per selected ordinate.
      auto check = [&](const YAML::Node& node, double x, const std::string& what) {
        if (!std::isfinite(x)) r.Fail(node, el, what + " must be finite");
        if (x < lower || x > upper)
          r.Fail(node, el, what + " " + Num(x) + " is outside the bounds [" + Num(lower) + ", " + Num(upper) + "]");
      };
      if (s.IsSequence()) {
        if (v["parameter"]) r.Fail(s, el, "start of a parameter is one number, got a list");
        if (s.size() != add.size())
          r.Fail(s, el, "start has " + std::to_string(s.size()) + " values, the variable " + std::to_string(add.size()) +
                            " ordinates (" + add.front().name + (add.size() > 1 ? " ... " + add.back().name : "") +
                            "): give one number for all, or one per ordinate");
        for (size_t i = 0; i < add.size(); ++i) {
          const std::string what = "start[" + std::to_string(i) + "]";
          add[i].start = r.Number(s[i], el, what);
          check(s[i], add[i].start, what);
          add[i].start_given = true;
        }
      } else {
        const double x = r.Number(s, el, "start");
        check(s, x, "start");
        for (auto& ov : add) {
          ov.start = x;
          ov.start_given = true;
        }
      }
    }
    for (auto& ov : add) {
      if (!seen.insert(ov.name).second) r.Fail(v, el, "variable '" + ov.name + "' is listed twice");
      ov.lower = lower;
      ov.upper = upper;
      p.variables.push_back(ov);
    }
  }

  // Objective and constraints.
  auto objective = [&](const YAML::Node& n, const std::string& el, const std::string& key) {
    const std::string name = r.Name(n, el, key);
    if (std::find(objectives.begin(), objectives.end(), name) == objectives.end())
      r.Fail(n, el, "unknown objective '" + name + "' of model " + p.model_path +
                        (objectives.empty() ? std::string(" (it has no `objectives:`)") : "; its objectives: " + Join(objectives)));
    return name;
  };
  p.objective = objective(required("minimize"), "minimize", "minimize");
  if (const YAML::Node cs = root["constraints"]) {
    if (!cs.IsSequence()) r.Fail(cs, "constraints", "expected a list of {objective: NAME, equals: V | lower: L, upper: U}, got " + r.Kind(cs));
    for (size_t k = 0; k < cs.size(); ++k) {
      const YAML::Node c = cs[k];
      const std::string el = "constraints[" + std::to_string(k) + "]";
      r.CheckKeys(c, el, {"objective", "equals", "lower", "upper"});
      if (!c["objective"]) r.Fail(c, el, "missing key 'objective'");
      OptimizationConstraint oc;
      oc.objective = objective(c["objective"], el, "objective");
      if (const YAML::Node e = c["equals"]) {
        if (c["lower"] || c["upper"]) r.Fail(e, el, "give either equals or lower/upper, not both");
        oc.lower = oc.upper = r.Number(e, el, "equals");
        if (!std::isfinite(oc.lower)) r.Fail(e, el, "equals must be finite");
      } else {
        if (!c["lower"] && !c["upper"]) r.Fail(c, el, "give equals, or lower and/or upper");
        if (c["lower"]) oc.lower = r.Number(c["lower"], el, "lower");
        if (c["upper"]) oc.upper = r.Number(c["upper"], el, "upper");
        if (oc.lower > oc.upper)
          r.Fail(c["lower"], el, "lower bound " + Num(oc.lower) + " is greater than upper bound " + Num(oc.upper));
      }
      p.constraints.push_back(oc);
    }
  }

  SettingsOverrides overrides;
  if (const YAML::Node s = root["simulation"]) {
    ReadSimulation(r, s, &overrides);
    try {
      p.settings = ResolveSettings(m.simulation, overrides);
    } catch (const InputError& e) {
      r.Fail(s, "simulation", e.what());
    }
  } else {
    p.settings = ResolveSettings(m.simulation, overrides);
  }
  if (const YAML::Node n = root["method"]) {
    const std::string v = r.Name(n, "method", "method");
    if (!ParseGradientMethod(v, &p.method)) r.Fail(n, "method", "expected adjoint, forward or fd, got '" + v + "'");
  }
  if (const YAML::Node n = root["ipopt"]) ReadIpoptOptions(r, n, &p.ipopt);
  if (const YAML::Node n = root["shooting"]) ReadShooting(r, n, fixed_nodes, &p);
  return p;
}

}  // namespace

OptimizationProblem LoadOptimizationProblem(const std::string& path) {
  YAML::Node root;
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path + ": the problem file is a directory");
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw InputError(path + ": cannot open the problem file");
  } catch (const YAML::Exception& e) {
    ProblemReader(path).Fail(e.mark, "problem", "not valid YAML: " + e.msg);
  }
  return ReadProblem(root, path);
}

OptimizationProblem LoadOptimizationProblemFromString(const std::string& text, const std::string& name) {
  const std::string path = name.empty() ? "<string>" : name;
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    ProblemReader(path).Fail(e.mark, "problem", "not valid YAML: " + e.msg);
  }
  return ReadProblem(root, path);
}

namespace {

// ---- the NLP ----------------------------------------------------------------------

// Evaluations of one point: values of every needed objective and their gradients.
struct Evaluation {
  std::vector<double> x;
  bool ok = false;
  double f = 0;
  std::vector<double> grad_f;  // n
  std::vector<double> g;       // m
  std::vector<double> jac;     // m x n, row-major
};

class ShootingNlp : public Ipopt::TNLP {
 public:
  ShootingNlp(const OptimizationProblem& p, const OptimizeOptions& o, OptimizationResult* r)
      : p_(p), o_(o), r_(r) {
    for (size_t k = 0; k < p.variables.size(); ++k) {
      if (p.variables[k].node > 0) continue;
      wrt_.push_back(p.variables[k].name);
      global_.push_back(static_cast<int>(k));
    }
    objectives_.push_back(p.objective);
    for (const auto& c : p.constraints)
      if (std::find(objectives_.begin(), objectives_.end(), c.objective) == objectives_.end())
        objectives_.push_back(c.objective);
    for (const auto& v : p.variables) has_parameters_ = has_parameters_ || v.parameter >= 0;
    final_x_.reserve(p.variables.size());
    for (const auto& v : p.variables) final_x_.push_back(v.start);
    const Shooting& sh = p.shooting;
    if (sh.intervals > 1) {
      for (int k = 1; k < sh.intervals; ++k) {
        node_.emplace_back();
        for (size_t v = 0; v < p.variables.size(); ++v)
          if (p.variables[v].node == k) node_.back().push_back(static_cast<int>(v));
      }
      for (size_t s = 0; s < sh.states.size(); ++s) end_names_.push_back(" shooting end " + sh.states[s].measure);
    }
  }

  int intervals() const { return p_.shooting.intervals; }
  size_t continuity_rows() const { return intervals() > 1 ? (intervals() - 1) * p_.shooting.states.size() : 0; }

  // The model with the variables at x (parameter variables by a reload, then the
  // ordinates); `extra` are further parameter overrides (fd's perturbations).
  mbs::Model ModelAt(const std::vector<double>& x, const std::map<std::string, double>& extra = {}) const {
    mbs::Model m;
    if (has_parameters_ || !extra.empty()) {
      mbs::LoadOptions lo;
      lo.parameter_overrides = p_.parameters;
      for (size_t k = 0; k < x.size(); ++k)
        if (p_.variables[k].parameter >= 0) lo.parameter_overrides[p_.variables[k].name] = x[k];
      for (const auto& [name, value] : extra) lo.parameter_overrides[name] = value;
      m = mbs::LoadAnyModel(p_.model_path, lo);
    } else {
      m = p_.model;
    }
    std::map<int, std::vector<double>> ordinates;
    for (size_t k = 0; k < x.size(); ++k) {
      const OptimizationVariable& v = p_.variables[k];
      if (v.spline < 0) continue;
      auto it = ordinates.find(v.spline);
      if (it == ordinates.end()) it = ordinates.emplace(v.spline, m.splines[v.spline].spline.y()).first;
      it->second[v.point] = x[k];
    }
    for (auto& [s, y] : ordinates) {
      mbs::Spline& spline = m.splines[s].spline;
      spline.SetPoints(spline.x(), y);
    }
    return m;
  }

  // Multiple shooting: the model of interval k (0-based) at x: reloaded with the time
  // parameter at the interval's start and (k >= 1) the states' parameters at the node
  // variables, angle measures counting turns from the nodes' angles; terminal parts of
  // the objectives only in the last interval; plus one terminal objective per state (its
  // measure at the interval's end).
  mbs::Model IntervalModel(const std::vector<double>& x, int k, const std::map<std::string, double>& extra = {}) const {
    const Shooting& sh = p_.shooting;
    std::map<std::string, double> overrides = {{sh.time, k * p_.settings.t_end / sh.intervals}};
    if (k >= 1)
      for (int v : node_[k - 1]) overrides[sh.states[p_.variables[v].state].parameter] = x[v];
    for (const auto& [name, value] : extra) overrides[name] = value;
    mbs::Model m = ModelAt(x, overrides);
    if (k >= 1)
      for (int v : node_[k - 1]) {
        const ShootingState& st = sh.states[p_.variables[v].state];
        if (st.angle) m.measures[st.measure_index].turn_reference = x[v];
      }
    if (k < sh.intervals - 1)
      for (mbs::Objective& o : m.objectives) {
        o.has_terminal = false;
        o.terminal = mbs::Expression();
      }
    mbs::SymbolTable symbols;
    for (const auto& q : m.parameters) symbols.parameters.push_back(q.name);
    for (const auto& q : m.measures) symbols.measures.push_back(q.name);
    symbols.allow_time = true;
    for (size_t s = 0; s < sh.states.size(); ++s) {
      mbs::Objective o;
      o.name = end_names_[s];
      o.terminal = mbs::Expression::Parse(sh.states[s].measure, symbols);
      o.has_terminal = true;
      m.objectives.push_back(o);
    }
    return m;
  }

  // One interval's run and gradient at x: the objectives_, then (not the last interval)
  // the states' end values, with respect to the global variables and (k >= 1) the node
  // variables of interval k.
  GradientResult Interval(const std::vector<double>& x, int k) {
    GradientRequest request;
    request.objectives = objectives_;
    if (k < intervals() - 1) request.objectives.insert(request.objectives.end(), end_names_.begin(), end_names_.end());
    request.wrt = wrt_;
    if (k >= 1)
      for (int v : node_[k - 1]) request.wrt.push_back(p_.shooting.states[p_.variables[v].state].parameter);
    request.method = p_.method;
    GradientOptions go;
    go.model_path = p_.model_path;
    go.reload = [this, &x, k](const std::map<std::string, double>& overrides) { return IntervalModel(x, k, overrides); };
    mbs::SimulationSettings settings = p_.settings;
    settings.t_end = p_.settings.t_end / intervals();
    const mbs::Model model = IntervalModel(x, k);
    ++r_->gradient_evaluations;
    const double cpu = CpuSeconds();
    GradientResult g = ComputeGradient(model, settings, request, go);
    r_->gradient_cpu_time += CpuSeconds() - cpu;
    r_->runs += g.runs;
    return g;
  }

  // Multiple shooting: the starting node variables from a forward sweep (each interval
  // from the end of the previous one), for the node variables without `start:`.
  void SweepStart(std::vector<double>* x) {
    for (int k = 0; k + 1 < intervals(); ++k) {
      bool given = true;  // every node variable of interval k + 1 has its `start:`
      for (int v : node_[k]) given = given && p_.variables[v].start_given;
      if (given) continue;
      const GradientResult g = Interval(*x, k);
      if (g.status != GradientResult::Status::kDone) return;  // the model's values stay
      for (int v : node_[k]) {
        if (p_.variables[v].start_given) continue;
        const auto it = std::find(g.objectives.begin(), g.objectives.end(), end_names_[p_.variables[v].state]);
        (*x)[v] = std::clamp(g.values[it - g.objectives.begin()], p_.variables[v].lower, p_.variables[v].upper);
      }
    }
  }

  // The objective, the constraints and the continuity defects at x as sums over the
  // intervals (the objectives' integrals add up; terminal parts come from the last).
  void EvaluateShooting(const std::vector<double>& x, Evaluation* e) {
    Clear(e, x.size());
    for (int k = 0; k < intervals(); ++k)
      if (!AddInterval(x, k, e)) return;
    CheckFinite(e);
  }

  // Zero values and derivatives for n variables.
  void Clear(Evaluation* e, size_t n) const {
    const size_t m = p_.constraints.size() + continuity_rows();
    e->ok = false;
    e->f = 0;
    e->grad_f.assign(n, 0.0);
    e->g.assign(m, 0.0);
    e->jac.assign(m * n, 0.0);
  }

  // Adds interval k's run at x to e: its share of the objective and constraints, and the
  // continuity row of its end (not the last interval). False (last_failure_ set) when the
  // run fails.
  bool AddInterval(const std::vector<double>& x, int k, Evaluation* e) {
    const size_t n = x.size(), m0 = p_.constraints.size(), ns = p_.shooting.states.size();
    const GradientResult g = Interval(x, k);
    if (g.status != GradientResult::Status::kDone) {
      last_failure_ = "interval " + std::to_string(k + 1) + ": " + g.failure_reason;
      ++r_->failed_evaluations;
      return false;
    }
    // wrt column c of this run -> variable index
    std::vector<int> column(global_);
    if (k >= 1) column.insert(column.end(), node_[k - 1].begin(), node_[k - 1].end());
    auto index = [&g](const std::string& name) {
      return static_cast<int>(std::find(g.objectives.begin(), g.objectives.end(), name) - g.objectives.begin());
    };
    auto add_row = [&](int io, double* row) {
      for (size_t c = 0; c < column.size(); ++c) row[column[c]] += g.Gradient(io, static_cast<int>(c));
    };
    const int io = index(p_.objective);
    e->f += g.values[io];
    add_row(io, e->grad_f.data());
    for (size_t i = 0; i < m0; ++i) {
      const int ic = index(p_.constraints[i].objective);
      e->g[i] += g.values[ic];
      add_row(ic, &e->jac[i * n]);
    }
    if (k + 1 < intervals())
      for (size_t s = 0; s < ns; ++s) {
        const size_t row = m0 + k * ns + s;
        const int ie = index(end_names_[s]);
        const int v = node_[k][s];
        e->g[row] = g.values[ie] - x[v];
        add_row(ie, &e->jac[row * n]);
        e->jac[row * n + v] -= 1.0;
      }
    return true;
  }

  // e is ok when every value and derivative is finite.
  void CheckFinite(Evaluation* e) {
    bool finite = std::isfinite(e->f);
    for (double v : e->grad_f) finite = finite && std::isfinite(v);
    for (double v : e->g) finite = finite && std::isfinite(v);
    for (double v : e->jac) finite = finite && std::isfinite(v);
    e->ok = finite;
    if (!finite) {
      last_failure_ = "a value or gradient is not finite";
      ++r_->failed_evaluations;
    }
  }

  // The largest |continuity defect| of the last evaluation.
  double Defect() const {
    double d = 0;
    for (size_t i = p_.constraints.size(); i < cache_.g.size(); ++i) d = std::max(d, std::abs(cache_.g[i]));
    return d;
  }

  // The evaluation at x (cached). Throws InputError only from the first evaluation (the
  // problem's variables checked by ComputeGradient); later failures give ok = false.
  const Evaluation& Evaluate(const std::vector<double>& x, bool first = false) {
    if (cache_.x == x && !cache_.x.empty()) return cache_;
    cache_ = Evaluation{};
    cache_.x = x;
    EvaluateInto(x, &cache_, first);
    return cache_;
  }

  // The evaluation at x into e (no cache).
  void EvaluateInto(const std::vector<double>& x, Evaluation* e, bool first = false) {
    const size_t n = x.size(), m = p_.constraints.size();
    if (intervals() > 1) {
      try {
        EvaluateShooting(x, e);
      } catch (const InputError&) {
        if (first) throw;
        last_failure_ = "bad input";
        ++r_->failed_evaluations;
      } catch (const std::exception& ex) {
        if (first) throw;
        last_failure_ = ex.what();
        ++r_->failed_evaluations;
      }
      return;
    }
    GradientRequest request;
    request.objectives = objectives_;
    request.wrt = wrt_;
    request.method = p_.method;
    GradientOptions go;
    go.model_path = p_.model_path;
    go.reload = [this, &x](const std::map<std::string, double>& overrides) { return ModelAt(x, overrides); };
    ++r_->gradient_evaluations;
    const double cpu = CpuSeconds();
    try {
      const mbs::Model model = ModelAt(x);
      const GradientResult g = ComputeGradient(model, p_.settings, request, go);
      r_->gradient_cpu_time += CpuSeconds() - cpu;
      r_->runs += g.runs;
      if (g.status != GradientResult::Status::kDone) {
        last_failure_ = g.failure_reason;
        ++r_->failed_evaluations;
        return;
      }
      auto index = [&g](const std::string& name) {
        return static_cast<int>(std::find(g.objectives.begin(), g.objectives.end(), name) - g.objectives.begin());
      };
      const int io = index(p_.objective);
      e->f = g.values[io];
      e->grad_f.resize(n);
      for (size_t k = 0; k < n; ++k) e->grad_f[k] = g.Gradient(io, static_cast<int>(k));
      e->g.resize(m);
      e->jac.resize(m * n);
      for (size_t i = 0; i < m; ++i) {
        const int ic = index(p_.constraints[i].objective);
        e->g[i] = g.values[ic];
        for (size_t k = 0; k < n; ++k) e->jac[i * n + k] = g.Gradient(ic, static_cast<int>(k));
      }
      CheckFinite(e);
    } catch (const InputError&) {
      r_->gradient_cpu_time += CpuSeconds() - cpu;
      if (first) throw;
      last_failure_ = "bad input";
      ++r_->failed_evaluations;
    } catch (const std::exception& ex) {
      r_->gradient_cpu_time += CpuSeconds() - cpu;
      if (first) throw;
      last_failure_ = ex.what();
      ++r_->failed_evaluations;
    }
  }

  // Second derivatives (`ipopt: {hessian_approximation: exact}`): the difference quotients
  // of every exact first derivative at x, (grad(x + h_j e_j) - grad(x)) / h_j for each
  // variable j, h_j = 1e-6 max(1, |x_j|) (backwards at an upper bound). Kept for the
  // point, so that Ipopt's new multipliers at the same x cost no run. Multiple shooting:
  // a node variable changes only its interval, which alone is rerun. False when a run
  // fails.
  bool DifferenceQuotients(const std::vector<double>& x) {
    if (hess_x_ == x && !hess_d_.empty()) return true;
    hess_d_.clear();
    hess_x_.clear();
    const size_t n = x.size();
    const int K = intervals();
    std::vector<Evaluation> base(K > 1 ? K : 1);
    if (K > 1) {
      for (int k = 0; k < K; ++k) {
        Clear(&base[k], n);
        if (!AddInterval(x, k, &base[k])) return false;
      }
    } else {
      base[0] = Evaluate(x);
      if (!base[0].ok) return false;
    }
    std::vector<Evaluation> d(n);
    for (size_t j = 0; j < n; ++j) {
      const OptimizationVariable& v = p_.variables[j];
      double h = 1e-6 * std::max(1.0, std::abs(x[j]));
      if (x[j] + h > v.upper) h = -h;
      std::vector<double> xp = x;
      xp[j] += h;
      h = xp[j] - x[j];  // the step as represented
      Clear(&d[j], n);
      auto add = [&](const Evaluation& e, const Evaluation& b) {
        d[j].f += (e.f - b.f) / h;
        for (size_t i = 0; i < n; ++i) d[j].grad_f[i] += (e.grad_f[i] - b.grad_f[i]) / h;
        for (size_t i = 0; i < e.jac.size(); ++i) d[j].jac[i] += (e.jac[i] - b.jac[i]) / h;
      };
      if (K > 1) {
        for (int k = 0; k < K; ++k) {
          if (v.node > 0 && v.node != k) continue;  // its run does not depend on x_j
          Evaluation e;
          Clear(&e, n);
          if (!AddInterval(xp, k, &e)) return false;
          add(e, base[k]);
        }
      } else {
        Evaluation e;
        EvaluateInto(xp, &e);
        if (!e.ok) return false;
        add(e, base[0]);
      }
    }
    ++r_->hessian_evaluations;
    hess_d_ = std::move(d);
    hess_x_ = x;
    return true;
  }

  void set_start(const std::vector<double>& x) { start_ = x; }
  void set_exact_hessian(bool on) { exact_hessian_ = on; }
  const std::string& last_failure() const { return last_failure_; }
  const std::vector<double>& final_x() const { return final_x_; }

  bool get_nlp_info(Ipopt::Index& n, Ipopt::Index& m, Ipopt::Index& nnz_jac_g, Ipopt::Index& nnz_h_lag,
                    IndexStyleEnum& index_style) override {
    n = static_cast<Ipopt::Index>(p_.variables.size());
    m = static_cast<Ipopt::Index>(p_.constraints.size() + continuity_rows());
    nnz_jac_g = n * m;
    nnz_h_lag = exact_hessian_ ? n * (n + 1) / 2 : 0;
    index_style = C_STYLE;
    return true;
  }

  bool get_bounds_info(Ipopt::Index n, Ipopt::Number* x_l, Ipopt::Number* x_u, Ipopt::Index m, Ipopt::Number* g_l,
                       Ipopt::Number* g_u) override {
    // Ipopt's infinity: beyond +-1e19 (nlp_lower/upper_bound_inf); 2e19 stays beyond it.
    auto clip = [](double v) { return std::isfinite(v) ? v : (v > 0 ? 2e19 : -2e19); };
    for (Ipopt::Index k = 0; k < n; ++k) {
      x_l[k] = clip(p_.variables[k].lower);
      x_u[k] = clip(p_.variables[k].upper);
    }
    for (Ipopt::Index i = 0; i < m; ++i) {
      const bool continuity = i >= static_cast<Ipopt::Index>(p_.constraints.size());
      g_l[i] = continuity ? 0.0 : clip(p_.constraints[i].lower);
      g_u[i] = continuity ? 0.0 : clip(p_.constraints[i].upper);
    }
    return true;
  }

  bool get_starting_point(Ipopt::Index n, bool init_x, Ipopt::Number* x, bool init_z, Ipopt::Number*, Ipopt::Number*,
                          Ipopt::Index, bool init_lambda, Ipopt::Number*) override {
    if (!init_x || init_z || init_lambda) return false;
    std::copy(start_.begin(), start_.end(), x);
    return static_cast<Ipopt::Index>(start_.size()) == n;
  }

  bool eval_f(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number& obj_value) override {
    const Evaluation& e = Evaluate(std::vector<double>(x, x + n));
    if (!e.ok) return false;
    obj_value = e.f;
    return true;
  }

  bool eval_grad_f(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number* grad_f) override {
    const Evaluation& e = Evaluate(std::vector<double>(x, x + n));
    if (!e.ok) return false;
    std::copy(e.grad_f.begin(), e.grad_f.end(), grad_f);
    return true;
  }

  bool eval_g(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Number* g) override {
    if (m == 0) return true;
    const Evaluation& e = Evaluate(std::vector<double>(x, x + n));
    if (!e.ok) return false;
    std::copy(e.g.begin(), e.g.end(), g);
    return true;
  }

  bool eval_jac_g(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Index, Ipopt::Index* iRow,
                  Ipopt::Index* jCol, Ipopt::Number* values) override {
    if (values == nullptr) {  // the dense structure, row by row
      for (Ipopt::Index i = 0; i < m; ++i)
        for (Ipopt::Index k = 0; k < n; ++k) {
          iRow[i * n + k] = i;
          jCol[i * n + k] = k;
        }
      return true;
    }
    if (m == 0) return true;
    const Evaluation& e = Evaluate(std::vector<double>(x, x + n));
    if (!e.ok) return false;
    std::copy(e.jac.begin(), e.jac.end(), values);
    return true;
  }

  // The Hessian of the Lagrangian, obj_factor f + sum lambda_i g_i, from the difference
  // quotients of the gradients (symmetrised), dense lower triangle row by row.
  bool eval_h(Ipopt::Index n, const Ipopt::Number* x, bool, Ipopt::Number obj_factor, Ipopt::Index m,
              const Ipopt::Number* lambda, bool, Ipopt::Index, Ipopt::Index* iRow, Ipopt::Index* jCol,
              Ipopt::Number* values) override {
    if (values == nullptr) {
      Ipopt::Index k = 0;
      for (Ipopt::Index i = 0; i < n; ++i)
        for (Ipopt::Index j = 0; j <= i; ++j, ++k) {
          iRow[k] = i;
          jCol[k] = j;
        }
      return true;
    }
    if (!DifferenceQuotients(std::vector<double>(x, x + n))) return false;
    // column j of the Lagrangian's Hessian: sigma d_j grad f + sum_i lambda_i d_j grad g_i
    auto entry = [&](Ipopt::Index i, Ipopt::Index j) {
      const Evaluation& d = hess_d_[j];
      double h = obj_factor * d.grad_f[i];
      for (Ipopt::Index r = 0; r < m; ++r) h += lambda[r] * d.jac[r * n + i];
      return h;
    };
    Ipopt::Index k = 0;
    for (Ipopt::Index i = 0; i < n; ++i)
      for (Ipopt::Index j = 0; j <= i; ++j, ++k) values[k] = 0.5 * (entry(i, j) + entry(j, i));
    return true;
  }

  bool intermediate_callback(Ipopt::AlgorithmMode, Ipopt::Index iter, Ipopt::Number obj_value, Ipopt::Number inf_pr,
                             Ipopt::Number inf_du, Ipopt::Number mu, Ipopt::Number, Ipopt::Number, Ipopt::Number,
                             Ipopt::Number alpha_pr, Ipopt::Index ls_trials, const Ipopt::IpoptData*,
                             Ipopt::IpoptCalculatedQuantities*) override {
    OptimizationIteration it;
    it.iteration = iter;
    it.objective = obj_value;
    it.constraint_violation = inf_pr;
    it.dual_infeasibility = inf_du;
    it.mu = mu;
    it.step = alpha_pr;
    it.line_search_trials = ls_trials;
    it.gradient_evaluations = r_->gradient_evaluations;
    r_->history.push_back(it);
    if (o_.iteration) o_.iteration(it);
    if (o_.stop && o_.stop(it)) return false;  // Ipopt: User_Requested_Stop
    return true;
  }

  void finalize_solution(Ipopt::SolverReturn, Ipopt::Index n, const Ipopt::Number* x, const Ipopt::Number*,
                         const Ipopt::Number*, Ipopt::Index, const Ipopt::Number*, const Ipopt::Number*, Ipopt::Number,
                         const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    if (x) final_x_.assign(x, x + n);
  }

 private:
  const OptimizationProblem& p_;
  const OptimizeOptions& o_;
  OptimizationResult* r_;
  std::vector<std::string> wrt_, objectives_;
  std::vector<int> global_;              // the variables that are not node variables
  std::vector<std::vector<int>> node_;   // node_[k - 1]: node variables of interval k, by state
  std::vector<std::string> end_names_;   // the states' end objectives
  std::vector<double> start_;
  bool has_parameters_ = false;
  Evaluation cache_;
  bool exact_hessian_ = false;      // ipopt: {hessian_approximation: exact}
  std::vector<double> hess_x_;      // the point of hess_d_
  std::vector<Evaluation> hess_d_;  // DifferenceQuotients: per variable, d/dx_j of every gradient
  std::string last_failure_;
  std::vector<double> final_x_;
};

const char* StatusName(Ipopt::ApplicationReturnStatus s) {
  switch (s) {
    case Ipopt::Solve_Succeeded: return "Solve_Succeeded";
    case Ipopt::Solved_To_Acceptable_Level: return "Solved_To_Acceptable_Level";
    case Ipopt::Infeasible_Problem_Detected: return "Infeasible_Problem_Detected";
    case Ipopt::Search_Direction_Becomes_Too_Small: return "Search_Direction_Becomes_Too_Small";
    case Ipopt::Diverging_Iterates: return "Diverging_Iterates";
    case Ipopt::User_Requested_Stop: return "User_Requested_Stop";
    case Ipopt::Feasible_Point_Found: return "Feasible_Point_Found";
    case Ipopt::Maximum_Iterations_Exceeded: return "Maximum_Iterations_Exceeded";
    case Ipopt::Restoration_Failed: return "Restoration_Failed";
    case Ipopt::Error_In_Step_Computation: return "Error_In_Step_Computation";
    case Ipopt::Maximum_CpuTime_Exceeded: return "Maximum_CpuTime_Exceeded";
    case Ipopt::Not_Enough_Degrees_Of_Freedom: return "Not_Enough_Degrees_Of_Freedom";
    case Ipopt::Invalid_Problem_Definition: return "Invalid_Problem_Definition";
    case Ipopt::Invalid_Option: return "Invalid_Option";
    case Ipopt::Invalid_Number_Detected: return "Invalid_Number_Detected";
    case Ipopt::Unrecoverable_Exception: return "Unrecoverable_Exception";
    case Ipopt::NonIpopt_Exception_Thrown: return "NonIpopt_Exception_Thrown";
    case Ipopt::Insufficient_Memory: return "Insufficient_Memory";
    case Ipopt::Internal_Error: return "Internal_Error";
  }
  return "Unknown";
}

// Adds the optimisation to the results file of the final run.
void WriteOptimization(const std::string& path, const OptimizationResult& r) {
  io::ResultsGroup g;
  g.path = "optimization";
  g.numbers = {{"objective", r.objective},
               {"constraint_violation", r.constraint_violation},
               {"iterations", static_cast<double>(r.iterations)},
               {"gradient_evaluations", static_cast<double>(r.gradient_evaluations)},
               {"shooting_intervals", static_cast<double>(r.shooting_intervals)},
               {"shooting_defect", r.shooting_defect}};
  g.strings = {{"objective_name", {r.objective_name}},
               {"constraint_names", r.constraint_names},
               {"ipopt_status", {r.ipopt_status}}};
  g.datasets = {{"variables", r.variables}, {"lower", r.lower}, {"upper", r.upper},
                {"constraint_values", r.constraint_values}};
  io::AddToResultsFile(path, {g}, {{"optimization_status", r.status}});
  io::AddStringsToResultsFile(path, "optimization/variable_names", r.variable_names);
  std::vector<double> rows;
  for (const auto& it : r.history) {
    rows.push_back(it.iteration);
    rows.push_back(it.objective);
    rows.push_back(it.constraint_violation);
    rows.push_back(it.dual_infeasibility);
    rows.push_back(static_cast<double>(it.gradient_evaluations));
  }
  io::AddTableToResultsFile(path, "optimization/history", 5, rows,
                            {"iteration", "objective", "constraint_violation", "dual_infeasibility",
                             "gradient_evaluations"});
}

}  // namespace

OptimizationResult Optimize(const OptimizationProblem& problem, const OptimizeOptions& options) {
  const auto wall_start = std::chrono::steady_clock::now();
  const double cpu_start = CpuSeconds();
  OptimizationResult r;
  r.objective_name = problem.objective;
  for (const auto& v : problem.variables) {
    r.variable_names.push_back(v.name);
    r.lower.push_back(v.lower);
    r.upper.push_back(v.upper);
  }
  for (const auto& c : problem.constraints) r.constraint_names.push_back(c.objective);

  Ipopt::SmartPtr<ShootingNlp> nlp = new ShootingNlp(problem, options, &r);
  // The starting point first: what ComputeGradient refuses (a variable the exact methods
  // cannot differentiate) is bad input, before anything is written.
  std::vector<double> x0;
  for (const auto& v : problem.variables) x0.push_back(std::clamp(v.start, v.lower, v.upper));
  r.shooting_intervals = problem.shooting.intervals;
  if (problem.shooting.intervals > 1) nlp->SweepStart(&x0);
  nlp->set_start(x0);
  for (const IpoptOption& o : problem.ipopt)
    if (o.name == "hessian_approximation") nlp->set_exact_hessian(o.text == "exact");
  nlp->Evaluate(x0, /*first=*/true);

  // Ipopt without its console output (mbdae prints its own lines; stdout may be JSON).
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = new Ipopt::IpoptApplication(false);
  app->Options()->SetStringValue("hessian_approximation", "limited-memory");
  app->Options()->SetIntegerValue("print_level", 0);
  app->Options()->SetStringValue("sb", "yes");
  for (const IpoptOption& o : problem.ipopt) {
    // Ipopt's own log, when asked for, on stderr (print_level sets the "console" journal).
    if (o.name == "print_level" && !Ipopt::IsValid(app->Jnlst()->GetJournal("console")))
      app->Jnlst()->AddFileJournal("console", "stderr", Ipopt::J_ITERSUMMARY);
    switch (o.kind) {
      case IpoptOption::Kind::kNumber: app->Options()->SetNumericValue(o.name, o.number); break;
      case IpoptOption::Kind::kInteger: app->Options()->SetIntegerValue(o.name, o.integer); break;
      case IpoptOption::Kind::kString: app->Options()->SetStringValue(o.name, o.text); break;
    }
  }
  Ipopt::ApplicationReturnStatus status = app->Initialize();
  if (status == Ipopt::Solve_Succeeded) status = app->OptimizeTNLP(Ipopt::SmartPtr<Ipopt::TNLP>(GetRawPtr(nlp)));
  r.ipopt_status = StatusName(status);
  r.solved = status == Ipopt::Solve_Succeeded || status == Ipopt::Solved_To_Acceptable_Level;
  r.status = r.solved ? "solved" : "failed";
  if (Ipopt::IsValid(app->Statistics())) r.iterations = app->Statistics()->IterationCount();
  else if (!r.history.empty()) r.iterations = r.history.back().iteration;
  r.variables = nlp->final_x();

  if (problem.shooting.intervals > 1) {
    nlp->Evaluate(r.variables);
    r.shooting_defect = nlp->Defect();
  }

  // The final run: the model at the final point, into the results file (multiple
  // shooting: one run over [0, t_end] with the time parameter at 0).
  try {
    std::map<std::string, double> time0;
    if (problem.shooting.intervals > 1) time0[problem.shooting.time] = 0.0;
    const mbs::Model model = nlp->ModelAt(r.variables, time0);
    Assembly asmb = Assemble(model);
    SimulationOptions so;
    so.model_path = problem.model_path;
    so.results_path = options.results_path;
    // HHT from the consistent start and with no looser Newton threshold than the default,
    // as the gradient runs: the final run is the run of the final point that the optimiser
    // saw (hht.start perturbed would move it by O(h^2), a loose threshold by about that).
    mbs::SimulationSettings settings = GradientRunSettings(problem.settings);
    settings.hht_start = "consistent";
    r.final_run = Simulate(model, asmb, settings, so);
    ++r.runs;
    if (r.final_run.status == SimulationSummary::Status::kDone) {
      std::map<std::string, double> values;
      for (const auto& o : r.final_run.objectives) values[o.name] = o.value;
      if (values.count(problem.objective)) r.objective = values[problem.objective];
      r.constraint_violation = 0;
      for (const auto& c : problem.constraints) {
        const double v = values.count(c.objective) ? values[c.objective] : std::numeric_limits<double>::quiet_NaN();
        r.constraint_values.push_back(v);
        const double d = std::max({c.lower - v, v - c.upper, 0.0});
        r.constraint_violation = std::isnan(v) ? v : std::max(r.constraint_violation, d);
      }
    } else {
      r.failure_reason = "the final run failed at t = " + Num(r.final_run.t_reached) + ": " + r.final_run.failure_reason;
    }
  } catch (const std::exception& e) {
    r.failure_reason = std::string("the final run failed: ") + e.what();
  }
  if (!r.failure_reason.empty()) {
    r.solved = false;
    r.status = "failed";
  }
  r.cpu_time = CpuSeconds() - cpu_start;
  r.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  if (!options.results_path.empty() && !r.final_run.results_path.empty()) WriteOptimization(options.results_path, r);
  return r;
}

std::string OptimizationResult::Report() const {
  std::ostringstream s;
  s << "status: " << status << " (Ipopt: " << ipopt_status << ")\n";
  if (!failure_reason.empty()) s << failure_reason << "\n";
  s << "objective " << objective_name << " = " << Num(objective) << "\n";
  if (!constraint_names.empty()) {
    s << "constraints (max violation " << Num(constraint_violation) << "):\n";
    for (size_t i = 0; i < constraint_names.size(); ++i)
      s << "  " << constraint_names[i] << " = " << Num(i < constraint_values.size() ? constraint_values[i] : NAN) << "\n";
  }
  if (shooting_intervals > 1)
    s << "multiple shooting: " << shooting_intervals << " intervals, largest continuity defect " << Num(shooting_defect)
      << " (the constraints above: one run over the whole time from the final variables)\n";
  s << "variables:\n";
  for (size_t k = 0; k < variable_names.size(); ++k) s << "  " << variable_names[k] << " = " << Num(variables[k]) << "\n";
  s << "iterations: " << iterations << ", gradient evaluations: " << gradient_evaluations;
  if (failed_evaluations) s << " (" << failed_evaluations << " failed)";
  if (hessian_evaluations) s << ", Hessians by differences of gradients: " << hessian_evaluations;
  s << ", runs: " << runs << "\n";
  char buf[160];
  std::snprintf(buf, sizeof buf, "CPU time %.3g s (gradient evaluations %.3g s, %.0f %%), wall time %.3g s\n", cpu_time,
                gradient_cpu_time, cpu_time > 0 ? 100 * gradient_cpu_time / cpu_time : 0.0, wall_time);
  s << buf;
  if (!final_run.results_path.empty()) s << "results: " << final_run.results_path << "\n";
  return s.str();
}

std::string OptimizationResult::Json() const {
  std::ostringstream s;
  s << "{\"status\": " << JsonString(status) << ", \"objective\": " << JsonNumber(objective)
    << ", \"iterations\": " << iterations << ", \"variables\": {";
  for (size_t k = 0; k < variable_names.size(); ++k)
    s << (k ? ", " : "") << JsonString(variable_names[k]) << ": " << JsonNumber(variables[k]);
  s << "}, \"constraint_violation\": " << JsonNumber(constraint_violation)
    << ", \"ipopt_status\": " << JsonString(ipopt_status) << ", \"shooting_intervals\": " << shooting_intervals
    << ", \"shooting_defect\": " << JsonNumber(shooting_defect) << ", \"objective_name\": " << JsonString(objective_name)
    << ", \"constraints\": {";
  for (size_t i = 0; i < constraint_names.size(); ++i)
    s << (i ? ", " : "") << JsonString(constraint_names[i]) << ": "
      << JsonNumber(i < constraint_values.size() ? constraint_values[i] : NAN);
  s << "}";
  if (!failure_reason.empty()) s << ", \"failure_reason\": " << JsonString(failure_reason);
  s << ", \"gradient_evaluations\": " << gradient_evaluations << ", \"failed_evaluations\": " << failed_evaluations
    << ", \"hessian_evaluations\": " << hessian_evaluations << ", \"runs\": " << runs << ", \"gradient_cpu_time\": " << JsonNumber(gradient_cpu_time)
    << ", \"cpu_time\": " << JsonNumber(cpu_time) << ", \"wall_time\": " << JsonNumber(wall_time) << "}";
  return s.str();
}

}  // namespace mbdae::driver
