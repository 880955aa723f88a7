// Triangle mesh reading (STL, OBJ) and mass properties of the solid a closed mesh bounds.
//
// Mass properties: by the divergence theorem the integrals of 1, x and x x^T over the
// solid are sums over the signed tetrahedra (p0, a, b, c) spanned by a reference point p0
// and each triangle (a, b, c) -- the tetrahedra outside the solid cancel. For one
// tetrahedron with edge vectors a, b, c from p0 (d = a . (b x c) = 6 x signed volume):
//   volume           V = d / 6
//   first moment     integral of x        = d / 24  (a + b + c)
//   second moment    integral of x x^T    = d / 120 (a a^T + b b^T + c c^T + s s^T),  s = a+b+c
// The last is the covariance of the canonical tetrahedron, 1/120 [[2,1,1],[1,2,1],[1,1,2]],
// mapped by the matrix A = [a b c]: d A C_can A^T (J. Blow and A. Binstock, "How to find
// the inertia tensor (or other mass properties) of a 3D solid body represented by a
// triangle mesh", 2004; the same integrals as B. Mirtich, "Fast and accurate computation
// of polyhedral mass properties", J. Graphics Tools 1(2), 1996). The inertia about the
// centre of mass c is I = tr(C_c) 1 - C_c with C_c = C - V c c^T (parallel axes), times
// the density. p0 is the mean of the vertices, so that the sums lose no digits to a mesh
// placed far from its origin.
#include "mbs/mesh.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <unordered_map>

namespace mbdae::mbs {

namespace {

[[noreturn]] void Fail(const std::string& file, const std::string& what) {
  throw std::runtime_error(file + ": " + what);
}

std::string Label(const TriangleMesh& mesh) { return mesh.name.empty() ? "mesh" : mesh.name; }

std::string FormatPoint(const Vec3& p) {
  std::ostringstream out;
  out << std::setprecision(10) << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return out.str();
}

// "triangle 7 (line 31)" / "triangle 7 (facet 7)", 1-based.
std::string WhereTriangle(const TriangleMesh& mesh, std::size_t t) {
  std::string s = "triangle " + std::to_string(t + 1);
  if (t < mesh.source_line.size()) {
    s += " (" + mesh.source_unit + " " + std::to_string(mesh.source_line[t]) + ")";
  }
  return s;
}

std::string ReadWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(path, "cannot open the mesh file");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) Fail(path, "error while reading the mesh file");
  return buffer.str();
}

std::string Lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// ASCII case-insensitive equality with a lower-case keyword.
bool IsKeyword(std::string_view token, std::string_view lower_keyword) {
  if (token.size() != lower_keyword.size()) return false;
  for (std::size_t i = 0; i < token.size(); ++i) {
    const char c = token[i];
    if ((c >= 'A' && c <= 'Z' ? char(c - 'A' + 'a') : c) != lower_keyword[i]) return false;
  }
  return true;
}

// White space of the "C" locale, without the locale look-up of std::isspace.
bool IsSpace(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}

// Splits a line into whitespace-separated tokens (views into the line).
void Tokenize(std::string_view line, std::vector<std::string_view>* tokens) {
  tokens->clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && IsSpace(line[i])) ++i;
    std::size_t j = i;
    while (j < line.size() && !IsSpace(line[j])) ++j;
    if (j > i) tokens->push_back(line.substr(i, j - i));
    i = j;
  }
}

// A finite number filling the whole token (a leading '+' allowed).
bool ParseDouble(std::string_view token, double* value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), *value);
  return ec == std::errc() && end == token.data() + token.size() && std::isfinite(*value);
}

bool ParseInt(std::string_view token, long* value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), *value);
  return ec == std::errc() && end == token.data() + token.size();
}

// Calls f(line_number, line) for every line of text (\n, \r\n or \r\n endings).
template <class F>
void ForEachLine(const std::string& text, F&& f) {
  std::size_t start = 0;
  int number = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    f(++number, line);
    start = end + 1;
  }
}

// ---- STL ----------------------------------------------------------------------------

std::uint32_t LittleEndian32(const char* p) {
  const auto* u = reinterpret_cast<const unsigned char*>(p);
  return std::uint32_t(u[0]) | std::uint32_t(u[1]) << 8 | std::uint32_t(u[2]) << 16 |
         std::uint32_t(u[3]) << 24;
}

float LittleEndianFloat(const char* p) {
  const std::uint32_t bits = LittleEndian32(p);
  float f;
  static_assert(sizeof(float) == 4, "IEEE single precision expected");
  std::memcpy(&f, &bits, 4);
  return f;
}

// Text: no NUL and no control characters other than white space.
bool LooksLikeText(const std::string& data) {
  for (char c : data) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 32 && u != '\n' && u != '\r' && u != '\t' && u != '\f' && u != '\v') return false;
  }
  return true;
}

TriangleMesh ParseBinaryStl(const std::string& path, const std::string& data, std::uint32_t n) {
  TriangleMesh mesh;
  mesh.name = path;
  mesh.source_unit = "facet";
  mesh.vertices.reserve(3 * std::size_t(n));
  mesh.triangles.reserve(n);
  mesh.source_line.reserve(n);
  for (std::uint32_t t = 0; t < n; ++t) {
    const char* facet = data.data() + 84 + 50 * std::size_t(t);
    const int first = static_cast<int>(mesh.vertices.size());
    for (int k = 0; k < 3; ++k) {
      Vec3 p;
      for (int i = 0; i < 3; ++i) p[i] = LittleEndianFloat(facet + 12 + 12 * k + 4 * i);
      if (!p.allFinite()) {
        Fail(path, "binary STL facet " + std::to_string(t + 1) + ": vertex " +
                       std::to_string(k + 1) + " is not finite");
      }
      mesh.vertices.push_back(p);
    }
    mesh.triangles.push_back({first, first + 1, first + 2});
    mesh.source_line.push_back(static_cast<int>(t + 1));
  }
  return mesh;
}

TriangleMesh ParseAsciiStl(const std::string& path, const std::string& data) {
  TriangleMesh mesh;
  mesh.name = path;
  mesh.source_unit = "line";
  enum class State { kBeforeSolid, kInSolid, kInFacet, kInLoop, kAfterLoop };
  State state = State::kBeforeSolid;
  int facet_line = 0;
  int loop_vertices = 0;
  std::vector<std::string_view> tokens;
  auto fail = [&](int line, const std::string& what) {
    Fail(path, "line " + std::to_string(line) + ": " + what);
  };
  ForEachLine(data, [&](int line, std::string_view text) {
    Tokenize(text, &tokens);
    if (tokens.empty()) return;
    const std::string_view key = tokens[0];
    switch (state) {
      case State::kBeforeSolid:
        if (!IsKeyword(key, "solid")) fail(line, "expected 'solid', found '" + std::string(tokens[0]) + "'");
        state = State::kInSolid;
        return;
      case State::kInSolid:
        if (IsKeyword(key, "facet")) {
          facet_line = line;
          state = State::kInFacet;
        } else if (IsKeyword(key, "endsolid")) {
          state = State::kBeforeSolid;
        } else {
          fail(line, "expected 'facet' or 'endsolid', found '" + std::string(tokens[0]) + "'");
        }
        return;
      case State::kInFacet:
        if (!IsKeyword(key, "outer") || tokens.size() < 2 || !IsKeyword(tokens[1], "loop")) {
          fail(line, "expected 'outer loop', found '" + std::string(text) + "'");
        }
        loop_vertices = 0;
        state = State::kInLoop;
        return;
      case State::kInLoop:
        if (IsKeyword(key, "vertex")) {
          Vec3 p;
          if (tokens.size() != 4 || !ParseDouble(tokens[1], &p[0]) ||
              !ParseDouble(tokens[2], &p[1]) || !ParseDouble(tokens[3], &p[2])) {
            fail(line, "expected 'vertex x y z' with three finite numbers, found '" +
                           std::string(text) + "'");
          }
          if (++loop_vertices > 3) {
            fail(line, "the facet of line " + std::to_string(facet_line) +
                           " has more than 3 vertices (STL facets are triangles)");
          }
          mesh.vertices.push_back(p);
        } else if (IsKeyword(key, "endloop")) {
          if (loop_vertices != 3) {
            fail(line, "the facet of line " + std::to_string(facet_line) + " has " +
                           std::to_string(loop_vertices) + " vertices, 3 expected");
          }
          const int first = static_cast<int>(mesh.vertices.size()) - 3;
          mesh.triangles.push_back({first, first + 1, first + 2});
          mesh.source_line.push_back(facet_line);
          state = State::kAfterLoop;
        } else {
          fail(line, "expected 'vertex' or 'endloop', found '" + std::string(tokens[0]) + "'");
        }
        return;
      case State::kAfterLoop:
        if (!IsKeyword(key, "endfacet")) fail(line, "expected 'endfacet', found '" + std::string(tokens[0]) + "'");
        state = State::kInSolid;
        return;
    }
  });
  if (state == State::kInFacet || state == State::kInLoop || state == State::kAfterLoop) {
    Fail(path, "the file ends inside the facet of line " + std::to_string(facet_line));
  }
  // A missing final 'endsolid' is accepted (several exporters omit it).
  return mesh;
}

// ---- OBJ ----------------------------------------------------------------------------

TriangleMesh ParseObj(const std::string& path, const std::string& data) {
  TriangleMesh mesh;
  mesh.name = path;
  mesh.source_unit = "line";
  struct Reference {
    long index;  // 1-based as written after resolving negative indices; validated at the end
    int line;
    std::string_view token;
  };
  std::vector<Reference> corners;  // of the current face
  std::vector<Reference> pending;  // corner of every triangle, 3 per triangle
  std::vector<std::string_view> tokens;
  ForEachLine(data, [&](int line, std::string_view text) {
    const std::size_t hash = text.find('#');
    if (hash != std::string_view::npos) text = text.substr(0, hash);
    Tokenize(text, &tokens);
    if (tokens.empty()) return;
    auto fail = [&](const std::string& what) {
      Fail(path, "line " + std::to_string(line) + ": " + what);
    };
    if (tokens[0] == "v") {
      // x y z, optionally followed by w or by a colour: only x y z are used.
      Vec3 p;
      if (tokens.size() < 4 || !ParseDouble(tokens[1], &p[0]) || !ParseDouble(tokens[2], &p[1]) ||
          !ParseDouble(tokens[3], &p[2])) {
        fail("expected 'v x y z' with three finite numbers, found '" + std::string(text) + "'");
      }
      mesh.vertices.push_back(p);
    } else if (tokens[0] == "f") {
      if (tokens.size() < 4) {
        fail("a face needs at least 3 vertices, found " + std::to_string(tokens.size() - 1));
      }
      corners.clear();
      for (std::size_t k = 1; k < tokens.size(); ++k) {
        const std::string_view token = tokens[k];
        const std::string_view index_text = token.substr(0, token.find('/'));
        long index = 0;
        if (!ParseInt(index_text, &index) || index == 0) {
          fail("bad vertex reference '" + std::string(token) +
               "' (a nonzero integer, optionally followed by /texture/normal, expected)");
        }
        if (index < 0) {  // relative to the vertices read so far: -1 is the last one
          const long resolved = static_cast<long>(mesh.vertices.size()) + 1 + index;
          if (resolved < 1) {
            fail("vertex index " + std::to_string(index) + " is out of range (only " +
                 std::to_string(mesh.vertices.size()) + " vertices before this line)");
          }
          index = resolved;
        }
        corners.push_back({index, line, token});
      }
      for (std::size_t k = 1; k + 1 < corners.size(); ++k) {  // fan from the first corner
        pending.push_back(corners[0]);
        pending.push_back(corners[k]);
        pending.push_back(corners[k + 1]);
        mesh.source_line.push_back(line);
      }
    }
    // Every other statement (vt, vn, vp, g, o, s, usemtl, mtllib, l, p, ...) is ignored.
  });
  const long n = static_cast<long>(mesh.vertices.size());
  mesh.triangles.resize(pending.size() / 3);
  for (std::size_t k = 0; k < pending.size(); ++k) {
    const Reference& r = pending[k];
    if (r.index > n) {
      Fail(path, "line " + std::to_string(r.line) + ": vertex index " + std::to_string(r.index) +
                     " is out of range (the file has " + std::to_string(n) + " vertices)");
    }
    mesh.triangles[k / 3][k % 3] = static_cast<int>(r.index - 1);
  }
  return mesh;
}

// ---- vertex merging -------------------------------------------------------------------

struct PointHash {
  std::size_t operator()(const std::array<std::int64_t, 3>& k) const {
    std::size_t h = 1469598103934665603ull;
    for (std::int64_t v : k) h = (h ^ static_cast<std::size_t>(v)) * 1099511628211ull;
    return h;
  }
};

std::array<std::int64_t, 3> ExactKey(const Vec3& p) {
  std::array<std::int64_t, 3> key;
  for (int i = 0; i < 3; ++i) {
    const double x = p[i] + 0.0;  // -0.0 becomes +0.0: equal coordinates, equal keys
    std::memcpy(&key[i], &x, 8);
  }
  return key;
}

}  // namespace

bool MeshReadOptions::IsValid(std::string* error) const {
  if (!(std::isfinite(merge_tolerance) && merge_tolerance >= 0)) {
    if (error) *error = "merge_tolerance must be finite and >= 0, got " + std::to_string(merge_tolerance);
    return false;
  }
  return true;
}

void MergeVertices(TriangleMesh* mesh, double tolerance) {
  const std::size_t n = mesh->vertices.size();
  for (const auto& tri : mesh->triangles) {
    for (int v : tri) {
      if (v < 0 || static_cast<std::size_t>(v) >= n) {
        Fail(Label(*mesh), "triangle vertex index " + std::to_string(v) + " is out of range");
      }
    }
  }
  std::vector<int> used(n, 0);
  for (const auto& tri : mesh->triangles) {
    for (int v : tri) used[v] = 1;
  }
  std::vector<int> new_index(n, -1);
  std::vector<Vec3> kept;
  kept.reserve(n);
  std::unordered_map<std::array<std::int64_t, 3>, int, PointHash> cells;
  cells.reserve(n);
  if (tolerance == 0) {
    for (std::size_t v = 0; v < n; ++v) {
      if (!used[v]) continue;
      const auto [it, inserted] = cells.emplace(ExactKey(mesh->vertices[v]), static_cast<int>(kept.size()));
      if (inserted) kept.push_back(mesh->vertices[v]);
      new_index[v] = it->second;
    }
  } else {
    // Grid of cell size h = 4 x tolerance: a kept vertex within the tolerance of p lies in
    // p's cell or, along an axis where p is within the tolerance of a cell face, in the
    // neighbour across that face (about 1.5^3 cells searched on average). Kept vertices
    // are more than the tolerance apart, so a cell holds at most 5^3 of them. Each cell
    // heads a list of its kept vertices, linked by `next_in_cell`.
    const double h = 4 * tolerance;
    std::unordered_map<std::array<std::int64_t, 3>, int, PointHash> head;
    std::vector<int> next_in_cell;
    for (std::size_t v = 0; v < n; ++v) {
      if (!used[v]) continue;
      const Vec3& p = mesh->vertices[v];
      std::array<std::int64_t, 3> cell;
      int low[3], high[3];
      for (int i = 0; i < 3; ++i) {
        const double x = p[i] / h;
        if (!(std::abs(x) < 1e18)) {
          Fail(Label(*mesh), "merge tolerance " + std::to_string(tolerance) +
                                 " is too small for the vertex coordinate " + std::to_string(p[i]));
        }
        const double f = std::floor(x);
        cell[i] = static_cast<std::int64_t>(f);
        // The distances to the cell faces, with a margin for the round-off of x - f.
        const double margin = tolerance * (1 + 1e-9) + 8e-16 * std::abs(x) * h;
        low[i] = (x - f) * h <= margin ? -1 : 0;
        high[i] = (f + 1 - x) * h <= margin ? 1 : 0;
      }
      int found = -1;  // the first kept vertex within the tolerance
      for (int dx = low[0]; dx <= high[0]; ++dx) {
        for (int dy = low[1]; dy <= high[1]; ++dy) {
          for (int dz = low[2]; dz <= high[2]; ++dz) {
            const auto it = head.find({cell[0] + dx, cell[1] + dy, cell[2] + dz});
            if (it == head.end()) continue;
            for (int k = it->second; k >= 0; k = next_in_cell[k]) {
              if ((found < 0 || k < found) && (kept[k] - p).cwiseAbs().maxCoeff() <= tolerance) {
                found = k;
              }
            }
          }
        }
      }
      if (found < 0) {
        found = static_cast<int>(kept.size());
        kept.push_back(p);
        const auto [it, inserted] = head.emplace(cell, found);
        next_in_cell.push_back(inserted ? -1 : it->second);
        it->second = found;
      }
      new_index[v] = found;
    }
  }
  for (auto& tri : mesh->triangles) {
    for (int& v : tri) v = new_index[v];
  }
  mesh->vertices = std::move(kept);
}

void FlipOrientation(TriangleMesh* mesh) {
  for (auto& tri : mesh->triangles) std::swap(tri[1], tri[2]);
}

TriangleMesh ReadStl(const std::string& path, const MeshReadOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) Fail(path, error);
  const std::string data = ReadWholeFile(path);
  TriangleMesh mesh;
  const bool has_header = data.size() >= 84;
  const std::uint32_t n = has_header ? LittleEndian32(data.data() + 80) : 0;
  const std::uint64_t binary_size = 84 + 50 * std::uint64_t(n);
  // ASCII STL: "solid" after an optional UTF-8 byte-order mark and white space.
  const bool bom = data.compare(0, 3, "\xEF\xBB\xBF") == 0;
  std::size_t first = bom ? 3 : 0;
  while (first < data.size() && IsSpace(data[first])) ++first;
  const bool starts_solid =
      data.size() >= first + 5 && IsKeyword(std::string_view(data.data() + first, 5), "solid");
  if (has_header && data.size() == binary_size) {
    mesh = ParseBinaryStl(path, data, n);
  } else if (starts_solid && LooksLikeText(data)) {
    mesh = bom ? ParseAsciiStl(path, "   " + data.substr(3)) : ParseAsciiStl(path, data);
  } else if (!has_header) {
    Fail(path, "not an STL file: " + std::to_string(data.size()) +
                   " bytes, shorter than a binary STL header (84 bytes), and not ASCII STL "
                   "(text beginning with 'solid')");
  } else {
    Fail(path, "binary STL of wrong size (truncated or padded): its header declares " +
                   std::to_string(n) + " triangles, i.e. 84 + 50 x " + std::to_string(n) +
                   " = " + std::to_string(binary_size) + " bytes, but the file has " +
                   std::to_string(data.size()) + " bytes (and it is not ASCII STL)");
  }
  MergeVertices(&mesh, options.merge_tolerance);
  return mesh;
}

TriangleMesh ReadObj(const std::string& path, const MeshReadOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) Fail(path, error);
  TriangleMesh mesh = ParseObj(path, ReadWholeFile(path));
  MergeVertices(&mesh, options.merge_tolerance);
  return mesh;
}

TriangleMesh ReadMesh(const std::string& path, const MeshReadOptions& options) {
  const std::size_t dot = path.find_last_of('.');
  const std::size_t slash = path.find_last_of("/\\");
  const std::string extension =
      (dot == std::string::npos || (slash != std::string::npos && dot < slash))
          ? std::string()
          : Lower(path.substr(dot + 1));
  if (extension == "stl") return ReadStl(path, options);
  if (extension == "obj") return ReadObj(path, options);
  Fail(path, "unknown mesh format '" + extension + "' (the file name must end in .stl or .obj)");
}

MeshInspection InspectMesh(const TriangleMesh& mesh) {
  const std::string label = Label(mesh);
  MeshInspection r;
  r.vertices = static_cast<int>(mesh.vertices.size());
  r.triangles = static_cast<int>(mesh.triangles.size());
  struct HalfEdge {
    int lo, hi;
    int triangle;
    bool forward;  // traversed lo -> hi
  };
  std::vector<HalfEdge> half_edges;
  half_edges.reserve(3 * mesh.triangles.size());
  std::vector<char> vertex_used(mesh.vertices.size(), 0);
  const Vec3 p0 = [&] {
    Vec3 sum = Vec3::Zero();
    for (const Vec3& p : mesh.vertices) sum += p;
    return mesh.vertices.empty() ? sum : Vec3(sum / double(mesh.vertices.size()));
  }();
  double six_volume = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    for (int v : tri) {
      if (v < 0 || v >= r.vertices) {
        Fail(label, WhereTriangle(mesh, t) + ": vertex index " + std::to_string(v) +
                        " is out of range (" + std::to_string(r.vertices) + " vertices)");
      }
      if (!vertex_used[v] && !mesh.vertices[v].allFinite()) {
        Fail(label, WhereTriangle(mesh, t) + ": vertex " + std::to_string(v) + " is not finite");
      }
      vertex_used[v] = 1;
    }
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      ++r.degenerate_triangles;
      continue;
    }
    const Vec3 a = mesh.vertices[tri[0]] - p0, b = mesh.vertices[tri[1]] - p0,
               c = mesh.vertices[tri[2]] - p0;
    const Vec3& pa = mesh.vertices[tri[0]];
    if ((mesh.vertices[tri[1]] - pa).cross(mesh.vertices[tri[2]] - pa).squaredNorm() == 0) {
      ++r.zero_area_triangles;
    }
    six_volume += a.dot(b.cross(c));
    for (int k = 0; k < 3; ++k) {
      const int u = tri[k], v = tri[(k + 1) % 3];
      half_edges.push_back({std::min(u, v), std::max(u, v), static_cast<int>(t), u < v});
    }
  }
  r.volume = six_volume / 6;
  std::sort(half_edges.begin(), half_edges.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return x.lo != y.lo ? x.lo < y.lo : x.hi != y.hi ? x.hi < y.hi : x.triangle < y.triangle;
  });
  std::string boundary_example, nonmanifold_example, misoriented_example;
  auto describe = [&](const HalfEdge* first, std::size_t count) {
    std::string s = "the edge " + FormatPoint(mesh.vertices[first->lo]) + " - " +
                    FormatPoint(mesh.vertices[first->hi]) + " of ";
    for (std::size_t k = 0; k < count; ++k) {
      if (k > 0) s += k + 1 == count ? " and " : ", ";
      s += WhereTriangle(mesh, first[k].triangle);
    }
    return s;
  };
  for (std::size_t i = 0; i < half_edges.size();) {
    std::size_t j = i;
    int forward = 0;
    while (j < half_edges.size() && half_edges[j].lo == half_edges[i].lo &&
           half_edges[j].hi == half_edges[i].hi) {
      forward += half_edges[j].forward;
      ++j;
    }
    const std::size_t count = j - i;
    ++r.edges;
    if (count == 1) {
      if (r.boundary_edges++ == 0) boundary_example = describe(&half_edges[i], count);
    } else if (count > 2) {
      if (r.nonmanifold_edges++ == 0) nonmanifold_example = describe(&half_edges[i], count);
    } else if (forward != 1) {
      if (r.misoriented_edges++ == 0) misoriented_example = describe(&half_edges[i], count);
    }
    i = j;
  }
  std::vector<std::string> problems;
  if (r.triangles - r.degenerate_triangles == 0) {
    problems.push_back(r.triangles == 0 ? "the mesh is empty (no triangles)"
                                        : "the mesh has no triangle with three distinct vertices");
  }
  if (r.boundary_edges > 0) {
    problems.push_back("the mesh is open: " + std::to_string(r.boundary_edges) +
                       " boundary edge(s) used by one triangle only, e.g. " + boundary_example);
  }
  if (r.nonmanifold_edges > 0) {
    problems.push_back("the mesh is non-manifold: " + std::to_string(r.nonmanifold_edges) +
                       " edge(s) used by more than two triangles, e.g. " + nonmanifold_example);
  }
  if (r.misoriented_edges > 0) {
    problems.push_back("the triangles are inconsistently oriented: " +
                       std::to_string(r.misoriented_edges) +
                       " edge(s) traversed twice in the same direction (a flipped triangle), e.g. " +
                       misoriented_example);
  }
  if (problems.empty() && !(r.volume > 0)) {
    std::ostringstream out;
    out << std::setprecision(10);
    if (r.volume < 0) {
      out << "the mesh is inside out: its signed volume is " << r.volume
          << " (the triangles must be counter-clockwise seen from outside; reverse the vertex "
             "order of every triangle)";
    } else {
      out << "the mesh encloses no volume (signed volume " << r.volume << ")";
    }
    problems.push_back(out.str());
  }
  for (std::size_t k = 0; k < problems.size(); ++k) r.message += (k ? "; " : "") + problems[k];
  return r;
}

double MeshVolume(const TriangleMesh& mesh) {
  const MeshInspection inspection = InspectMesh(mesh);
  if (!inspection.IsClosed()) Fail(Label(mesh), inspection.message);
  return inspection.volume;
}

namespace {

MassProperties ComputeMassProperties(const TriangleMesh& mesh, double density, double scale,
                                     Vec3* centre_of_mass, double* scaled_volume) {
  const std::string label = Label(mesh);
  if (!(std::isfinite(density) && density > 0)) {
    Fail(label, "mesh density must be > 0, got " + std::to_string(density));
  }
  if (!(std::isfinite(scale) && scale > 0)) {
    Fail(label, "mesh scale must be > 0, got " + std::to_string(scale));
  }
  const MeshInspection inspection = InspectMesh(mesh);
  if (!inspection.IsClosed()) Fail(label, inspection.message);

  Vec3 p0 = Vec3::Zero();
  for (const Vec3& p : mesh.vertices) p0 += p;
  p0 /= double(mesh.vertices.size());
  double six_volume = 0;    // sum of d
  Vec3 first = Vec3::Zero();   // sum of d s
  Mat3 second = Mat3::Zero();  // sum of d (a a^T + b b^T + c c^T + s s^T)
  for (const auto& tri : mesh.triangles) {
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) continue;  // degenerate
    const Vec3 a = mesh.vertices[tri[0]] - p0, b = mesh.vertices[tri[1]] - p0,
               c = mesh.vertices[tri[2]] - p0;
    const double d = a.dot(b.cross(c));
    const Vec3 s = a + b + c;
    six_volume += d;
    first += d * s;
    second.noalias() += d * (a * a.transpose() + b * b.transpose() + c * c.transpose() +
                             s * s.transpose());
  }
  const double volume = six_volume / 6;
  const Vec3 centroid = first / 24 / volume;  // from p0, file units
  // Second moment about the centroid (file units^5), symmetrised against round-off.
  Mat3 covariance = second / 120 - volume * centroid * centroid.transpose();
  covariance = 0.5 * (covariance + covariance.transpose()).eval();
  const double s3 = scale * scale * scale;
  MassProperties p;
  p.mass = density * volume * s3;
  p.inertia = density * s3 * scale * scale *
              (covariance.trace() * Mat3::Identity() - covariance);
  if (centre_of_mass) *centre_of_mass = scale * (p0 + centroid);
  if (scaled_volume) *scaled_volume = volume * s3;
  return p;
}

}  // namespace

MassProperties MeshMassProperties(const TriangleMesh& mesh, double density, double scale,
                                  Vec3* centre_of_mass) {
  return ComputeMassProperties(mesh, density, scale, centre_of_mass, nullptr);
}

MeshBodyProperties LoadMeshBody(const std::string& path, double density, double scale,
                                const MeshReadOptions& options) {
  const TriangleMesh mesh = ReadMesh(path, options);
  MeshBodyProperties body;
  body.mass = ComputeMassProperties(mesh, density, scale, &body.centre_of_mass, &body.volume);
  body.vertices = static_cast<int>(mesh.vertices.size());
  body.triangles = static_cast<int>(mesh.triangles.size());
  return body;
}

}  // namespace mbdae::mbs
