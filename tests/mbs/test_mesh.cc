// Tests of mbs/mesh: reading STL (ASCII, binary) and OBJ, the checks of closed meshes, and
// mass properties against closed forms (mbs/geometry.h) and independent constructions.
// Every mesh file is written at run time into the test's temporary directory.
#include "mbs/mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "mbs/geometry.h"

namespace mbdae::mbs {
namespace {

// ---- helpers -------------------------------------------------------------------------

// A file name unique to the running test (ctest runs tests in parallel processes).
std::string TempPath(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return ::testing::TempDir() + "mbdae_mesh_" + info->test_suite_name() + "_" + info->name() +
         "_" + name;
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

Vec3 Normal(const TriangleMesh& m, const std::array<int, 3>& t) {
  const Vec3 n = (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]);
  return n.norm() > 0 ? Vec3(n.normalized()) : n;
}

void WriteAsciiStl(const std::string& path, const TriangleMesh& m) {
  std::string s = "solid test\n";
  char line[256];
  for (const auto& t : m.triangles) {
    const Vec3 n = Normal(m, t);
    std::snprintf(line, sizeof line, "  facet normal %.17g %.17g %.17g\n    outer loop\n", n.x(),
                  n.y(), n.z());
    s += line;
    for (int v : t) {
      const Vec3& p = m.vertices[v];
      std::snprintf(line, sizeof line, "      vertex %.17g %.17g %.17g\n", p.x(), p.y(), p.z());
      s += line;
    }
    s += "    endloop\n  endfacet\n";
  }
  s += "endsolid test\n";
  WriteText(path, s);
}

void PutU32(std::string* s, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) s->push_back(static_cast<char>((v >> (8 * k)) & 0xff));
}
void PutFloat(std::string* s, double x) {
  const float f = static_cast<float>(x);
  std::uint32_t bits;
  std::memcpy(&bits, &f, 4);
  PutU32(s, bits);
}

// Binary STL; the 80-byte header begins with `header` (e.g. "solid", to check that the
// size rule, not the prefix, decides).
std::string BinaryStl(const TriangleMesh& m, const std::string& header = "binary test") {
  std::string s(80, ' ');
  s.replace(0, header.size(), header);
  PutU32(&s, static_cast<std::uint32_t>(m.triangles.size()));
  for (const auto& t : m.triangles) {
    const Vec3 n = Normal(m, t);
    for (int i = 0; i < 3; ++i) PutFloat(&s, n[i]);
    for (int v : t) {
      for (int i = 0; i < 3; ++i) PutFloat(&s, m.vertices[v][i]);
    }
    s.push_back(0);
    s.push_back(0);
  }
  return s;
}

void WriteObj(const std::string& path, const TriangleMesh& m) {
  std::string s = "# test mesh\n";
  char line[256];
  for (const Vec3& p : m.vertices) {
    std::snprintf(line, sizeof line, "v %.17g %.17g %.17g\n", p.x(), p.y(), p.z());
    s += line;
  }
  for (const auto& t : m.triangles) {
    s += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " +
         std::to_string(t[2] + 1) + "\n";
  }
  WriteText(path, s);
}

// Corner k of the unit cube: (k & 1, k >> 1 & 1, k >> 2 & 1). Faces as quads,
// counter-clockwise seen from outside.
constexpr int kCubeQuads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                  {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};

// A box of edge lengths `size` centred at `centre`, rotated by R: 8 vertices, 12 triangles.
TriangleMesh BoxMesh(const Vec3& size, const Mat3& R = Mat3::Identity(),
                     const Vec3& centre = Vec3::Zero()) {
  TriangleMesh m;
  m.name = "box";
  for (int k = 0; k < 8; ++k) {
    const Vec3 unit((k & 1) - 0.5, ((k >> 1) & 1) - 0.5, ((k >> 2) & 1) - 0.5);
    m.vertices.push_back(R * unit.cwiseProduct(size) + centre);
  }
  for (const auto& q : kCubeQuads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

// Icosahedron inscribed in the sphere of radius r, subdivided k times (each triangle into
// four by its edge midpoints, pushed out onto the sphere): 20 4^k triangles.
TriangleMesh IcoSphere(double r, int k) {
  const double phi = (1 + std::sqrt(5.0)) / 2;
  TriangleMesh m;
  m.name = "icosphere";
  const double raw[12][3] = {{-1, phi, 0}, {1, phi, 0}, {-1, -phi, 0}, {1, -phi, 0},
                             {0, -1, phi}, {0, 1, phi}, {0, -1, -phi}, {0, 1, -phi},
                             {phi, 0, -1}, {phi, 0, 1}, {-phi, 0, -1}, {-phi, 0, 1}};
  for (const auto& p : raw) m.vertices.push_back(r * Vec3(p[0], p[1], p[2]).normalized());
  m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& t : m.triangles) {  // outward orientation
    const Vec3 c = m.vertices[t[0]] + m.vertices[t[1]] + m.vertices[t[2]];
    if (Normal(m, t).dot(c) < 0) std::swap(t[1], t[2]);
  }
  for (int level = 0; level < k; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      m.vertices.push_back(r * (m.vertices[a] + m.vertices[b]).normalized());
      return midpoint[key] = static_cast<int>(m.vertices.size()) - 1;
    };
    std::vector<std::array<int, 3>> refined;
    for (const auto& t : m.triangles) {
      const int ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      refined.push_back({t[0], ab, ca});
      refined.push_back({t[1], bc, ab});
      refined.push_back({t[2], ca, bc});
      refined.push_back({ab, bc, ca});
    }
    m.triangles = std::move(refined);
  }
  return m;
}

Mat3 RandomishRotation() {
  return Eigen::AngleAxisd(0.7, Vec3(1, -2, 0.5).normalized()).toRotationMatrix() *
         Eigen::AngleAxisd(-1.3, Vec3(0.2, 0.4, 1).normalized()).toRotationMatrix();
}

// Relative difference of two inertia tensors, relative to the largest entry of b.
double InertiaError(const Mat3& a, const Mat3& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// Calls f, which must throw std::runtime_error whose message contains every piece.
void ExpectError(const std::function<void()>& f, const std::vector<std::string>& pieces) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one containing '" << pieces.front() << "'";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    for (const std::string& piece : pieces) {
      EXPECT_NE(what.find(piece), std::string::npos) << "'" << piece << "' not in: " << what;
    }
  }
}

// ---- box: closed forms to 1e-12 -----------------------------------------------------

// The box edge lengths and centre are exact in single precision, so that the binary STL
// holds the same box.
const Vec3 kSize(0.5, 0.25, 2.0);
const Vec3 kCentre(1.5, -2.25, 0.75);
constexpr double kDensity = 7800;

void ExpectBox(const TriangleMesh& mesh, const Vec3& size, const Mat3& R, const Vec3& centre,
               double density = kDensity, double scale = 1.0) {
  Vec3 c;
  const MassProperties p = MeshMassProperties(mesh, density, scale, &c);
  const MassProperties ref = BoxMass(scale * size, density);
  EXPECT_NEAR(p.mass / ref.mass, 1.0, 1e-12) << mesh.name;
  EXPECT_LT(InertiaError(p.inertia, R * ref.inertia * R.transpose()), 1e-12) << mesh.name;
  EXPECT_LT((c - scale * centre).norm(), 1e-12 * (1 + scale * centre.norm())) << mesh.name;
  EXPECT_EQ(p.inertia, p.inertia.transpose());
}

TEST(MeshMass, BoxInMemoryCentredOffsetRotated) {
  const MeshInspection inspection = InspectMesh(BoxMesh(kSize));
  EXPECT_TRUE(inspection.IsClosed()) << inspection.message;
  EXPECT_EQ(inspection.vertices, 8);
  EXPECT_EQ(inspection.triangles, 12);
  EXPECT_EQ(inspection.edges, 18);
  EXPECT_NEAR(inspection.volume, kSize.prod(), 1e-15);
  ExpectBox(BoxMesh(kSize), kSize, Mat3::Identity(), Vec3::Zero());
  ExpectBox(BoxMesh(kSize, Mat3::Identity(), kCentre), kSize, Mat3::Identity(), kCentre);
  const Mat3 R = RandomishRotation();
  ExpectBox(BoxMesh(kSize, R, kCentre), kSize, R, kCentre);
  // Far from the origin of the mesh axes: the reference point keeps the digits.
  const Vec3 far(1e3, -2e3, 5e2);
  ExpectBox(BoxMesh(kSize, R, far), kSize, R, far);
}

TEST(MeshMass, BoxFromAsciiStl) {
  const std::string path = TempPath("box.stl");
  const Mat3 R = RandomishRotation();
  WriteAsciiStl(path, BoxMesh(kSize, R, kCentre));
  const TriangleMesh mesh = ReadMesh(path);
  EXPECT_EQ(mesh.vertices.size(), 8u);  // 36 corners merged into 8
  EXPECT_EQ(mesh.triangles.size(), 12u);
  EXPECT_EQ(mesh.name, path);
  ExpectBox(mesh, kSize, R, kCentre);
}

TEST(MeshRead, AsciiStlWithByteOrderMarkLeadingSpaceAndUpperCase) {
  const std::string path = TempPath("tet.STL");
  // The unit tetrahedron (0, e_x, e_y, e_z): volume V = 1/6, centroid (1/4, 1/4, 1/4),
  // moments about the origin int x_i x_j dV = V (1 + delta_ij) / 20 (the simplex moments),
  // so about the centroid 1/60 - V/16 = 1/160 (i = j) and 1/120 - V/16 = -1/480 (i != j);
  // with density 6: Ixx = 6 (2/160) = 0.075, Ixy = -6 (-1/480) = 0.0125.
  WriteText(path,
            "\xEF\xBB\xBF  \n  SOLID tet\n"
            "FACET NORMAL 0 0 -1\n OUTER LOOP\n VERTEX 0 0 0\n VERTEX 0 1 0\n VERTEX 1 0 0\n"
            " ENDLOOP\nENDFACET\n"
            "facet normal 0 -1 0\n outer loop\n vertex 0 0 0\n vertex +1 0 0\n vertex 0 0 1e0\n"
            " endloop\nendfacet\n"
            "facet normal -1 0 0\n outer loop\n vertex 0 0 0\n vertex 0 0 1\n vertex 0 1 0\n"
            " endloop\nendfacet\n"
            "facet normal 1 1 1\n outer loop\n vertex 1 0 0\n vertex 0 1 0\n vertex 0 0 1\n"
            " endloop\nendfacet\n");  // no endsolid: accepted
  const MeshBodyProperties body = LoadMeshBody(path, 6.0);
  EXPECT_EQ(body.vertices, 4);
  EXPECT_NEAR(body.volume, 1.0 / 6.0, 1e-16);
  EXPECT_NEAR(body.mass.mass, 1.0, 1e-15);
  EXPECT_LT((body.centre_of_mass - Vec3::Constant(0.25)).norm(), 1e-15);
  Mat3 reference = Mat3::Constant(0.0125);
  reference.diagonal().setConstant(0.075);
  EXPECT_LT(InertiaError(body.mass.inertia, reference), 1e-14);
}

TEST(MeshMass, BoxFromBinaryStlEvenWithSolidInHeader) {
  for (const std::string header : {"binary box", "solid box (binary: the size rule decides)"}) {
    const std::string path = TempPath("box.stl");
    WriteText(path, BinaryStl(BoxMesh(kSize, Mat3::Identity(), kCentre), header));
    const TriangleMesh mesh = ReadMesh(path);
    EXPECT_EQ(mesh.vertices.size(), 8u);
    EXPECT_EQ(mesh.source_unit, "facet");
    ExpectBox(mesh, kSize, Mat3::Identity(), kCentre);
  }
}

TEST(MeshMass, BoxFromObjWithQuadsNegativeIndicesAndSlashForms) {
  const TriangleMesh box = BoxMesh(kSize, Mat3::Identity(), kCentre);
  std::string s =
      "# a box\nmtllib box.mtl\no box\ng faces\n\n";
  char line[128];
  for (const Vec3& p : box.vertices) {
    std::snprintf(line, sizeof line, "v %.17g %.17g %.17g 1.0\n", p.x(), p.y(), p.z());
    s += line;
  }
  s += "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nusemtl steel\ns off\n";
  const char* forms[] = {"%d", "%d/1", "%d//1", "%d/2/1"};
  for (int f = 0; f < 6; ++f) {
    s += "f";
    for (int k = 0; k < 4; ++k) {
      // Faces 0-2 with 1-based indices, faces 3-5 with negative (relative) ones.
      const int index = f < 3 ? kCubeQuads[f][k] + 1 : kCubeQuads[f][k] - 8;
      std::snprintf(line, sizeof line, forms[(f + k) % 4], index);
      s += std::string(" ") + line;
    }
    s += f == 2 ? "   # a comment\r\n" : "\n";
  }
  s += "l 1 2\n";
  const std::string path = TempPath("box.OBJ");
  WriteText(path, s);
  const TriangleMesh mesh = ReadMesh(path);
  EXPECT_EQ(mesh.vertices.size(), 8u);
  ASSERT_EQ(mesh.triangles.size(), 12u);  // 6 quads, fan-triangulated
  ASSERT_EQ(mesh.source_line.size(), 12u);
  EXPECT_EQ(mesh.source_line[0], 20);  // the first f line
  ExpectBox(mesh, kSize, Mat3::Identity(), kCentre);
}

TEST(MeshMass, ScaleGivesMassCubedAndInertiaToTheFifth) {
  const Mat3 R = RandomishRotation();
  const TriangleMesh mesh = BoxMesh(Vec3(50, 20, 10), R, Vec3(3, 4, 5));  // millimetres
  Vec3 c1, cs;
  const MassProperties p1 = MeshMassProperties(mesh, 2700, 1.0, &c1);
  const double s = 1e-3;
  const MassProperties ps = MeshMassProperties(mesh, 2700, s, &cs);
  EXPECT_NEAR(ps.mass / (p1.mass * s * s * s), 1.0, 1e-14);
  EXPECT_LT(InertiaError(ps.inertia, p1.inertia * std::pow(s, 5)), 1e-14);
  EXPECT_LT((cs - s * c1).norm(), 1e-15);
  // And the scaled mesh is the box of scaled size: 0.05 x 0.02 x 0.01 m of aluminium.
  ExpectBox(mesh, Vec3(50, 20, 10), R, Vec3(3, 4, 5), 2700, s);
  EXPECT_NEAR(ps.mass, 0.05 * 0.02 * 0.01 * 2700, 1e-15);
  // Density enters linearly.
  EXPECT_NEAR(MeshMassProperties(mesh, 5400, s, nullptr).mass / ps.mass, 2.0, 1e-15);
}

// ---- a non-symmetric solid: an L-shaped prism against two boxes ------------------------

// The L = box A [0,2]x[0,1]x[0,1] + box B [0,1]x[1,3]x[0,1], as an extruded L polygon: 12
// vertices, 20 triangles. Reference: BoxMass of A and B moved to the common centre of
// mass by the parallel-axis theorem, I_c = I_box + m (|d|^2 1 - d d^T); it has a nonzero
// product of inertia Ixy.
TriangleMesh LPrism(const Mat3& R, const Vec3& offset) {
  const double polygon[6][2] = {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 3}, {0, 3}};  // ccw
  TriangleMesh m;
  m.name = "L";
  for (int z = 0; z < 2; ++z) {
    for (const auto& p : polygon) m.vertices.push_back(R * Vec3(p[0], p[1], z) + offset);
  }
  const int fan[4][3] = {{3, 4, 5}, {3, 5, 0}, {3, 0, 1}, {3, 1, 2}};  // from the reflex corner
  for (const auto& t : fan) {
    m.triangles.push_back({t[0] + 6, t[1] + 6, t[2] + 6});  // top, ccw from above
    m.triangles.push_back({t[0], t[2], t[1]});              // bottom, reversed
  }
  for (int i = 0; i < 6; ++i) {
    const int j = (i + 1) % 6;
    m.triangles.push_back({i, j, j + 6});
    m.triangles.push_back({i, j + 6, i + 6});
  }
  return m;
}

TEST(MeshMass, LPrismAgainstParallelAxisTheorem) {
  const double rho = 3.0;
  const MassProperties a = BoxMass(Vec3(2, 1, 1), rho), b = BoxMass(Vec3(1, 2, 1), rho);
  const Vec3 ca(1, 0.5, 0.5), cb(0.5, 2, 0.5);
  const double m = a.mass + b.mass;  // 12
  const Vec3 c = (a.mass * ca + b.mass * cb) / m;
  auto shifted = [&](const MassProperties& p, const Vec3& cp) {
    const Vec3 d = cp - c;
    return Mat3(p.inertia + p.mass * (d.squaredNorm() * Mat3::Identity() - d * d.transpose()));
  };
  const Mat3 reference = shifted(a, ca) + shifted(b, cb);
  ASSERT_GT(std::abs(reference(0, 1)), 1.0);  // a real product of inertia (Ixy = 3.0)

  const Mat3 R = RandomishRotation();
  const Vec3 offset(-40, 25, 7);
  Vec3 com;
  for (int run = 0; run < 2; ++run) {  // twice: no state kept between calls
    const MassProperties p = MeshMassProperties(LPrism(R, offset), rho, 1.0, &com);
    EXPECT_NEAR(p.mass, m, 1e-12 * m);
    EXPECT_LT(InertiaError(p.inertia, R * reference * R.transpose()), 1e-12);
    EXPECT_LT((com - (R * c + offset)).norm(), 1e-12 * offset.norm());
  }
}

// ---- sphere: the discretisation error of the closed form ------------------------------

// Icospheres of radius r subdivided k = 0..5 times. Checks, for each k:
//  - the volume equals the polyhedron's own volume computed independently, as the sum of
//    the pyramids from the centre over the faces, area x (distance of the face plane) / 3,
//    to 1e-13;
//  - inclusion bounds: the polyhedron contains the ball of radius r_in (the smallest
//    distance from the centre to a face plane) and lies inside the ball of radius r, so
//    its mass and each diagonal moment of inertia lie between those of the two balls
//    (the integrands 1, y^2 + z^2, ... are non-negative; the centre of mass is the centre
//    by the icosahedral symmetry, which also makes the inertia isotropic: checked);
//  - the relative errors of mass and inertia against SphereMass(r) fall ~4x per
//    refinement (second order in the edge length): ratios within 4 +- 0.15 for k >= 3
//    (measured: mass 3.93, 3.98, 3.98; inertia 3.90, 3.97, 3.99 for k = 3, 4, 5).
TEST(MeshMass, IcoSphereConvergesToSphereAtSecondOrder) {
  const double r = 0.1, rho = 7800;
  const MassProperties sphere = SphereMass(r, rho);
  double previous_mass_error = 0, previous_inertia_error = 0;
  for (int k = 0; k <= 5; ++k) {
    const TriangleMesh mesh = IcoSphere(r, k);
    ASSERT_EQ(mesh.triangles.size(), 20u << (2 * k));
    double pyramids = 0, r_in = r;
    for (const auto& t : mesh.triangles) {
      const Vec3 n = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                         .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
      const double area = n.norm() / 2, height = n.normalized().dot(mesh.vertices[t[0]]);
      pyramids += area * height / 3;
      r_in = std::min(r_in, height);
    }
    Vec3 c;
    const MassProperties p = MeshMassProperties(mesh, rho, 1.0, &c);
    EXPECT_NEAR(MeshVolume(mesh) / pyramids, 1.0, 1e-13) << "k = " << k;
    EXPECT_NEAR(p.mass / (rho * pyramids), 1.0, 1e-13) << "k = " << k;
    EXPECT_LT(c.norm(), 1e-15) << "k = " << k;
    EXPECT_LT(InertiaError(p.inertia, p.inertia(0, 0) * Mat3::Identity()), 1e-12) << "k = " << k;

    const MassProperties inner = SphereMass(r_in, rho);
    EXPECT_GT(p.mass, inner.mass);
    EXPECT_LT(p.mass, sphere.mass);
    for (int i = 0; i < 3; ++i) {
      EXPECT_GT(p.inertia(i, i), inner.inertia(i, i));
      EXPECT_LT(p.inertia(i, i), sphere.inertia(i, i));
    }
    const double mass_error = 1 - p.mass / sphere.mass;
    const double inertia_error = 1 - p.inertia(0, 0) / sphere.inertia(0, 0);
    if (k >= 3) {
      EXPECT_NEAR(previous_mass_error / mass_error, 4.0, 0.15) << "k = " << k;
      EXPECT_NEAR(previous_inertia_error / inertia_error, 4.0, 0.15) << "k = " << k;
    }
    std::printf("icosphere k=%d triangles=%6zu mass rel. error %.4e inertia rel. error %.4e\n", k,
                mesh.triangles.size(), mass_error, inertia_error);
    previous_mass_error = mass_error;
    previous_inertia_error = inertia_error;
  }
  // At k = 5 (20480 triangles) the mesh is within 1e-3 of the sphere in mass.
  EXPECT_LT(previous_mass_error, 1e-3);
}

// A shell with a cavity: the outer icosphere and the inner one turned inside out, in one
// mesh. The divergence theorem subtracts the cavity: mass and inertia are the differences.
TEST(MeshMass, HollowSphereSubtractsTheCavity) {
  const TriangleMesh outer = IcoSphere(1.0, 3);
  TriangleMesh inner = IcoSphere(0.6, 2);
  FlipOrientation(&inner);
  TriangleMesh hollow = outer;
  const int offset = static_cast<int>(outer.vertices.size());
  hollow.vertices.insert(hollow.vertices.end(), inner.vertices.begin(), inner.vertices.end());
  for (const auto& t : inner.triangles) {
    hollow.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  }
  FlipOrientation(&inner);
  const MassProperties po = MeshMassProperties(outer, 2.0, 1.0, nullptr);
  const MassProperties pi = MeshMassProperties(inner, 2.0, 1.0, nullptr);
  const MassProperties ph = MeshMassProperties(hollow, 2.0, 1.0, nullptr);
  EXPECT_NEAR(ph.mass, po.mass - pi.mass, 1e-13 * po.mass);
  EXPECT_LT(InertiaError(ph.inertia, po.inertia - pi.inertia), 1e-12);
}

TEST(MeshMass, IcoSphereThroughStlAndObjFiles) {
  const TriangleMesh mesh = IcoSphere(0.5, 3);
  const MassProperties direct = MeshMassProperties(mesh, 1000, 1.0, nullptr);
  const std::string stl = TempPath("sphere.stl"), obj = TempPath("sphere.obj");
  WriteAsciiStl(stl, mesh);
  WriteObj(obj, mesh);
  for (const std::string& path : {stl, obj}) {
    const MeshBodyProperties body = LoadMeshBody(path, 1000, 1.0);
    EXPECT_EQ(body.vertices, static_cast<int>(mesh.vertices.size())) << path;
    EXPECT_EQ(body.triangles, static_cast<int>(mesh.triangles.size())) << path;
    EXPECT_NEAR(body.mass.mass / direct.mass, 1.0, 1e-13) << path;
    EXPECT_NEAR(body.volume * 1000 / direct.mass, 1.0, 1e-13) << path;
    EXPECT_LT(InertiaError(body.mass.inertia, direct.inertia), 1e-12) << path;
  }
}

// ---- vertex merging and degenerate triangles ----------------------------------------

TEST(MeshRead, MergeToleranceClosesANearlyClosedStl) {
  TriangleMesh soup = BoxMesh(kSize);
  // As STL stores it: every triangle its own corners; one corner moved by 1e-9.
  TriangleMesh separate;
  for (const auto& t : soup.triangles) {
    const int first = static_cast<int>(separate.vertices.size());
    for (int v : t) separate.vertices.push_back(soup.vertices[v]);
    separate.triangles.push_back({first, first + 1, first + 2});
  }
  separate.vertices[4] += Vec3(1e-9, 0, -1e-9);
  const std::string path = TempPath("near.stl");
  WriteAsciiStl(path, separate);
  ExpectError([&] { MeshMassProperties(ReadMesh(path), 1, 1, nullptr); },
              {path, "open", "4 boundary edge(s)"});  // the two edges at the moved corner, both sides
  MeshReadOptions options;
  options.merge_tolerance = 1e-6;
  const TriangleMesh merged = ReadMesh(path, options);
  EXPECT_EQ(merged.vertices.size(), 8u);
  EXPECT_NEAR(MeshVolume(merged), kSize.prod(), 1e-9);

  options.merge_tolerance = -1;
  std::string error;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("merge_tolerance"), std::string::npos);
  ExpectError([&] { ReadMesh(path, options); }, {path, "merge_tolerance"});
}

// MergeVertices with a tolerance against the quadratic rule it implements: each vertex, in
// order, joins the first kept vertex within the tolerance in every coordinate, or is kept.
// Clusters of points jittered around lattice points, so that many cross cell faces.
TEST(MeshRead, MergeToleranceMatchesBruteForce) {
  const double tolerance = 0.01;
  TriangleMesh mesh;
  mesh.name = "cloud";
  unsigned state = 12345;
  auto uniform = [&state] {  // a small linear congruential generator: same points everywhere
    state = state * 1103515245u + 12345u;
    return ((state >> 8) & 0xffff) / 65535.0;
  };
  for (int k = 0; k < 1500; ++k) {
    const Vec3 lattice(k % 7 * 0.013, k / 7 % 5 * 0.011, k / 35 % 3 * 0.017);
    mesh.vertices.push_back(lattice + 0.012 * Vec3(uniform(), uniform(), uniform()) -
                            Vec3::Constant(0.006) + Vec3(-0.5, 3.0, 1.0));
  }
  for (int k = 0; k + 2 < 1500; k += 3) mesh.triangles.push_back({k, k + 1, k + 2});
  std::vector<Vec3> kept;
  std::vector<int> expected;
  for (const Vec3& p : mesh.vertices) {
    int found = -1;
    for (std::size_t j = 0; j < kept.size() && found < 0; ++j) {
      if ((kept[j] - p).cwiseAbs().maxCoeff() <= tolerance) found = static_cast<int>(j);
    }
    if (found < 0) {
      found = static_cast<int>(kept.size());
      kept.push_back(p);
    }
    expected.push_back(found);
  }
  ASSERT_GT(kept.size(), 20u);
  ASSERT_LT(kept.size(), 1000u);
  TriangleMesh merged = mesh;
  MergeVertices(&merged, tolerance);
  ASSERT_EQ(merged.vertices.size(), kept.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(merged.triangles[t][c], expected[mesh.triangles[t][c]]) << "vertex " << 3 * t + c;
    }
  }
  for (std::size_t j = 0; j < kept.size(); ++j) EXPECT_EQ(merged.vertices[j], kept[j]);
}

TEST(MeshRead, DegenerateTrianglesAreSkipped) {
  TriangleMesh mesh = BoxMesh(kSize);
  mesh.triangles.push_back({0, 0, 1});  // a repeated index: no area, no edge
  mesh.triangles.push_back({2, 5, 5});
  const MeshInspection inspection = InspectMesh(mesh);
  EXPECT_TRUE(inspection.IsClosed()) << inspection.message;
  EXPECT_EQ(inspection.degenerate_triangles, 2);
  EXPECT_EQ(inspection.edges, 18);
  ExpectBox(mesh, kSize, Mat3::Identity(), Vec3::Zero());
}

TEST(MeshRead, ZeroAreaSliverIsKeptAndCounted) {
  // A T-junction closed by a sliver: the triangle (1, 3, 7) of the face x = +1 is split
  // at the midpoint m of its edge 1-3 into (1, m, 7) and (m, 3, 7); the edge 3 -> 1 of the
  // face z = -1 is then matched by the sliver (1, 3, m), whose three corners are collinear.
  TriangleMesh mesh = BoxMesh(Vec3(2, 2, 2));
  const int m = static_cast<int>(mesh.vertices.size());
  mesh.vertices.push_back(0.5 * (mesh.vertices[1] + mesh.vertices[3]));
  std::vector<std::array<int, 3>> triangles;
  for (const auto& t : mesh.triangles) {
    if (t == std::array<int, 3>{1, 3, 7}) {  // on the face x = +1: split at m
      triangles.push_back({1, m, 7});
      triangles.push_back({m, 3, 7});
    } else {
      triangles.push_back(t);
    }
  }
  triangles.push_back({1, 3, m});  // the sliver: edges 1-3, 3-m, m-1 collinear
  mesh.triangles = triangles;
  const MeshInspection inspection = InspectMesh(mesh);
  EXPECT_TRUE(inspection.IsClosed()) << inspection.message;
  EXPECT_EQ(inspection.zero_area_triangles, 1);
  ExpectBox(mesh, Vec3(2, 2, 2), Mat3::Identity(), Vec3::Zero(), 1.0);
}

// ---- rejected meshes: each with its message -----------------------------------------

TEST(MeshErrors, OpenMeshNamesBoundaryEdges) {
  TriangleMesh mesh = BoxMesh(kSize);
  mesh.triangles.pop_back();  // a hole: the triangle (4, 7, 6) of the face z = +c/2
  const std::string path = TempPath("open.stl");
  WriteAsciiStl(path, mesh);
  const MeshInspection inspection = InspectMesh(ReadMesh(path));
  EXPECT_EQ(inspection.boundary_edges, 3);
  EXPECT_EQ(inspection.nonmanifold_edges, 0);
  EXPECT_EQ(inspection.misoriented_edges, 0);
  // The first boundary edge in vertex order, with its coordinates and its facet's line.
  ExpectError([&] { LoadMeshBody(path, 1000); },
              {path + ": the mesh is open: 3 boundary edge(s) used by one triangle only, e.g. the edge (",
               "(-0.25, -0.125, 1) - (-0.25, 0.125, 1) of triangle 1 (line 2)"});
}

TEST(MeshErrors, NonManifoldEdge) {
  // Two boxes sharing one edge only (x = y = 0.5 of the first): that edge has 4 triangles.
  TriangleMesh mesh = BoxMesh(Vec3(1, 1, 1));
  const TriangleMesh other = BoxMesh(Vec3(1, 1, 1), Mat3::Identity(), Vec3(1, 1, 0));
  for (const auto& t : other.triangles) mesh.triangles.push_back({t[0] + 8, t[1] + 8, t[2] + 8});
  mesh.vertices.insert(mesh.vertices.end(), other.vertices.begin(), other.vertices.end());
  mesh.name = "two boxes";
  MergeVertices(&mesh, 0);
  EXPECT_EQ(mesh.vertices.size(), 14u);
  const MeshInspection inspection = InspectMesh(mesh);
  EXPECT_EQ(inspection.nonmanifold_edges, 1);
  EXPECT_EQ(inspection.boundary_edges, 0);
  EXPECT_EQ(inspection.misoriented_edges, 0);
  ExpectError([&] { MeshMassProperties(mesh, 1, 1, nullptr); },
              {"two boxes: the mesh is non-manifold: 1 edge(s) used by more than two triangles",
               "(0.5, 0.5, -0.5) - (0.5, 0.5, 0.5)", " and triangle "});
}

TEST(MeshErrors, FlippedTriangle) {
  TriangleMesh mesh = BoxMesh(kSize);
  std::swap(mesh.triangles[5][1], mesh.triangles[5][2]);
  const std::string path = TempPath("flipped.obj");
  WriteObj(path, mesh);
  const MeshInspection inspection = InspectMesh(ReadMesh(path));
  EXPECT_EQ(inspection.misoriented_edges, 3);
  EXPECT_EQ(inspection.boundary_edges, 0);
  ExpectError([&] { LoadMeshBody(path, 1); },
              {path + ": the triangles are inconsistently oriented: 3 edge(s) traversed twice in "
                      "the same direction",
               "triangle 6 (line 15)"});
}

TEST(MeshErrors, InsideOutMeshAndItsFlip) {
  TriangleMesh mesh = BoxMesh(kSize);
  FlipOrientation(&mesh);
  EXPECT_NEAR(InspectMesh(mesh).volume, -kSize.prod(), 1e-15);
  ExpectError([&] { MeshMassProperties(mesh, 1, 1, nullptr); },
              {"box: the mesh is inside out: its signed volume is -0.25", "reverse the vertex order"});
  FlipOrientation(&mesh);
  ExpectBox(mesh, kSize, Mat3::Identity(), Vec3::Zero());
}

TEST(MeshErrors, TruncatedBinaryStl) {
  std::string data = BinaryStl(BoxMesh(kSize));
  ASSERT_EQ(data.size(), 684u);
  data.resize(data.size() - 10);
  const std::string path = TempPath("truncated.stl");
  WriteText(path, data);
  ExpectError([&] { ReadMesh(path); },
              {path + ": binary STL of wrong size (truncated or padded): its header declares 12 "
                      "triangles, i.e. 84 + 50 x 12 = 684 bytes, but the file has 674 bytes"});
  // Even when the header begins with "solid".
  data = BinaryStl(BoxMesh(kSize), "solid");
  data.resize(600);
  WriteText(path, data);
  ExpectError([&] { ReadMesh(path); }, {"684 bytes, but the file has 600 bytes"});
  WriteText(path, "abc");
  ExpectError([&] { ReadMesh(path); }, {"shorter than a binary STL header"});
}

TEST(MeshErrors, MalformedAsciiStl) {
  const std::string path = TempPath("bad.stl");
  WriteText(path, "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0\n");
  ExpectError([&] { ReadMesh(path); }, {path + ": line 5: expected 'vertex x y z'"});
  WriteText(path, "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n");
  ExpectError([&] { ReadMesh(path); }, {"line 6: the facet of line 2 has 2 vertices, 3 expected"});
  WriteText(path, "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 nan\n");
  ExpectError([&] { ReadMesh(path); }, {"line 5: expected 'vertex x y z' with three finite"});
  WriteText(path, "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n");
  ExpectError([&] { ReadMesh(path); }, {"the file ends inside the facet of line 2"});
  WriteText(path, "solid x\nfacet normal 0 0 1\nbanana\n");
  ExpectError([&] { ReadMesh(path); }, {"line 3: expected 'outer loop'"});
  WriteText(path, "solid empty\nendsolid empty\n");
  ExpectError([&] { LoadMeshBody(path, 1); }, {path + ": the mesh is empty (no triangles)"});
}

TEST(MeshErrors, ObjBadIndices) {
  const std::string path = TempPath("bad.obj");
  const std::string cube_vertices =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n";
  WriteText(path, cube_vertices + "f 1 2 3\nf 1 2 9\n");
  ExpectError([&] { ReadMesh(path); },
              {path + ": line 10: vertex index 9 is out of range (the file has 8 vertices)"});
  WriteText(path, cube_vertices + "f 1 0 3\n");
  ExpectError([&] { ReadMesh(path); }, {"line 9: bad vertex reference '0'"});
  WriteText(path, cube_vertices + "f 1 -9 3\n");
  ExpectError([&] { ReadMesh(path); },
              {"line 9: vertex index -9 is out of range (only 8 vertices before this line)"});
  WriteText(path, cube_vertices + "f 1 2x 3\n");
  ExpectError([&] { ReadMesh(path); }, {"line 9: bad vertex reference '2x'"});
  WriteText(path, cube_vertices + "f 1 2\n");
  ExpectError([&] { ReadMesh(path); }, {"line 9: a face needs at least 3 vertices, found 2"});
  WriteText(path, "v 0 0\n");
  ExpectError([&] { ReadMesh(path); }, {"line 1: expected 'v x y z'"});
}

TEST(MeshErrors, BadArgumentsAndFiles) {
  const TriangleMesh box = BoxMesh(kSize);
  ExpectError([&] { MeshMassProperties(box, 0, 1, nullptr); }, {"box: mesh density must be > 0"});
  ExpectError([&] { MeshMassProperties(box, -1, 1, nullptr); }, {"density must be > 0, got -1"});
  ExpectError([&] { MeshMassProperties(box, 1, 0, nullptr); }, {"box: mesh scale must be > 0"});
  ExpectError([&] { MeshMassProperties(box, 1, NAN, nullptr); }, {"scale must be > 0"});
  ExpectError([&] { MeshMassProperties(TriangleMesh{}, 1, 1, nullptr); },
              {"mesh: the mesh is empty"});
  ExpectError([&] { ReadMesh(TempPath("missing.stl")); }, {"missing.stl: cannot open"});
  ExpectError([&] { ReadMesh(TempPath("part.step")); }, {"unknown mesh format 'step'"});
  TriangleMesh bad = box;
  bad.triangles[3][1] = 8;
  ExpectError([&] { InspectMesh(bad); }, {"box: triangle 4: vertex index 8 is out of range"});
}

}  // namespace
}  // namespace mbdae::mbs
