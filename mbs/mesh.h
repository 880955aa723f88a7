// Triangle meshes as body geometry: reading STL (ASCII and binary) and Wavefront OBJ, and
// the exact volume, centre of mass and inertia tensor of the solid a closed mesh bounds.
//
// Typical use (what the loader does for `geometry: {shape: mesh, file, scale, density}`):
//
//   const TriangleMesh mesh = ReadMesh(path);                  // throws on malformed input
//   Vec3 c;                                                    // centre of mass, mesh axes
//   const MassProperties p = MeshMassProperties(mesh, density, scale, &c);
//
// Every error is a std::runtime_error whose message begins with the file name (the
// TriangleMesh::name for a mesh built in code) and says where and what.
// See docs/meshes.md for the formats accepted and the checks made.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "mbs/geometry.h"
#include "mbs/model.h"

namespace mbdae::mbs {

// An indexed triangle mesh. Triangles are counter-clockwise seen from outside (outward
// normal by the right-hand rule), as STL and OBJ require.
struct TriangleMesh {
  std::vector<Vec3> vertices;                 // file units, mesh axes
  std::vector<std::array<int, 3>> triangles;  // indices into vertices
  // For messages only. name: the file (or any label for a mesh built in code);
  // source_line[t]: where triangle t came from, the line of its `facet` (ASCII STL) or its
  // `f` line (OBJ), or its 1-based facet number (binary STL), with source_unit saying
  // which ("line" or "facet"). May be empty.
  std::string name;
  std::vector<int> source_line;
  std::string source_unit = "line";
};

struct MeshReadOptions {
  // Vertices are merged when every coordinate differs by at most this (file units).
  // 0 (default): only vertices with exactly equal coordinates are merged, which is what
  // STL needs (it stores each triangle's corners separately) and exact for any mesh
  // written by a program from shared vertices. Must be >= 0 and finite.
  double merge_tolerance = 0;

  bool IsValid(std::string* error) const;
};

// Reads an STL or OBJ file, chosen by the extension (.stl, .obj, any case). STL is binary
// when the file size is 84 + 50 n for the n in its header, ASCII otherwise.
// OBJ: `v` and `f` lines (polygons fan-triangulated, 1-based and negative indices, the
// v, v/vt, v//vn and v/vt/vn forms); every other statement is ignored.
TriangleMesh ReadMesh(const std::string& path, const MeshReadOptions& options = {});
TriangleMesh ReadStl(const std::string& path, const MeshReadOptions& options = {});
TriangleMesh ReadObj(const std::string& path, const MeshReadOptions& options = {});

// Merges vertices closer than `tolerance` (every coordinate) and renumbers the triangles;
// unused vertices are dropped. Keeps the first vertex of each group. ReadMesh calls it.
void MergeVertices(TriangleMesh* mesh, double tolerance);

// Reverses the vertex order of every triangle (turns an inside-out mesh outside in).
void FlipOrientation(TriangleMesh* mesh);

// What InspectMesh found. A mesh is accepted as a closed solid when it has triangles and
// no boundary, non-manifold or misoriented edge, and a positive volume.
struct MeshInspection {
  int vertices = 0;
  int triangles = 0;             // including the degenerate ones
  int degenerate_triangles = 0;  // a repeated vertex index: skipped (no area, no edges)
  int zero_area_triangles = 0;   // three distinct but collinear vertices: kept (volume 0)
  int edges = 0;                 // distinct undirected edges
  int boundary_edges = 0;        // used by one triangle only (an open mesh)
  int nonmanifold_edges = 0;     // used by more than two triangles
  int misoriented_edges = 0;     // used twice in the same direction
  double volume = 0;             // signed, file units (negative: inside out)
  std::string message;           // empty when closed; otherwise every problem, with an example

  bool IsClosed() const { return message.empty(); }
};

// Checks the topology and orientation of a mesh; never throws for a bad mesh (but does
// for a triangle index out of range).
MeshInspection InspectMesh(const TriangleMesh& mesh);

// Volume of the solid bounded by a closed mesh (file units), after the checks of
// InspectMesh; throws std::runtime_error when they fail.
double MeshVolume(const TriangleMesh& mesh);

// Mass and inertia about the centre of mass, in mesh axes, of the homogeneous solid
// bounded by the closed mesh, its vertices multiplied by `scale` (e.g. 1e-3 for a file
// in millimetres), with `density` per unit volume of the scaled mesh. Writes the centre
// of mass (mesh axes, scaled) to *centre_of_mass when not null. Exact for a closed mesh
// up to round-off (divergence theorem over signed tetrahedra, see mesh.cc).
// Throws std::runtime_error naming the mesh when density or scale is not positive and
// finite, or the mesh is empty, open, non-manifold, inconsistently oriented or inside out.
MassProperties MeshMassProperties(const TriangleMesh& mesh, double density, double scale,
                                  Vec3* centre_of_mass);

// ReadMesh + MeshMassProperties, for the loader.
struct MeshBodyProperties {
  MassProperties mass;             // about the centre of mass, mesh axes
  Vec3 centre_of_mass = Vec3::Zero();  // mesh axes, scaled
  double volume = 0;               // scaled
  int vertices = 0;
  int triangles = 0;
};
MeshBodyProperties LoadMeshBody(const std::string& path, double density, double scale = 1.0,
                                const MeshReadOptions& options = {});

}  // namespace mbdae::mbs
