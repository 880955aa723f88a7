// mbs::Model -> model file text (YAML, format 1). See model_writer.h.
#include "mbs/model_writer.h"

#include "dae/format.h"
#include "mbs/user_force.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "mbs/kinematics.h"

namespace mbdae::mbs {

std::string DoubleQuoted(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += static_cast<char>(c);
        }
    }
  }
  return out + "\"";
}

namespace {

// Shortest of 15 or 17 significant digits that reads back exactly.
std::string Num(double x) { return x == 0 ? "0" : FormatRoundTrip(x); }  // -0 too

// A YAML double-quoted scalar (JSON string syntax, which YAML reads alike).
std::string Quoted(const std::string& s) { return DoubleQuoted(s); }

std::string Vector(const Vec3& v) { return "[" + Num(v[0]) + ", " + Num(v[1]) + ", " + Num(v[2]) + "]"; }

// An expression: its text (quoted), or the number of an expression made with Constant().
std::string Expr(const Expression& e) {
  if (e.text().empty()) return Num(e.Evaluate(static_cast<const double*>(nullptr)));
  char* end = nullptr;
  const double x = std::strtod(e.text().c_str(), &end);
  if (end == e.text().c_str() + e.text().size() && std::isfinite(x)) return Num(x);
  return Quoted(e.text());
}

std::string Orientation(const Quat& q) {
  return "[" + Num(q[0]) + ", " + Num(q[1]) + ", " + Num(q[2]) + ", " + Num(q[3]) + "]";
}

bool IsIdentity(const Mat3& R) { return (R - Mat3::Identity()).cwiseAbs().maxCoeff() == 0; }

// The local part of a marker's full name "BODY.NAME".
std::string Local(const std::string& full) {
  const size_t dot = full.find('.');
  return dot == std::string::npos ? full : full.substr(dot + 1);
}

void WriteMarkers(std::ostringstream& s, const Model& model, int body, const char* indent) {
  bool any = false;
  for (size_t k = 0; k < model.markers.size(); ++k) {
    const Marker& m = model.markers[k];
    if (m.body != body) continue;
    if (body < 0 && k == 0) continue;                                   // ground.O
    if (body >= 0 && static_cast<int>(k) == model.bodies[body].cm_marker) continue;  // BODY.cm
    if (!any) s << indent << "markers:\n";
    any = true;
    s << indent << "  " << Local(m.name) << ": {position: " << Vector(m.position);
    if (!IsIdentity(m.orientation)) s << ", orientation: " << Orientation(QuaternionFromMatrix(m.orientation));
    s << "}\n";
  }
}

// `visual:` (drawing only; VisualShape in mbs/model.h): one flow mapping per shape.
void WriteVisuals(std::ostringstream& s, const std::vector<VisualShape>& visuals, const char* indent) {
  if (visuals.empty()) return;
  s << indent << "visual:\n";
  for (const VisualShape& v : visuals) {
    s << indent << "  - {shape: ";
    switch (v.kind) {
      case VisualKind::kBox: s << "box, size: " << Vector(v.size); break;
      case VisualKind::kSphere: s << "sphere, radius: " << Num(v.radius); break;
      case VisualKind::kCylinder: s << "cylinder, radius: " << Num(v.radius) << ", length: " << Num(v.length); break;
      case VisualKind::kCapsule: s << "capsule, radius: " << Num(v.radius) << ", length: " << Num(v.length); break;
      case VisualKind::kCone: s << "cone, radius: " << Num(v.radius) << ", length: " << Num(v.length); break;
      case VisualKind::kMesh: {
        // Absolute, so that the written file finds the mesh from wherever it is written.
        std::error_code ec;
        std::filesystem::path path = std::filesystem::absolute(v.mesh_file, ec);
        if (ec) path = v.mesh_file;
        s << "mesh, file: " << Quoted(path.lexically_normal().string());
        if (v.mesh_scale != 1) s << ", scale: " << Num(v.mesh_scale);
        break;
      }
    }
    if (v.position != Vec3::Zero()) s << ", position: " << Vector(v.position);
    if (!IsIdentity(v.orientation)) s << ", orientation: " << Orientation(QuaternionFromMatrix(v.orientation));
    s << ", color: [" << Num(v.color[0]) << ", " << Num(v.color[1]) << ", " << Num(v.color[2]) << ", "
      << Num(v.color[3]) << "]}\n";
  }
}

const char* InterpolationKey(Interpolation kind) { return InterpolationName(kind); }

const char* JointTypeName(JointType t) {
  switch (t) {
    case JointType::kFixed: return "fixed";
    case JointType::kSpherical: return "spherical";
    case JointType::kRevolute: return "revolute";
    case JointType::kPrismatic: return "prismatic";
    case JointType::kCylindrical: return "cylindrical";
    case JointType::kUniversal: return "universal";
    case JointType::kPlanar: return "planar";
    case JointType::kMotion: return "motion";
    case JointType::kGear: return "gear";
    default: return "generic";
  }
}

}  // namespace

std::string WriteModelYaml(const Model& model, const ModelWriterOptions& options) {
  std::ostringstream s;
  if (!options.source.empty()) s << "# written by mbdae from " << options.source << "\n";
  for (const std::string& note : model.notes) s << "# note: " << note << "\n";
  s << "format: 1\n";
  if (!model.name.empty()) s << "name: " << Quoted(model.name) << "\n";
  if (model.gravity != Vec3::Zero()) s << "gravity: " << Vector(model.gravity) << "\n";

  if (!model.parameters.empty()) {
    s << "parameters:\n";
    for (const Parameter& p : model.parameters) {
      s << "  " << p.name << ": " << (p.expression.empty() ? Num(p.value) : Quoted(p.expression)) << "\n";
    }
  }

  if (!model.splines.empty()) {
    s << "splines:\n";
    for (const SplineDef& d : model.splines) {
      const bool expressions = !d.x_expressions.empty() && d.x_expressions.size() == d.spline.x().size() &&
                               d.y_expressions.size() == d.spline.y().size();
      s << "  " << d.name << ":\n    x: [";
      for (size_t k = 0; k < d.spline.x().size(); ++k)
        s << (k ? ", " : "") << (expressions ? Expr(d.x_expressions[k]) : Num(d.spline.x()[k]));
      s << "]\n    y: [";
      for (size_t k = 0; k < d.spline.y().size(); ++k)
        s << (k ? ", " : "") << (expressions ? Expr(d.y_expressions[k]) : Num(d.spline.y()[k]));
      s << "]\n    interpolation: " << InterpolationKey(d.spline.kind()) << "\n";
    }
  }

  bool ground_markers = false;
  for (size_t k = 1; k < model.markers.size(); ++k) ground_markers = ground_markers || model.markers[k].body < 0;
  if (ground_markers || !model.ground_visuals.empty()) {
    s << "ground:\n";
    WriteMarkers(s, model, -1, "  ");
    WriteVisuals(s, model.ground_visuals, "  ");
  }

  if (!model.bodies.empty()) {
    s << "bodies:\n";
    for (size_t b = 0; b < model.bodies.size(); ++b) {
      const Body& body = model.bodies[b];
      s << "  - name: " << body.name << "\n";
      s << "    mass: " << Num(body.mass) << "\n";
      const Mat3& I = body.inertia;
      s << "    inertia: [" << Num(I(0, 0)) << ", " << Num(I(1, 1)) << ", " << Num(I(2, 2));
      if (I(0, 1) != 0 || I(0, 2) != 0 || I(1, 2) != 0) {
        s << ", " << Num(I(0, 1)) << ", " << Num(I(0, 2)) << ", " << Num(I(1, 2));
      }
      s << "]\n";
      s << "    position: " << Vector(body.position) << "\n";
      s << "    orientation: " << Orientation(body.orientation) << "\n";
      if (body.velocity != Vec3::Zero()) s << "    velocity: " << Vector(body.velocity) << "\n";
      if (body.angular_velocity != Vec3::Zero()) s << "    angular_velocity: " << Vector(body.angular_velocity) << "\n";
      WriteMarkers(s, model, static_cast<int>(b), "    ");
      WriteVisuals(s, body.visuals, "    ");
    }
  }

  if (!model.measures.empty()) {
    s << "measures:\n";
    for (const Measure& m : model.measures) {
      const bool rotational = m.type == MeasureType::kRotational;
      s << "  - name: " << m.name << "\n";
      if (m.type == MeasureType::kReaction) {
        const char* axis = m.component == Component::kX ? "x" : m.component == Component::kY ? "y" : "z";
        s << "    type: reaction\n";
        s << "    joint: " << model.joints[m.joint].name << "\n";
        s << "    component: " << (m.torque ? "r" : "") << axis << "\n";
        s << "    frame: " << (m.frame == MeasureFrame::kWorld ? "world" : "j") << "\n";
        continue;
      }
      s << "    type: " << (rotational ? "rotational" : "translational") << "\n";
      s << "    i: " << model.markers[m.i].name << "\n";
      s << "    j: " << model.markers[m.j].name << "\n";
      const char* axis = m.component == Component::kX   ? "x"
                         : m.component == Component::kY ? "y"
                         : m.component == Component::kZ ? "z"
                                                        : "distance";
      if (rotational) {
        s << "    axis: " << axis << "\n";
        s << "    quantity: "
          << (m.quantity == Quantity::kPosition   ? "angle"
              : m.quantity == Quantity::kVelocity ? "angular_velocity"
                                                  : "angular_acceleration")
          << "\n";
      } else {
        s << "    component: " << axis << "\n";
        s << "    frame: " << (m.frame == MeasureFrame::kWorld ? "world" : "j") << "\n";
        s << "    quantity: "
          << (m.quantity == Quantity::kPosition   ? "position"
              : m.quantity == Quantity::kVelocity ? "velocity"
                                                  : "acceleration")
          << "\n";
      }
      if (m.offset_initial) s << "    offset_initial: true\n";
    }
  }

  if (!model.joints.empty()) {
    s << "joints:\n";
    for (const Joint& j : model.joints) {
      s << "  - name: " << j.name << "\n";
      s << "    type: " << JointTypeName(j.type) << "\n";
      if (j.type == JointType::kMotion) {
        s << "    measure: " << model.measures[j.measures[0]].name << "\n";
        s << "    value: " << Expr(j.value) << "\n";
        continue;
      }
      if (j.type == JointType::kGear) {
        s << "    measures: [" << model.measures[j.measures[0]].name << ", "
          << model.measures[j.measures[1]].name << "]\n";
        s << "    ratio: " << Num(j.ratio) << "\n";
        continue;
      }
      s << "    i: " << model.markers[j.i].name << "\n";
      s << "    j: " << model.markers[j.j].name << "\n";
      if (j.type == JointType::kGeneric) {
        static const std::pair<unsigned, const char*> bits[] = {{kLockX, "x"},   {kLockY, "y"},   {kLockZ, "z"},
                                                                {kLockRx, "rx"}, {kLockRy, "ry"}, {kLockRz, "rz"}};
        s << "    lock: [";
        bool first = true;
        for (const auto& [bit, name] : bits) {
          if (!(j.locks & bit)) continue;
          s << (first ? "" : ", ") << name;
          first = false;
        }
        s << "]\n";
      }
      if (j.limits) {
        s << "    limits: {";
        if (j.limits->has_position) s << "lower: " << Num(j.limits->lower) << ", upper: " << Num(j.limits->upper) << ", ";
        s << "effort: " << Num(j.limits->effort) << ", velocity: " << Num(j.limits->velocity) << "}\n";
      }
    }
  }

  if (!model.forces.empty()) {
    s << "forces:\n";
    for (const Force& f : model.forces) {
      s << "  - name: " << f.name << "\n";
      s << "    i: " << model.markers[f.i].name << "\n";
      s << "    j: " << model.markers[f.j].name << "\n";
      if (f.type == ForceType::kSpringDamper) {
        s << "    type: spring_damper\n";
        s << "    stiffness: " << Expr(f.stiffness) << "\n";
        s << "    damping: " << Expr(f.damping) << "\n";
        s << "    free_length: " << Expr(f.free_length) << "\n";
        s << "    preload: " << Expr(f.preload) << "\n";
      } else if (f.type == ForceType::kBushing) {
        s << "    type: bushing\n";
        for (int which = 0; which < 2; ++which) {
          const auto& v = which == 0 ? f.bushing_stiffness : f.bushing_damping;
          s << (which == 0 ? "    stiffness: [" : "    damping: [");
          for (int c = 0; c < 6; ++c) s << (c ? ", " : "") << Expr(v[c]);
          s << "]\n";
        }
      } else if (f.type == ForceType::kUser) {
        s << "    type: user\n";
        // The resolved path (absolute when the model file's was), so the written file
        // finds the library wherever it is written.
        s << "    library: " << Quoted(f.library ? f.library->path() : f.library_path) << "\n";
        s << "    function: " << f.function << "\n";
        s << "    parameters: [";
        for (size_t c = 0; c < f.user_parameters.size(); ++c) s << (c ? ", " : "") << Expr(f.user_parameters[c]);
        s << "]\n";
      } else {
        s << "    type: " << (f.type == ForceType::kTorque ? "torque" : "force") << "\n";
        s << "    frame: " << (f.frame == ForceFrame::kWorld ? "world" : f.frame == ForceFrame::kI ? "i" : "j") << "\n";
        s << "    value: [" << Expr(f.value[0]) << ", " << Expr(f.value[1]) << ", " << Expr(f.value[2]) << "]\n";
      }
    }
  }

  if (!model.objectives.empty()) {
    s << "objectives:\n";
    for (const Objective& o : model.objectives) {
      s << "  - name: " << o.name << "\n";
      if (o.has_integral) s << "    integral: " << Expr(o.integral) << "\n";
      if (o.has_terminal) s << "    terminal: " << Expr(o.terminal) << "\n";
    }
  }

  const SimulationSettings& sim = model.simulation;
  s << "simulation:\n";
  s << "  t_end: " << Num(sim.t_end) << "\n";
  s << "  output_step: " << Num(sim.output_step) << "\n";
  s << "  integrator: " << (sim.integrator == IntegratorKind::kHht   ? "hht"
                                 : sim.integrator == IntegratorKind::kIda ? "ida"
                                 : sim.integrator == IntegratorKind::kErk ? "erk"
                                                                          : "kinematic") << "\n";
  s << "  output_accelerations: " << sim.output_accelerations << "\n";
  if (sim.output_bodies || sim.output_joints || sim.output_forces || sim.output_measures) {
    s << "  output:\n";
    for (const auto& [key, names] : {std::pair{"bodies", &sim.output_bodies}, std::pair{"joints", &sim.output_joints},
                                     std::pair{"forces", &sim.output_forces}, std::pair{"measures", &sim.output_measures}}) {
      if (!*names) continue;
      s << "    " << key << ": [";
      for (size_t i = 0; i < (*names)->size(); ++i) s << (i ? ", " : "") << Quoted((**names)[i]);
      s << "]\n";
    }
  }
  s << "  hht: {alpha: " << Num(sim.hht_alpha) << ", step: " << Num(sim.hht_step)
    << ", adaptive: " << (sim.hht_adaptive ? "true" : "false") << ", tolerance: " << Num(sim.hht_tolerance)
    << ", modified: " << (sim.hht_modified ? "true" : "false") << ", form: " << sim.hht_form
    << ", start: " << sim.hht_start << (sim.hht_dense_output ? ", dense_output: true" : "");
  if (sim.hht_newton_tolerance != SimulationSettings().hht_newton_tolerance)
    s << ", newton_tolerance: " << Num(sim.hht_newton_tolerance);
  if (sim.hht_linear_solver != SimulationSettings().hht_linear_solver)
    s << ", linear_solver: " << sim.hht_linear_solver;
  if (sim.hht_jacobian_cost >= 0) s << ", jacobian_cost: " << Num(sim.hht_jacobian_cost);
  if (sim.hht_predictor != SimulationSettings().hht_predictor) s << ", predictor: " << sim.hht_predictor;
  if (sim.hht_rotation_jacobian != SimulationSettings().hht_rotation_jacobian)
    s << ", rotation_jacobian: " << sim.hht_rotation_jacobian;
  s << "}\n";
  s << "  ida: {rtol: " << Num(sim.ida_rtol) << ", atol: " << Num(sim.ida_atol);
  if (sim.ida_max_steps != SimulationSettings().ida_max_steps) s << ", max_steps: " << sim.ida_max_steps;
  if (sim.ida_min_step > 0) s << ", min_step: " << Num(sim.ida_min_step);
  if (sim.ida_dense_output) s << ", dense_output: true";
  if (sim.ida_linear_solver != SimulationSettings().ida_linear_solver)
    s << ", linear_solver: " << sim.ida_linear_solver;
  s << "}\n";
  // The erk block only when it is used or set (files written before it existed stay as
  // they were).
  const SimulationSettings defaults;
  if (sim.integrator == IntegratorKind::kErk || sim.erk_rtol != defaults.erk_rtol ||
      sim.erk_atol != defaults.erk_atol || sim.erk_max_steps != defaults.erk_max_steps ||
      sim.erk_min_step > 0 || sim.erk_max_step > 0) {
    s << "  erk: {rtol: " << Num(sim.erk_rtol) << ", atol: " << Num(sim.erk_atol);
    if (sim.erk_max_steps != defaults.erk_max_steps) s << ", max_steps: " << sim.erk_max_steps;
    if (sim.erk_min_step > 0) s << ", min_step: " << Num(sim.erk_min_step);
    if (sim.erk_max_step > 0) s << ", max_step: " << Num(sim.erk_max_step);
    s << "}\n";
  }
  return s.str();
}

void WriteModelFile(const Model& model, const std::string& path, const ModelWriterOptions& options) {
  const std::string text = WriteModelYaml(model, options);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error(path + ": cannot create the file");
  out << text;
  out.flush();
  if (!out) throw std::runtime_error(path + ": cannot write the file");
}

}  // namespace mbdae::mbs
