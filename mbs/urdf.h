// Reading URDF robot descriptions (.urdf) into an mbs::Model, with Debian's urdfdom parser
// (liburdfdom-dev). docs/urdf.md describes what each URDF element becomes.
//
//   - every link with mass becomes a body named as the link; its centre of mass and
//     inertia come from <inertial>, the body axes are the principal axes of the inertia
//     (the eigenvectors of the tensor, ordered and signed to stay nearest to the
//     <inertial> frame's axes; a diagonal tensor keeps those axes), so the body's inertia
//     is diagonal;
//   - a link without mass on a fixed joint is merged into its parent: its frame becomes a
//     marker of the parent's body, named as the link (Model::notes says so);
//   - joints are named as the URDF's: revolute and continuous become `revolute`, prismatic
//     `prismatic`, planar `planar`, fixed `fixed`; a floating joint leaves its child free
//     (no equations); the joint's markers (named as the joint on both bodies) have their z
//     axis along the URDF axis. A mimic joint gets a `gear` joint JOINT_mimic between the
//     angle measures JOINT_q of the two joints. Limits and effort are kept in
//     Joint::limits (recorded, not enforced);
//   - the root link is the ground (fixed to the world, the URDF's default), or with
//     LoadOptions::urdf_floating_base a free body;
//   - gravity is -9.81 m/s^2 along world z (REP 103); the initial state is the zero
//     joint position (mimic joints at their offset) at rest.
//
// A mistake (a joint whose parent link does not exist, a cycle, a link without mass that
// has children on a movable joint, an axis of zero length, ...) is a ModelError
// "FILE:LINE:COLUMN: joint 'NAME': what" (or link 'NAME').
#pragma once

#include <string>

#include "mbs/loader.h"
#include "mbs/model.h"

namespace mbdae::mbs {

Model LoadUrdfModel(const std::string& path, const LoadOptions& options = {});
// Same from text; `file` is used in messages.
Model LoadUrdfModelFromString(const std::string& text, const std::string& file, const LoadOptions& options = {});

// Whether `path` ends in ".urdf", in any letter case.
bool IsUrdfPath(const std::string& path);

}  // namespace mbdae::mbs
