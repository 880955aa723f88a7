// Model file reader, format 1 (YAML, via yaml-cpp). Every mapping's keys are checked
// against the allowed ones, every scalar may be an expression, and every mistake is a
// ModelError "FILE:LINE:COLUMN: ELEMENT: what is wrong" at the offending node.
#include "mbs/loader.h"

#include <yaml-cpp/yaml.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <initializer_list>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <unordered_map>
#include <utility>

#include "dae/format.h"
#include "dae/hht.h"
#include "mbs/freedyn.h"  // LoadAnyModel, for `extends:`
#include "mbs/geometry.h"
#include "mbs/mesh.h"
#include "mbs/kinematics.h"
#include "mbs/user_force.h"

namespace mbdae::mbs {

namespace {

std::string FormatError(const SourceLocation& where, const std::string& element,
                        const std::string& what) {
  std::ostringstream s;
  s << where.file << ":";
  if (where.line > 0) s << where.line << ":" << where.column << ":";
  s << " " << element << ": " << what;
  return s.str();
}

std::string Num(double v) { return std::isnan(v) ? "nan" : FormatG(v, 10); }

// A large count in three significant digits: 1e+12.
std::string Rounded(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

std::string Join(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "(none)" : out;
}

// Levenshtein distance, for "did you mean" hints.
int EditDistance(const std::string& a, const std::string& b) {
  std::vector<int> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    int diagonal = row[0];
    row[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

// "; did you mean 'x'?" if some candidate is close, else "".
std::string Suggest(const std::string& name, const std::vector<std::string>& candidates) {
  int best = 3;
  std::string hit;
  for (const std::string& c : candidates) {
    const int d = EditDistance(name, c);
    if (d < best) best = d, hit = c;
  }
  return hit.empty() ? "" : "; did you mean '" + hit + "'?";
}

bool IsIdentifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

// Words an expression gives a meaning of its own: not usable as parameter or measure names.
const std::set<std::string>& ReservedWords() {
  static const std::set<std::string> words = {
      "pi",   "t",    "spline", "sin",  "cos",  "tan",   "asin", "acos", "atan", "atan2",
      "sinh", "cosh", "tanh",   "exp",  "log",  "sqrt",  "abs",  "sign", "min",  "max",
      "pow",  "step"};
  return words;
}

using Keys = std::initializer_list<const char*>;

class Loader {
 public:
  Loader(std::string file, const LoadOptions& options) : file_(std::move(file)), options_(options) {}

  Model Load(const std::string& text) {
    YAML::Node root;
    try {
      root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
      throw ModelError(At(e.mark), "model", "YAML syntax error: " + e.msg);
    }
    model_.file = file_;
    if (!root.IsDefined() || root.IsNull()) {
      throw ModelError(SourceLocation{file_, 1, 1}, "model",
                       "the file is empty; a model is a mapping that starts with 'format: 1'");
    }
    if (!root.IsMap()) Fail(root, "model", "the top level must be a mapping (key: value), got " + Kind(root));

    // The format first: a file of another format gets that message, not unknown keys.
    const YAML::Node format = root["format"];
    if (!format) Fail(root, "model", "missing required key 'format' (this version reads 'format: 1')");
    const double version = LoadTimeNumber(format, "model", "format");
    if (version != 1) Fail(format, "model", "unsupported format " + Num(version) + "; this version reads format 1");

    CheckKeys(root, "model",
              {"format", "name", "gravity", "parameters", "splines", "ground", "bodies", "measures",
               "joints", "forces", "objectives", "simulation", "extends", "modify"});
    if (const YAML::Node base = root["extends"]) {
      Extend(base);
    } else if (root["modify"]) {
      Fail(KeyNode(root, "modify"), "model", "'modify' changes elements of the model named by 'extends', and there is none");
    }
    if (const YAML::Node name = root["name"]) model_.name = String(name, "model", "name");

    CollectMeasureNames(root["measures"]);
    LoadParameters(root["parameters"]);
    LoadSplines(root["splines"]);
    if (const YAML::Node gravity = root["gravity"]) {
      KeepExpressions keep(this, &model_.gravity_expressions);
      model_.gravity = Vector3(gravity, "model", "gravity");
    }
    LoadGround(root["ground"]);
    LoadBodies(root["bodies"]);
    Modify(root["modify"]);
    LoadMeasures(root["measures"]);
    LoadJoints(root["joints"]);
    ResolveReactionJoints();
    LoadForces(root["forces"]);
    LoadObjectives(root["objectives"]);
    LoadSimulation(root["simulation"]);
    LoadUserLibraries();  // last: no library code runs for a refused file
    model_.load_time_values = std::move(load_time_values_);
    return std::move(model_);
  }

 private:
  // While one exists, LoadTimeNumber appends every expression it evaluates to *out and
  // records its parameter uses as kept (their derivatives are exact; see LoadTimeValue).
  class KeepExpressions {
   public:
    KeepExpressions(const Loader* loader, std::vector<Expression>* out) : loader_(loader) {
      loader_->keep_ = out;
    }
    ~KeepExpressions() { loader_->keep_ = nullptr; }
    KeepExpressions(const KeepExpressions&) = delete;
    KeepExpressions& operator=(const KeepExpressions&) = delete;
   private:
    const Loader* loader_;
  };
  mutable std::vector<Expression>* keep_ = nullptr;
  mutable std::vector<LoadTimeValue> load_time_values_;
  mutable OrientationForm orientation_form_ = OrientationForm::kNone;
  // While true, load-time values are drawing only (`visual:`): not recorded as uses of
  // parameters (they do not affect the motion).
  mutable bool drawing_ = false;

  // ---- locations and failures ------------------------------------------------------

  SourceLocation At(const YAML::Mark& mark) const {
    SourceLocation where{file_, 0, 0};
    if (mark.line >= 0) {
      where.line = mark.line + 1;
      where.column = mark.column + 1;
    }
    return where;
  }
  SourceLocation At(const YAML::Node& node) const { return At(node.Mark()); }

  [[noreturn]] void Fail(const YAML::Node& node, const std::string& element, const std::string& what) const {
    throw ModelError(At(node), element, what);
  }

  static std::string Kind(const YAML::Node& node) {
    switch (node.Type()) {
      case YAML::NodeType::Null: return "nothing";
      case YAML::NodeType::Scalar: return "'" + node.Scalar() + "'";
      case YAML::NodeType::Sequence: return "a list";
      case YAML::NodeType::Map: return "a mapping";
      default: return "nothing";
    }
  }

  // ---- generic readers ---------------------------------------------------------------

  // `node` must be a mapping whose keys are all in `allowed`, each once.
  void CheckKeys(const YAML::Node& node, const std::string& element, Keys allowed,
                 const std::string& what = "") const {
    if (!node.IsMap()) {
      Fail(node, element, (what.empty() ? std::string("expected") : "'" + what + "' must be") +
                              " a mapping (key: value), got " + Kind(node));
    }
    std::vector<std::string> names;
    for (const char* k : allowed) names.emplace_back(k);
    std::set<std::string> seen;
    for (auto it = node.begin(); it != node.end(); ++it) {
      const YAML::Node key = it->first;
      if (!key.IsScalar()) Fail(key, element, "a key must be a plain name, got " + Kind(key));
      const std::string& k = key.Scalar();
      if (std::find(names.begin(), names.end(), k) == names.end()) {
        Fail(key, element, "unknown key '" + k + "'" + Suggest(k, names) + " (allowed keys: " + Join(names) + ")");
      }
      if (!seen.insert(k).second) Fail(key, element, "key '" + k + "' is given twice");
    }
  }

  // The key node of `key` in `map` (for messages that point at the key).
  static YAML::Node KeyNode(const YAML::Node& map, const std::string& key) {
    for (auto it = map.begin(); it != map.end(); ++it) {
      if (it->first.IsScalar() && it->first.Scalar() == key) return it->first;
    }
    return map;
  }

  YAML::Node Required(const YAML::Node& map, const std::string& element, const char* key) const {
    const YAML::Node value = map[key];
    if (!value) Fail(map, element, std::string("missing required key '") + key + "'");
    return value;
  }

  std::string String(const YAML::Node& node, const std::string& element, const std::string& key) const {
    if (!node.IsScalar()) Fail(node, element, "'" + key + "' must be a name (text), got " + Kind(node));
    return node.Scalar();
  }

  bool Bool(const YAML::Node& node, const std::string& element, const std::string& key) const {
    if (node.IsScalar()) {
      const std::string& s = node.Scalar();
      if (s == "true" || s == "True" || s == "TRUE") return true;
      if (s == "false" || s == "False" || s == "FALSE") return false;
    }
    Fail(node, element, "'" + key + "' must be true or false, got " + Kind(node));
  }

  // The scalar's text as an Expression over the parameters (measures reserved).
  Expression Parse(const YAML::Node& node, const std::string& element, const std::string& key) const {
    if (!node.IsScalar()) {
      Fail(node, element, "'" + key + "' must be a number or an expression, got " + Kind(node));
    }
    const std::string& text = node.Scalar();
    try {
      return Expression::Parse(text, symbols_);
    } catch (const ExpressionError& e) {
      Fail(node, element, "'" + key + "': in expression '" + text + "': " + e.what());
    }
  }

  // A value evaluated during the run (force values): over the parameters, t, every
  // measure (Model::measures index) and spline(NAME, x) (Model::splines index). A measure
  // at acceleration level is rejected, naming the measure.
  Expression ParseRunTime(const YAML::Node& node, const std::string& element, const std::string& key) const {
    if (!node.IsScalar()) {
      Fail(node, element, "'" + key + "' must be a number or an expression, got " + Kind(node));
    }
    SymbolTable symbols;
    symbols.parameters = symbols_.parameters;
    for (const Measure& m : model_.measures) symbols.measures.push_back(m.name);
    for (const SplineDef& sp : model_.splines) symbols.splines.push_back(sp.name);
    symbols.allow_time = true;
    const std::string& text = node.Scalar();
    Expression e;
    try {
      e = Expression::Parse(text, symbols);
    } catch (const ExpressionError& err) {
      Fail(node, element, "'" + key + "': in expression '" + text + "': " + err.what());
    }
    for (int m : e.measures_used()) {
      if (model_.measures[m].quantity == Quantity::kAcceleration) {
        Fail(node, element, "'" + key + "': measure '" + model_.measures[m].name +
                                "' is an acceleration; a force may use position and velocity measures only");
      }
      if (model_.measures[m].type == MeasureType::kReaction) {
        Fail(node, element, "'" + key + "': measure '" + model_.measures[m].name +
                                "' is a joint reaction; a force may not use reactions (that would make the "
                                "system implicit in the multipliers, which is not supported)");
      }
    }
    return e;
  }

  // A force value (ParseRunTime). One that uses no measure is evaluated at t = 0 here and
  // refused where it is written if it is not finite (`what` names it: "'value' entry 1");
  // one over measures is checked at the initial state when the system is built.
  Expression ForceValue(const YAML::Node& node, const std::string& element, const std::string& what) const {
    const std::string key = what.substr(1, what.find('\'', 1) - 1);
    Expression e = ParseRunTime(node, element, key);
    if (e.depends_on_state()) return e;
    std::vector<const Spline*> splines;
    for (const SplineDef& sp : model_.splines) splines.push_back(&sp.spline);
    ExpressionInputs in;
    in.t = 0;
    in.parameters = values_.data();
    in.splines = splines.empty() ? nullptr : splines.data();
    const double x = e.Evaluate(in);
    if (!std::isfinite(x)) {
      Fail(node, element, what + " ('" + node.Scalar() + "') is " + Num(x) +
                              " at the initial state of the model file (t = 0); a force value must be finite");
    }
    return e;
  }

  // A measure of a motion or gear joint, by name: position level (a rotational angle if
  // `rotational`).
  int PositionMeasure(const YAML::Node& node, const std::string& element, const std::string& key,
                      bool rotational) const {
    const std::string name = String(node, element, key);
    const int m = model_.find_measure(name);
    if (m < 0) {
      std::vector<std::string> names;
      for (const Measure& me : model_.measures) names.push_back(me.name);
      Fail(node, element, "'" + key + "': unknown measure '" + name + "'" + Suggest(name, names));
    }
    const Measure& me = model_.measures[m];
    if (me.type == MeasureType::kReaction) {
      Fail(node, element, "'" + key + "': measure '" + name + "' is a joint reaction; a " +
                              (rotational ? "gear" : "motion") +
                              " constrains position-level kinematic measures only (a reaction would make "
                              "the system implicit in the multipliers, which is not supported)");
    }
    if (rotational && me.type != MeasureType::kRotational) {
      Fail(node, element, "'" + key + "': measure '" + name + "' is translational; a gear joins two rotational angle measures");
    }
    if (me.quantity != Quantity::kPosition) {
      Fail(node, element, "'" + key + "': measure '" + name + "' is a " +
                              (me.quantity == Quantity::kVelocity ? "velocity" : "acceleration") +
                              "; a " + (rotational ? "gear" : "motion") + " constrains position-level measures only");
    }
    return m;
  }

  // The value of a motion joint: over t, the parameters and spline(NAME, t); measures
  // are reserved (a motion prescribes a function of time).
  Expression ParseMotionValue(const YAML::Node& node, const std::string& element, const std::string& key) const {
    if (!node.IsScalar()) {
      Fail(node, element, "'" + key + "' must be a number or an expression, got " + Kind(node));
    }
    SymbolTable symbols;
    symbols.parameters = symbols_.parameters;
    symbols.reserved = symbols_.reserved;
    for (const SplineDef& sp : model_.splines) symbols.splines.push_back(sp.name);
    symbols.allow_time = true;
    const std::string& text = node.Scalar();
    try {
      return Expression::Parse(text, symbols);
    } catch (const ExpressionError& err) {
      Fail(node, element, "'" + key + "': in expression '" + text + "': " + err.what());
    }
  }

  double LoadTimeNumber(const YAML::Node& node, const std::string& element, const std::string& key) const {
    const Expression e = Parse(node, element, key);
    const double value = e.Evaluate(values_.data());
    // Parameter derivatives: every load-time use of a parameter is recorded; within a
    // KeepExpressions scope the expression is also kept where the value is used.
    if (keep_) keep_->push_back(e);
    if (!drawing_ && !e.parameters_used().empty()) {
      load_time_values_.push_back(LoadTimeValue{e, element, key, keep_ != nullptr, At(node)});
    }
    if (!std::isfinite(value)) {
      Fail(node, element, "'" + key + "' evaluates to " + Num(value) + " ('" + node.Scalar() + "')");
    }
    return value;
  }

  std::vector<double> Numbers(const YAML::Node& node, const std::string& element, const std::string& key,
                              std::initializer_list<size_t> lengths) const {
    std::string expected;
    for (size_t n : lengths) expected += (expected.empty() ? "" : " or ") + std::to_string(n);
    if (!node.IsSequence()) {
      Fail(node, element, "'" + key + "' must be a list of " + expected + " numbers, got " + Kind(node));
    }
    if (std::find(lengths.begin(), lengths.end(), node.size()) == lengths.end()) {
      Fail(node, element, "'" + key + "' must have " + expected + " entries, got " + std::to_string(node.size()));
    }
    std::vector<double> out;
    for (size_t k = 0; k < node.size(); ++k) out.push_back(LoadTimeNumber(node[k], element, key));
    return out;
  }

  Vec3 Vector3(const YAML::Node& node, const std::string& element, const std::string& key) const {
    const std::vector<double> v = Numbers(node, element, key, {3});
    return Vec3(v[0], v[1], v[2]);
  }

  template <typename E>
  E Enum(const YAML::Node& node, const std::string& element, const std::string& key,
         std::initializer_list<std::pair<const char*, E>> choices) const {
    const std::string s = String(node, element, key);
    std::vector<std::string> names;
    for (const auto& [name, value] : choices) {
      if (s == name) return value;
      names.emplace_back(name);
    }
    Fail(node, element, "unknown " + key + " '" + s + "'" + Suggest(s, names) + " (allowed: " + Join(names) + ")");
  }

  // One of `names` (a choice option whose names another layer owns, e.g. dae::HhtFormNames).
  std::string Choice(const YAML::Node& node, const std::string& element, const std::string& key,
                     const std::vector<std::string>& names) const {
    const std::string s = String(node, element, key);
    if (std::find(names.begin(), names.end(), s) != names.end()) return s;
    Fail(node, element, "unknown " + key + " '" + s + "'" + Suggest(s, names) + " (allowed: " + Join(names) + ")");
  }

  // Orientation in one of the three forms: Euler parameters [e0, e1, e2, e3] (normalised
  // when within 1e-6 of unit norm), {axis, angle}, {matrix} (orthonormal, det +1).
  Quat Orientation(const YAML::Node& node, const std::string& element, const std::string& key) const {
    if (node.IsSequence()) {
      orientation_form_ = OrientationForm::kEulerParameters;
      const std::vector<double> v = Numbers(node, element, key, {4});
      Quat e(v[0], v[1], v[2], v[3]);
      const double n = e.norm();
      if (!(std::abs(n - 1.0) <= 1e-6)) {
        Fail(node, element, "'" + key + "': Euler parameters must have unit norm (within 1e-6), got norm " + Num(n));
      }
      return e / n;
    }
    if (node.IsMap()) {
      if (node["matrix"]) {
        CheckKeys(node, element, {"matrix"}, key);
        orientation_form_ = OrientationForm::kMatrix;
        std::vector<Expression>* const keep = keep_;  // a matrix is not kept: refused
        keep_ = nullptr;
        const YAML::Node rows = node["matrix"];
        if (!rows.IsSequence() || rows.size() != 3) {
          Fail(rows, element, "'" + key + "': 'matrix' must be a list of 3 rows of 3 numbers");
        }
        Mat3 A;
        for (int r = 0; r < 3; ++r) {
          const std::vector<double> row = Numbers(rows[r], element, key + " matrix row", {3});
          for (int c = 0; c < 3; ++c) A(r, c) = row[c];
        }
        const double orthogonality = (A.transpose() * A - Mat3::Identity()).cwiseAbs().maxCoeff();
        if (!(orthogonality <= 1e-9)) {
          Fail(rows, element, "'" + key + "': the matrix is not orthonormal (|A^T A - I| = " + Num(orthogonality) +
                                  ", tolerance 1e-9)");
        }
        const double det = A.determinant();
        if (!(std::abs(det - 1.0) <= 1e-9)) {
          Fail(rows, element, "'" + key + "': the matrix is not a rotation (determinant " + Num(det) + ", must be +1)");
        }
        keep_ = keep;
        return QuaternionFromMatrix(A);
      }
      CheckKeys(node, element, {"axis", "angle"}, key);
      orientation_form_ = OrientationForm::kAxisAngle;
      const Vec3 axis = Vector3(Required(node, element, "axis"), element, key + " axis");
      const double angle = LoadTimeNumber(Required(node, element, "angle"), element, key + " angle");
      if (!(axis.cwiseAbs().maxCoeff() > 0)) {
        Fail(node["axis"], element, "'" + key + "': the rotation axis must not be zero");
      }
      return QuaternionFromAxisAngle(axis, angle);
    }
    Fail(node, element,
         "'" + key + "' must be Euler parameters [e0, e1, e2, e3], {axis: [x, y, z], angle: a} or "
         "{matrix: [[...], [...], [...]]}, got " + Kind(node));
  }

  // ---- names ----------------------------------------------------------------------------

  void CollectMeasureNames(const YAML::Node& measures) {
    if (!measures || !measures.IsSequence()) return;
    for (const YAML::Node& m : measures) {
      if (m.IsMap() && m["name"] && m["name"].IsScalar()) symbols_.reserved.push_back(m["name"].Scalar());
    }
  }

  // The index of the first item named `name` (-1: none), as Model::find_marker: the
  // vectors only grow while loading, so the items appended since the last call are
  // added to the index; an entry changed in place is caught and the index rebuilt.
  template <typename T>
  static int FindIndexed(const std::vector<T>& items, std::unordered_map<std::string, int>& index,
                         size_t& indexed, const std::string& name) {
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (indexed > items.size()) {
        index.clear();
        indexed = 0;
      }
      for (; indexed < items.size(); ++indexed) index.emplace(items[indexed].name, static_cast<int>(indexed));
      const auto it = index.find(name);
      if (it == index.end()) return -1;
      if (items[it->second].name == name) return it->second;
      index.clear();
      indexed = 0;
    }
    return -1;
  }
  int FindMarker(const std::string& name) const {
    return FindIndexed(model_.markers, marker_index_, markers_indexed_, name);
  }
  int FindBody(const std::string& name) const {
    return FindIndexed(model_.bodies, body_index_, bodies_indexed_, name);
  }
  int FindJoint(const std::string& name) const {
    return FindIndexed(model_.joints, joint_index_, joints_indexed_, name);
  }
  int FindForce(const std::string& name) const {
    return FindIndexed(model_.forces, force_index_, forces_indexed_, name);
  }

  // Marker by full name "BODY.MARKER" / "ground.MARKER".
  int Marker(const YAML::Node& node, const std::string& element, const std::string& key) const {
    const std::string name = String(node, element, key);
    const int index = FindMarker(name);
    if (index >= 0) return index;
    const size_t dot = name.find('.');
    if (dot == std::string::npos) {
      Fail(node, element, "'" + key + "': marker '" + name + "' must be written BODY.MARKER (e.g. ground.O, " +
                              (model_.bodies.empty() ? std::string("crank") : model_.bodies[0].name) + ".cm)");
    }
    const std::string body = name.substr(0, dot);
    std::vector<std::string> bodies{"ground"};
    for (const Body& b : model_.bodies) bodies.push_back(b.name);
    const int b = body == "ground" ? -1 : FindBody(body);
    if (body != "ground" && b < 0) {
      Fail(node, element, "'" + key + "': unknown body '" + body + "' in marker '" + name + "'" + Suggest(body, bodies) +
                              " (bodies: " + Join(bodies) + ")");
    }
    std::vector<std::string> markers, full_names;
    for (const mbs::Marker& m : model_.markers) {
      if (m.body != b) continue;
      full_names.push_back(m.name);
      markers.push_back(m.name.substr(m.name.find('.') + 1));
    }
    Fail(node, element, "'" + key + "': unknown marker '" + name + "'" + Suggest(name, full_names) + " (markers of " +
                            body + ": " + Join(markers) + ")");
  }

  // ---- parameters -------------------------------------------------------------------

  void LoadParameters(const YAML::Node& node) {
    std::vector<YAML::Node> value_nodes;
    std::vector<std::string> names;
    if (node) {
      if (!node.IsMap()) Fail(node, "model", "'parameters' must be a mapping {name: value}, got " + Kind(node));
      std::set<std::string> seen;
      for (auto it = node.begin(); it != node.end(); ++it) {
        const YAML::Node key = it->first;
        if (!key.IsScalar()) Fail(key, "model", "a parameter name must be a plain name, got " + Kind(key));
        const std::string& name = key.Scalar();
        const std::string element = "parameter '" + name + "'";
        if (!IsIdentifier(name)) {
          Fail(key, element, "a parameter name must be letters, digits and '_', not starting with a digit");
        }
        if (ReservedWords().count(name)) Fail(key, element, "'" + name + "' is reserved in expressions");
        if (!seen.insert(name).second) Fail(key, element, "duplicate parameter name");
        for (const std::string& m : symbols_.reserved) {
          if (m == name) Fail(key, element, "a measure has the same name; names in expressions must be unique");
        }
        Parameter p;
        p.name = name;
        p.where = At(key);
        model_.parameters.push_back(p);
        names.push_back(name);
        value_nodes.push_back(it->second);
      }
    }
    for (const auto& [name, value] : options_.parameter_overrides) {
      if (std::find(names.begin(), names.end(), name) == names.end()) {
        throw ModelError(node ? At(node) : SourceLocation{file_, 0, 0}, "parameter '" + name + "'",
                         "cannot set '" + name + "=" + Num(value) + "': the model has no such parameter" +
                             Suggest(name, names) + " (parameters: " + Join(names) + ")");
      }
    }

    // Every parameter may use any other one: parse all, then evaluate in dependency
    // order (depth-first), reporting a cycle by its path.
    symbols_.parameters = names;
    const size_t n = names.size();
    std::vector<Expression> expressions(n);
    for (size_t k = 0; k < n; ++k) {
      const std::string element = "parameter '" + names[k] + "'";
      expressions[k] = Parse(value_nodes[k], element, names[k]);
      const std::string& text = value_nodes[k].Scalar();
      char* end = nullptr;
      std::strtod(text.c_str(), &end);
      if (end == text.c_str() || *end != '\0') model_.parameters[k].expression = text;
    }
    values_.assign(n, 0.0);
    std::vector<int> state(n, 0);  // 0 not yet, 1 being evaluated, 2 done
    std::vector<int> path;
    std::function<void(int)> visit = [&](int k) {
      if (state[k] == 2) return;
      if (state[k] == 1) {
        std::string cycle;
        auto from = std::find(path.begin(), path.end(), k);
        for (auto it = from; it != path.end(); ++it) cycle += names[*it] + " -> ";
        cycle += names[k];
        Fail(value_nodes[k], "parameter '" + names[k] + "'", "parameters depend on each other in a cycle: " + cycle);
      }
      const auto override_it = options_.parameter_overrides.find(names[k]);
      if (override_it != options_.parameter_overrides.end()) {
        values_[k] = override_it->second;
      } else {
        state[k] = 1;
        path.push_back(k);
        for (int dep : expressions[k].parameters_used()) visit(dep);
        path.pop_back();
        values_[k] = expressions[k].Evaluate(values_.data());
        if (!std::isfinite(values_[k])) {
          Fail(value_nodes[k], "parameter '" + names[k] + "'",
               "evaluates to " + Num(values_[k]) + " ('" + value_nodes[k].Scalar() + "')");
        }
      }
      state[k] = 2;
    };
    for (size_t k = 0; k < n; ++k) visit(static_cast<int>(k));
    for (size_t k = 0; k < n; ++k) {
      model_.parameters[k].value = values_[k];
      model_.parameters[k].formula = expressions[k];
      model_.parameters[k].overridden = options_.parameter_overrides.count(names[k]) > 0;
    }
  }

  // ---- splines --------------------------------------------------------------------------

  // A non-negative integer (column, line count).
  int Count(const YAML::Node& node, const std::string& element, const std::string& key) const {
    const double v = LoadTimeNumber(node, element, key);
    if (!(v >= 0 && v == std::floor(v) && v <= 1e6)) {
      Fail(node, element, "'" + key + "' must be a whole number >= 0, got " + Num(v));
    }
    return static_cast<int>(v);
  }

  // splines: {NAME: {x: [...], y: [...], interpolation}, NAME: {file, x_column, y_column,
  // header_lines, interpolation}}. Default interpolation akima (as FreeDyn), columns 0
  // and 1, no header lines. Relative data files are relative to the model file.
  void LoadSplines(const YAML::Node& node) {
    if (!node) return;
    if (!node.IsMap()) Fail(node, "model", "'splines' must be a mapping {NAME: {x: [...], y: [...]}}, got " + Kind(node));
    for (auto it = node.begin(); it != node.end(); ++it) {
      const YAML::Node key = it->first, n = it->second;
      if (!key.IsScalar()) Fail(key, "model", "a spline name must be a plain name, got " + Kind(key));
      SplineDef def;
      def.name = key.Scalar();
      def.where = At(key);
      const std::string element = "spline '" + def.name + "'";
      if (!IsIdentifier(def.name)) {
        Fail(key, element, "a spline name must be letters, digits and '_', not starting with a digit "
                           "(it is used in expressions as spline(NAME, x))");
      }
      if (model_.find_spline(def.name) >= 0) Fail(key, element, "duplicate spline name");
      if (!n.IsMap()) {
        Fail(n, element, "a spline must be a mapping {x: [...], y: [...]} or {file: NAME.csv}, got " + Kind(n));
      }
      Interpolation kind = Interpolation::kAkima;
      if (const YAML::Node i = n["interpolation"]) {
        kind = Enum<Interpolation>(i, element, "interpolation",
                                   {{"linear", Interpolation::kLinear}, {"cubic", Interpolation::kCubic},
                                    {"akima", Interpolation::kAkima}});
      }
      std::vector<double> x, y;
      if (n["file"]) {
        if (n["x"] || n["y"]) {
          Fail(KeyNode(n, n["x"] ? "x" : "y"), element, "give either 'file' or the points 'x' and 'y', not both");
        }
        CheckKeys(n, element, {"file", "x_column", "y_column", "header_lines", "interpolation"});
        const YAML::Node f = n["file"];
        const std::string name = String(f, element, "file");
        if (name.empty()) Fail(f, element, "'file' must name a data file");
        std::filesystem::path path(name);
        if (path.is_relative()) path = std::filesystem::path(file_).parent_path() / path;
        def.file = path.lexically_normal().string();
        const int x_column = n["x_column"] ? Count(n["x_column"], element, "x_column") : 0;
        const int y_column = n["y_column"] ? Count(n["y_column"], element, "y_column") : 1;
        const int header_lines = n["header_lines"] ? Count(n["header_lines"], element, "header_lines") : 0;
        if (x_column == y_column) {
          Fail(n["y_column"] ? n["y_column"] : n["x_column"], element,
               "x_column and y_column are both " + std::to_string(x_column) + "; they must differ");
        }
        std::error_code ignored;
        if (!std::filesystem::exists(path, ignored)) {
          Fail(f, element, "data file '" + def.file + "' not found ('" + name + "' is relative to the model file)");
        }
        if (std::filesystem::is_directory(path, ignored)) Fail(f, element, "data file '" + def.file + "' is a directory");
        std::vector<int> lines;
        try {
          ReadSplineFile(def.file, header_lines, x_column, y_column, &x, &y, &lines);
        } catch (const std::exception& e) {
          Fail(f, element, std::string("in data file: ") + e.what());
        }
        if (x.size() < 2) {
          Fail(f, element, "data file '" + def.file + "' has " + std::to_string(x.size()) + " point" +
                               (x.size() == 1 ? "" : "s") + " after " + std::to_string(header_lines) +
                               " header line" + (header_lines == 1 ? "" : "s") + "; a spline needs at least 2");
        }
        for (size_t k = 1; k < x.size(); ++k) {
          if (!(x[k] > x[k - 1])) {
            Fail(f, element, "in data file: " + def.file + ":" + std::to_string(lines[k]) + ": x = " + Num(x[k]) +
                                 " is not greater than x = " + Num(x[k - 1]) + " on line " +
                                 std::to_string(lines[k - 1]) + "; x must be strictly increasing");
          }
        }
      } else {
        CheckKeys(n, element, {"x", "y", "interpolation"});
        if (!n["x"] && !n["y"]) {
          Fail(n, element, "missing the points: give 'x' and 'y' (lists of numbers) or 'file'");
        }
        const YAML::Node xs = Required(n, element, "x"), ys = Required(n, element, "y");
        auto list = [&](const YAML::Node& v, const char* key, std::vector<Expression>* expressions) {
          if (!v.IsSequence()) Fail(v, element, std::string("'") + key + "' must be a list of numbers, got " + Kind(v));
          std::vector<double> out;
          for (size_t k = 0; k < v.size(); ++k) {
            const std::string entry = std::string(key) + "[" + std::to_string(k) + "]";
            out.push_back(LoadTimeNumber(v[k], element, entry));
            expressions->push_back(Parse(v[k], element, entry));
          }
          return out;
        };
        x = list(xs, "x", &def.x_expressions);
        {
          std::vector<Expression> kept;  // y is kept in def.y_expressions (by `list`)
          KeepExpressions keep(this, &kept);
          y = list(ys, "y", &def.y_expressions);
        }
        if (x.size() != y.size()) {
          Fail(ys, element, "'x' has " + std::to_string(x.size()) + " entries but 'y' has " + std::to_string(y.size()) +
                                "; they must have the same number");
        }
        if (x.size() < 2) {
          Fail(xs, element, "a spline needs at least 2 points, got " + std::to_string(x.size()));
        }
        for (size_t k = 1; k < x.size(); ++k) {
          if (!(x[k] > x[k - 1])) {
            Fail(xs[k], element, "'x' must be strictly increasing: x[" + std::to_string(k) + "] = " + Num(x[k]) +
                                     " is not greater than x[" + std::to_string(k - 1) + "] = " + Num(x[k - 1]));
          }
        }
      }
      try {
        def.spline = Spline(std::move(x), std::move(y), kind);
      } catch (const std::invalid_argument& e) {  // the checks above should have caught it
        Fail(n, element, e.what());
      }
      model_.splines.push_back(std::move(def));
    }
  }

  // ---- markers, ground, bodies ---------------------------------------------------

  mbs::Marker LoadMarker(const YAML::Node& node, const std::string& element, int body,
                         const std::string& full_name) const {
    CheckKeys(node, element, {"position", "orientation"});
    mbs::Marker m;
    m.name = full_name;
    m.body = body;
    m.where = At(node);
    if (const YAML::Node p = node["position"]) m.position = Vector3(p, element, "position");
    if (const YAML::Node o = node["orientation"]) m.orientation = RotationMatrix(Orientation(o, element, "orientation"));
    return m;
  }

  // The implicit markers (ground.O, BODY.cm) may be listed, but only where they are.
  void CheckImplicit(const YAML::Node& node, const mbs::Marker& m, const std::string& element,
                     const std::string& what) const {
    if (m.position.norm() != 0 || (m.orientation - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-12) {
      Fail(node, element, "marker '" + m.name + "' is " + what + " and cannot be moved or rotated");
    }
  }

  void LoadGround(const YAML::Node& node) {
    mbs::Marker origin;
    origin.name = "ground.O";
    origin.where = SourceLocation{file_, 0, 0};
    if (!extended_) model_.markers.push_back(origin);  // an extended model has it
    if (!node) return;
    CheckKeys(node, "ground", {"markers", "visual"}, "ground");
    if (const YAML::Node v = node["visual"]) model_.ground_visuals = Visuals(v, "ground");
    const YAML::Node markers = node["markers"];
    if (!markers) return;
    if (!markers.IsMap()) Fail(markers, "ground", "'markers' must be a mapping {NAME: {position, orientation}}");
    for (auto it = markers.begin(); it != markers.end(); ++it) {
      const std::string name = String(it->first, "ground", "marker name");
      const std::string element = "ground marker '" + name + "'";
      CheckMarkerName(it->first, element, name);
      const mbs::Marker m = LoadMarker(it->second, element, -1, "ground." + name);
      if (name == "O") {
        CheckImplicit(it->second, m, element, "the world origin with world axes");
        continue;
      }
      if (FindMarker(m.name) >= 0) Fail(it->first, element, "duplicate marker name");
      model_.markers.push_back(m);
    }
  }

  // Names of bodies, markers, joints and forces: letters, digits, '_' and '-' (they
  // appear in marker names BODY.MARKER and in the results file's paths).
  void CheckName(const YAML::Node& node, const std::string& element, const std::string& name,
                 const char* what) const {
    bool ok = !name.empty();
    for (char c : name) ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-');
    if (!ok) Fail(node, element, std::string("a ") + what + " name may only use letters, digits, '_' and '-'");
  }
  void CheckMarkerName(const YAML::Node& node, const std::string& element, const std::string& name) const {
    CheckName(node, element, name, "marker");
  }

  void LoadBodies(const YAML::Node& node) {
    if (!node) return;
    if (!node.IsSequence()) Fail(node, "model", "'bodies' must be a list, got " + Kind(node));
    for (size_t k = 0; k < node.size(); ++k) LoadBody(node[k], static_cast<int>(k));
  }

  void LoadBody(const YAML::Node& node, int index) {
    std::string element = "body #" + std::to_string(index + 1);
    if (!node.IsMap()) Fail(node, element, "a body must be a mapping, got " + Kind(node));
    if (const YAML::Node name = node["name"]) element = "body '" + String(name, element, "name") + "'";
    CheckKeys(node, element,
              {"name", "mass", "inertia", "geometry", "position", "orientation", "velocity", "angular_velocity",
               "markers", "visual"});
    Body body;
    body.name = String(Required(node, element, "name"), element, "name");
    body.where = At(node);
    CheckName(node["name"], element, body.name, "body");
    if (body.name == "ground") Fail(node["name"], element, "'ground' is reserved for the fixed frame");
    if (FindBody(body.name) >= 0) Fail(node["name"], element, "duplicate body name");

    // Mass properties: explicit values win; a geometry with a density gives the rest.
    std::optional<MassProperties> from_geometry;
    if (const YAML::Node g = node["geometry"]) from_geometry = Geometry(g, element, &body.visuals);
    if (const YAML::Node v = node["visual"]) body.visuals = Visuals(v, element);
    if (from_geometry) {
      body.mass = from_geometry->mass;
      body.inertia = from_geometry->inertia;
    }
    if (const YAML::Node m = node["mass"]) {
      KeepExpressions keep(this, &body.expressions.mass);
      body.mass = LoadTimeNumber(m, element, "mass");
      if (body.mass < 0) Fail(m, element, "mass must be >= 0, got " + Num(body.mass));
    }
    if (const YAML::Node in = node["inertia"]) {
      std::vector<double> v;
      {
        KeepExpressions keep(this, &body.expressions.inertia);
        v = Numbers(in, element, "inertia", {3, 6});
      }
      body.inertia = Mat3::Zero();
      body.inertia.diagonal() << v[0], v[1], v[2];
      if (v.size() == 6) {  // tensor entries [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]
        body.inertia(0, 1) = body.inertia(1, 0) = v[3];
        body.inertia(0, 2) = body.inertia(2, 0) = v[4];
        body.inertia(1, 2) = body.inertia(2, 1) = v[5];
      }
      std::string why;
      if (!IsPhysicalInertia(body.inertia, &why)) Fail(in, element, why);
    }
    if (const YAML::Node p = node["position"]) {
      KeepExpressions keep(this, &body.expressions.position);
      body.position = Vector3(p, element, "position");
    }
    if (const YAML::Node o = node["orientation"]) {
      KeepExpressions keep(this, &body.expressions.orientation);
      body.orientation = Orientation(o, element, "orientation");
      body.expressions.orientation_form = orientation_form_;
      if (orientation_form_ == OrientationForm::kMatrix) body.expressions.orientation.clear();
    }
    if (const YAML::Node v = node["velocity"]) {
      KeepExpressions keep(this, &body.expressions.velocity);
      body.velocity = Vector3(v, element, "velocity");
    }
    if (const YAML::Node w = node["angular_velocity"]) {
      KeepExpressions keep(this, &body.expressions.angular_velocity);
      body.angular_velocity = Vector3(w, element, "angular_velocity");
    }

    const int b = static_cast<int>(model_.bodies.size());
    mbs::Marker cm;
    cm.name = body.name + ".cm";
    cm.body = b;
    cm.where = body.where;
    body.cm_marker = static_cast<int>(model_.markers.size());
    model_.markers.push_back(cm);
    model_.bodies.push_back(body);

    if (const YAML::Node markers = node["markers"]) {
      if (!markers.IsMap()) Fail(markers, element, "'markers' must be a mapping {NAME: {position, orientation}}");
      for (auto it = markers.begin(); it != markers.end(); ++it) {
        const std::string name = String(it->first, element, "marker name");
        const std::string marker_element = element + ", marker '" + name + "'";
        CheckMarkerName(it->first, marker_element, name);
        const mbs::Marker m = LoadMarker(it->second, marker_element, b, body.name + "." + name);
        if (name == "cm") {
          CheckImplicit(it->second, m, marker_element, "the centre of mass with body axes");
          continue;
        }
        if (FindMarker(m.name) >= 0) Fail(it->first, marker_element, "duplicate marker name");
        model_.markers.push_back(m);
      }
    }
  }

  // Geometry: mass properties if it has a density.
  // *drawn (if not null) gets the shape as drawn (mbs/visual.h).
  std::optional<MassProperties> Geometry(const YAML::Node& node, const std::string& element,
                                         std::vector<VisualShape>* drawn = nullptr) const {
    if (!node.IsMap()) Fail(node, element, "'geometry' must be a mapping {shape: ...}, got " + Kind(node));
    enum Shape { kSphere, kCylinder, kCone, kBox, kMesh };
    const Shape shape = Enum<Shape>(Required(node, element, "shape"), element, "shape",
                                    {{"sphere", kSphere}, {"cylinder", kCylinder}, {"cone", kCone}, {"box", kBox},
                                     {"mesh", kMesh}});
    if (shape == kMesh) return MeshGeometry(node, element, drawn);
    switch (shape) {
      case kSphere: CheckKeys(node, element, {"shape", "radius", "density"}, "geometry"); break;
      case kCylinder:
      case kCone: CheckKeys(node, element, {"shape", "radius", "length", "density"}, "geometry"); break;
      default: CheckKeys(node, element, {"shape", "size", "density"}, "geometry"); break;
    }
    auto positive = [&](const char* key) {
      const YAML::Node v = Required(node, element, key);
      const double x = LoadTimeNumber(v, element, std::string("geometry ") + key);
      if (!(x > 0)) Fail(v, element, std::string("geometry ") + key + " must be > 0, got " + Num(x));
      return x;
    };
    const double radius = shape == kBox ? 0 : positive("radius");
    const double length = (shape == kCylinder || shape == kCone) ? positive("length") : 0;
    Vec3 size = Vec3::Zero();
    if (shape == kBox) {
      const YAML::Node s = Required(node, element, "size");
      size = Vector3(s, element, "geometry size");
      if (!(size.minCoeff() > 0)) Fail(s, element, "geometry size must be > 0 along each axis");
    }
    if (drawn) {
      VisualShape v;
      v.kind = shape == kSphere ? VisualKind::kSphere : shape == kCylinder ? VisualKind::kCylinder
               : shape == kCone ? VisualKind::kCone : VisualKind::kBox;
      v.size = size;
      v.radius = radius;
      v.length = length;
      v.where = At(node);
      drawn->assign(1, v);
    }
    const YAML::Node d = node["density"];
    if (!d) return std::nullopt;
    const double density = LoadTimeNumber(d, element, "geometry density");
    if (!(density >= 0)) Fail(d, element, "geometry density must be >= 0, got " + Num(density));
    switch (shape) {
      case kSphere: return SphereMass(radius, density);
      case kCylinder: return CylinderMass(radius, length, density);
      case kCone: return ConeMass(radius, length, density);
      default: return BoxMass(size, density);
    }
  }

  // A triangle mesh (STL or OBJ; the file relative to the model file) scaled by
  // `scale`: with a density, mass and inertia about its centre of mass in mesh axes.
  // The body's axes are the mesh axes; its markers are relative to the centre of mass.
  std::optional<MassProperties> MeshGeometry(const YAML::Node& node, const std::string& element,
                                             std::vector<VisualShape>* drawn = nullptr) const {
    CheckKeys(node, element, {"shape", "file", "scale", "density"}, "geometry");
    const YAML::Node f = Required(node, element, "file");
    const std::string name = String(f, element, "geometry file");
    std::filesystem::path path(name);
    if (path.is_relative()) path = std::filesystem::path(file_).parent_path() / path;
    double scale = 1.0;
    if (const YAML::Node s = node["scale"]) {
      scale = LoadTimeNumber(s, element, "geometry scale");
      if (!(scale > 0)) Fail(s, element, "geometry scale must be > 0, got " + Num(scale));
    }
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
      Fail(f, element, "mesh file '" + name + "' not found (relative paths are relative to the model file)");
    const YAML::Node d = node["density"];
    double density = 0;
    if (d) {
      density = LoadTimeNumber(d, element, "geometry density");
      if (!(density >= 0)) Fail(d, element, "geometry density must be >= 0, got " + Num(density));
    }
    try {
      // Read and checked (closed, consistently oriented) even without a density.
      const MeshBodyProperties mesh = LoadMeshBody(path.string(), density > 0 ? density : 1.0, scale);
      if (drawn) {  // mesh axes are body axes, the body origin its centre of mass
        VisualShape v;
        v.kind = VisualKind::kMesh;
        v.mesh_file = path.string();
        v.mesh_scale = scale;
        v.position = -mesh.centre_of_mass;
        v.where = At(node);
        drawn->assign(1, v);
      }
      if (!d) return std::nullopt;
      MassProperties mp = mesh.mass;
      if (density == 0) mp = MassProperties{};
      return mp;
    } catch (const std::exception& e) {
      Fail(f, element, std::string("mesh: ") + e.what());
    }
    return std::nullopt;
  }

  // `visual:` of a body or of ground: one shape or a list of shapes (drawing only; see
  // VisualShape in mbs/model.h and docs/model-format.md, "Visual geometry").
  std::vector<VisualShape> Visuals(const YAML::Node& node, const std::string& element) const {
    struct Drawing {
      explicit Drawing(const Loader* l) : l_(l) { l_->drawing_ = true; }
      ~Drawing() { l_->drawing_ = false; }
      const Loader* l_;
    } drawing(this);
    std::vector<VisualShape> out;
    if (node.IsMap()) {
      out.push_back(Visual(node, element));
    } else if (node.IsSequence()) {
      for (size_t k = 0; k < node.size(); ++k) out.push_back(Visual(node[k], element + ", visual #" + std::to_string(k + 1)));
    } else {
      Fail(node, element, "'visual' must be a shape {shape: ...} or a list of shapes, got " + Kind(node));
    }
    return out;
  }

  VisualShape Visual(const YAML::Node& node, const std::string& element) const {
    if (!node.IsMap()) Fail(node, element, "a visual shape must be a mapping {shape: ...}, got " + Kind(node));
    VisualShape v;
    v.where = At(node);
    v.kind = Enum<VisualKind>(Required(node, element, "shape"), element, "shape",
                              {{"box", VisualKind::kBox}, {"sphere", VisualKind::kSphere},
                               {"cylinder", VisualKind::kCylinder}, {"capsule", VisualKind::kCapsule},
                               {"cone", VisualKind::kCone}, {"mesh", VisualKind::kMesh}});
    auto positive = [&](const char* key) {
      const YAML::Node n = Required(node, element, key);
      const double x = LoadTimeNumber(n, element, std::string("visual ") + key);
      if (!(x > 0)) Fail(n, element, std::string("visual ") + key + " must be > 0, got " + Num(x));
      return x;
    };
    switch (v.kind) {
      case VisualKind::kBox: {
        CheckKeys(node, element, {"shape", "size", "position", "orientation", "color"}, "visual");
        const YAML::Node s = Required(node, element, "size");
        v.size = Vector3(s, element, "visual size");
        if (!(v.size.minCoeff() > 0)) Fail(s, element, "visual size must be > 0 along each axis");
        break;
      }
      case VisualKind::kSphere:
        CheckKeys(node, element, {"shape", "radius", "position", "orientation", "color"}, "visual");
        v.radius = positive("radius");
        break;
      case VisualKind::kMesh: {
        CheckKeys(node, element, {"shape", "file", "scale", "position", "orientation", "color"}, "visual");
        const YAML::Node f = Required(node, element, "file");
        const std::string name = String(f, element, "visual file");
        std::filesystem::path path(name);
        if (path.is_relative()) path = std::filesystem::path(file_).parent_path() / path;
        std::error_code ec;
        if (!std::filesystem::is_regular_file(path, ec))
          Fail(f, element, "mesh file '" + name + "' not found (relative paths are relative to the model file)");
        v.mesh_file = path.string();
        if (node["scale"]) v.mesh_scale = positive("scale");
        try {
          ReadMesh(v.mesh_file);  // checked now: a bad file fails here, not when drawn
        } catch (const std::exception& e) {
          Fail(f, element, std::string("mesh: ") + e.what());
        }
        break;
      }
      default:  // cylinder, capsule, cone
        CheckKeys(node, element, {"shape", "radius", "length", "position", "orientation", "color"}, "visual");
        v.radius = positive("radius");
        v.length = positive("length");
        break;
    }
    if (const YAML::Node p = node["position"]) v.position = Vector3(p, element, "visual position");
    if (const YAML::Node o = node["orientation"]) {
      const OrientationForm form = orientation_form_;
      v.orientation = RotationMatrix(Orientation(o, element, "visual orientation"));
      orientation_form_ = form;
    }
    if (const YAML::Node c = node["color"]) {
      const std::vector<double> rgba = Numbers(c, element, "visual color", {3, 4});
      for (size_t k = 0; k < rgba.size(); ++k) {
        if (!(rgba[k] >= 0 && rgba[k] <= 1))
          Fail(c[k], element, "visual color: red, green, blue (and opacity) must be in [0, 1], got " + Num(rgba[k]));
        v.color[k] = rgba[k];
      }
    }
    return v;
  }

  // ---- measures, joints, forces -------------------------------------------------

  // Reads `name` of a list item; returns the element text.
  std::string ItemName(const YAML::Node& node, const char* kind, size_t index, std::string* name) const {
    std::string element = std::string(kind) + " #" + std::to_string(index + 1);
    if (!node.IsMap()) Fail(node, element, std::string("a ") + kind + " must be a mapping, got " + Kind(node));
    *name = String(Required(node, element, "name"), element, "name");
    return std::string(kind) + " '" + *name + "'";
  }

  void LoadMeasures(const YAML::Node& node) {
    if (!node) return;
    if (!node.IsSequence()) Fail(node, "model", "'measures' must be a list, got " + Kind(node));
    for (size_t k = 0; k < node.size(); ++k) {
      const YAML::Node m = node[k];
      Measure measure;
      const std::string element = ItemName(m, "measure", k, &measure.name);
      measure.where = At(m);
      if (!IsIdentifier(measure.name)) {
        Fail(m["name"], element, "a measure name must be letters, digits and '_' (it is used in expressions)");
      }
      if (ReservedWords().count(measure.name)) Fail(m["name"], element, "'" + measure.name + "' is reserved in expressions");
      if (model_.find_measure(measure.name) >= 0) Fail(m["name"], element, "duplicate measure name");
      measure.type = Enum<MeasureType>(Required(m, element, "type"), element, "type",
                                       {{"translational", MeasureType::kTranslational},
                                        {"rotational", MeasureType::kRotational},
                                        {"reaction", MeasureType::kReaction}});
      if (measure.type == MeasureType::kReaction) {
        // {name, type: reaction, joint: NAME, component: x|y|z|rx|ry|rz, frame: j|world};
        // the joint is resolved after the joints are read (ResolveReactionJoints).
        CheckKeys(m, element, {"name", "type", "joint", "component", "frame"});
        reaction_joints_.emplace_back(model_.measures.size(), Required(m, element, "joint"));
        String(reaction_joints_.back().second, element, "joint");
        enum Comp { kFx, kFy, kFz, kTx, kTy, kTz };
        const Comp c = Enum<Comp>(Required(m, element, "component"), element, "component",
                                  {{"x", kFx}, {"y", kFy}, {"z", kFz}, {"rx", kTx}, {"ry", kTy}, {"rz", kTz}});
        measure.torque = c >= kTx;
        measure.component = static_cast<Component>(static_cast<int>(c) % 3);
        if (const YAML::Node f = m["frame"]) {
          measure.frame = Enum<MeasureFrame>(f, element, "frame", {{"j", MeasureFrame::kJ}, {"world", MeasureFrame::kWorld}});
        }
        measure.i = measure.j = 0;  // set with the joint
        model_.measures.push_back(measure);
        continue;
      }
      if (measure.type == MeasureType::kTranslational) {
        CheckKeys(m, element, {"name", "type", "i", "j", "component", "frame", "quantity", "offset_initial"});
        measure.component = Enum<Component>(Required(m, element, "component"), element, "component",
                                            {{"x", Component::kX}, {"y", Component::kY}, {"z", Component::kZ},
                                             {"distance", Component::kDistance}});
        if (const YAML::Node f = m["frame"]) {
          measure.frame = Enum<MeasureFrame>(f, element, "frame", {{"j", MeasureFrame::kJ}, {"world", MeasureFrame::kWorld}});
        }
        if (const YAML::Node q = m["quantity"]) {
          measure.quantity = Enum<Quantity>(q, element, "quantity",
                                            {{"position", Quantity::kPosition}, {"velocity", Quantity::kVelocity},
                                             {"acceleration", Quantity::kAcceleration}});
        }
      } else {
        CheckKeys(m, element, {"name", "type", "i", "j", "axis", "quantity", "offset_initial"});
        measure.component = Enum<Component>(Required(m, element, "axis"), element, "axis",
                                            {{"x", Component::kX}, {"y", Component::kY}, {"z", Component::kZ}});
        if (const YAML::Node q = m["quantity"]) {
          measure.quantity = Enum<Quantity>(q, element, "quantity",
                                            {{"angle", Quantity::kPosition},
                                             {"angular_velocity", Quantity::kVelocity},
                                             {"angular_acceleration", Quantity::kAcceleration}});
        }
      }
      measure.i = Marker(Required(m, element, "i"), element, "i");
      measure.j = m["j"] ? Marker(m["j"], element, "j") : 0;
      if (const YAML::Node o = m["offset_initial"]) measure.offset_initial = Bool(o, element, "offset_initial");
      model_.measures.push_back(measure);
    }
  }

  void LoadJoints(const YAML::Node& node) {
    if (!node) return;
    if (!node.IsSequence()) Fail(node, "model", "'joints' must be a list, got " + Kind(node));
    for (size_t k = 0; k < node.size(); ++k) {
      const YAML::Node n = node[k];
      Joint joint;
      const std::string element = ItemName(n, "joint", k, &joint.name);
      joint.where = At(n);
      if (FindJoint(joint.name) >= 0) Fail(n["name"], element, "duplicate joint name");
      CheckName(n["name"], element, joint.name, "joint");
      enum JointKind { kFixed, kSpherical, kRevolute, kPrismatic, kCylindrical, kUniversal, kPlanar, kGeneric, kMotion, kGear };
      const YAML::Node type_node = Required(n, element, "type");
      const JointKind type = Enum<JointKind>(type_node, element, "joint type",
                                   {{"fixed", kFixed}, {"spherical", kSpherical}, {"revolute", kRevolute},
                                    {"prismatic", kPrismatic}, {"cylindrical", kCylindrical},
                                    {"universal", kUniversal}, {"planar", kPlanar}, {"generic", kGeneric},
                                    {"motion", kMotion}, {"gear", kGear}});
      if (type == kMotion || type == kGear) {
        if (n["i"] || n["j"] || n["lock"]) {
          const char* key = n["i"] ? "i" : n["j"] ? "j" : "lock";
          Fail(KeyNode(n, key), element,
               std::string("a ") + type_node.Scalar() + " joint acts on measures, it has no '" + key + "'");
        }
        if (type == kMotion) {
          CheckKeys(n, element, {"name", "type", "measure", "value"});
          joint.type = JointType::kMotion;
          const YAML::Node mnode = Required(n, element, "measure");
          joint.measures[0] = PositionMeasure(mnode, element, "measure", false);
          joint.value = ParseMotionValue(Required(n, element, "value"), element, "value");
        } else {
          CheckKeys(n, element, {"name", "type", "measures", "ratio"});
          joint.type = JointType::kGear;
          const YAML::Node list = Required(n, element, "measures");
          if (!list.IsSequence() || list.size() != 2) {
            Fail(list, element, "'measures' must be a list of 2 rotational angle measures, got " +
                                    (list.IsSequence() ? std::to_string(list.size()) + " entries" : Kind(list)));
          }
          joint.measures[0] = PositionMeasure(list[0], element, "measures", true);
          joint.measures[1] = PositionMeasure(list[1], element, "measures", true);
          if (joint.measures[0] == joint.measures[1]) Fail(list[1], element, "the two measures of a gear must differ");
          joint.ratio = LoadTimeNumber(Required(n, element, "ratio"), element, "ratio");
        }
        model_.joints.push_back(joint);
        continue;
      }
      // Locks per type, in marker j's axes (model format, "Joints").
      constexpr unsigned kAllT = kLockX | kLockY | kLockZ, kAllR = kLockRx | kLockRy | kLockRz;
      switch (type) {
        case kFixed: joint.type = JointType::kFixed; joint.locks = kAllT | kAllR; break;
        case kSpherical: joint.type = JointType::kSpherical; joint.locks = kAllT; break;
        case kRevolute: joint.type = JointType::kRevolute; joint.locks = kAllT | kLockRx | kLockRy; break;
        case kPrismatic: joint.type = JointType::kPrismatic; joint.locks = kLockX | kLockY | kAllR; break;
        case kCylindrical:
          joint.type = JointType::kCylindrical;
          joint.locks = kLockX | kLockY | kLockRx | kLockRy;
          break;
        case kUniversal: joint.type = JointType::kUniversal; joint.locks = kAllT | kLockRz; break;
        case kPlanar: joint.type = JointType::kPlanar; joint.locks = kLockZ | kLockRx | kLockRy; break;
        default: joint.type = JointType::kGeneric; break;
      }
      if (type == kGeneric) {
        CheckKeys(n, element, {"name", "type", "i", "j", "lock"});
        const YAML::Node lock = Required(n, element, "lock");
        if (!lock.IsSequence() || lock.size() == 0) {
          Fail(lock, element, "'lock' must be a non-empty list of x, y, z, rx, ry, rz, got " + Kind(lock));
        }
        for (const YAML::Node& l : lock) {
          const unsigned bit = Enum<unsigned>(l, element, "lock", {{"x", kLockX}, {"y", kLockY}, {"z", kLockZ},
                                                                  {"rx", kLockRx}, {"ry", kLockRy}, {"rz", kLockRz}});
          if (joint.locks & bit) Fail(l, element, "'" + l.Scalar() + "' is locked twice");
          joint.locks |= bit;
        }
      } else {
        if (n["lock"]) {
          Fail(KeyNode(n, "lock"), element,
               "'lock' is only for joints of type generic; a " + type_node.Scalar() + " joint locks what its type says");
        }
        CheckKeys(n, element, {"name", "type", "i", "j", "limits"});
        if (const YAML::Node l = n["limits"]) joint.limits = JointLimits(l, element);
      }
      joint.i = Marker(Required(n, element, "i"), element, "i");
      joint.j = Marker(Required(n, element, "j"), element, "j");
      const int bi = model_.markers[joint.i].body, bj = model_.markers[joint.j].body;
      if (bi == bj) {
        Fail(n, element, "markers i and j are both on " +
                             (bi < 0 ? std::string("ground") : "body '" + model_.bodies[bi].name + "'") +
                             "; a joint connects two different bodies");
      }
      model_.joints.push_back(joint);
    }
  }

  // `limits: {lower, upper, effort, velocity}` of a joint (URDF's <limit>): recorded, not
  // enforced; lower and upper together or neither, effort and velocity >= 0.
  Joint::Limits JointLimits(const YAML::Node& l, const std::string& element) {
    if (!l.IsMap()) Fail(l, element, "'limits' must be a mapping {lower, upper, effort, velocity}, got " + Kind(l));
    CheckKeys(l, element, {"lower", "upper", "effort", "velocity"});
    Joint::Limits out;
    if (l["lower"] || l["upper"]) {
      out.lower = LoadTimeNumber(Required(l, element, "lower"), element, "limits lower");
      out.upper = LoadTimeNumber(Required(l, element, "upper"), element, "limits upper");
      out.has_position = true;
    }
    if (l["effort"]) out.effort = LoadTimeNumber(l["effort"], element, "limits effort");
    if (l["velocity"]) out.velocity = LoadTimeNumber(l["velocity"], element, "limits velocity");
    if (out.effort < 0) Fail(l["effort"], element, "limits effort must be >= 0, got " + Num(out.effort));
    if (out.velocity < 0) Fail(l["velocity"], element, "limits velocity must be >= 0, got " + Num(out.velocity));
    return out;
  }

  // `extends: FILE` (docs/model-format.md, "Extending a model"): the model of FILE (any
  // format: YAML, .fds, .urdf; relative to this file) is the start, and this file adds
  // elements to it and changes named ones (`modify:`). The base's parameters (if it has
  // any) cannot be combined with this file's yet.
  void Extend(const YAML::Node& node) {
    const std::string element = "model";
    const std::string written = String(node, element, "extends");
    std::filesystem::path path(written);
    if (path.is_relative()) path = std::filesystem::path(file_).parent_path() / path;
    static thread_local std::vector<std::string> chain;  // files being extended, for cycles
    std::error_code ec;
    const std::string key = std::filesystem::weakly_canonical(path, ec).string();
    for (const std::string& f : chain)
      if (f == key) Fail(node, element, "'extends': '" + written + "' extends this file again (a cycle)");
    if (!std::filesystem::is_regular_file(path, ec)) Fail(node, element, "'extends': cannot read '" + path.string() + "'");
    LoadOptions base_options;  // --set of the base's parameters only
    chain.push_back(key);
    struct Pop {
      ~Pop() { chain.pop_back(); }
    } pop;
    Model base = LoadAnyModel(path.string(), base_options);
    if (!base.parameters.empty())
      Fail(node, element, "'extends': '" + written + "' has parameters; extending a model with parameters is not "
                          "supported yet (convert it and edit the copy)");
    base.file = file_;
    base.notes.push_back("extends " + written);
    model_ = std::move(base);
    marker_index_.clear();  // the name indices restart from the extended model
    body_index_.clear();
    markers_indexed_ = bodies_indexed_ = 0;
    joint_index_.clear();
    force_index_.clear();
    joints_indexed_ = forces_indexed_ = 0;
    extended_ = true;
    for (const Measure& m : model_.measures) symbols_.reserved.push_back(m.name);
  }

  // `modify: {bodies: {NAME: {mass, inertia, markers}}, joints: {NAME: {limits}}}`: changes
  // of elements of the extended model, by name.
  void Modify(const YAML::Node& node) {
    if (!node) return;
    const std::string element = "modify";
    if (!node.IsMap()) Fail(node, element, "'modify' must be a mapping {bodies: ..., joints: ...}, got " + Kind(node));
    CheckKeys(node, element, {"bodies", "joints"});
    auto names = [](const auto& items) {
      std::vector<std::string> out;
      for (const auto& x : items) out.push_back(x.name);
      return out;
    };
    if (const YAML::Node bodies = node["bodies"]) {
      if (!bodies.IsMap()) Fail(bodies, element, "'bodies' must be a mapping {NAME: {mass, inertia, markers}}");
      for (auto it = bodies.begin(); it != bodies.end(); ++it) {
        const std::string name = String(it->first, element, "body name");
        const int b = FindBody(name);
        if (b < 0)
          Fail(it->first, element, "no body '" + name + "' in the extended model" + Suggest(name, names(model_.bodies)) +
                                       " (bodies: " + Join(names(model_.bodies)) + ")");
        const std::string body_element = "body '" + name + "'";
        const YAML::Node n = it->second;
        if (!n.IsMap()) Fail(n, body_element, "a change must be a mapping {mass, inertia, markers}, got " + Kind(n));
        CheckKeys(n, body_element, {"mass", "inertia", "markers"});
        Body& body = model_.bodies[b];
        if (const YAML::Node m = n["mass"]) {
          body.mass = LoadTimeNumber(m, body_element, "mass");
          if (body.mass < 0) Fail(m, body_element, "mass must be >= 0, got " + Num(body.mass));
        }
        if (const YAML::Node in = n["inertia"]) {
          const std::vector<double> v = Numbers(in, body_element, "inertia", {3, 6});
          Mat3 J = Mat3::Zero();
          J.diagonal() << v[0], v[1], v[2];
          if (v.size() == 6) {
            J(0, 1) = J(1, 0) = v[3];
            J(0, 2) = J(2, 0) = v[4];
            J(1, 2) = J(2, 1) = v[5];
          }
          std::string why;
          if (!IsPhysicalInertia(J, &why)) Fail(in, body_element, why);
          body.inertia = J;
        }
        if (const YAML::Node markers = n["markers"]) {
          if (!markers.IsMap()) Fail(markers, body_element, "'markers' must be a mapping {NAME: {position, orientation}}");
          for (auto mk = markers.begin(); mk != markers.end(); ++mk) {
            const std::string local = String(mk->first, body_element, "marker name");
            const std::string marker_element = body_element + ", marker '" + local + "'";
            CheckMarkerName(mk->first, marker_element, local);
            const mbs::Marker m = LoadMarker(mk->second, marker_element, b, name + "." + local);
            if (FindMarker(m.name) >= 0) Fail(mk->first, marker_element, "duplicate marker name");
            model_.markers.push_back(m);
          }
        }
      }
    }
    if (const YAML::Node joints = node["joints"]) {
      if (!joints.IsMap()) Fail(joints, element, "'joints' must be a mapping {NAME: {limits}}");
      for (auto it = joints.begin(); it != joints.end(); ++it) {
        const std::string name = String(it->first, element, "joint name");
        int j = -1;
        for (size_t k = 0; k < model_.joints.size(); ++k)
          if (model_.joints[k].name == name) j = static_cast<int>(k);
        if (j < 0)
          Fail(it->first, element, "no joint '" + name + "' in the extended model" + Suggest(name, names(model_.joints)) +
                                       " (joints: " + Join(names(model_.joints)) + ")");
        const std::string joint_element = "joint '" + name + "'";
        const YAML::Node n = it->second;
        if (!n.IsMap()) Fail(n, joint_element, "a change must be a mapping {limits}, got " + Kind(n));
        CheckKeys(n, joint_element, {"limits"});
        if (const YAML::Node l = n["limits"]) model_.joints[j].limits = JointLimits(l, joint_element);
      }
    }
  }
  bool extended_ = false;

  void LoadForces(const YAML::Node& node) {
    if (!node) return;
    if (!node.IsSequence()) Fail(node, "model", "'forces' must be a list, got " + Kind(node));
    for (size_t k = 0; k < node.size(); ++k) {
      const YAML::Node n = node[k];
      Force force;
      const std::string element = ItemName(n, "force", k, &force.name);
      force.where = At(n);
      if (FindForce(force.name) >= 0) Fail(n["name"], element, "duplicate force name");
      CheckName(n["name"], element, force.name, "force");
      enum ForceKind { kSpring, kForce, kTorque, kBushing, kUser };
      const YAML::Node type_node = Required(n, element, "type");
      const ForceKind type = Enum<ForceKind>(type_node, element, "force type",
                                   {{"spring_damper", kSpring}, {"force", kForce}, {"torque", kTorque},
                                    {"bushing", kBushing}, {"user", kUser}});
      if (type == kSpring) {
        force.type = ForceType::kSpringDamper;
        CheckKeys(n, element, {"name", "type", "i", "j", "stiffness", "damping", "free_length", "preload"});
        force.stiffness = ForceValue(Required(n, element, "stiffness"), element, "'stiffness'");
        force.free_length = ForceValue(Required(n, element, "free_length"), element, "'free_length'");
        force.damping = n["damping"] ? ForceValue(n["damping"], element, "'damping'") : Expression::Constant(0);
        force.preload = n["preload"] ? ForceValue(n["preload"], element, "'preload'") : Expression::Constant(0);
      } else if (type == kBushing) {
        force.type = ForceType::kBushing;
        CheckKeys(n, element, {"name", "type", "i", "j", "stiffness", "damping"});
        for (int which = 0; which < 2; ++which) {
          const char* key = which == 0 ? "stiffness" : "damping";
          const YAML::Node list = which == 0 ? Required(n, element, key) : n[key];
          auto& out = which == 0 ? force.bushing_stiffness : force.bushing_damping;
          if (!list) {
            out.fill(Expression::Constant(0));
            continue;
          }
          if (!list.IsSequence() || list.size() != 6) {
            Fail(list, element, std::string("'") + key + "' must be a list of 6 numbers or expressions of the parameters, got " +
                                    (list.IsSequence() ? std::to_string(list.size()) + " entries" : Kind(list)));
          }
          for (int c = 0; c < 6; ++c) {
            out[c] = Parse(list[c], element, key);
            const double x = out[c].Evaluate(model_.parameter_values().data());
            if (!(x >= 0) || !std::isfinite(x)) {
              Fail(list[c], element, std::string("'") + key + "' entry " + std::to_string(c + 1) + " is " +
                                         Num(x) + "; it must be finite and >= 0");
            }
          }
        }
      } else if (type == kUser) {
        force.type = ForceType::kUser;
        CheckKeys(n, element, {"name", "type", "i", "j", "library", "function", "parameters"});
        const YAML::Node lib = Required(n, element, "library");
        force.library_path = String(lib, element, "library");
        force.function = String(Required(n, element, "function"), element, "function");
        if (const YAML::Node ps = n["parameters"]) {
          if (!ps.IsSequence()) Fail(ps, element, "'parameters' must be a list of numbers or expressions, got " + Kind(ps));
          for (size_t c = 0; c < ps.size(); ++c) force.user_parameters.push_back(Parse(ps[c], element, "parameters"));
        }
        if (force.library_path.empty()) Fail(lib, element, "'library' must name a shared library file");
        // Opened by LoadUserLibraries once the whole file has been checked.
        pending_libraries_.push_back(PendingLibrary{model_.forces.size(), lib, n["function"]});
      } else {
        force.type = type == kForce ? ForceType::kForce : ForceType::kTorque;
        CheckKeys(n, element, {"name", "type", "i", "j", "frame", "value"});
        if (const YAML::Node f = n["frame"]) {
          force.frame = Enum<ForceFrame>(f, element, "frame",
                                         {{"world", ForceFrame::kWorld}, {"i", ForceFrame::kI}, {"j", ForceFrame::kJ}});
        }
        const YAML::Node value = Required(n, element, "value");
        if (!value.IsSequence() || value.size() != 3) {
          Fail(value, element, "'value' must be a list of 3 numbers or expressions, got " +
                                   (value.IsSequence() ? std::to_string(value.size()) + " entries" : Kind(value)));
        }
        for (int c = 0; c < 3; ++c) {
          force.value[c] = ForceValue(value[c], element, "'value' entry " + std::to_string(c + 1));
        }
      }
      force.i = Marker(Required(n, element, "i"), element, "i");
      force.j = n["j"] ? Marker(n["j"], element, "j") : 0;
      model_.forces.push_back(force);
    }
  }

  // The libraries of `user` forces, opened (dlopen runs the library's initialisers) only
  // after everything else in the file has been checked: a refused model runs no library
  // code. A relative path is relative to the model file's folder, and is given to dlopen
  // with a '/' ("./libx.so" for a model in the current folder), which would otherwise
  // search the system's library path.
  void LoadUserLibraries() {
    for (const PendingLibrary& p : pending_libraries_) {
      Force& force = model_.forces[p.force];
      const std::string element = "force '" + force.name + "'";
      std::filesystem::path path(force.library_path);
      if (path.is_relative()) {
        std::filesystem::path folder = std::filesystem::path(file_).parent_path();
        if (folder.empty()) folder = ".";
        path = folder / path;
      }
      std::string key = path.lexically_normal().string();
      if (key.find('/') == std::string::npos) key = "./" + key;
      auto it = libraries_.find(key);
      if (it == libraries_.end()) {
        try {
          it = libraries_.emplace(key, std::make_shared<const UserForceLibrary>(key)).first;
        } catch (const std::exception& e) {
          Fail(p.library, element,
               std::string("cannot use the library (relative paths are relative to the model file): ") + e.what());
        }
      }
      force.library = it->second;
      try {
        force.library->Symbol(force.function, true);
      } catch (const std::exception& e) {
        Fail(p.function, element, e.what());
      }
    }
  }

  // Reaction measures: the joint by name, and markers i and j from it (motion joints:
  // those of the driven measure; gear joints: those of the second measure).
  void ResolveReactionJoints() {
    for (const auto& [index, node] : reaction_joints_) {
      Measure& measure = model_.measures[index];
      const std::string element = "measure '" + measure.name + "'";
      const std::string name = node.Scalar();
      const int joint = FindJoint(name);
      if (joint < 0) {
        std::vector<std::string> names;
        for (const Joint& jt : model_.joints) names.push_back(jt.name);
        Fail(node, element, "'joint': unknown joint '" + name + "'" + Suggest(name, names) +
                                (names.empty() ? std::string(" (the model has no joints)")
                                               : " (joints: " + Join(names) + ")"));
      }
      const Joint& jt = model_.joints[joint];
      measure.joint = joint;
      if (jt.type == JointType::kMotion || jt.type == JointType::kGear) {
        const Measure& driven = model_.measures[jt.measures[jt.type == JointType::kGear ? 1 : 0]];
        measure.i = driven.i;
        measure.j = driven.j;
      } else {
        measure.i = jt.i;
        measure.j = jt.j;
      }
    }
  }

  // ---- objectives -------------------------------------------------------------------

  void LoadObjectives(const YAML::Node& node) {
    if (!node) return;
    if (!node.IsSequence()) Fail(node, "model", "'objectives' must be a list, got " + Kind(node));
    SymbolTable symbols;
    symbols.parameters = symbols_.parameters;
    for (const Measure& m : model_.measures) symbols.measures.push_back(m.name);
    for (const SplineDef& sp : model_.splines) symbols.splines.push_back(sp.name);
    symbols.allow_time = true;
    for (size_t k = 0; k < node.size(); ++k) {
      const YAML::Node n = node[k];
      Objective objective;
      const std::string element = ItemName(n, "objective", k, &objective.name);
      objective.where = At(n);
      CheckKeys(n, element, {"name", "integral", "terminal"});
      if (!IsIdentifier(objective.name)) {
        Fail(n["name"], element, "an objective name must be letters, digits and '_', not starting with a digit");
      }
      if (model_.find_objective(objective.name) >= 0) Fail(n["name"], element, "duplicate objective name");
      if (!n["integral"] && !n["terminal"]) {
        Fail(n, element, "an objective needs 'integral', 'terminal' or both");
      }
      auto parse = [&](const char* key) {
        const YAML::Node e = n[key];
        if (!e.IsScalar()) Fail(e, element, std::string("'") + key + "' must be a number or an expression, got " + Kind(e));
        try {
          return Expression::Parse(e.Scalar(), symbols);
        } catch (const ExpressionError& err) {
          Fail(e, element, std::string("'") + key + "': in expression '" + e.Scalar() + "': " + err.what());
        }
      };
      if (n["integral"]) {
        objective.integral = parse("integral");
        objective.has_integral = true;
      }
      if (n["terminal"]) {
        objective.terminal = parse("terminal");
        objective.has_terminal = true;
      }
      model_.objectives.push_back(objective);
    }
  }

  // ---- simulation -------------------------------------------------------------------

  // simulation: {output: {bodies, joints, forces, measures}}: each `all` or a list of
  // names of elements of that kind, each named once.
  void LoadOutputSelection(const YAML::Node& node) {
    const std::string element = "simulation";
    CheckKeys(node, element, {"bodies", "joints", "forces", "measures"}, "output");
    SimulationSettings& s = model_.simulation;
    auto load = [&](const char* key, const char* kind, const std::vector<std::string>& names,
                    std::optional<std::vector<std::string>>* out) {
      const YAML::Node n = node[key];
      if (!n) return;
      const std::string what = std::string("output ") + key;
      if (n.IsScalar() && n.Scalar() == "all") {
        out->reset();
        return;
      }
      if (!n.IsSequence())
        Fail(n, element, what + " must be 'all' or a list of " + kind + " names, got " + Kind(n));
      const std::set<std::string> known(names.begin(), names.end());
      std::set<std::string> seen;
      std::vector<std::string> chosen;
      for (const YAML::Node& item : n) {
        const std::string name = String(item, element, what);
        if (!known.count(name))
          Fail(item, element, what + ": no " + kind + " named '" + name + "'" + Suggest(name, names));
        if (!seen.insert(name).second) Fail(item, element, what + ": " + kind + " '" + name + "' is named twice");
        chosen.push_back(name);
      }
      *out = std::move(chosen);
    };
    std::vector<std::string> names;
    for (const auto& b : model_.bodies) names.push_back(b.name);
    load("bodies", "body", names, &s.output_bodies);
    names.clear();
    for (const auto& j : model_.joints) names.push_back(j.name);
    load("joints", "joint", names, &s.output_joints);
    names.clear();
    for (const auto& f : model_.forces) names.push_back(f.name);
    load("forces", "force", names, &s.output_forces);
    names.clear();
    for (const auto& m : model_.measures) names.push_back(m.name);
    load("measures", "measure", names, &s.output_measures);
  }

  void LoadSimulation(const YAML::Node& node) {
    if (!node) return;
    const std::string element = "simulation";
    SimulationSettings& s = model_.simulation;
    CheckKeys(node, element,
              {"t_end", "output_step", "integrator", "hht", "ida", "erk", "output_accelerations", "output"},
              "simulation");
    auto positive = [&](const YAML::Node& n, const std::string& key) {
      const double x = LoadTimeNumber(n, element, key);
      if (!(x > 0)) Fail(n, element, key + " must be > 0, got " + Num(x));
      return x;
    };
    if (const YAML::Node n = node["t_end"]) s.t_end = positive(n, "t_end");
    if (const YAML::Node n = node["output_step"]) s.output_step = positive(n, "output_step");
    if (const YAML::Node n = node["integrator"]) {
      s.integrator = Enum<IntegratorKind>(n, element, "integrator",
                                          {{"hht", IntegratorKind::kHht},
                                           {"ida", IntegratorKind::kIda},
                                           {"kinematic", IntegratorKind::kKinematic},
                                           {"erk", IntegratorKind::kErk}});
      s.integrator_named = true;
      s.integrator_where = At(n);
    }
    if (const YAML::Node n = node["output_accelerations"]) {
      s.output_accelerations = Enum<std::string>(n, element, "output_accelerations",
                                                 {{"solved", "solved"}, {"integrator", "integrator"}});
    }
    if (const YAML::Node o = node["output"]) LoadOutputSelection(o);
    if (const YAML::Node h = node["hht"]) {
      CheckKeys(h, element, {"alpha", "step", "adaptive", "tolerance", "modified", "form", "start", "dense_output",
                    "newton_tolerance", "linear_solver", "jacobian_cost", "predictor",
                    "rotation_jacobian"},
                "hht");
      if (const YAML::Node n = h["alpha"]) {
        s.hht_alpha = LoadTimeNumber(n, element, "alpha");
        if (!(s.hht_alpha >= -1.0 / 3.0 - 1e-15 && s.hht_alpha <= 0)) {
          Fail(n, element, "hht alpha must be in [-1/3, 0], got " + Num(s.hht_alpha));
        }
      }
      if (const YAML::Node n = h["step"]) s.hht_step = positive(n, "hht step");
      if (const YAML::Node n = h["adaptive"]) s.hht_adaptive = Bool(n, element, "adaptive");
      if (const YAML::Node n = h["tolerance"]) s.hht_tolerance = positive(n, "hht tolerance");
      if (const YAML::Node n = h["modified"]) s.hht_modified = Bool(n, element, "modified");
      if (const YAML::Node n = h["dense_output"]) s.hht_dense_output = Bool(n, element, "dense_output");
      if (const YAML::Node n = h["newton_tolerance"]) {
        s.hht_newton_tolerance = positive(n, "hht newton_tolerance");
        if (!(s.hht_newton_tolerance < 1))
          Fail(n, element, "hht newton_tolerance must be below 1, got " + Num(s.hht_newton_tolerance));
      }
      if (const YAML::Node n = h["form"]) {
        s.hht_form = Choice(n, element, "form", dae::HhtFormNames());
      }
      if (const YAML::Node n = h["start"]) {
        s.hht_start = Choice(n, element, "start", dae::HhtStartNames());
      }
      if (const YAML::Node n = h["linear_solver"]) {
        s.hht_linear_solver = Choice(n, element, "linear_solver", dae::HhtLinearSolverNames());
      }
      if (const YAML::Node n = h["jacobian_cost"]) {
        if (n.IsScalar() && n.Scalar() == "auto") {
          s.hht_jacobian_cost = -1;
        } else {
          s.hht_jacobian_cost = LoadTimeNumber(n, element, "jacobian_cost");
          if (!(s.hht_jacobian_cost >= 0 && std::isfinite(s.hht_jacobian_cost)))
            Fail(n, element, "hht jacobian_cost must be auto or a number >= 0, got " +
                                 Num(s.hht_jacobian_cost));
        }
      }
      if (const YAML::Node n = h["predictor"]) {
        s.hht_predictor = Choice(n, element, "predictor", dae::HhtPredictorNames());
      }
      if (const YAML::Node n = h["rotation_jacobian"]) {
        s.hht_rotation_jacobian =
            Choice(n, element, "rotation_jacobian", dae::HhtRotationJacobianNames());
      }
    }
    if (const YAML::Node i = node["ida"]) {
      CheckKeys(i, element, {"rtol", "atol", "max_steps", "min_step", "dense_output", "linear_solver"},
                "ida");
      if (const YAML::Node n = i["dense_output"]) s.ida_dense_output = Bool(n, element, "dense_output");
      if (const YAML::Node n = i["linear_solver"]) {
        s.ida_linear_solver = Choice(n, element, "linear_solver", dae::HhtLinearSolverNames());
      }
      if (const YAML::Node n = i["rtol"]) s.ida_rtol = positive(n, "ida rtol");
      if (const YAML::Node n = i["atol"]) s.ida_atol = positive(n, "ida atol");
      if (const YAML::Node n = i["max_steps"]) {
        const double x = LoadTimeNumber(n, element, "ida max_steps");
        if (!(x >= 1 && x == std::floor(x) && x <= 9e18)) {
          Fail(n, element, "ida max_steps must be a whole number >= 1, got " + Num(x));
        }
        s.ida_max_steps = static_cast<long>(x);
      }
      if (const YAML::Node n = i["min_step"]) s.ida_min_step = positive(n, "ida min_step");
    }
    if (const YAML::Node e = node["erk"]) {
      CheckKeys(e, element, {"rtol", "atol", "max_steps", "min_step", "max_step"}, "erk");
      if (const YAML::Node n = e["rtol"]) s.erk_rtol = positive(n, "erk rtol");
      if (const YAML::Node n = e["atol"]) s.erk_atol = positive(n, "erk atol");
      if (const YAML::Node n = e["max_steps"]) {
        const double x = LoadTimeNumber(n, element, "erk max_steps");
        if (!(x >= 1 && x == std::floor(x) && x <= 9e18)) {
          Fail(n, element, "erk max_steps must be a whole number >= 1, got " + Num(x));
        }
        s.erk_max_steps = static_cast<long>(x);
      }
      if (const YAML::Node n = e["min_step"]) s.erk_min_step = positive(n, "erk min_step");
      if (const YAML::Node n = e["max_step"]) s.erk_max_step = positive(n, "erk max_step");
      if (const YAML::Node n = e["min_step"]; n && s.erk_max_step > 0 && s.erk_min_step > s.erk_max_step) {
        Fail(n, element, "erk min_step " + Num(s.erk_min_step) + " is larger than its max_step " +
                             Num(s.erk_max_step));
      }
    }
    // Settings that are each > 0 but cannot be used together or by the integrator.
    const double rows = s.t_end / s.output_step;
    if (!(rows <= kMaxOutputRows)) {
      const YAML::Node at = node["output_step"] ? node["output_step"] : node["t_end"];
      Fail(at, element, "t_end " + Num(s.t_end) + " with output_step " + Num(s.output_step) + " gives " +
                            Rounded(rows) + " output rows; at most " + Rounded(kMaxOutputRows) +
                            " (make output_step larger)");
    }
    const double min_step = dae::HhtOptions().min_step;
    if (const YAML::Node h = node["hht"]) {
      if (const YAML::Node n = h["step"]; n && !(s.hht_step >= min_step)) {
        Fail(n, element, "hht step " + Num(s.hht_step) + " is smaller than the smallest step of the HHT integrator, " +
                             Num(min_step));
      }
    }
  }

  std::string file_;
  // User-force libraries by normalised path: each loaded once and shared.
  std::map<std::string, std::shared_ptr<const UserForceLibrary>> libraries_;
  // `user` forces whose library is still to be opened: Model::forces index, the
  // `library` and `function` nodes.
  struct PendingLibrary {
    size_t force;
    YAML::Node library, function;
  };
  std::vector<PendingLibrary> pending_libraries_;
  const LoadOptions& options_;
  Model model_;
  // Name indices of model_.markers and model_.bodies (FindMarker, FindBody): a linear
  // search per lookup made loading a chain of N bodies cost O(N^2).
  mutable std::unordered_map<std::string, int> marker_index_, body_index_;
  mutable size_t markers_indexed_ = 0, bodies_indexed_ = 0;
  // The same for the duplicate-name checks of joints and forces and the joints of
  // reaction measures (each was a linear search: O(N^2) for a chain of N joints).
  mutable std::unordered_map<std::string, int> joint_index_, force_index_;
  mutable size_t joints_indexed_ = 0, forces_indexed_ = 0;
  SymbolTable symbols_;
  // Reaction measures (Model::measures index) and their `joint` node, until the joints are read.
  std::vector<std::pair<size_t, YAML::Node>> reaction_joints_;
  std::vector<double> values_;  // parameter values, index as in symbols_.parameters
};

}  // namespace

ModelError::ModelError(const SourceLocation& where, const std::string& element, const std::string& what)
    : std::runtime_error(FormatError(where, element, what)), where_(where), element_(element) {}

Model LoadModel(const std::string& path, const LoadOptions& options) {
  std::error_code ignored;
  if (std::filesystem::is_directory(path, ignored)) {
    throw ModelError(SourceLocation{path, 0, 0}, "model", "cannot read the file: it is a directory");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw ModelError(SourceLocation{path, 0, 0}, "model", std::string("cannot open the file: ") + std::strerror(errno));
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) {
    throw ModelError(SourceLocation{path, 0, 0}, "model", std::string("cannot read the file: ") + std::strerror(errno));
  }
  return LoadModelFromString(text.str(), path, options);
}

Model LoadModelFromString(const std::string& text, const std::string& file, const LoadOptions& options) {
  return Loader(file, options).Load(text);
}

}  // namespace mbdae::mbs
