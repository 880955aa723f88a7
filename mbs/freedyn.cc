// FreeDyn model files (.fds) -> mbs::Model. The format and the conventions taken here
// are described in docs/freedyn.md.
#include "mbs/freedyn.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

#include "dae/format.h"
#include "dae/hht.h"
#include "mbs/kinematics.h"
#include "mbs/urdf.h"

namespace mbdae::mbs {

namespace {

std::string Trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return s.substr(b, e - b);
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Shortest of 15 or 17 significant digits that reads back exactly.
std::string Num(double x) { return FormatRoundTrip(x); }

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

bool IsIdentifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

// Words with a meaning of their own in expressions (as in the YAML loader).
bool IsReservedWord(const std::string& s) {
  static const std::set<std::string> words = {
      "pi",   "t",    "spline", "sin", "cos", "tan",  "asin", "acos", "atan", "atan2", "sinh",
      "cosh", "tanh", "exp",    "log", "sqrt", "abs", "sign", "min",  "max",  "pow",   "step"};
  return words.count(s) > 0;
}

// ---- the text: blocks of "Key = value" lines ----------------------------------------

struct Entry {
  std::string key, value;
  int line = 0, key_column = 0, value_column = 0;
};

struct Block {
  std::string category, type;  // "Body", "Rigid_EulerParameter_PAI"
  int line = 0, column = 0;
  std::vector<Entry> entries;
};

// The known block categories and their closing words.
const std::vector<std::string>& Categories() {
  static const std::vector<std::string> c = {"Header",  "Body",       "Constraint", "Force",
                                             "DataObject", "Measure", "Simulation", "Solver",
                                             "Globals"};
  return c;
}

}  // namespace

const std::vector<std::pair<std::string, std::string>>& IgnoredFreeDynKeys() {
  static const std::vector<std::pair<std::string, std::string>> keys = {
      {"Body", "RegardVelocityInertiaForcesInsideJacobian"},
      {"Body", "Geometry Transparency"},
      {"Simulation", "isExactOutputTimeEnforced"},
      {"Simulation", "WriteConstraintForceResultFile"},
      {"Simulation", "WriteForceResultFile"},
      {"Simulation", "WriteVelocityResultFile"},
      {"Simulation", "WriteStateResultFile"},
      {"Simulation", "WriteAccelerationResultFile"},
      {"Simulation", "WriteExtConstraintLagrangeResultFile"},
      {"Simulation", "WriteMeasureResultFile"},
      {"Solver", "MaxNumberOfInnerIterations"},
      {"Solver", "SolverMinTimeStep"},
      {"Solver", "MaxNumOfTimeStepsUsingSameFactorizedJacobian"},
      {"Solver", "UsePardisoScalingAndMatching"},
      {"Solver", "DebugLevel"},
      {"Solver", "DebugTimeBegin"},
      {"Solver", "DebugTimeEnd"},
      {"Globals", "(every key)"},
  };
  return keys;
}

bool IsFreeDynPath(const std::string& path) {
  return path.size() >= 4 && Lower(path.substr(path.size() - 4)) == ".fds";
}

// ---- expressions ----------------------------------------------------------------------

namespace {

const std::string* Lookup(const std::vector<std::pair<std::string, std::string>>& table, const std::string& name) {
  for (const auto& [from, to] : table)
    if (from == name) return &to;
  return nullptr;
}

struct Translator {
  const std::string& text;
  const FreeDynNames& names;
  size_t pos = 0;

  [[noreturn]] void Fail(size_t at, const std::string& what) const {
    throw std::make_pair(static_cast<int>(at) + 1, what);
  }

  // Translates up to (not including) a top-level ',' or ']' when `inside` is true, else
  // to the end.
  std::string Run(bool inside) {
    std::string out;
    int parens = 0;
    while (pos < text.size()) {
      const char c = text[pos];
      if (inside && parens == 0 && (c == ',' || c == ']')) return out;
      if (c == '(') ++parens;
      if (c == ')') --parens;
      if (c == '[' || c == ']') Fail(pos, std::string("unexpected '") + c + "'");
      if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
        const size_t start = pos;
        while (pos < text.size() && (std::isalnum(static_cast<unsigned char>(text[pos])) || text[pos] == '_')) ++pos;
        const std::string word = text.substr(start, pos - start);
        size_t look = pos;
        while (look < text.size() && text[look] == ' ') ++look;
        if (look < text.size() && text[look] == '[') {
          pos = look + 1;
          out += Function(word, start);
        } else if (look < text.size() && text[look] == '(' && IsReservedWord(Lower(word))) {
          out += Lower(word);  // SIN(x) -> sin(x): function names in any letter case
        } else {
          out += word;
        }
        continue;
      }
      out += c;
      ++pos;
    }
    if (inside) Fail(pos, "missing ']'");
    return out;
  }

  // The name inside NAME[...] up to ']'.
  std::string Name(size_t start) {
    const size_t close = text.find(']', pos);
    if (close == std::string::npos) Fail(start, "missing ']'");
    const std::string name = Trim(text.substr(pos, close - pos));
    if (name.empty()) Fail(start, "empty name in []");
    pos = close + 1;
    return name;
  }

  std::string Function(const std::string& word, size_t start) {
    const std::string upper = [&] {
      std::string u = word;
      for (char& ch : u) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
      return u;
    }();
    if (upper == "PARVAL" || upper == "MEAVAL") {
      const std::string name = Name(start);
      const bool parameter = upper == "PARVAL";
      const std::string* to = Lookup(parameter ? names.parameters : names.measures, name);
      if (!to) Fail(start, std::string("unknown ") + (parameter ? "parameter" : "measure") + " '" + name + "' in " + word + "[]");
      return *to;
    }
    if (upper == "SIMTIME") {
      while (pos < text.size() && text[pos] == ' ') ++pos;
      if (pos >= text.size() || text[pos] != ']') Fail(start, "SIMTIME[] takes no argument");
      ++pos;
      return "t";
    }
    if (upper == "SPL") {
      const std::string x = Run(true);
      if (pos >= text.size() || text[pos] != ',') Fail(start, "SPL[x, name] needs two arguments");
      ++pos;
      const std::string name = Name(start);
      const std::string* to = Lookup(names.splines, name);
      if (!to) Fail(start, "unknown spline '" + name + "' in SPL[]");
      return "spline(" + *to + ", " + Trim(x) + ")";
    }
    Fail(start, "unknown FreeDyn function '" + word + "[...]' (known: PARVAL[], MEAVAL[], SIMTIME[], SPL[x, name])");
  }
};

}  // namespace

std::string TranslateFreeDynExpression(const std::string& text, const FreeDynNames& names, int* column) {
  Translator t{text, names};
  try {
    return t.Run(false);
  } catch (const std::pair<int, std::string>& e) {
    if (column) *column = e.first;
    throw std::invalid_argument(e.second);
  }
}

// ---- the reader -------------------------------------------------------------------------

namespace {

class FreeDynReader {
 public:
  FreeDynReader(std::string file, const LoadOptions& options) : file_(std::move(file)), options_(options) {}

  Model Read(const std::string& text) {
    Split(text);
    model_.file = file_;
    model_.name = std::filesystem::path(file_).stem().string();
    pending_.push_back(Marker{"O", -1, Vec3::Zero(), Mat3::Identity(), SourceLocation{file_, 0, 0}});
    // Names first (expressions may refer to elements defined further down), then the
    // elements in dependency order.
    for (const Block& b : blocks_) Check(b);
    for (const Block& b : blocks_)
      if (b.category == "DataObject" && b.type == "Parameter") ReadParameter(b);
    ApplyOverrides();
    for (const Block& b : blocks_)
      if (b.category == "DataObject" && b.type == "Spline_1D") ReadSpline(b);
    for (const Block& b : blocks_)
      if (b.category == "Body") ReadBody(b);
    for (const Block& b : blocks_)
      if (b.category == "Measure") NameMeasure(b);
    for (const Block& b : blocks_)
      if (b.category == "Measure") ReadMeasure(b);
    for (const Block& b : blocks_)
      if (b.category == "Constraint") ReadConstraint(b);
    for (const Block& b : blocks_)
      if (b.category == "Force") ReadForce(b);
    for (const Block& b : blocks_)
      if (b.category == "Simulation") ReadSimulation(b);
    for (const Block& b : blocks_)
      if (b.category == "Solver") ReadSolver(b);
    Finish();
    return std::move(model_);
  }

 private:
  // ---- failures ---------------------------------------------------------------------------

  SourceLocation At(int line, int column) const { return SourceLocation{file_, line, column}; }
  [[noreturn]] void Fail(int line, int column, const std::string& element, const std::string& what) const {
    throw ModelError(At(line, column), element, what);
  }
  [[noreturn]] void Fail(const Entry& e, const std::string& element, const std::string& what) const {
    Fail(e.line, e.value_column, element, "'" + e.key + "': " + what);
  }
  [[noreturn]] void Fail(const Block& b, const std::string& what) const {
    Fail(b.line, b.column, Element(b), what);
  }

  // "Body 'mass_1'" (or "Body Rigid_EulerParameter_PAI" without a name).
  static std::string Element(const Block& b) {
    for (const Entry& e : b.entries)
      if (e.key == "Name" && !e.value.empty()) return b.category + " '" + e.value + "'";
    return b.category + " " + b.type;
  }

  // ---- splitting into blocks ---------------------------------------------------------------

  void Split(const std::string& text) {
    std::istringstream in(text);
    std::string raw;
    int line = 0;
    Block* open = nullptr;
    while (std::getline(in, raw)) {
      ++line;
      if (!raw.empty() && raw.back() == '\r') raw.pop_back();
      if (line == 1 && raw.size() >= 3 && raw.compare(0, 3, "\xEF\xBB\xBF") == 0) raw = std::string(3, ' ') + raw.substr(3);
      const std::string t = Trim(raw);
      if (t.empty() || t[0] == '%') continue;
      const int column = static_cast<int>(raw.find_first_not_of(" \t")) + 1;
      if (!open) {
        if (t.compare(0, 3, "End") == 0 && t.find('=') == std::string::npos) {
          Fail(line, column, "model", "'" + t + "' closes no block");
        }
        std::istringstream words(t);
        Block b;
        std::string extra;
        words >> b.category >> b.type >> extra;
        if (b.type.empty() || !extra.empty() || t.find('=') != std::string::npos) {
          Fail(line, column, "model", "expected a block header 'CATEGORY TYPE' (e.g. 'Body Rigid_EulerParameter_PAI'), got '" + t + "'");
        }
        if (std::find(Categories().begin(), Categories().end(), b.category) == Categories().end()) {
          Fail(line, column, "model", "unknown block '" + t + "' (blocks read: " + Join(Categories()) + ")");
        }
        b.line = line;
        b.column = column;
        blocks_.push_back(b);
        open = &blocks_.back();
        continue;
      }
      if (t == "End" + open->category) {
        open = nullptr;
        continue;
      }
      const size_t eq = raw.find('=');
      if (eq == std::string::npos) {
        if (t.compare(0, 3, "End") == 0) {
          Fail(line, column, Element(*open), "expected 'End" + open->category + "' to close the block opened at line " +
                                                 std::to_string(open->line) + ", got '" + t + "'");
        }
        Fail(line, column, Element(*open), "expected 'Key = value', got '" + t + "'");
      }
      Entry e;
      e.key = Trim(raw.substr(0, eq));
      e.value = Trim(raw.substr(eq + 1));
      e.line = line;
      e.key_column = column;
      const size_t v = raw.find_first_not_of(" \t", eq + 1);
      e.value_column = static_cast<int>(v == std::string::npos ? eq + 2 : v + 1);
      if (e.key.empty()) Fail(line, column, Element(*open), "a key is missing before '='");
      open->entries.push_back(e);
    }
    if (open) {
      Fail(open->line, open->column, Element(*open),
           "the block is not closed: 'End" + open->category + "' is missing before the end of the file");
    }
  }

  // ---- keys ---------------------------------------------------------------------------------

  // The keys a block may have, per category and type (besides ID and Name).
  static std::vector<std::string> KnownKeys(const Block& b) {
    const std::string& c = b.category;
    const std::string& t = b.type;
    if (c == "Header") return {};
    if (c == "Body")
      return {"InitialVelocityVector", "InitialOmegaVector", "Mass", "LocationCenterMass", "Inertia", "OrientationPAI",
              "Geometry", "Geometry Position", "Geometry Orientation", "Geometry Color"};
    if (c == "Constraint") return {"BodyIDs", "dxFixed", "dyFixed", "dzFixed", "axFixed", "ayFixed", "azFixed", "Location", "ConstraintOrientation"};
    if (c == "Force" && t == "GenericForce")
      return {"BodyIDs", "PointOfApplication_Body1", "PointOfApplication_Body2", "ForceDirectionType", "ForceDirection", "ForceExpression"};
    if (c == "Force" && t == "GenericTorque") return {"BodyIDs", "AxisType", "Axis", "TorqueExpression"};
    if (c == "Force" && t == "Gravity") return {"GravityAccVector", "ActivationTime"};
    if (c == "DataObject" && t == "Parameter") return {"InitialValue"};
    if (c == "DataObject" && t == "Spline_1D") return {"InterpolationType", "PathToSplineData", "NumberOfHeaderLines", "ColumnXData", "ColumnYData"};
    if (c == "Measure" && t == "Translational")
      return {"BodyIDs", "MeasureMode", "MeasureCoordinate", "MeasureLocation_Body1", "MeasureLocation_Body2", "UseInitialValueAsOffset"};
    if (c == "Measure" && t == "Rotational")
      return {"BodyIDs", "MeasureMode", "MeasureCoordinate", "MeasureOrientation", "UseInitialValueAsOffset"};
    if (c == "Simulation")
      return {"SimulationTimeBegin", "SimulationTimeEnd", "OutputTimeBegin", "OutputTimeStepSize", "InitialPositionFromFile", "InitialVelocityFromFile"};
    if (c == "Solver") return {"Alpha", "GlobalErrorTolerance", "SolverMaxTimeStep", "ModifyNewmark"};
    return {};
  }

  // The block's type is one read here, and every key is known or ignored, each once.
  void Check(const Block& b) const {
    static const std::map<std::string, std::vector<std::string>> types = {
        {"Header", {}},  // any type
        {"Body", {"Rigid_EulerParameter_PAI"}},
        {"Constraint", {"Generic"}},
        {"Force", {"GenericForce", "GenericTorque", "Gravity"}},
        {"DataObject", {"Parameter", "Spline_1D"}},
        {"Measure", {"Translational", "Rotational"}},
        {"Simulation", {"Dynamic"}},
        {"Solver", {"HHT"}},
        {"Globals", {}}};
    const std::vector<std::string>& allowed = types.at(b.category);
    if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), b.type) == allowed.end()) {
      Fail(b, "block type '" + b.category + " " + b.type + "' is not read by this program (" + b.category +
                  " blocks read: " + Join(allowed) + "); write this element in the YAML model format instead");
    }
    if (b.category == "Globals") return;  // display settings of FreeDyn's user interface
    std::vector<std::string> known = KnownKeys(b);
    known.insert(known.begin(), {"ID", "Name"});
    if (b.category == "Header") known.clear();
    std::set<std::string> seen;
    for (const Entry& e : b.entries) {
      bool ok = std::find(known.begin(), known.end(), e.key) != known.end();
      for (const auto& [category, key] : IgnoredFreeDynKeys()) ok = ok || (category == b.category && key == e.key);
      if (!ok) {
        Fail(e.line, e.key_column, Element(b),
             "unknown key '" + e.key + "' in a '" + b.category + " " + b.type + "' block (keys read: " + Join(known) + ")");
      }
      if (!seen.insert(e.key).second) Fail(e.line, e.key_column, Element(b), "key '" + e.key + "' is given twice");
    }
  }

  static const Entry* Find(const Block& b, const std::string& key) {
    for (const Entry& e : b.entries)
      if (e.key == key) return &e;
    return nullptr;
  }
  const Entry& Required(const Block& b, const std::string& key) const {
    const Entry* e = Find(b, key);
    if (!e) Fail(b, "missing required key '" + key + "'");
    return *e;
  }
  std::string Value(const Block& b, const std::string& key) const {
    const Entry* e = Find(b, key);
    return e ? e->value : std::string();
  }

  double Number(const Entry& e, const std::string& element, const std::string& text) const {
    const std::string t = Trim(text);
    char* end = nullptr;
    errno = 0;
    const double x = std::strtod(t.c_str(), &end);
    if (t.empty() || end != t.c_str() + t.size() || !std::isfinite(x)) {
      Fail(e, element, "expected a number, got '" + t + "'");
    }
    return x;
  }
  double Number(const Entry& e, const std::string& element) const { return Number(e, element, e.value); }

  std::vector<double> Numbers(const Entry& e, const std::string& element, size_t n) const {
    std::vector<double> out;
    std::string item;
    std::istringstream in(e.value);
    while (std::getline(in, item, ',')) out.push_back(Number(e, element, item));
    if (!e.value.empty() && e.value.back() == ',') out.push_back(Number(e, element, ""));
    if (out.size() != n) {
      Fail(e, element, "expected " + std::to_string(n) + " numbers separated by commas, got " + std::to_string(out.size()));
    }
    return out;
  }
  Vec3 Vector(const Entry& e, const std::string& element) const {
    const std::vector<double> v = Numbers(e, element, 3);
    return Vec3(v[0], v[1], v[2]);
  }
  Vec3 Vector(const Block& b, const std::string& key, const Vec3& default_value) const {
    const Entry* e = Find(b, key);
    return e ? Vector(*e, Element(b)) : default_value;
  }
  bool YesNo(const Entry& e, const std::string& element) const {
    const std::string v = Lower(e.value);
    if (v == "yes" || v == "1" || v == "true") return true;
    if (v == "no" || v == "0" || v == "false") return false;
    Fail(e, element, "expected yes or no, got '" + e.value + "'");
  }
  bool YesNo(const Block& b, const std::string& key, bool default_value) const {
    const Entry* e = Find(b, key);
    return e ? YesNo(*e, Element(b)) : default_value;
  }

  // A 3x3 matrix written row by row whose rows are axes in world coordinates -> the
  // rotation from those axes to world (its transpose), made exactly orthonormal (the
  // files carry 6 digits). Identity when the key is absent.
  Mat3 Axes(const Block& b, const std::string& key) const {
    const Entry* e = Find(b, key);
    if (!e) return Mat3::Identity();
    const std::vector<double> v = Numbers(*e, Element(b), 9);
    Mat3 rows;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) rows(r, c) = v[3 * r + c];
    const Mat3 A = rows.transpose();
    const double error = (A.transpose() * A - Mat3::Identity()).cwiseAbs().maxCoeff();
    if (!(error <= 1e-4)) {
      Fail(*e, Element(b), "the 9 numbers are not an orthonormal matrix (|R R^T - I| = " + Num(error) + ", tolerance 1e-4)");
    }
    if (!(A.determinant() > 0)) Fail(*e, Element(b), "the matrix is a reflection (determinant < 0), not a rotation");
    // The nearest rotation (polar decomposition), then through Euler parameters so that
    // it is the same matrix a body with these Euler parameters has.
    const Eigen::JacobiSVD<Mat3> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Quat q = QuaternionFromMatrix(svd.matrixU() * svd.matrixV().transpose());
    q.normalize();
    return RotationMatrix(q);
  }

  // ---- names ----------------------------------------------------------------------------------

  // A name usable for bodies, markers, joints and forces: letters, digits, '_', '-'.
  static std::string PlainName(const std::string& raw, const std::string& fallback) {
    std::string s;
    for (char c : raw) s += (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-') ? c : '_';
    return s.empty() ? fallback : s;
  }
  static std::string Unique(std::string name, const std::set<std::string>& taken) {
    if (!taken.count(name)) return name;
    for (int k = 2;; ++k) {
      const std::string candidate = name + "_" + std::to_string(k);
      if (!taken.count(candidate)) return candidate;
    }
  }
  // A name usable in expressions (parameters and measures share them).
  std::string ExpressionName(const std::string& raw, const std::string& fallback) {
    std::string s;
    for (char c : raw) s += (std::isalnum(static_cast<unsigned char>(c)) || c == '_') ? c : '_';
    if (s.empty()) s = fallback;
    if (!IsIdentifier(s)) s = "_" + s;
    if (IsReservedWord(s)) s += "_";
    s = Unique(s, expression_names_);
    expression_names_.insert(s);
    return s;
  }

  std::string NameOf(const Block& b) const { return Value(b, "Name"); }

  // ---- parameters and splines -----------------------------------------------------------------

  void ReadParameter(const Block& b) {
    const std::string element = Element(b);
    const std::string raw = NameOf(b);
    if (raw.empty()) Fail(b, "missing 'Name' (PARVAL[] refers to a parameter by its name)");
    if (Lookup(names_.parameters, raw)) Fail(Required(b, "Name"), element, "duplicate parameter name");
    Parameter p;
    p.name = ExpressionName(raw, "parameter");
    p.value = Number(Required(b, "InitialValue"), element);
    p.where = At(b.line, b.column);
    names_.parameters.emplace_back(raw, p.name);
    model_.parameters.push_back(p);
  }

  void ApplyOverrides() {
    for (const auto& [name, value] : options_.parameter_overrides) {
      bool found = false;
      for (size_t k = 0; k < model_.parameters.size(); ++k) {
        if (names_.parameters[k].first == name || model_.parameters[k].name == name) {
          model_.parameters[k].value = value;
          found = true;
        }
      }
      if (!found) {
        std::vector<std::string> names;
        for (const Parameter& p : model_.parameters) names.push_back(p.name);
        throw ModelError(SourceLocation{file_, 0, 0}, "parameter '" + name + "'",
                         "cannot set '" + name + "=" + Num(value) + "': the model has no such parameter (parameters: " +
                             Join(names) + ")");
      }
    }
  }

  int Count(const Block& b, const std::string& key, int default_value) const {
    const Entry* e = Find(b, key);
    if (!e) return default_value;
    const double v = Number(*e, Element(b));
    if (!(v >= 0 && v == std::floor(v) && v <= 1e6)) Fail(*e, Element(b), "expected a whole number >= 0, got '" + e->value + "'");
    return static_cast<int>(v);
  }

  void ReadSpline(const Block& b) {
    const std::string element = Element(b);
    const std::string raw = NameOf(b);
    if (raw.empty()) Fail(b, "missing 'Name' (SPL[] refers to a spline by its name)");
    if (Lookup(names_.splines, raw)) Fail(Required(b, "Name"), element, "duplicate spline name");
    SplineDef def;
    std::string name;
    for (char c : raw) name += (std::isalnum(static_cast<unsigned char>(c)) || c == '_') ? c : '_';
    if (!IsIdentifier(name)) name = "_" + name;
    std::set<std::string> taken;
    for (const SplineDef& s : model_.splines) taken.insert(s.name);
    def.name = Unique(name, taken);
    def.where = At(b.line, b.column);
    Interpolation kind = Interpolation::kAkima;
    if (const Entry* e = Find(b, "InterpolationType")) {
      const std::string v = Lower(e->value);
      if (v == "akima") kind = Interpolation::kAkima;
      else if (v == "linear") kind = Interpolation::kLinear;
      else if (v == "cubic") kind = Interpolation::kCubic;
      else if (v == "zccspl")
        Fail(*e, element, "interpolation 'zccspl' (FreeDyn's cubic spline with zero end conditions) is not available here "
                          "(available: akima, linear, cubic = natural cubic)");
      else Fail(*e, element, "unknown interpolation '" + e->value + "' (available: akima, linear, cubic)");
    }
    const Entry& f = Required(b, "PathToSplineData");
    if (f.value.empty()) Fail(f, element, "the data file name is empty");
    std::filesystem::path path(f.value);
    if (path.is_relative()) path = std::filesystem::path(file_).parent_path() / path;
    def.file = path.lexically_normal().string();
    const int header = Count(b, "NumberOfHeaderLines", 0);
    const int x_column = Count(b, "ColumnXData", 0), y_column = Count(b, "ColumnYData", 1);
    std::error_code ignored;
    if (!std::filesystem::is_regular_file(path, ignored)) {
      Fail(f, element, "data file '" + def.file + "' not found ('" + f.value + "' is relative to the model file)");
    }
    std::vector<double> x, y;
    std::vector<int> lines;
    try {
      ReadSplineFile(def.file, header, x_column, y_column, &x, &y, &lines);
    } catch (const std::exception& e) {
      Fail(f, element, std::string("in data file: ") + e.what());
    }
    if (x.size() < 2) Fail(f, element, "data file '" + def.file + "' has fewer than 2 points; a spline needs at least 2");
    for (size_t k = 1; k < x.size(); ++k) {
      if (!(x[k] > x[k - 1])) {
        Fail(f, element, "in data file: " + def.file + ":" + std::to_string(lines[k]) + ": x = " + Num(x[k]) +
                             " is not greater than the x before it; x must be strictly increasing");
      }
    }
    def.spline = Spline(std::move(x), std::move(y), kind);
    names_.splines.emplace_back(raw, def.name);
    model_.splines.push_back(std::move(def));
  }

  // ---- bodies and markers -----------------------------------------------------------------------

  void ReadBody(const Block& b) {
    const std::string element = Element(b);
    const Entry& id = Required(b, "ID");
    if (id.value.empty() || id.value == "0") Fail(id, element, "a body needs an ID other than 0 (0 is ground)");
    if (body_ids_.count(id.value)) Fail(id, element, "duplicate body ID (also used at line " + std::to_string(body_ids_[id.value].second) + ")");
    Body body;
    std::set<std::string> taken{"ground"};
    for (const Body& other : model_.bodies) taken.insert(other.name);
    body.name = Unique(PlainName(NameOf(b), "body_" + std::to_string(model_.bodies.size() + 1)), taken);
    body.where = At(b.line, b.column);
    const Entry& mass = Required(b, "Mass");
    body.mass = Number(mass, element);
    if (body.mass < 0) Fail(mass, element, "mass must be >= 0, got " + Num(body.mass));
    const Entry& inertia = Required(b, "Inertia");
    const Vec3 principal = Vector(inertia, element);
    if (principal.minCoeff() < 0) Fail(inertia, element, "principal moments of inertia must be >= 0");
    body.inertia = principal.asDiagonal();
    std::string why;
    if (!IsPhysicalInertia(body.inertia, &why)) Fail(inertia, element, why);
    body.position = Vector(Required(b, "LocationCenterMass"), element);
    const Mat3 A = Axes(b, "OrientationPAI");
    body.orientation = QuaternionFromMatrix(A);
    body.orientation.normalize();
    body.velocity = Vector(b, "InitialVelocityVector", Vec3::Zero());
    body.angular_velocity = Vector(b, "InitialOmegaVector", Vec3::Zero());
    const int index = static_cast<int>(model_.bodies.size());
    body_ids_[id.value] = {index, id.line};
    body.cm_marker = static_cast<int>(pending_.size());
    pending_.push_back(Marker{"cm", index, Vec3::Zero(), Mat3::Identity(), body.where});
    ReadGeometry(b, &body, A);
    model_.bodies.push_back(body);
  }

  // `Geometry = Box a b c` (edge lengths), placed by `Geometry Position` (world, t = 0;
  // default the centre of mass) and `Geometry Orientation` (rows: the box's axes in
  // world), coloured by `Geometry Color` (r, g, b, a in 0..255). Other Geometry values
  // are not drawn (the body gets the default drawing; docs/freedyn.md).
  void ReadGeometry(const Block& b, Body* body, const Mat3& A) const {
    const Entry* g = Find(b, "Geometry");
    if (!g) return;
    std::istringstream words(g->value);
    std::string kind;
    words >> kind;
    if (Lower(kind) != "box") return;
    std::vector<double> size;
    std::string word;
    while (words >> word) size.push_back(Number(*g, Element(b), word));
    if (size.size() != 3 || !(std::min({size[0], size[1], size[2]}) > 0))
      Fail(*g, Element(b), "'Geometry = Box' takes three edge lengths > 0, got '" + g->value + "'");
    VisualShape v;
    v.kind = VisualKind::kBox;
    v.size = Vec3(size[0], size[1], size[2]);
    v.position = A.transpose() * (Vector(b, "Geometry Position", body->position) - body->position);
    for (int k = 0; k < 3; ++k)
      if (std::abs(v.position[k]) < 1e-14 * std::max(1.0, body->position.norm())) v.position[k] = 0;
    v.orientation = A.transpose() * Axes(b, "Geometry Orientation");
    if ((v.orientation - Mat3::Identity()).cwiseAbs().maxCoeff() <= 1e-14) v.orientation = Mat3::Identity();
    if (const Entry* c = Find(b, "Geometry Color")) {
      const std::vector<double> rgba = Numbers(*c, Element(b), 4);
      for (int k = 0; k < 4; ++k) {
        if (!(rgba[k] >= 0 && rgba[k] <= 255)) Fail(*c, Element(b), "'Geometry Color' takes 4 numbers in 0..255");
        v.color[k] = rgba[k] / 255.0;
      }
    }
    v.where = At(g->line, g->key_column);
    body->visuals.push_back(v);
  }

  // Body index for an ID ("0": ground, -1).
  int BodyOf(const Entry& e, const std::string& element, const std::string& id) const {
    const std::string t = Trim(id);
    if (t == "0") return -1;
    auto it = body_ids_.find(t);
    if (it == body_ids_.end()) Fail(e, element, "no body has the ID '" + t + "' (0 is ground)");
    return it->second.first;
  }
  std::pair<int, int> BodyPair(const Block& b) const {
    const Entry& e = Required(b, "BodyIDs");
    const size_t comma = e.value.find(',');
    if (comma == std::string::npos || e.value.find(',', comma + 1) != std::string::npos) {
      Fail(e, Element(b), "expected two body IDs 'ID1, ID2' (0 for ground), got '" + e.value + "'");
    }
    const int b1 = BodyOf(e, Element(b), e.value.substr(0, comma));
    const int b2 = BodyOf(e, Element(b), e.value.substr(comma + 1));
    if (b1 == b2) {
      Fail(e, Element(b), "both IDs name " + (b1 < 0 ? std::string("ground") : "body '" + model_.bodies[b1].name + "'") +
                              "; the element connects two different bodies");
    }
    return {b1, b2};
  }

  // The axes of `body` (-1: ground) in world, at t = 0.
  Mat3 BodyAxes(int body) const {
    return body < 0 ? Mat3::Identity() : RotationMatrix(model_.bodies[body].orientation);
  }

  // A marker on `body` (-1: ground) at the world point `p` with axes `R` (to world), both
  // at t = 0; reuses the centre of mass, ground.O or an equal marker on the same body.
  int MarkerAt(int body, const Vec3& p, const Mat3& R, const std::string& name, const SourceLocation& where) {
    Vec3 local = p;
    Mat3 axes = R;
    if (body >= 0) {
      const Mat3 A = RotationMatrix(model_.bodies[body].orientation);
      local = A.transpose() * (p - model_.bodies[body].position);
      axes = A.transpose() * R;
    }
    // Round-off of the transformation (1e-15) must not create a marker next to the centre.
    for (int k = 0; k < 3; ++k)
      if (std::abs(local[k]) < 1e-14 * std::max(1.0, p.norm())) local[k] = 0;
    if ((axes - Mat3::Identity()).cwiseAbs().maxCoeff() <= 1e-14) axes = Mat3::Identity();
    std::set<std::string> taken;
    for (size_t k = 0; k < pending_.size(); ++k) {
      const Marker& m = pending_[k];
      if (m.body != body) continue;
      if ((m.position - local).cwiseAbs().maxCoeff() <= 1e-14 && (m.orientation - axes).cwiseAbs().maxCoeff() <= 1e-14) {
        return static_cast<int>(k);
      }
      taken.insert(m.name);
    }
    pending_.push_back(Marker{Unique(PlainName(name, "m"), taken), body, local, axes, where});
    return static_cast<int>(pending_.size()) - 1;
  }

  // ---- measures ---------------------------------------------------------------------------------

  void NameMeasure(const Block& b) {
    const std::string raw = NameOf(b);
    if (raw.empty()) Fail(b, "missing 'Name' (MEAVAL[] refers to a measure by its name)");
    if (Lookup(names_.measures, raw)) Fail(Required(b, "Name"), Element(b), "duplicate measure name");
    names_.measures.emplace_back(raw, ExpressionName(raw, "measure"));
  }

  void ReadMeasure(const Block& b) {
    const std::string element = Element(b);
    Measure m;
    m.name = *Lookup(names_.measures, NameOf(b));
    m.where = At(b.line, b.column);
    const auto [b1, b2] = BodyPair(b);
    const bool rotational = b.type == "Rotational";
    m.type = rotational ? MeasureType::kRotational : MeasureType::kTranslational;
    m.frame = MeasureFrame::kWorld;
    const Entry& mode = Required(b, "MeasureMode");
    const std::string v = Lower(mode.value);
    if (v == "disp") m.quantity = Quantity::kPosition;
    else if (v == "vel") m.quantity = Quantity::kVelocity;
    else if (v == "acc") m.quantity = Quantity::kAcceleration;
    else Fail(mode, element, "unknown measure mode '" + mode.value + "' (known: disp, vel, acc)");
    const Entry& coordinate = Required(b, "MeasureCoordinate");
    const std::string c = Lower(coordinate.value);
    if (c == "x") m.component = Component::kX;
    else if (c == "y") m.component = Component::kY;
    else if (c == "z") m.component = Component::kZ;
    else if (c == "xyz" && !rotational) m.component = Component::kDistance;
    else Fail(coordinate, element, "unknown coordinate '" + coordinate.value + "' (known: X, Y, Z" + (rotational ? ")" : ", XYZ)"));
    m.offset_initial = YesNo(b, "UseInitialValueAsOffset", false);
    if (rotational) {
      // Both frames are the given axes (world, t = 0) fixed on their bodies; the angle is
      // body 1's rotation relative to body 2 about the chosen axis of those axes.
      const Mat3 R = Axes(b, "MeasureOrientation");
      const Vec3 zero = Vec3::Zero();
      const Vec3 p1 = b1 >= 0 ? model_.bodies[b1].position : zero, p2 = b2 >= 0 ? model_.bodies[b2].position : zero;
      m.i = MarkerAt(b1, p1, R, m.name, m.where);
      m.j = MarkerAt(b2, p2, R, m.name, m.where);
    } else {
      m.i = MarkerAt(b1, Vector(Required(b, "MeasureLocation_Body1"), element), BodyAxes(b1), m.name, m.where);
      m.j = MarkerAt(b2, Vector(Required(b, "MeasureLocation_Body2"), element), BodyAxes(b2), m.name, m.where);
    }
    model_.measures.push_back(m);
  }

  // ---- constraints ------------------------------------------------------------------------------

  void ReadConstraint(const Block& b) {
    const std::string element = Element(b);
    Joint joint;
    std::set<std::string> taken;
    for (const Joint& other : model_.joints) taken.insert(other.name);
    joint.name = Unique(PlainName(NameOf(b), "joint_" + std::to_string(model_.joints.size() + 1)), taken);
    joint.type = JointType::kGeneric;
    joint.where = At(b.line, b.column);
    const auto [b1, b2] = BodyPair(b);
    const std::pair<const char*, unsigned> locks[] = {{"dxFixed", kLockX},  {"dyFixed", kLockY},  {"dzFixed", kLockZ},
                                                      {"axFixed", kLockRx}, {"ayFixed", kLockRy}, {"azFixed", kLockRz}};
    for (const auto& [key, bit] : locks)
      if (YesNo(b, key, false)) joint.locks |= bit;
    if (joint.locks == 0) Fail(b, "the constraint fixes nothing (every dxFixed ... azFixed is no)");
    const Vec3 location = Vector(Required(b, "Location"), element);
    const Mat3 R = Axes(b, "ConstraintOrientation");
    joint.i = MarkerAt(b1, location, R, joint.name, joint.where);
    joint.j = MarkerAt(b2, location, R, joint.name, joint.where);
    model_.joints.push_back(joint);
  }

  // ---- forces -------------------------------------------------------------------------------------

  SymbolTable Symbols() const {
    SymbolTable s;
    for (const Parameter& p : model_.parameters) s.parameters.push_back(p.name);
    for (const Measure& m : model_.measures) s.measures.push_back(m.name);
    for (const SplineDef& d : model_.splines) s.splines.push_back(d.name);
    s.allow_time = true;
    return s;
  }

  Expression ParseValue(const Entry& e, const std::string& element, const std::string& text) const {
    try {
      return Expression::Parse(text, Symbols());
    } catch (const ExpressionError& error) {
      Fail(e, element, "in expression '" + text + "' (translated from '" + e.value + "'): " + error.what());
    }
  }

  // The scalar expression of `key`, translated.
  std::string Translated(const Entry& e, const std::string& element) const {
    if (e.value.empty()) Fail(e, element, "the expression is empty");
    int column = 0;
    try {
      return TranslateFreeDynExpression(e.value, names_, &column);
    } catch (const std::invalid_argument& error) {
      Fail(e.line, e.value_column + column - 1, element, "'" + e.key + "': " + error.what());
    }
  }

  // Components within 1e-14 of 0, 1 or -1 (round-off of a rotation) set to that value.
  static Vec3 Snap(Vec3 u) {
    for (int k = 0; k < 3; ++k) {
      for (double v : {0.0, 1.0, -1.0})
        if (std::abs(u[k] - v) < 1e-14) u[k] = v;
    }
    return u;
  }

  // "d*(E)" with the shortest form for d = 0, 1, -1.
  static std::string Scaled(double d, const std::string& e) {
    if (d == 0) return "0";
    if (d == 1) return e;
    if (d == -1) return "-(" + e + ")";
    return Num(d) + "*(" + e + ")";
  }

  Vec3 Direction(const Entry& e, const std::string& element) const {
    const Vec3 d = Vector(e, element);
    if (!(d.norm() > 0)) Fail(e, element, "the direction must not be zero");
    return Snap(d / d.norm());
  }

  void ReadForce(const Block& b) {
    const std::string element = Element(b);
    if (b.type == "Gravity") {
      if (have_gravity_) Fail(b, "a second Force Gravity block; the model has one gravity");
      have_gravity_ = true;
      model_.gravity = Vector(Required(b, "GravityAccVector"), element);
      if (const Entry* t = Find(b, "ActivationTime")) {
        if (Number(*t, element) != 0) Fail(*t, element, "gravity switched on at a later time is not available here (only 0)");
      }
      return;
    }
    Force force;
    std::set<std::string> taken;
    for (const Force& other : model_.forces) taken.insert(other.name);
    force.name = Unique(PlainName(NameOf(b), "force_" + std::to_string(model_.forces.size() + 1)), taken);
    force.where = At(b.line, b.column);
    const auto [b1, b2] = BodyPair(b);
    if (b.type == "GenericTorque") {
      force.type = ForceType::kTorque;
      const Entry& expression = Required(b, "TorqueExpression");
      const std::string e = Translated(expression, element);
      Vec3 axis = Direction(Required(b, "Axis"), element);
      const Entry& type = Required(b, "AxisType");
      if (type.value == "SpaceFixed") {
        force.frame = ForceFrame::kWorld;
      } else if (type.value == "BodyFixed") {
        force.frame = ForceFrame::kI;
      } else {
        Fail(type, element, "unknown axis type '" + type.value + "' (known: SpaceFixed, BodyFixed)");
      }
      // The axis is given in world axes at t = 0; body-fixed, it turns with body 1.
      const Vec3 zero = Vec3::Zero();
      force.i = MarkerAt(b1, b1 >= 0 ? model_.bodies[b1].position : zero, BodyAxes(b1), force.name, force.where);
      force.j = MarkerAt(b2, b2 >= 0 ? model_.bodies[b2].position : zero, BodyAxes(b2), force.name, force.where);
      if (force.frame == ForceFrame::kI && b1 >= 0) axis = Snap(RotationMatrix(model_.bodies[b1].orientation).transpose() * axis);
      for (int c = 0; c < 3; ++c) force.value[c] = ParseValue(expression, element, Scaled(axis[c], e));
      model_.forces.push_back(force);
      return;
    }
    force.type = ForceType::kForce;
    const Entry& expression = Required(b, "ForceExpression");
    const std::string e = Translated(expression, element);
    force.i = MarkerAt(b1, Vector(Required(b, "PointOfApplication_Body1"), element), BodyAxes(b1), force.name, force.where);
    force.j = MarkerAt(b2, Vector(Required(b, "PointOfApplication_Body2"), element), BodyAxes(b2), force.name, force.where);
    const Entry& type = Required(b, "ForceDirectionType");
    if (type.value == "SpaceFixed" || type.value == "BodyFixed") {
      Vec3 d = Direction(Required(b, "ForceDirection"), element);
      force.frame = ForceFrame::kWorld;
      if (type.value == "BodyFixed") {
        force.frame = ForceFrame::kI;
        if (b1 >= 0) d = Snap(RotationMatrix(model_.bodies[b1].orientation).transpose() * d);
      }
      for (int c = 0; c < 3; ++c) force.value[c] = ParseValue(expression, element, Scaled(d[c], e));
    } else if (type.value == "In-line-of-sight") {
      // Along the line from point 1 to point 2: F (p2 - p1)/|p2 - p1| on body 1, from four
      // measures of p1 - p2 (world components and length) added to the model.
      // ForceDirection, if given, is FreeDyn's initial direction and is not needed.
      const char* parts[] = {"dx", "dy", "dz", "length"};
      const Component components[] = {Component::kX, Component::kY, Component::kZ, Component::kDistance};
      std::string names[4];
      for (int k = 0; k < 4; ++k) {
        Measure m;
        m.name = ExpressionName(force.name + "_" + parts[k], "line_of_sight");
        m.type = MeasureType::kTranslational;
        m.i = force.i;
        m.j = force.j;
        m.component = components[k];
        m.frame = MeasureFrame::kWorld;
        m.where = force.where;
        model_.measures.push_back(m);
        names[k] = m.name;
      }
      force.frame = ForceFrame::kWorld;
      for (int c = 0; c < 3; ++c) {
        force.value[c] = ParseValue(expression, element, "-(" + e + ")*" + names[c] + "/" + names[3]);
      }
    } else {
      Fail(type, element, "unknown force direction type '" + type.value + "' (known: SpaceFixed, BodyFixed, In-line-of-sight)");
    }
    model_.forces.push_back(force);
  }

  // ---- simulation and solver ----------------------------------------------------------------------

  void ReadSimulation(const Block& b) {
    const std::string element = Element(b);
    if (have_simulation_) Fail(b, "a second Simulation block");
    have_simulation_ = true;
    auto zero = [&](const char* key, const char* what) {
      if (const Entry* e = Find(b, key)) {
        if (Number(*e, element) != 0) Fail(*e, element, std::string(what) + " is not available here (only 0)");
      }
    };
    zero("SimulationTimeBegin", "a start time other than 0");
    zero("OutputTimeBegin", "an output start time other than 0");
    zero("InitialPositionFromFile", "initial positions from a file");
    zero("InitialVelocityFromFile", "initial velocities from a file");
    SimulationSettings& s = model_.simulation;
    if (const Entry* e = Find(b, "SimulationTimeEnd")) {
      s.t_end = Number(*e, element);
      if (!(s.t_end > 0)) Fail(*e, element, "must be > 0, got " + e->value);
    }
    if (const Entry* e = Find(b, "OutputTimeStepSize")) {
      s.output_step = Number(*e, element);
      if (!(s.output_step > 0)) Fail(*e, element, "must be > 0, got " + e->value);
      output_step_entry_ = e;
    }
    const double rows = s.t_end / s.output_step;
    if (!(rows <= kMaxOutputRows)) {
      const Entry* e = output_step_entry_ ? output_step_entry_ : Find(b, "SimulationTimeEnd");
      const std::string what = "SimulationTimeEnd " + Num(s.t_end) + " with OutputTimeStepSize " +
                               Num(s.output_step) + " gives " + Rounded(rows) + " output rows; at most " +
                               Rounded(kMaxOutputRows) + " (make OutputTimeStepSize larger)";
      if (e) Fail(*e, element, what);
      Fail(b, what);
    }
  }

  void ReadSolver(const Block& b) {
    const std::string element = Element(b);
    if (have_solver_) Fail(b, "a second Solver block");
    have_solver_ = true;
    solver_ = &b;
  }

  // The solver's settings need the output step (the HHT step is at most one output step).
  void ApplySolver() {
    if (!solver_) return;
    const Block& b = *solver_;
    const std::string element = Element(b);
    SimulationSettings& s = model_.simulation;
    s.integrator = IntegratorKind::kHht;
    if (const Entry* e = Find(b, "Alpha")) {
      s.hht_alpha = Number(*e, element);
      if (!(s.hht_alpha >= -1.0 / 3.0 - 1e-15 && s.hht_alpha <= 0)) Fail(*e, element, "alpha must be in [-1/3, 0], got " + e->value);
    }
    if (const Entry* e = Find(b, "GlobalErrorTolerance")) {
      s.hht_tolerance = Number(*e, element);
      if (!(s.hht_tolerance > 0)) Fail(*e, element, "must be > 0, got " + e->value);
      s.hht_adaptive = true;
    }
    s.hht_step = s.output_step;
    if (const Entry* e = Find(b, "SolverMaxTimeStep")) {
      const double h = Number(*e, element);
      if (!(h > 0)) Fail(*e, element, "must be > 0, got " + e->value);
      s.hht_step = std::min(h, s.output_step);
    }
    const double min_step = dae::HhtOptions().min_step;
    if (!(s.hht_step >= min_step)) {
      const Entry* e = Find(b, "SolverMaxTimeStep");
      if (!e || s.output_step < Number(*e, element)) e = output_step_entry_;
      const std::string what = "the HHT step " + Num(s.hht_step) +
                               " (the smaller of SolverMaxTimeStep and OutputTimeStepSize) is smaller than the "
                               "smallest step of the HHT integrator, " + Num(min_step);
      if (e) Fail(*e, element, what);
      Fail(b, what);
    }
    s.hht_modified = YesNo(b, "ModifyNewmark", s.hht_modified);
  }

  // ---- the model's markers in the loader's order ------------------------------------------------

  void Finish() {
    ApplySolver();
    // Ground markers first (ground.O at 0), then each body's: its centre of mass, then the
    // others in the order they were made.
    std::vector<int> order(pending_.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return pending_[a].body < pending_[b].body; });
    std::vector<int> index(pending_.size());
    for (size_t k = 0; k < order.size(); ++k) {
      Marker m = pending_[order[k]];
      m.name = (m.body < 0 ? std::string("ground") : model_.bodies[m.body].name) + "." + m.name;
      index[order[k]] = static_cast<int>(k);
      model_.markers.push_back(m);
    }
    for (Body& b : model_.bodies) b.cm_marker = index[b.cm_marker];
    for (Measure& m : model_.measures) m.i = index[m.i], m.j = index[m.j];
    for (Joint& j : model_.joints) j.i = index[j.i], j.j = index[j.j];
    for (Force& f : model_.forces) f.i = index[f.i], f.j = index[f.j];
  }

  std::string file_;
  const LoadOptions& options_;
  Model model_;
  std::vector<Block> blocks_;
  FreeDynNames names_;                  // FreeDyn names -> model names
  std::set<std::string> expression_names_;
  std::map<std::string, std::pair<int, int>> body_ids_;  // ID -> (body, line)
  std::vector<Marker> pending_;         // markers, names without the body part
  bool have_gravity_ = false, have_simulation_ = false, have_solver_ = false;
  const Block* solver_ = nullptr;
  const Entry* output_step_entry_ = nullptr;  // OutputTimeStepSize of the Simulation block
};

}  // namespace

Model LoadFreeDynModelFromString(const std::string& text, const std::string& file, const LoadOptions& options) {
  return FreeDynReader(file, options).Read(text);
}

Model LoadFreeDynModel(const std::string& path, const LoadOptions& options) {
  std::error_code ignored;
  if (std::filesystem::is_directory(path, ignored)) {
    throw ModelError(SourceLocation{path, 0, 0}, "model", "cannot read the file: it is a directory");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ModelError(SourceLocation{path, 0, 0}, "model", std::string("cannot open the file: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return LoadFreeDynModelFromString(text.str(), path, options);
}

Model LoadAnyModel(const std::string& path, const LoadOptions& options) {
  if (IsUrdfPath(path)) return LoadUrdfModel(path, options);
  return IsFreeDynPath(path) ? LoadFreeDynModel(path, options) : LoadModel(path, options);
}

}  // namespace mbdae::mbs
