// Reading FreeDyn model files (.fds) into an mbs::Model.
//
// A .fds file is plain text: blocks "CATEGORY TYPE" ... "EndCATEGORY" separated by lines
// holding "%", each block a list of "Key = value" lines. The blocks read here are those
// FreeDyn shares with this project (docs/freedyn.md lists every block and key, what it
// becomes, and the conventions found from FreeDyn's published example files):
//
//   Header, Body Rigid_EulerParameter_PAI, Constraint Generic, Force GenericForce,
//   Force GenericTorque, Force Gravity, DataObject Parameter, DataObject Spline_1D,
//   Measure Translational, Measure Rotational, Simulation Dynamic, Solver HHT,
//   Globals Settings.
//
// Geometric input (centre-of-mass location, joint location, points of application,
// measure locations) is in world coordinates at t = 0; it becomes markers on the bodies,
// body-relative from the initial body poses. Orientation matrices (OrientationPAI,
// ConstraintOrientation) are 9 numbers, row by row, whose rows are the body's (the
// constraint's) axes in world coordinates; the body-to-world rotation is the transpose.
//
// Every mistake, an unknown block, an unknown key, a key given twice, a missing key, an
// element that cannot be represented, is a ModelError "FILE:LINE:COLUMN: ELEMENT: what";
// nothing is skipped silently. Keys that only concern FreeDyn's user interface, its
// result files or its debugging output are accepted and ignored (the list is in
// docs/freedyn.md and in IgnoredFreeDynKeys()).
#pragma once

#include <string>
#include <vector>

#include "mbs/loader.h"
#include "mbs/model.h"

namespace mbdae::mbs {

// Reads the .fds file at `path`; relative spline data files are relative to it.
// options.parameter_overrides override DataObject Parameter values (an unknown name is a
// ModelError, as for the YAML loader).
Model LoadFreeDynModel(const std::string& path, const LoadOptions& options = {});
// Same from text; `file` is used in messages and for relative paths.
Model LoadFreeDynModelFromString(const std::string& text, const std::string& file,
                                 const LoadOptions& options = {});

// Whether `path` names a FreeDyn model file: it ends in ".fds", in any letter case.
bool IsFreeDynPath(const std::string& path);

// LoadFreeDynModel for .fds files, LoadModel (YAML) for anything else.
Model LoadAnyModel(const std::string& path, const LoadOptions& options = {});

// A FreeDyn force expression in this project's expression syntax:
//   PARVAL[name] -> name, MEAVAL[name] -> name, SIMTIME[] -> t,
//   SPL[x, name] -> spline(name, x)   (x translated recursively),
// with names mapped through the given tables (FreeDyn name -> name in the model; a name
// missing from its table is an error). Other text is copied. Throws
// std::invalid_argument with the reason (unknown name, unknown FreeDyn function,
// unbalanced brackets), the 1-based column of the mistake in `text` in *column.
struct FreeDynNames {
  std::vector<std::pair<std::string, std::string>> parameters, measures, splines;
};
std::string TranslateFreeDynExpression(const std::string& text, const FreeDynNames& names,
                                       int* column = nullptr);

// Keys accepted and ignored (FreeDyn's user interface, result files, debugging, and
// solver settings without an equivalent here), by block ("Body", "Simulation", ...).
const std::vector<std::pair<std::string, std::string>>& IgnoredFreeDynKeys();

}  // namespace mbdae::mbs
