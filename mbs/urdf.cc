// URDF -> mbs::Model. See urdf.h and docs/urdf.md.
#include "mbs/urdf.h"

#include <console_bridge/console.h>
#include <tinyxml.h>
#include <urdf_parser/urdf_parser.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <map>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>

#include "dae/format.h"
#include "mbs/kinematics.h"

namespace mbdae::mbs {

namespace {

std::string Num(double v) { return FormatG(v, 10); }

// urdfdom reports through console_bridge; its errors are collected while it parses and
// become the message of the ModelError. console_bridge's handler is global: one parse at
// a time.
class CollectingHandler : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR) errors.push_back(text);
  }
  std::vector<std::string> errors;
};
std::mutex& ParserMutex() {
  static std::mutex m;
  return m;
}

// A rigid transform: x_parent = R x_child + p.
struct Frame {
  Mat3 R = Mat3::Identity();
  Vec3 p = Vec3::Zero();
  Frame operator*(const Frame& b) const { return Frame{R * b.R, R * b.p + p}; }
};

Frame FromPose(const urdf::Pose& pose) {
  Frame f;
  const urdf::Rotation& r = pose.rotation;  // x y z w
  Quat e(r.w, r.x, r.y, r.z);
  const double n = e.norm();
  f.R = n > 0 ? RotationMatrix(e / n) : Mat3::Identity();
  f.p = Vec3(pose.position.x, pose.position.y, pose.position.z);
  return f;
}

// A rotation that takes the z axis to the unit vector a: the least rotation (about z x a).
Mat3 ZTo(const Vec3& a) {
  const Vec3 z(0, 0, 1);
  const double c = z.dot(a);
  if (c > 1 - 1e-15) return Mat3::Identity();
  if (c < -1 + 1e-15) return Eigen::AngleAxisd(M_PI, Vec3::UnitX()).toRotationMatrix();
  const Vec3 axis = z.cross(a);
  return Eigen::AngleAxisd(std::atan2(axis.norm(), c), axis.normalized()).toRotationMatrix();
}

// Principal axes of J (symmetric): V with J = V diag(I) V^T, det V = +1, the columns
// ordered and signed so that V stays nearest to the identity (a diagonal J gives V = I).
void PrincipalAxes(const Mat3& J, Mat3* V, Vec3* I) {
  if (J(0, 1) == 0 && J(0, 2) == 0 && J(1, 2) == 0 && J(1, 0) == 0 && J(2, 0) == 0 && J(2, 1) == 0) {
    *V = Mat3::Identity();
    *I = J.diagonal();
    return;
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(J);
  const Mat3 E = eig.eigenvectors();
  const Vec3 lambda = eig.eigenvalues();
  // The permutation of the eigenvectors with the largest |trace|-like alignment.
  int perm[3] = {0, 1, 2}, best[3] = {0, 1, 2};
  double best_score = -1;
  do {
    double score = 0;
    for (int k = 0; k < 3; ++k) score += std::abs(E(k, perm[k]));
    if (score > best_score + 1e-12) {
      best_score = score;
      std::copy(perm, perm + 3, best);
    }
  } while (std::next_permutation(perm, perm + 3));
  for (int k = 0; k < 3; ++k) {
    V->col(k) = E.col(best[k]);
    if ((*V)(k, k) < 0) V->col(k) = -V->col(k);
    (*I)[k] = lambda[best[k]];
  }
  if (V->determinant() < 0) V->col(2) = -V->col(2);  // only when (2,2) was 0
}

// Names of the model: letters, digits, '_' and '-'; other characters become '_'.
std::string PlainName(const std::string& name) {
  std::string out;
  for (char c : name) out += (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-') ? c : '_';
  return out.empty() ? "_" : out;
}
// Measure names: letters, digits and '_', not starting with a digit.
std::string IdentifierName(const std::string& name) {
  std::string out;
  for (char c : name) out += (std::isalnum(static_cast<unsigned char>(c)) || c == '_') ? c : '_';
  if (out.empty() || std::isdigit(static_cast<unsigned char>(out[0]))) out = "q_" + out;
  return out;
}
std::string Unique(const std::string& name, const std::set<std::string>& taken) {
  if (!taken.count(name)) return name;
  for (int k = 2;; ++k) {
    const std::string candidate = name + "_" + std::to_string(k);
    if (!taken.count(candidate)) return candidate;
  }
}

const char* TypeName(int type) {
  switch (type) {
    case urdf::Joint::REVOLUTE: return "revolute";
    case urdf::Joint::CONTINUOUS: return "continuous";
    case urdf::Joint::PRISMATIC: return "prismatic";
    case urdf::Joint::FLOATING: return "floating";
    case urdf::Joint::PLANAR: return "planar";
    case urdf::Joint::FIXED: return "fixed";
    default: return "unknown";
  }
}

class UrdfReader {
 public:
  UrdfReader(const std::string& file, const LoadOptions& options) : file_(file), options_(options) {}

  Model Read(const std::string& text) {
    Locate(text);
    Parse(text);
    CheckTree();
    model_.file = file_;
    model_.name = robot_->getName();
    model_.gravity = Vec3(0, 0, -9.81);
    InitialJointValues();
    Poses();
    MakeBodies();
    MakeJoints();
    MakeVisuals();
    Finish();
    if (!options_.parameter_overrides.empty()) {
      throw ModelError(Where("robot", ""), "model",
                       "--set " + options_.parameter_overrides.begin()->first +
                           ": a URDF model has no parameters (convert it and add parameters, or extend it: "
                           "docs/urdf.md)");
    }
    return std::move(model_);
  }

 private:
  // ---- where elements are, for messages ----------------------------------------------------------

  void Locate(const std::string& text) {
    TiXmlDocument doc;
    doc.Parse(text.c_str(), nullptr, TIXML_ENCODING_UTF8);
    if (doc.Error()) {
      throw ModelError(SourceLocation{file_, doc.ErrorRow(), doc.ErrorCol()}, "model",
                       std::string("not a valid XML file: ") + doc.ErrorDesc());
    }
    const TiXmlElement* robot = doc.FirstChildElement("robot");
    if (!robot) throw ModelError(SourceLocation{file_, 0, 0}, "model", "no <robot> element: not a URDF file");
    places_[{"robot", ""}] = SourceLocation{file_, robot->Row(), robot->Column()};
    for (const TiXmlElement* e = robot->FirstChildElement(); e; e = e->NextSiblingElement()) {
      const char* name = e->Attribute("name");
      if (!name) continue;
      const std::string kind = e->ValueStr();
      if (kind != "link" && kind != "joint") continue;
      places_.emplace(std::make_pair(kind, std::string(name)), SourceLocation{file_, e->Row(), e->Column()});
      if (kind == "joint") {
        // urdfdom keeps the last joint that names a link as its child: a second one is a loop.
        const TiXmlElement* child = e->FirstChildElement("child");
        const TiXmlElement* parent = e->FirstChildElement("parent");
        const char* link = child ? child->Attribute("link") : nullptr;
        const char* up = parent ? parent->Attribute("link") : nullptr;
        if (link && up) {
          auto [it, inserted] = parent_of_.emplace(link, std::make_pair(std::string(up), std::string(name)));
          if (!inserted) {
            throw ModelError(Where("joint", name), "joint '" + std::string(name) + "'",
                             "link '" + std::string(link) + "' is already the child of joint '" + it->second.second +
                                 "': a link has one parent, and the joints form a tree (a second parent closes a loop)");
          }
        }
      }
    }
    // A cycle: following the parents from some link comes back to it.
    for (const auto& start : parent_of_) {
      std::vector<std::string> path{start.first};
      std::string link = start.first;
      for (size_t step = 0; step <= parent_of_.size(); ++step) {
        auto it = parent_of_.find(link);
        if (it == parent_of_.end()) break;
        link = it->second.first;
        if (link == start.first) {
          std::string text = start.first;
          std::string l = start.first;
          std::string first_joint;
          do {
            const auto& [up, joint] = parent_of_.at(l);
            if (first_joint.empty()) first_joint = joint;
            text += " <-(" + joint + ")- " + up;
            l = up;
          } while (l != start.first);
          FailJoint(first_joint, "the joints form a cycle (child <-(joint)- parent: " + text +
                                     "); URDF describes a tree");
        }
      }
    }
  }
  SourceLocation Where(const std::string& kind, const std::string& name) const {
    auto it = places_.find({kind, name});
    return it == places_.end() ? SourceLocation{file_, 0, 0} : it->second;
  }
  [[noreturn]] void FailJoint(const std::string& name, const std::string& what) const {
    throw ModelError(Where("joint", name), "joint '" + name + "'", what);
  }
  [[noreturn]] void FailLink(const std::string& name, const std::string& what) const {
    throw ModelError(Where("link", name), "link '" + name + "'", what);
  }

  // ---- urdfdom ----------------------------------------------------------------------------------

  void Parse(const std::string& text) {
    CollectingHandler handler;
    {
      std::lock_guard<std::mutex> lock(ParserMutex());
      console_bridge::useOutputHandler(&handler);
      try {
        robot_ = urdf::parseURDF(text);
      } catch (const std::exception& e) {
        handler.errors.push_back(e.what());
      }
      console_bridge::restorePreviousOutputHandler();
    }
    if (robot_) return;
    // The messages of urdfdom that name a joint and a link, said with the joint's line.
    static const std::regex missing(R"((parent|child) link \[([^\]]*)\] of joint \[([^\]]*)\] not found)");
    for (const std::string& e : handler.errors) {
      std::smatch m;
      if (std::regex_search(e, m, missing)) {
        FailJoint(m[3], "its " + m[1].str() + " link '" + m[2].str() + "' does not exist (no <link name=\"" +
                            m[2].str() + "\"> in the file)");
      }
    }
    std::string what;
    for (const std::string& e : handler.errors) what += (what.empty() ? "" : "; ") + e;
    throw ModelError(Where("robot", ""), "model", "urdfdom cannot read the file: " + (what.empty() ? "unknown reason" : what));
  }

  // ---- the tree ---------------------------------------------------------------------------------

  void CheckTree() {
    root_ = robot_->getRoot();
    // Every link reachable from the root once: a link outside that tree sits on a cycle
    // (each of its links has a parent).
    std::set<std::string> seen;
    std::function<void(const urdf::LinkConstSharedPtr&)> visit = [&](const urdf::LinkConstSharedPtr& link) {
      seen.insert(link->name);
      order_.push_back(link);
      for (const urdf::LinkSharedPtr& c : link->child_links) visit(c);
    };
    visit(root_);
    std::vector<urdf::LinkSharedPtr> links;
    robot_->getLinks(links);
    for (const urdf::LinkSharedPtr& link : links)
      if (!seen.count(link->name)) FailLink(link->name, "not connected to the root link '" + root_->name + "'");
    // Axes, masses.
    for (const urdf::LinkConstSharedPtr& link : order_) {
      const urdf::JointConstSharedPtr& j = link->parent_joint;
      if (!j) continue;
      if (j->type == urdf::Joint::REVOLUTE || j->type == urdf::Joint::CONTINUOUS || j->type == urdf::Joint::PRISMATIC ||
          j->type == urdf::Joint::PLANAR) {
        const Vec3 a(j->axis.x, j->axis.y, j->axis.z);
        if (!a.allFinite() || a.norm() == 0)
          FailJoint(j->name, "the axis [" + Num(a[0]) + ", " + Num(a[1]) + ", " + Num(a[2]) +
                                 "] has zero length; a " + TypeName(j->type) + " joint needs a direction");
        if (std::abs(a.norm() - 1) > 1e-6)
          model_.notes.push_back("joint '" + j->name + "': axis of length " + Num(a.norm()) + " normalised");
      }
      if (j->type == urdf::Joint::UNKNOWN) FailJoint(j->name, "unknown joint type");
    }
  }

  static bool HasMass(const urdf::LinkConstSharedPtr& link) {
    return link->inertial && link->inertial->mass > 0;
  }
  bool Movable(const urdf::JointConstSharedPtr& j) const {
    return j && j->type != urdf::Joint::FIXED;
  }

  // The joint values of the initial state: 0, mimic joints at offset + multiplier q(other).
  void InitialJointValues() {
    std::function<double(const urdf::JointConstSharedPtr&, int)> value = [&](const urdf::JointConstSharedPtr& j,
                                                                              int depth) -> double {
      if (!j->mimic) return 0.0;
      if (depth > 100) FailJoint(j->name, "mimic joints mimic each other in a cycle");
      const urdf::JointConstSharedPtr other = robot_->getJoint(j->mimic->joint_name);
      if (!other) FailJoint(j->name, "mimics the joint '" + j->mimic->joint_name + "', which does not exist");
      return j->mimic->offset + j->mimic->multiplier * value(other, depth + 1);
    };
    for (const urdf::LinkConstSharedPtr& link : order_)
      if (link->parent_joint) q0_[link->parent_joint->name] = value(link->parent_joint, 0);
  }

  static Vec3 Axis(const urdf::JointConstSharedPtr& j) {
    const Vec3 a(j->axis.x, j->axis.y, j->axis.z);
    return a / a.norm();
  }

  // World frames of the links and of the joints (at joint value 0), at the initial state.
  void Poses() {
    link_frame_[root_->name] = Frame{};
    for (const urdf::LinkConstSharedPtr& link : order_) {
      const urdf::JointConstSharedPtr& j = link->parent_joint;
      if (!j) continue;
      const Frame joint0 = link_frame_.at(link->getParent()->name) * FromPose(j->parent_to_joint_origin_transform);
      joint_frame_[j->name] = joint0;
      Frame motion;
      const double q = q0_[j->name];
      if (j->type == urdf::Joint::REVOLUTE || j->type == urdf::Joint::CONTINUOUS)
        motion.R = Eigen::AngleAxisd(q, Axis(j)).toRotationMatrix();
      else if (j->type == urdf::Joint::PRISMATIC)
        motion.p = q * Axis(j);
      link_frame_[link->name] = joint0 * motion;
    }
  }

  // ---- bodies -----------------------------------------------------------------------------------

  void MakeBodies() {
    const bool floating = options_.urdf_floating_base;
    std::set<std::string> taken{"ground"};
    for (const urdf::LinkConstSharedPtr& link : order_) {
      const urdf::JointConstSharedPtr& j = link->parent_joint;
      const bool root = link == root_;
      if (link->inertial && !(link->inertial->mass >= 0 && std::isfinite(link->inertial->mass)))
        FailLink(link->name, "mass must be >= 0, got " + Num(link->inertial->mass));
      if (root && !floating) {
        owner_[link->name] = -1;
        if (HasMass(link))
          model_.notes.push_back("link '" + link->name + "' is the root, fixed to the world: the ground (its mass " +
                                 Num(link->inertial->mass) + " kg does not enter the model)");
        continue;
      }
      if (!HasMass(link)) {
        if (root) {
          FailLink(link->name, "the root link has no mass, and a floating base (--floating-base) makes it a free "
                               "body: give it an <inertial> with a mass, or keep it fixed to the world");
        }
        if (!Movable(j)) {
          owner_[link->name] = owner_.at(link->getParent()->name);
          const int o = owner_[link->name];
          model_.notes.push_back("link '" + link->name + "' has no mass: merged into " +
                                 (o < 0 ? std::string("the ground") : "'" + model_.bodies[o].name + "'") +
                                 " (fixed joint '" + j->name + "'); its frame is the marker " +
                                 (o < 0 ? std::string("ground") : model_.bodies[o].name) + "." +
                                 PlainName(link->name));
          continue;
        }
        if (!link->child_links.empty())
          FailLink(link->name, "zero mass with children: the link has no mass (no <inertial> or mass 0), moves on the " +
                                   std::string(TypeName(j->type)) + " joint '" + j->name +
                                   "' and carries other links; give it a mass and an inertia");
        FailLink(link->name, "zero mass on the " + std::string(TypeName(j->type)) + " joint '" + j->name +
                                 "': its motion would not be determined; give it a mass and an inertia, or make "
                                 "the joint fixed");
      }
      const urdf::Inertial& in = *link->inertial;
      Mat3 J;
      J << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
      std::string why;
      if (!IsPhysicalInertia(J, &why)) FailLink(link->name, why);
      Mat3 V;
      Vec3 I;
      PrincipalAxes(J, &V, &I);
      const Frame com = link_frame_.at(link->name) * FromPose(in.origin);
      Body body;
      body.name = Unique(PlainName(link->name), taken);
      taken.insert(body.name);
      if (body.name != link->name)
        model_.notes.push_back("link '" + link->name + "' is the body '" + body.name + "'");
      body.where = Where("link", link->name);
      body.mass = in.mass;
      body.inertia = I.cwiseMax(0.0).asDiagonal();
      body.position = com.p;
      const Mat3 R = com.R * V;
      body.orientation = QuaternionFromMatrix(R);
      body.orientation.normalize();
      // The body axes as the model will see them (from the normalised Euler parameters).
      const int index = static_cast<int>(model_.bodies.size());
      owner_[link->name] = index;
      model_.bodies.push_back(body);
      AddMarker(index, "cm", Vec3::Zero(), Mat3::Identity(), body.where, /*fixed_name=*/true);
      if (V != Mat3::Identity())
        model_.notes.push_back("link '" + link->name + "': body axes are the principal axes of the inertia");
    }
    if (model_.bodies.empty())
      throw ModelError(Where("robot", ""), "model", "no link with mass besides the root: nothing moves");
  }

  Frame BodyFrame(int body) const {
    if (body < 0) return Frame{};
    return Frame{RotationMatrix(model_.bodies[body].orientation), model_.bodies[body].position};
  }

  // A marker on `body` (-1: ground) with the world frame `f` at the initial state.
  int AddMarker(int body, const std::string& name, const Vec3& local, const Mat3& axes, const SourceLocation& where,
                bool fixed_name = false) {
    std::set<std::string> taken;
    for (const Marker& m : pending_)
      if (m.body == body) taken.insert(m.name);
    const std::string n = fixed_name ? name : Unique(PlainName(name), taken);
    pending_.push_back(Marker{n, body, local, axes, where});
    return static_cast<int>(pending_.size()) - 1;
  }
  int MarkerAt(int body, const std::string& name, const Frame& world, const SourceLocation& where) {
    const Frame b = BodyFrame(body);
    Vec3 local = b.R.transpose() * (world.p - b.p);
    Mat3 axes = b.R.transpose() * world.R;
    for (int k = 0; k < 3; ++k)
      if (std::abs(local[k]) < 1e-14 * std::max(1.0, world.p.norm())) local[k] = 0;
    if ((axes - Mat3::Identity()).cwiseAbs().maxCoeff() <= 1e-14) axes = Mat3::Identity();
    return AddMarker(body, name, local, axes, where);
  }

  // ---- joints -----------------------------------------------------------------------------------

  void MakeJoints() {
    // The frames of merged links (and of every link: its own frame), for loads and sensors.
    for (const urdf::LinkConstSharedPtr& link : order_) {
      const int o = owner_.at(link->name);
      if (o < 0 && link == root_) continue;  // ground.O is the root's frame
      const bool own = o >= 0 && model_.bodies[o].where.line == Where("link", link->name).line &&
                       model_.bodies[o].name == PlainName(link->name);
      MarkerAt(o, own ? "frame" : link->name, link_frame_.at(link->name), Where("link", link->name));
    }
    std::set<std::string> taken;
    std::map<std::string, int> angle_measure;  // joint -> its angle measure
    std::vector<urdf::JointConstSharedPtr> mimics;
    for (const urdf::LinkConstSharedPtr& link : order_) {
      const urdf::JointConstSharedPtr& j = link->parent_joint;
      if (!j) continue;
      const int child = owner_.at(link->name), parent = owner_.at(link->getParent()->name);
      if (child == parent) continue;  // merged
      const SourceLocation where = Where("joint", j->name);
      if (j->type == urdf::Joint::FLOATING) {
        model_.notes.push_back("joint '" + j->name + "' (floating): no equations, the body '" + model_.bodies[child].name +
                               "' is free");
        continue;
      }
      Joint joint;
      joint.name = Unique(PlainName(j->name), taken);
      taken.insert(joint.name);
      if (joint.name != j->name) model_.notes.push_back("joint '" + j->name + "' is the joint '" + joint.name + "'");
      joint.where = where;
      const Mat3 A = j->type == urdf::Joint::FIXED ? Mat3::Identity() : ZTo(Axis(j));
      Frame child_frame = link_frame_.at(link->name), parent_frame = joint_frame_.at(j->name);
      child_frame.R = child_frame.R * A;
      parent_frame.R = parent_frame.R * A;
      constexpr unsigned kAllT = kLockX | kLockY | kLockZ, kAllR = kLockRx | kLockRy | kLockRz;
      switch (j->type) {  // the locks of the model file's joint types
        case urdf::Joint::REVOLUTE:
        case urdf::Joint::CONTINUOUS:
          joint.type = JointType::kRevolute;
          joint.locks = kAllT | kLockRx | kLockRy;
          break;
        case urdf::Joint::PRISMATIC:
          joint.type = JointType::kPrismatic;
          joint.locks = kLockX | kLockY | kAllR;
          break;
        case urdf::Joint::PLANAR:
          joint.type = JointType::kPlanar;
          joint.locks = kLockZ | kLockRx | kLockRy;
          break;
        default:
          joint.type = JointType::kFixed;
          joint.locks = kAllT | kAllR;
          break;
      }
      joint.i = MarkerAt(child, j->name, child_frame, where);
      joint.j = MarkerAt(parent, j->name, parent_frame, where);
      if (j->limits && j->type != urdf::Joint::FIXED) {
        Joint::Limits l;
        l.lower = j->limits->lower;
        l.upper = j->limits->upper;
        l.effort = j->limits->effort;
        l.velocity = j->limits->velocity;
        l.has_position = j->type == urdf::Joint::REVOLUTE || j->type == urdf::Joint::PRISMATIC;
        joint.limits = l;
      }
      if (j->dynamics && (j->dynamics->damping != 0 || j->dynamics->friction != 0))
        model_.notes.push_back("joint '" + j->name + "': <dynamics damping=\"" + Num(j->dynamics->damping) +
                               "\" friction=\"" + Num(j->dynamics->friction) + "\"> is not modelled");
      if (j->mimic) mimics.push_back(j);
      joint_of_[j->name] = static_cast<int>(model_.joints.size());
      model_.joints.push_back(joint);
    }
    for (const urdf::JointConstSharedPtr& j : mimics) {
      const urdf::JointConstSharedPtr other = robot_->getJoint(j->mimic->joint_name);
      auto rotational = [](const urdf::JointConstSharedPtr& x) {
        return x->type == urdf::Joint::REVOLUTE || x->type == urdf::Joint::CONTINUOUS;
      };
      if (!rotational(j) || !rotational(other))
        FailJoint(j->name, "mimics '" + other->name + "': only revolute and continuous joints can mimic each other "
                           "(a mimic becomes a gear joint, which couples two angles)");
      if (!joint_of_.count(other->name)) FailJoint(j->name, "mimics '" + other->name + "', which is merged away");
      Joint gear;
      gear.name = Unique(PlainName(j->name) + "_mimic", taken);
      taken.insert(gear.name);
      gear.type = JointType::kGear;
      gear.where = Where("joint", j->name);
      gear.measures = {AngleMeasure(other->name), AngleMeasure(j->name)};
      gear.ratio = j->mimic->multiplier;
      model_.joints.push_back(gear);
      model_.notes.push_back("joint '" + j->name + "' mimics '" + other->name + "': the gear joint '" + gear.name +
                             "' (ratio " + Num(j->mimic->multiplier) + ", offset " + Num(j->mimic->offset) +
                             " in the initial state)");
    }
  }

  // The angle measure JOINT_q of a revolute joint made from a URDF joint.
  int AngleMeasure(const std::string& urdf_joint) {
    const Joint& joint = model_.joints[joint_of_.at(urdf_joint)];
    const std::string name = IdentifierName(joint.name + "_q");
    for (size_t k = 0; k < model_.measures.size(); ++k)
      if (model_.measures[k].name == name) return static_cast<int>(k);
    Measure m;
    m.name = name;
    m.type = MeasureType::kRotational;
    m.component = Component::kZ;
    m.i = joint.i;
    m.j = joint.j;
    m.where = joint.where;
    model_.measures.push_back(m);
    return static_cast<int>(model_.measures.size()) - 1;
  }

  // ---- visual and collision geometry ---------------------------------------------------------

  void MakeVisuals() {
    int collisions = 0;
    for (const urdf::LinkConstSharedPtr& link : order_) {
      collisions += static_cast<int>(link->collision_array.size());
      const int o = owner_.at(link->name);
      for (const urdf::VisualSharedPtr& v : link->visual_array) {
        if (!v || !v->geometry) continue;
        VisualShape s;
        s.where = Where("link", link->name);
        switch (v->geometry->type) {
          case urdf::Geometry::SPHERE:
            s.kind = VisualKind::kSphere;
            s.radius = static_cast<const urdf::Sphere&>(*v->geometry).radius;
            break;
          case urdf::Geometry::BOX: {
            const urdf::Vector3& d = static_cast<const urdf::Box&>(*v->geometry).dim;
            s.kind = VisualKind::kBox;
            s.size = Vec3(d.x, d.y, d.z);
            break;
          }
          case urdf::Geometry::CYLINDER: {
            const auto& c = static_cast<const urdf::Cylinder&>(*v->geometry);
            s.kind = VisualKind::kCylinder;
            s.radius = c.radius;
            s.length = c.length;
            break;
          }
          case urdf::Geometry::MESH: {
            const auto& m = static_cast<const urdf::Mesh&>(*v->geometry);
            std::string path = m.filename;
            if (path.rfind("file://", 0) == 0) path = path.substr(7);
            std::string ext = std::filesystem::path(path).extension().string();
            for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
            if (path.rfind("package://", 0) == 0 || (ext != ".stl" && ext != ".obj") ||
                !(m.scale.x == m.scale.y && m.scale.y == m.scale.z)) {
              model_.notes.push_back("link '" + link->name + "': visual mesh '" + m.filename +
                                     "' not drawn (only STL and OBJ files by path, with one scale for all axes)");
              continue;
            }
            const std::filesystem::path resolved =
                std::filesystem::path(path).is_absolute() ? std::filesystem::path(path)
                                                          : std::filesystem::path(file_).parent_path() / path;
            std::error_code ec;
            if (!std::filesystem::is_regular_file(resolved, ec)) {
              model_.notes.push_back("link '" + link->name + "': visual mesh '" + m.filename + "' not found (" +
                                     resolved.string() + "): not drawn");
              continue;
            }
            s.kind = VisualKind::kMesh;
            s.mesh_file = resolved.string();
            s.mesh_scale = m.scale.x;
            break;
          }
        }
        if (v->material) {
          const urdf::Color& c = v->material->color;
          s.color = {c.r, c.g, c.b, c.a};
        }
        const Frame world = link_frame_.at(link->name) * FromPose(v->origin);
        const Frame b = BodyFrame(o);
        s.position = b.R.transpose() * (world.p - b.p);
        s.orientation = b.R.transpose() * world.R;
        if (o < 0)
          model_.ground_visuals.push_back(s);
        else
          model_.bodies[o].visuals.push_back(s);
      }
    }
    if (collisions > 0)
      model_.notes.push_back(std::to_string(collisions) + " <collision> elements not represented (no contact)");
  }

  // ---- the model's markers in the loader's order ------------------------------------------------

  void Finish() {
    std::vector<int> order(pending_.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return pending_[a].body < pending_[b].body; });
    std::vector<int> index(pending_.size());
    model_.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), Where("robot", "")});
    for (size_t k = 0; k < order.size(); ++k) {
      Marker m = pending_[order[k]];
      m.name = (m.body < 0 ? std::string("ground") : model_.bodies[m.body].name) + "." + m.name;
      index[order[k]] = static_cast<int>(model_.markers.size());
      model_.markers.push_back(m);
    }
    for (size_t b = 0; b < model_.bodies.size(); ++b)
      for (size_t k = 0; k < pending_.size(); ++k)
        if (pending_[k].body == static_cast<int>(b) && pending_[k].name == "cm") model_.bodies[b].cm_marker = index[k];
    for (Measure& m : model_.measures) m.i = index[m.i], m.j = index[m.j];
    for (Joint& j : model_.joints)
      if (j.i >= 0) j.i = index[j.i], j.j = index[j.j];
  }

  std::string file_;
  const LoadOptions& options_;
  Model model_;
  urdf::ModelInterfaceSharedPtr robot_;
  urdf::LinkConstSharedPtr root_;
  std::vector<urdf::LinkConstSharedPtr> order_;  // depth first from the root
  std::map<std::pair<std::string, std::string>, SourceLocation> places_;
  std::map<std::string, std::pair<std::string, std::string>> parent_of_;  // link -> (parent, joint)
  std::map<std::string, double> q0_;
  std::map<std::string, Frame> link_frame_, joint_frame_;
  std::map<std::string, int> owner_;     // link -> body (-1: ground)
  std::map<std::string, int> joint_of_;  // URDF joint -> Model::joints index
  std::vector<Marker> pending_;          // names without the body part; ground.O added at the end
};

}  // namespace

bool IsUrdfPath(const std::string& path) {
  if (path.size() < 5) return false;
  std::string ext = path.substr(path.size() - 5);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".urdf";
}

Model LoadUrdfModelFromString(const std::string& text, const std::string& file, const LoadOptions& options) {
  return UrdfReader(file, options).Read(text);
}

Model LoadUrdfModel(const std::string& path, const LoadOptions& options) {
  std::error_code ignored;
  if (std::filesystem::is_directory(path, ignored))
    throw ModelError(SourceLocation{path, 0, 0}, "model", "cannot read the file: it is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ModelError(SourceLocation{path, 0, 0}, "model", std::string("cannot open the file: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return LoadUrdfModelFromString(text.str(), path, options);
}

}  // namespace mbdae::mbs
