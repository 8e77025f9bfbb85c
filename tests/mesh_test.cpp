// Tests for mesh/: built-in base meshes against their analytic frames, OBJ loading with UV seams,
// and the bad inputs loadBaseMesh and computeTangentFrames must reject or survive.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "common/error.h"
#include "common/position_weld.h"
#include "detail_meshes.h"
#include "mesh/base_mesh.h"
#include "mesh/detail_mesh.h"
#include "mesh/polygon.h"

namespace distile {
namespace {

constexpr double kPi = std::numbers::pi;

/// Angle between two vectors in radians, in double so it resolves angles down to ~1e-8.
double angleBetween(const glm::dvec3& a, const glm::dvec3& b) {
    return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}

glm::dvec3 bitangentOf(const BaseMesh& mesh, std::size_t v) {
    const glm::dvec3 n(mesh.normals[v]);
    const glm::dvec3 t(mesh.tangents[v]);
    return double(mesh.tangents[v].w) * glm::cross(n, t);
}

/// Every frame is finite and orthonormal, w is exactly +1 or -1, uvs are in [0, 1] when asked.
/// 1e-5 covers the float rounding of vectors normalised in double and then stored as float
/// (each component carries ~6e-8 relative error; lengths and dot products stay far below 1e-5).
void expectValidFrames(const BaseMesh& mesh, bool uvsInUnitSquare) {
    ASSERT_EQ(mesh.normals.size(), mesh.positions.size());
    ASSERT_EQ(mesh.tangents.size(), mesh.positions.size());
    ASSERT_EQ(mesh.uvs.size(), mesh.positions.size());
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        const glm::vec3 n = mesh.normals[v];
        const glm::vec4 t = mesh.tangents[v];
        ASSERT_TRUE(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z)) << v;
        ASSERT_TRUE(std::isfinite(t.x) && std::isfinite(t.y) && std::isfinite(t.z)) << v;
        EXPECT_NEAR(glm::length(n), 1.0, 1e-5) << "vertex " << v;
        EXPECT_NEAR(glm::length(glm::vec3(t)), 1.0, 1e-5) << "vertex " << v;
        EXPECT_NEAR(glm::dot(n, glm::vec3(t)), 0.0, 1e-5) << "vertex " << v;
        EXPECT_TRUE(t.w == 1.0f || t.w == -1.0f) << "vertex " << v << " w " << t.w;
        if (uvsInUnitSquare) {
            EXPECT_TRUE(mesh.uvs[v].x >= 0.0f && mesh.uvs[v].x <= 1.0f) << v;
            EXPECT_TRUE(mesh.uvs[v].y >= 0.0f && mesh.uvs[v].y <= 1.0f) << v;
        }
    }
    for (const glm::uvec3& triangle : mesh.triangles) {
        for (int corner = 0; corner < 3; ++corner)
            ASSERT_LT(triangle[corner], mesh.positions.size());
    }
}

/// Every triangle is counter-clockwise seen from outside: its geometric normal agrees with the
/// vertex normals (positive dot product with their sum).
void expectOutwardWinding(const BaseMesh& mesh) {
    for (std::size_t k = 0; k < mesh.triangles.size(); ++k) {
        const glm::uvec3& tri = mesh.triangles[k];
        const glm::dvec3 p0(mesh.positions[tri[0]]);
        const glm::dvec3 faceNormal = glm::cross(glm::dvec3(mesh.positions[tri[1]]) - p0,
                                                 glm::dvec3(mesh.positions[tri[2]]) - p0);
        const glm::dvec3 vertexNormals = glm::dvec3(mesh.normals[tri[0]]) +
                                         glm::dvec3(mesh.normals[tri[1]]) +
                                         glm::dvec3(mesh.normals[tri[2]]);
        EXPECT_GT(glm::dot(faceNormal, vertexNormals), 0.0) << "triangle " << k;
    }
}

/// A file in the temp folder, unique per test and process, removed at the end of the test.
class TempFile {
  public:
    TempFile(const std::string& name, const std::string& contents)
        : path_(std::filesystem::temp_directory_path() /
                ("distile_mesh_test_" + std::to_string(::getpid()) + "_" + name)) {
        std::ofstream(path_, std::ios::binary) << contents;
    }
    ~TempFile() {
        std::error_code ignored;
        std::filesystem::remove(path_, ignored);
    }
    const std::filesystem::path& path() const { return path_; }

  private:
    std::filesystem::path path_;
};

/// The message of the exception `call` throws as E (fails the test if it throws nothing or
/// something else).
template <typename E, typename Call>
std::string messageOf(Call call) {
    try {
        call();
    } catch (const E& error) {
        return error.what();
    } catch (const std::exception& other) {
        ADD_FAILURE() << "threw another exception: " << other.what();
        return {};
    }
    ADD_FAILURE() << "threw nothing";
    return {};
}

// ---- built-in meshes -----------------------------------------------------------------------

TEST(Plane, FrameIsExactlyXYZ) {
    const BaseMesh plane = makePlane(2.0f, 4);
    EXPECT_EQ(plane.positions.size(), 25u);
    EXPECT_EQ(plane.triangles.size(), 32u);
    expectValidFrames(plane, true);
    expectOutwardWinding(plane);
    // Grid positions and uvs are multiples of 1/4 (exact in float), so every face normal is
    // exactly along +z and every dP/du exactly along +x: only normalisation rounding remains.
    for (std::size_t v = 0; v < plane.positions.size(); ++v) {
        EXPECT_EQ(plane.normals[v], glm::vec3(0, 0, 1)) << v;
        EXPECT_NEAR(plane.tangents[v].x, 1.0f, 1e-6f) << v;
        EXPECT_NEAR(plane.tangents[v].y, 0.0f, 1e-6f) << v;
        EXPECT_NEAR(plane.tangents[v].z, 0.0f, 1e-6f) << v;
        EXPECT_EQ(plane.tangents[v].w, 1.0f) << v;
        const glm::dvec3 b = bitangentOf(plane, v);
        EXPECT_NEAR(b.y, 1.0, 1e-6) << v;
        // u along +x, v along +y, centred: position = (uv - 0.5) * size.
        EXPECT_NEAR(plane.positions[v].x, (plane.uvs[v].x - 0.5f) * 2.0f, 1e-6f) << v;
        EXPECT_NEAR(plane.positions[v].y, (plane.uvs[v].y - 0.5f) * 2.0f, 1e-6f) << v;
        EXPECT_EQ(plane.positions[v].z, 0.0f) << v;
    }
}

TEST(Plane, MirroredUvsGiveNegativeHandedness) {
    BaseMesh plane = makePlane(1.0f, 3);
    for (glm::vec2& uv : plane.uvs) uv.x = 1.0f - uv.x;  // u now runs along -x
    computeTangentFrames(plane);
    expectValidFrames(plane, true);
    for (std::size_t v = 0; v < plane.positions.size(); ++v) {
        EXPECT_NEAR(plane.tangents[v].x, -1.0f, 1e-6f) << v;
        EXPECT_EQ(plane.tangents[v].w, -1.0f) << v;
        EXPECT_NEAR(bitangentOf(plane, v).y, 1.0, 1e-6) << v;  // B still along +v = +y
    }
}

// Worst angle errors of the computed per-vertex frames against the analytic frame, over all
// non-pole vertices. Also checks the uv <-> position mapping and w = +1 on the way.
struct FrameErrors {
    double normal = 0, tangent = 0, bitangent = 0;  ///< radians
};

FrameErrors sphereFrameErrors(const BaseMesh& sphere, float radius) {
    FrameErrors worst;
    for (std::size_t v = 0; v < sphere.positions.size(); ++v) {
        const glm::dvec3 p(sphere.positions[v]);
        EXPECT_NEAR(glm::length(p), radius, 1e-5) << v;
        if (sphere.uvs[v].y == 0.0f || sphere.uvs[v].y == 1.0f) {
            // All pole copies share one position, hence the fan's summed normal: ±z up to the
            // float rounding of the ring positions.
            EXPECT_NEAR(sphere.normals[v].z, p.z > 0 ? 1.0f : -1.0f, 1e-5f) << v;
            continue;
        }
        const double phi = 2.0 * kPi * sphere.uvs[v].x;
        const double polar = kPi * sphere.uvs[v].y;
        const glm::dvec3 n(std::sin(polar) * std::cos(phi), std::sin(polar) * std::sin(phi),
                           -std::cos(polar));
        const glm::dvec3 t(-std::sin(phi), std::cos(phi), 0.0);
        const glm::dvec3 towardsNorth = glm::cross(n, t);
        EXPECT_GT(towardsNorth.z, 0.0);
        EXPECT_LT(glm::length(p / double(radius) - n), 1e-5) << v;
        EXPECT_EQ(sphere.tangents[v].w, 1.0f) << v;
        worst.normal = std::max(worst.normal, angleBetween(glm::dvec3(sphere.normals[v]), n));
        worst.tangent = std::max(worst.tangent, angleBetween(glm::dvec3(sphere.tangents[v]), t));
        worst.bitangent =
            std::max(worst.bitangent, angleBetween(bitangentOf(sphere, v), towardsNorth));
    }
    return worst;
}

FrameErrors torusFrameErrors(const BaseMesh& torus, float majorRadius, float minorRadius) {
    FrameErrors worst;
    for (std::size_t v = 0; v < torus.positions.size(); ++v) {
        const double theta = 2.0 * kPi * torus.uvs[v].x;
        const double psi = 2.0 * kPi * torus.uvs[v].y;
        const double ring = majorRadius + minorRadius * std::cos(psi);
        const glm::dvec3 p(ring * std::cos(theta), ring * std::sin(theta),
                           minorRadius * std::sin(psi));
        EXPECT_LT(glm::length(glm::dvec3(torus.positions[v]) - p), 1e-5) << v;
        const glm::dvec3 n(std::cos(psi) * std::cos(theta), std::cos(psi) * std::sin(theta),
                           std::sin(psi));
        const glm::dvec3 t(-std::sin(theta), std::cos(theta), 0.0);
        // dP/dψ / r = (-sin ψ cos θ, -sin ψ sin θ, cos ψ), which is exactly cross(N, T): w = +1.
        const glm::dvec3 dPdpsiUnit(-std::sin(psi) * std::cos(theta),
                                    -std::sin(psi) * std::sin(theta), std::cos(psi));
        EXPECT_LT(glm::length(glm::cross(n, t) - dPdpsiUnit), 1e-12);
        EXPECT_EQ(torus.tangents[v].w, 1.0f) << v;
        worst.normal = std::max(worst.normal, angleBetween(glm::dvec3(torus.normals[v]), n));
        worst.tangent = std::max(worst.tangent, angleBetween(glm::dvec3(torus.tangents[v]), t));
        worst.bitangent =
            std::max(worst.bitangent, angleBetween(bitangentOf(torus, v), dPdpsiUnit));
    }
    return worst;
}

/// Vertices with the same position (seam and pole copies) have bit-identical normals, and
/// bit-identical tangents when their uvs differ by whole numbers (wrapping seams).
void expectSeamCopiesAgree(const BaseMesh& mesh) {
    int wrappingPairs = 0;
    for (std::size_t a = 0; a < mesh.positions.size(); ++a) {
        for (std::size_t b = a + 1; b < mesh.positions.size(); ++b) {
            if (mesh.positions[a] != mesh.positions[b]) continue;
            EXPECT_EQ(mesh.normals[a], mesh.normals[b]) << a << " " << b;
            const glm::vec2 offset = mesh.uvs[a] - mesh.uvs[b];
            if (offset == glm::round(offset)) {
                ++wrappingPairs;
                EXPECT_EQ(mesh.tangents[a], mesh.tangents[b]) << a << " " << b;
            }
        }
    }
    EXPECT_GT(wrappingPairs, 0);
}

// How close the computed frames come to the analytic ones, with h the angular step:
// - Tangents (chords of circles of latitude / of the major circle) are parallel to the analytic
//   tangent at their mid-angle, so the two sides of a vertex cancel to second order: error
//   c * h^2. Wrapping-seam copies pool their sums, so seams are no exception.
// - Torus normals: neighbouring faces differ in area by a factor 1 + O(h) (the ring radius
//   R + r cos ψ varies slowly), so area weighting stays second order as well.
// - Sphere normals (and hence B = cross(N, T)) are first order: next to the poles, the bands
//   above and below a ring differ in area by a factor up to 3 (band area grows like sin of the
//   polar angle), which tilts the area-weighted sum by a fraction of h.
// Measured (32 x 16 sphere, 48 x 24 torus): sphere N and B 0.17 h, T 0.25 h^2; torus N
// 0.06 h^2, T 0.05 h^2. The bounds below (h/4 for first order, h^2/2 for second order) leave a
// margin of 1.5x or more and stay well below h/2, the tilt of a single face.
TEST(UvSphere, FramesMatchAnalyticAwayFromPoles) {
    const int around = 32;
    const int rings = 16;
    const float radius = 1.5f;
    const BaseMesh sphere = makeUvSphere(radius, around, rings);
    EXPECT_EQ(sphere.positions.size(), std::size_t((rings - 1) * (around + 1) + 2 * around));
    EXPECT_EQ(sphere.triangles.size(), std::size_t(2 * around * (rings - 1)));
    expectValidFrames(sphere, true);
    expectOutwardWinding(sphere);
    expectSeamCopiesAgree(sphere);
    const double h = std::max(2.0 * kPi / around, kPi / rings);
    const FrameErrors worst = sphereFrameErrors(sphere, radius);
    EXPECT_LT(worst.normal, h / 4);
    EXPECT_LT(worst.tangent, h * h / 2);
    EXPECT_LT(worst.bitangent, h / 4);
}

TEST(UvSphere, FrameErrorsShrinkWithTessellation) {
    // Doubling the resolution must at least roughly halve the first-order errors and quarter
    // the second-order ones (0.6 and 0.35 allow for the higher-order terms).
    const FrameErrors coarse = sphereFrameErrors(makeUvSphere(1.0f, 24, 12), 1.0f);
    const FrameErrors fine = sphereFrameErrors(makeUvSphere(1.0f, 48, 24), 1.0f);
    EXPECT_LT(fine.normal, 0.6 * coarse.normal);
    EXPECT_LT(fine.tangent, 0.35 * coarse.tangent);
}

TEST(Torus, FramesMatchAnalytic) {
    const int major = 48;
    const int minor = 24;
    const float majorRadius = 2.0f;
    const float minorRadius = 0.5f;
    const BaseMesh torus = makeTorus(majorRadius, minorRadius, major, minor);
    EXPECT_EQ(torus.positions.size(), std::size_t((major + 1) * (minor + 1)));
    EXPECT_EQ(torus.triangles.size(), std::size_t(2 * major * minor));
    expectValidFrames(torus, true);
    expectOutwardWinding(torus);
    expectSeamCopiesAgree(torus);
    const double h = std::max(2.0 * kPi / major, 2.0 * kPi / minor);
    const FrameErrors worst = torusFrameErrors(torus, majorRadius, minorRadius);
    EXPECT_LT(worst.normal, h * h / 2);
    EXPECT_LT(worst.tangent, h * h / 2);
    EXPECT_LT(worst.bitangent, h * h / 2);
}

TEST(Torus, FrameErrorsShrinkWithTessellation) {
    const FrameErrors coarse = torusFrameErrors(makeTorus(2.0f, 0.5f, 24, 12), 2.0f, 0.5f);
    const FrameErrors fine = torusFrameErrors(makeTorus(2.0f, 0.5f, 48, 24), 2.0f, 0.5f);
    EXPECT_LT(fine.normal, 0.35 * coarse.normal);
    EXPECT_LT(fine.tangent, 0.35 * coarse.tangent);
}

TEST(BuiltIns, SmallestTessellationsAreValid) {
    for (const BaseMesh& mesh :
         {makePlane(1.0f, 1), makeUvSphere(1.0f, 3, 2), makeTorus(1.0f, 0.25f, 3, 3)}) {
        ASSERT_NO_FATAL_FAILURE(expectValidFrames(mesh, true));
        ASSERT_NO_FATAL_FAILURE(expectOutwardWinding(mesh));
    }
}

TEST(BuiltIns, RejectBadArguments) {
    EXPECT_THROW(makePlane(0.0f, 4), InputError);
    EXPECT_THROW(makePlane(std::nanf(""), 4), InputError);
    EXPECT_THROW(makePlane(1.0f, 0), InputError);
    EXPECT_THROW(makeUvSphere(-1.0f, 8, 4), InputError);
    EXPECT_THROW(makeUvSphere(1.0f, 2, 4), InputError);
    EXPECT_THROW(makeUvSphere(1.0f, 8, 1), InputError);
    EXPECT_THROW(makeUvSphere(1.0f, kMaxSegments + 1, 4), InputError);
    EXPECT_THROW(makeTorus(1.0f, 1.0f, 8, 8), InputError);
    EXPECT_THROW(makeTorus(1.0f, 2.0f, 8, 8), InputError);
    EXPECT_THROW(makeTorus(1.0f, 0.0f, 8, 8), InputError);
    EXPECT_THROW(makeTorus(INFINITY, 0.5f, 8, 8), InputError);
    EXPECT_THROW(makeTorus(1.0f, 0.5f, 2, 8), InputError);
    const std::string message = messageOf<InputError>([] { makeTorus(1.0f, 0.5f, 8, 1); });
    EXPECT_NE(message.find("segmentsMinor = 1"), std::string::npos) << message;
}

// ---- computeTangentFrames on awkward input -------------------------------------------------

TEST(TangentFrames, DegenerateUvTriangleGetsFallbackFrame) {
    BaseMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    mesh.uvs = {{0.5f, 0.5f}, {0.5f, 0.5f}, {0.5f, 0.5f}};  // zero uv area
    mesh.triangles = {{0, 1, 2}};
    computeTangentFrames(mesh);
    expectValidFrames(mesh, true);
    for (std::size_t v = 0; v < 3; ++v) {
        EXPECT_EQ(mesh.normals[v], glm::vec3(0, 0, 1));
        EXPECT_EQ(mesh.tangents[v], glm::vec4(1, 0, 0, 1));  // documented fallback for N = +z
    }
}

TEST(TangentFrames, DegenerateUvTriangleContributesNothing) {
    // A good unit triangle plus a neighbour whose uvs are collinear: the shared vertices keep the
    // good triangle's exact tangent +x.
    BaseMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    // uv(3) lies on the line from uv(1) to uv(2), so triangle {1, 3, 2} has zero uv area.
    mesh.uvs = {{0, 0}, {1, 0}, {0, 1}, {0.5f, 0.5f}};
    mesh.triangles = {{0, 1, 2}, {1, 3, 2}};
    computeTangentFrames(mesh);
    expectValidFrames(mesh, true);
    for (std::size_t v = 0; v < 3; ++v) {
        EXPECT_NEAR(mesh.tangents[v].x, 1.0f, 1e-6f) << v;
        EXPECT_EQ(mesh.tangents[v].w, 1.0f) << v;
    }
}

TEST(TangentFrames, ZeroAreaTrianglesStayFinite) {
    BaseMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {5, 5, 5}};  // collinear and coincident
    mesh.uvs = {{0, 0}, {1, 0}, {0, 1}, {1, 1}};
    mesh.triangles = {{0, 1, 2}, {3, 3, 3}};
    computeTangentFrames(mesh);
    expectValidFrames(mesh, true);
    for (std::size_t v = 0; v < 4; ++v) EXPECT_EQ(mesh.normals[v], glm::vec3(0, 0, 1)) << v;
}

TEST(TangentFrames, TwoSidedSheetKeepsEachSidesNormal) {
    // The same square twice, the back copy wound the other way: the same-position sums cancel,
    // so each vertex falls back on its own faces instead of an arbitrary direction.
    BaseMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    mesh.uvs = {{0, 0}, {1, 0}, {0, 1}, {0, 0}, {1, 0}, {0, 1}};
    mesh.triangles = {{0, 1, 2}, {3, 5, 4}};
    computeTangentFrames(mesh);
    expectValidFrames(mesh, true);
    for (std::size_t v = 0; v < 3; ++v) EXPECT_EQ(mesh.normals[v], glm::vec3(0, 0, 1)) << v;
    for (std::size_t v = 3; v < 6; ++v) EXPECT_EQ(mesh.normals[v], glm::vec3(0, 0, -1)) << v;
    // Back side: u still runs along +x, but seen from -z that is mirrored: w = -1.
    for (std::size_t v = 3; v < 6; ++v) EXPECT_EQ(mesh.tangents[v].w, -1.0f) << v;
}

/// An open cylinder of radius 1 around z, height 1, `segments` quads around, its seam column
/// (u = 1) at angle 2 pi computed as a script or exporter would: sin(2 pi) is -2.4e-16, not 0,
/// so the seam copies differ from the u = 0 column by rounding noise.
BaseMesh cylinderWithNoisySeam(int segments) {
    BaseMesh mesh;
    for (int column = 0; column <= segments; ++column) {
        const double angle = 2.0 * kPi * column / segments;
        for (int row = 0; row < 2; ++row) {
            mesh.positions.emplace_back(std::cos(angle), std::sin(angle), row);
            mesh.uvs.emplace_back(double(column) / segments, row);
        }
    }
    for (std::uint32_t column = 0; column < std::uint32_t(segments); ++column) {
        const std::uint32_t a = 2 * column, b = a + 2;
        mesh.triangles.push_back({a, b, b + 1});
        mesh.triangles.push_back({a, b + 1, a + 1});
    }
    return mesh;
}

TEST(TangentFrames, SeamCopiesWithRoundingNoiseWeldIntoOneNormal) {
    constexpr int kSegments = 12;
    BaseMesh mesh = cylinderWithNoisySeam(kSegments);
    const std::uint32_t seam = 2 * kSegments;            // the first vertex of the u = 1 column
    ASSERT_NE(mesh.positions[seam], mesh.positions[0]);  // the noise survives in float
    const std::vector<std::uint32_t> groups = weldedPositionGroups(mesh.positions, mesh.triangles);
    EXPECT_EQ(groups[seam], 0u);
    EXPECT_EQ(groups[seam + 1], 1u);
    for (std::uint32_t v = 2; v < seam; ++v) EXPECT_EQ(groups[v], v);
    computeTangentFrames(mesh);
    expectValidFrames(mesh, true);
    // One normal on both sides of the seam, the one every column has (the cylinder turns into
    // itself): column 0's is column 6's (at angle pi) turned by pi about z, to float rounding.
    for (std::uint32_t row = 0; row < 2; ++row) {
        EXPECT_EQ(mesh.normals[seam + row], mesh.normals[row]) << row;
        EXPECT_EQ(mesh.tangents[seam + row], mesh.tangents[row]) << row;
        const glm::dvec3 opposite(mesh.normals[2 * (kSegments / 2) + row]);
        EXPECT_LT(
            angleBetween(glm::dvec3(mesh.normals[row]), {-opposite.x, -opposite.y, opposite.z}),
            1e-6)
            << row;
    }
}

TEST(TangentFrames, VerticesApartByMoreThanTheWeldToleranceStayApart) {
    // The weld takes 1e-3 of the median edge length (here 1: three triangles of edges 1, 1 and
    // sqrt 2): a crack of 2e-3 in the file is kept; 5e-4 is welded. A stray face a million away
    // changes nothing: the weld is not a fraction of the mesh's extent.
    for (const auto& [gap, welded] : {std::pair{2e-3f, false}, std::pair{5e-4f, true}}) {
        const std::vector<glm::vec3> positions = {{0, 0, 0}, {1, 0, 0},    {0, 1, 0},   {1, gap, 0},
                                                  {0, 0, 0}, {1e6f, 0, 0}, {0, 1e6f, 0}};
        const std::vector<glm::uvec3> triangles = {{0, 1, 2}, {0, 1, 2}, {0, 1, 2}, {0, 5, 6}};
        const std::vector<std::uint32_t> groups = weldedPositionGroups(positions, triangles);
        EXPECT_EQ(groups[3], welded ? 1u : 3u) << gap;
        EXPECT_EQ(groups[4], 0u) << gap;
        EXPECT_EQ(groups[2], 2u) << gap;
    }
}

TEST(TangentFrames, WeldGroupsAreTheComponentsOfPairsWithinTheTolerance) {
    // Clusters of points jittered around random centres by up to a few tolerances, straddling
    // the weld's cells every way: its groups are the connected components of the pairs closer
    // than the tolerance (chains included), each named by its lowest index.
    std::mt19937 random(7);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    // 101 triangles of edges 1, 1 and sqrt 2 far from the clusters: the median edge is 1.
    std::vector<glm::vec3> positions;
    std::vector<glm::uvec3> triangles;
    for (std::uint32_t t = 0; t < 101; ++t) {
        const glm::vec3 corner(10.0f + 3.0f * float(t), 0.0f, 0.0f);
        positions.insert(positions.end(),
                         {corner, corner + glm::vec3(1, 0, 0), corner + glm::vec3(0, 1, 0)});
        triangles.push_back({3 * t, 3 * t + 1, 3 * t + 2});
    }
    const std::size_t triangleCorners = positions.size();
    const double tolerance = 1e-3;
    for (int cluster = 0; cluster < 300; ++cluster) {
        const glm::vec3 centre(unit(random), unit(random), unit(random));
        const int members = 1 + cluster % 4;
        for (int member = 0; member < members; ++member) {
            const glm::vec3 jitter(unit(random) - 0.5f, unit(random) - 0.5f, unit(random) - 0.5f);
            positions.push_back(centre + jitter * float(2.0 * tolerance));
        }
    }
    const std::size_t count = positions.size();
    std::vector<std::uint32_t> expected(count);
    std::iota(expected.begin(), expected.end(), 0u);
    bool merged = true;
    while (merged) {  // relax to the components' lowest indices
        merged = false;
        for (std::size_t a = 0; a < count; ++a) {
            for (std::size_t b = a + 1; b < count; ++b) {
                if (glm::distance(glm::dvec3(positions[a]), glm::dvec3(positions[b])) > tolerance)
                    continue;
                const std::uint32_t least = std::min(expected[a], expected[b]);
                if (expected[a] != least || expected[b] != least) merged = true;
                expected[a] = expected[b] = least;
            }
        }
    }
    const std::vector<std::uint32_t> groups = weldedPositionGroups(positions, triangles);
    int weldedVertices = 0;
    for (std::size_t v = 0; v < count; ++v) {
        EXPECT_EQ(groups[v], expected[v]) << v;
        weldedVertices += groups[v] != v;
    }
    // The case welds many and leaves many apart within clusters (300 clusters and the
    // triangles' corners).
    EXPECT_GT(weldedVertices, 100);
    EXPECT_GT(int(count) - weldedVertices, int(300 + triangleCorners) + 50);
}

TEST(TangentFrames, RejectsInconsistentMeshes) {
    BaseMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    mesh.uvs = {{0, 0}, {1, 0}};
    mesh.triangles = {{0, 1, 2}};
    EXPECT_THROW(computeTangentFrames(mesh), InputError);
    mesh.uvs.emplace_back(0, 1);
    mesh.triangles = {{0, 1, 3}};
    const std::string message = messageOf<InputError>([&] { computeTangentFrames(mesh); });
    EXPECT_NE(message.find("vertex 3"), std::string::npos) << message;
    mesh.triangles = {{0, 1, 2}};
    mesh.positions[1].y = NAN;
    EXPECT_THROW(computeTangentFrames(mesh), InputError);
}

// ---- loading -------------------------------------------------------------------------------

// A ridge: two quads sharing the edge 2-3 (at z = 0.5) with separate UV islands, so positions 2
// and 3 each appear with two uvs. Quad A's face normal is along (-0.5, 0, 1), quad B's along
// (0.5, 0, 1), equal areas: the ridge normal is exactly +z.
const char* const kRidgeObj =
    "# ridge with a UV seam\n"
    "v 0 0 0\nv 1 0 0.5\nv 1 1 0.5\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
    "vt 0 0\nvt 0.5 0\nvt 0.5 1\nvt 0 1\n"
    "vt 0.6 0\nvt 1 0\nvt 1 1\nvt 0.6 1\n"
    "f 1/1 2/2 3/3 4/4\n"
    "f 3/8 2/5 5/6 6/7\n";

TEST(LoadBaseMesh, ObjUvSeamSplitsVerticesThatShareNormals) {
    const TempFile file("ridge.obj", kRidgeObj);
    const BaseMesh mesh = loadBaseMesh(file.path());
    EXPECT_EQ(mesh.positions.size(), 8u);  // 6 positions + 2 seam duplicates
    EXPECT_EQ(mesh.triangles.size(), 4u);  // two quads, fan-triangulated
    expectValidFrames(mesh, true);
    expectOutwardWinding(mesh);
    int ridgeVertices = 0;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        EXPECT_EQ(mesh.tangents[v].w, 1.0f) << v;
        if (mesh.positions[v].z != 0.5f) continue;
        ++ridgeVertices;
        // Same position, so the exact same normal on both sides of the seam: (0, 0, 1) up to the
        // rounding of summing two mirrored float normals.
        EXPECT_NEAR(mesh.normals[v].x, 0.0f, 1e-6f) << v;
        EXPECT_NEAR(mesh.normals[v].z, 1.0f, 1e-6f) << v;
        for (std::size_t other = 0; other < mesh.positions.size(); ++other) {
            if (mesh.positions[other] == mesh.positions[v]) {
                EXPECT_EQ(mesh.normals[other], mesh.normals[v]);
            }
        }
    }
    EXPECT_EQ(ridgeVertices, 4);
    // Off the ridge the normal is quad A's or B's face normal.
    const double slope = 1.0 / std::sqrt(1.25);
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        if (mesh.positions[v].z != 0.0f) continue;
        const double expectedX = mesh.positions[v].x < 1.0f ? -0.5 * slope : 0.5 * slope;
        EXPECT_NEAR(mesh.normals[v].x, expectedX, 1e-6) << v;
    }
}

TEST(LoadBaseMesh, OffWithVertexTexcoords) {
    const TempFile file("quad.off",
                        "STOFF\n4 1 0\n0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n4 0 1 2 3\n");
    const BaseMesh mesh = loadBaseMesh(file.path());
    EXPECT_EQ(mesh.positions.size(), 4u);
    EXPECT_EQ(mesh.triangles.size(), 2u);
    expectValidFrames(mesh, true);
    for (std::size_t v = 0; v < 4; ++v) {
        EXPECT_EQ(mesh.uvs[v], glm::vec2(mesh.positions[v]));
        EXPECT_NEAR(mesh.tangents[v].x, 1.0f, 1e-6f);
    }
}

std::string plyQuad(const std::string& lastVertex) {
    return "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\nproperty float u\nproperty float v\nelement face 1\n"
           "property list uchar int vertex_indices\nend_header\n"
           "0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n" +
           lastVertex + "\n4 0 1 2 3\n";
}

TEST(LoadBaseMesh, PlyWithVertexTexcoords) {
    const TempFile good("quad.ply", plyQuad("0 1 0 0 1"));
    const BaseMesh mesh = loadBaseMesh(good.path());
    EXPECT_EQ(mesh.triangles.size(), 2u);
    expectValidFrames(mesh, true);
    // OpenMesh's ASCII PLY reader cannot parse "inf": it loses its place and drops the face,
    // which loadBaseMesh reports instead of returning an empty or partial mesh.
    const TempFile bad("inf.ply", plyQuad("0 1 0 inf 1"));
    EXPECT_THROW(loadBaseMesh(bad.path()), FormatError);
}

TEST(LoadBaseMesh, NonManifoldObjLoadsQuietly) {
    // Four triangles on one edge: OpenMesh duplicates vertices and logs "complex edge"; our
    // loader keeps the faces and prints nothing.
    const TempFile file("fan.obj",
                        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                        "vt 0 0\nvt 1 0\nvt 0 1\n"
                        "f 1/1 2/2 3/3\nf 2/2 1/1 4/3\nf 1/1 2/2 5/3\nf 2/2 1/1 6/3\n");
    testing::internal::CaptureStderr();
    testing::internal::CaptureStdout();
    const BaseMesh mesh = loadBaseMesh(file.path());
    const std::string printed =
        testing::internal::GetCapturedStderr() + testing::internal::GetCapturedStdout();
    EXPECT_EQ(printed, "");
    EXPECT_EQ(mesh.triangles.size(), 4u);
    expectValidFrames(mesh, true);
}

// Faces OpenMesh's halfedge mesh cannot take as they are: a fin on the edge 1-2 of the strip
// (the edge's third face) and the strip's last quad wound against its neighbour. Each triangle
// corner, in file order, and whether its uv comes with the face (OBJ `f v/vt`) or the vertex.
struct FileCorner {
    glm::vec3 position;
    glm::vec2 uv;
};
const std::vector<std::vector<FileCorner>> kAwkwardFaces = {
    {{{0, 0, 0}, {0.0f, 0.0f}}, {{1, 0, 0}, {0.5f, 0.0f}}, {{1, 1, 0}, {0.5f, 1.0f}}},
    {{{0, 0, 0}, {0.0f, 0.0f}}, {{1, 1, 0}, {0.5f, 1.0f}}, {{0, 1, 0}, {0.0f, 1.0f}}},
    {{{1, 0, 0}, {0.5f, 0.0f}}, {{1, 1, 0}, {0.5f, 1.0f}}, {{2, 1, 0}, {1.0f, 1.0f}}},  // flipped
    {{{1, 0, 0}, {0.5f, 0.0f}}, {{2, 1, 0}, {1.0f, 1.0f}}, {{2, 0, 0}, {1.0f, 0.0f}}},  // flipped
    {{{1, 0, 0}, {0.5f, 0.0f}}, {{1, 1, 0}, {0.5f, 1.0f}}, {{1, 0.5f, 1}, {0.8f, 0.3f}}},  // fin
};

void expectTheFilesCorners(const BaseMesh& mesh) {
    ASSERT_EQ(mesh.triangles.size(), kAwkwardFaces.size());
    for (std::size_t t = 0; t < kAwkwardFaces.size(); ++t) {
        for (int corner = 0; corner < 3; ++corner) {
            const std::uint32_t v = mesh.triangles[t][corner];
            EXPECT_EQ(mesh.positions[v], kAwkwardFaces[t][corner].position) << t << " " << corner;
            EXPECT_EQ(mesh.uvs[v], kAwkwardFaces[t][corner].uv) << t << " " << corner;
        }
    }
}

TEST(LoadBaseMesh, FacesOnAnEdgeOfThreeOrWoundAgainstTheirNeighboursKeepTheirUvs) {
    // OBJ, one vt per corner: OpenMesh re-added the fin and the flipped triangles on copies of
    // their vertices and handed their uvs over rotated by one corner.
    std::ostringstream obj;
    for (const auto& face : kAwkwardFaces) {
        for (const FileCorner& corner : face) {
            obj << "v " << corner.position.x << " " << corner.position.y << " " << corner.position.z
                << "\n";
            obj << "vt " << corner.uv.x << " " << corner.uv.y << "\n";
        }
    }
    for (std::size_t face = 0, next = 1; face < kAwkwardFaces.size(); ++face, next += 3)
        obj << "f " << next << "/" << next << " " << next + 1 << "/" << next + 1 << " " << next + 2
            << "/" << next + 2 << "\n";
    const TempFile objFile("awkward.obj", obj.str());
    ASSERT_NO_FATAL_FAILURE(expectTheFilesCorners(loadBaseMesh(objFile.path())));

    // PLY, one uv per vertex, the faces sharing vertices: OpenMesh's copies had no uvs at all.
    std::vector<FileCorner> vertices;
    std::ostringstream faces;
    for (const auto& face : kAwkwardFaces) {
        faces << "3";
        for (const FileCorner& corner : face) {
            std::size_t index = 0;
            while (index < vertices.size() && vertices[index].position != corner.position) ++index;
            if (index == vertices.size()) vertices.push_back(corner);
            faces << " " << index;
        }
        faces << "\n";
    }
    std::ostringstream ply;
    ply << "ply\nformat ascii 1.0\nelement vertex " << vertices.size()
        << "\nproperty float x\nproperty float y\nproperty float z\nproperty float u\n"
           "property float v\nelement face "
        << kAwkwardFaces.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
    for (const FileCorner& vertex : vertices) {
        ply << vertex.position.x << " " << vertex.position.y << " " << vertex.position.z << " "
            << vertex.uv.x << " " << vertex.uv.y << "\n";
    }
    const TempFile plyFile("awkward.ply", ply.str() + faces.str());
    ASSERT_NO_FATAL_FAILURE(expectTheFilesCorners(loadBaseMesh(plyFile.path())));
}

TEST(LoadBaseMesh, TrianglesWithoutAreaAreLeftOut) {
    // The unit square (faces 1, 2), a triangle along its diagonal 1-3 through the midpoint 5
    // (face 3), one with two corners 1e-7 apart, under the weld distance (1e-3 of the median edge,
    // 1) (face 4), and a sliver 2e-3 high over the edge 1-2, thin but over it (face 5).
    const TempFile file("flat.obj",
                        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 0\nv 1e-7 0 0\n"
                        "v 0.5 -2e-3 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
                        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 1/1 5/5 3/3\nf 1/1 6/2 4/4\n"
                        "f 1/1 7/5 2/2\n");
    const BaseMesh mesh = loadBaseMesh(file.path());
    ASSERT_EQ(mesh.triangles.size(), 3u);
    const glm::vec3 kept[3][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}},
                                  {{0, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                                  {{0, 0, 0}, {0.5f, -2e-3f, 0}, {1, 0, 0}}};
    for (int t = 0; t < 3; ++t) {
        for (int corner = 0; corner < 3; ++corner)
            EXPECT_EQ(mesh.positions[mesh.triangles[t][corner]], kept[t][corner]) << t;
    }
    const TempFile none("none.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nvt 0 0\nf 1/1 2/1 3/1\n");
    const std::string message = messageOf<FormatError>([&] { loadBaseMesh(none.path()); });
    EXPECT_NE(message.find("none.obj: none of its 1 faces has an area"), std::string::npos)
        << message;
}

TEST(LoadBaseMesh, AnObjStartingWithAByteOrderMarkReadsItsFirstLine) {
    // Some Windows tools start text files with a UTF-8 byte-order mark; OpenMesh's reader took
    // it as part of the first line's keyword and skipped the line (here the first vertex).
    const std::string ridge(kRidgeObj);
    const std::string body = ridge.substr(ridge.find('\n') + 1);  // from its first v line
    const TempFile plain("plain.obj", body);
    const TempFile marked("marked.obj", "\xEF\xBB\xBF" + body);
    const BaseMesh expected = loadBaseMesh(plain.path());
    const BaseMesh mesh = loadBaseMesh(marked.path());
    EXPECT_EQ(mesh.positions, expected.positions);
    EXPECT_EQ(mesh.uvs, expected.uvs);
    EXPECT_EQ(mesh.triangles, expected.triangles);
}

TEST(LoadBaseMesh, AnObjFaceNamingOneVertexTwiceTakesItsVerticesUvs) {
    // OpenMesh leaves the repeated corner out of the face but not out of its uvs, which then
    // no longer match the corners one to one: the face takes its vertices' uvs.
    const TempFile file("twice.obj",
                        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
                        "f 1/1 2/2 3/3 1/1\n");
    const BaseMesh mesh = loadBaseMesh(file.path());
    ASSERT_EQ(mesh.triangles.size(), 1u);
    const glm::vec2 expected[3] = {{0, 0}, {1, 0}, {1, 1}};
    for (int corner = 0; corner < 3; ++corner)
        EXPECT_EQ(mesh.uvs[mesh.triangles[0][corner]], expected[corner]) << corner;
}

TEST(LoadBaseMesh, MissingFileIsInputError) {
    const std::filesystem::path missing =
        std::filesystem::temp_directory_path() / "no_such_mesh.obj";
    const std::string message = messageOf<InputError>([&] { loadBaseMesh(missing); });
    EXPECT_EQ(message, missing.string() + ": no such file");
}

TEST(LoadBaseMesh, ObjWithoutTexcoordsIsFormatError) {
    const TempFile file("nouv.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const std::string message = messageOf<FormatError>([&] { loadBaseMesh(file.path()); });
    EXPECT_EQ(message, file.path().string() +
                           ": has no texture coordinates (vt lines); base meshes need UVs");
}

TEST(LoadBaseMesh, AnObjWhoseOnlyFaceRepeatsACornerHasNoFaceToRead) {
    // OpenMesh drops the face; the message said the file had no f lines.
    const TempFile file("repeated.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 1/1 1/1\n");
    const std::string message = messageOf<FormatError>([&] { loadBaseMesh(file.path()); });
    EXPECT_NE(message.find("has no faces OpenMesh could read"), std::string::npos) << message;
    EXPECT_NE(message.find("three distinct corners"), std::string::npos) << message;
}

TEST(LoadBaseMesh, ObjWithNanVertexIsFormatError) {
    const TempFile file("nan.obj",
                        "v 0 0 0\nv nan 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                        "f 1/1 2/2 3/3\n");
    const std::string message = messageOf<FormatError>([&] { loadBaseMesh(file.path()); });
    EXPECT_NE(message.find("vertex 2"), std::string::npos) << message;
    EXPECT_NE(message.find("line 2"), std::string::npos) << message;
}

TEST(LoadBaseMesh, ObjWithInfTexcoordIsFormatError) {
    const TempFile file("inf.obj",
                        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1e39 0\nvt 0 1\n"
                        "f 1/1 2/2 3/3\n");
    const std::string message = messageOf<FormatError>([&] { loadBaseMesh(file.path()); });
    EXPECT_NE(message.find("texture coordinate 2"), std::string::npos) << message;
}

TEST(LoadBaseMesh, ObjWithOutOfRangeIndicesIsFormatError) {
    // OpenMesh alone would drop the first face with a log line and leave the second's third
    // corner uv uninitialised.
    const std::string header = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";
    const TempFile badVertex("badv.obj", header + "f 1/1 2/2 9/3\n");
    std::string message = messageOf<FormatError>([&] { loadBaseMesh(badVertex.path()); });
    EXPECT_NE(message.find("refers to vertex 9"), std::string::npos) << message;
    const TempFile badUv("badvt.obj", header + "f 1/1 2/2 3/7\n");
    message = messageOf<FormatError>([&] { loadBaseMesh(badUv.path()); });
    EXPECT_NE(message.find("refers to texture coordinate 7"), std::string::npos) << message;
    const TempFile missingUv("mixed.obj", header + "f 1/1 2/2 3/3\nf 1 3 2\n");
    message = messageOf<FormatError>([&] { loadBaseMesh(missingUv.path()); });
    EXPECT_NE(message.find("line 8"), std::string::npos) << message;
    // Negative (relative) indices are valid OBJ.
    const TempFile relative("relative.obj", header + "f -3/-3 -2/-2 -1/-1\n");
    EXPECT_EQ(loadBaseMesh(relative.path()).triangles.size(), 1u);
}

// OpenMesh leaves out a v line it cannot read whole or that starts with a form feed; the faces
// after it would then index past its vertex arrays (the reader wrote past them, found by fuzzing).
TEST(LoadBaseMesh, ObjLinesOpenMeshWouldLeaveOutAreFormatErrors) {
    const std::string rest = "v 1 1 1\nv 0 1 0\nvt 1 1\nvt 0 1\nf 1/1 3/2 2/2\n";
    const TempFile formFeed("formfeed.obj", "\fv 0 0 0\n" + rest);
    std::string message = messageOf<FormatError>([&] { loadBaseMesh(formFeed.path()); });
    EXPECT_NE(message.find("line 1: the 'v' line starts with a form feed"), std::string::npos)
        << message;
    const TempFile hex("hex.obj", "v 0x1 0 0\n" + rest);
    message = messageOf<FormatError>([&] { loadBaseMesh(hex.path()); });
    EXPECT_NE(message.find("line 1: vertex 1 has '0x1'; expected a decimal number"),
              std::string::npos)
        << message;
    const TempFile hexUv("hexuv.obj", "v 0 0 0\n" + rest + "vt 0X1p1 0\n");
    message = messageOf<FormatError>([&] { loadDetailMesh(hexUv.path()); });
    EXPECT_NE(message.find("texture coordinate 3 has '0X1p1'"), std::string::npos) << message;
    // Form feeds elsewhere are white space between the numbers, as OpenMesh reads them too.
    const TempFile inside("inside.obj", "v 0\f0 0\n" + rest);
    EXPECT_EQ(loadBaseMesh(inside.path()).triangles.size(), 1u);
}

TEST(LoadBaseMesh, EmptyOrUnknownFilesAreFormatErrors) {
    const TempFile empty("empty.obj", "");
    EXPECT_THROW(loadBaseMesh(empty.path()), FormatError);
    const TempFile noFaces("nofaces.obj", "v 0 0 0\nvt 0 0\n");
    EXPECT_THROW(loadBaseMesh(noFaces.path()), FormatError);
    const TempFile garbage("garbage.ply", "this is not a ply file\n");
    EXPECT_THROW(loadBaseMesh(garbage.path()), FormatError);
    const TempFile unknown("mesh.xyz", "1 2 3\n");
    const std::string message = messageOf<FormatError>([&] { loadBaseMesh(unknown.path()); });
    EXPECT_NE(message.find("accepted: .obj, .off, .ply"), std::string::npos) << message;
    const TempFile offWithoutUvs("nouv.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_THROW(loadBaseMesh(offWithoutUvs.path()), FormatError);
}

}  // namespace
}  // namespace distile

namespace distile {
namespace {

TEST(TangentFrames, MirroredUvLayoutSplitsTheMirrorLineIntoTwoFrames) {
    // Two unit quads side by side in the z = 0 plane, sharing the edge x = 1. The left quad maps
    // u = x, the right one u = 2 - x (mirrored about x = 1): along the shared edge the two sides
    // need opposite tangents, which one vertex cannot hold.
    BaseMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 1, 0}, {1, 1, 0}, {2, 1, 0}};
    mesh.uvs = {{0, 0}, {1, 0}, {0, 0}, {0, 1}, {1, 1}, {0, 1}};
    mesh.triangles = {{0, 1, 4}, {0, 4, 3}, {1, 2, 5}, {1, 5, 4}};
    computeTangentFrames(mesh);
    // The two vertices on the mirror line are split: 6 + 2 vertices.
    ASSERT_EQ(mesh.positions.size(), 8u);
    for (const glm::uvec3& triangle : mesh.triangles) {
        const bool right = mesh.positions[triangle[0]].x + mesh.positions[triangle[1]].x +
                               mesh.positions[triangle[2]].x >
                           3.0f;
        for (int corner = 0; corner < 3; ++corner) {
            const glm::vec4 tangent = mesh.tangents[triangle[corner]];
            // Exact: a flat quad's dP/du is +x on the left and -x on the right, v is +y on both.
            EXPECT_NEAR(tangent.x, right ? -1.0f : 1.0f, 1e-6f);
            EXPECT_NEAR(tangent.y, 0.0f, 1e-6f);
            EXPECT_EQ(tangent.w, right ? -1.0f : 1.0f);
            const glm::vec3 normal = mesh.normals[triangle[corner]];
            EXPECT_NEAR(normal.z, 1.0f, 1e-6f);
            // B = w cross(N, T) is +y on both sides: the detail is not flipped.
            const glm::vec3 bitangent = tangent.w * glm::cross(normal, glm::vec3(tangent));
            EXPECT_NEAR(bitangent.y, 1.0f, 1e-6f);
        }
    }
}

// ---- detail meshes (loadDetailMesh) ----------------------------------------------------------

const std::string kTetrahedronObj =
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// Binary STL of the tetrahedron above; `dropBytes` cuts the end off.
std::string tetrahedronBinaryStl(std::size_t dropBytes = 0) {
    const float corners[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const int faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    std::string bytes(80, ' ');
    const std::uint32_t count = 4;
    bytes.append(reinterpret_cast<const char*>(&count), 4);  // little-endian host (x86-64)
    for (const auto& face : faces) {
        const float normal[3] = {0, 0, 0};
        bytes.append(reinterpret_cast<const char*>(normal), 12);
        for (int c = 0; c < 3; ++c)
            bytes.append(reinterpret_cast<const char*>(corners[face[c]]), 12);
        bytes.append(2, '\0');
    }
    bytes.resize(bytes.size() - dropBytes);
    return bytes;
}

TEST(DetailMesh, ReadsObjOffPlyStl) {
    const TempFile obj("tet.obj", kTetrahedronObj);
    const TempFile off(
        "tet.off", "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n");
    const TempFile ply(
        "tet.ply",
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n");
    const TempFile stl("tet.stl", tetrahedronBinaryStl());
    for (const TempFile* file : {&obj, &off, &ply, &stl}) {
        const TriangleSoup soup = loadDetailMesh(file->path());
        EXPECT_EQ(soup.positions.size(), 4u) << file->path();  // STL corners merged
        EXPECT_EQ(soup.triangles.size(), 4u) << file->path();
        const Bounds3 box = boundsOf(soup);
        EXPECT_EQ(box.min, glm::dvec3(0.0)) << file->path();
        EXPECT_EQ(box.max, glm::dvec3(1.0)) << file->path();
    }
}

TEST(DetailMesh, WeldsCornersInEveryFormat) {
    // A closed box whose 12 triangles each have their own 3 corners (a soup, as exporters write
    // OBJ) and the same triangles as binary STL: both load as 8 vertices, 12 triangles, closed.
    const TriangleSoup box = test::makeBoxSoup(glm::dvec3(0.0), glm::dvec3(1.0, 2.0, 3.0));
    std::string obj, stl(80, ' ');
    const std::uint32_t count = std::uint32_t(box.triangles.size());
    stl.append(reinterpret_cast<const char*>(&count), 4);
    for (const glm::uvec3& triangle : box.triangles) {
        const float normal[3] = {0, 0, 0};
        stl.append(reinterpret_cast<const char*>(normal), 12);
        for (int c = 0; c < 3; ++c) {
            const glm::dvec3& p = box.positions[triangle[c]];
            obj += "v " + std::to_string(p.x) + " " + std::to_string(p.y) + " " +
                   std::to_string(p.z) + "\n";
            const float corner[3] = {float(p.x), float(p.y), float(p.z)};
            stl.append(reinterpret_cast<const char*>(corner), 12);
        }
        stl.append(2, '\0');
    }
    for (std::size_t t = 0; t < box.triangles.size(); ++t) {
        obj += "f " + std::to_string(3 * t + 1) + " " + std::to_string(3 * t + 2) + " " +
               std::to_string(3 * t + 3) + "\n";
    }
    const TempFile objFile("box_soup.obj", obj), stlFile("box_soup.stl", stl);
    const TriangleSoup fromObj = loadDetailMesh(objFile.path());
    const TriangleSoup fromStl = loadDetailMesh(stlFile.path());
    for (const TriangleSoup* soup : {&fromObj, &fromStl}) {
        EXPECT_EQ(soup->positions.size(), 8u);
        EXPECT_EQ(soup->triangles.size(), 12u);
        // Closed and consistently oriented: every directed edge once, its reverse once.
        std::map<std::pair<unsigned, unsigned>, int> directedEdges;
        for (const glm::uvec3& triangle : soup->triangles) {
            for (int c = 0; c < 3; ++c) ++directedEdges[{triangle[c], triangle[(c + 1) % 3]}];
        }
        EXPECT_EQ(directedEdges.size(), 36u);
        for (const auto& [edge, uses] : directedEdges) {
            EXPECT_EQ(uses, 1);
            EXPECT_EQ(directedEdges.count({edge.second, edge.first}), 1u);
        }
    }
    // The same triangles on the same positions (both keep the file's corner order).
    ASSERT_EQ(fromObj.triangles.size(), fromStl.triangles.size());
    for (std::size_t t = 0; t < fromObj.triangles.size(); ++t) {
        for (int c = 0; c < 3; ++c) {
            EXPECT_EQ(fromObj.positions[fromObj.triangles[t][c]],
                      fromStl.positions[fromStl.triangles[t][c]]);
        }
    }
}

TEST(DetailMesh, KeepsEveryFaceOfANonManifoldSoup) {
    // Three triangles on one edge (0-1) and a fourth through a vertex they share: no halfedge
    // mesh holds them as they are; a detail mesh keeps all four as written, whatever the format.
    const std::string points = "0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n1 1 1\n";
    const std::vector<glm::uvec3> faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}, {0, 5, 2}};
    std::string obj, off = "OFF\n6 4 0\n" + points;
    std::istringstream lines(points);
    for (std::string line; std::getline(lines, line);) obj += "v " + line + "\n";
    for (const glm::uvec3& f : faces) {
        obj += "f " + std::to_string(f.x + 1) + " " + std::to_string(f.y + 1) + " " +
               std::to_string(f.z + 1) + "\n";
        off += "3 " + std::to_string(f.x) + " " + std::to_string(f.y) + " " + std::to_string(f.z) +
               "\n";
    }
    const TempFile objFile("book.obj", obj), offFile("book.off", off);
    for (const TempFile* file : {&objFile, &offFile}) {
        const TriangleSoup soup = loadDetailMesh(file->path());
        EXPECT_EQ(soup.positions.size(), 6u) << file->path();
        ASSERT_EQ(soup.triangles.size(), faces.size()) << file->path();
        for (std::size_t t = 0; t < faces.size(); ++t) EXPECT_EQ(soup.triangles[t], faces[t]);
    }
}

TEST(DetailMesh, RejectsBadFilesWithOneLineMessages) {
    const auto expectFormatError = [](const std::string& name, const std::string& contents,
                                      const std::string& expectedPart) {
        const TempFile file(name, contents);
        const std::string message = messageOf<FormatError>([&] { loadDetailMesh(file.path()); });
        EXPECT_NE(message.find(expectedPart), std::string::npos) << name << ": " << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    };
    expectFormatError("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "non-finite");
    expectFormatError("inf.obj", "v inf 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "non-finite");
    expectFormatError("empty.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces");
    expectFormatError("empty.stl", "", "binary STL");
    expectFormatError("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", "refers to vertex 7");
    expectFormatError("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n",
                      "invalid vertex index");
    expectFormatError("range.ply",
                      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                      "property float y\nproperty float z\nelement face 1\n"
                      "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
                      "3 0 1 9\n",
                      "refers to vertex 9 (counting from 0); the file has 3 vertices");
    // OpenMesh reads an obj_info line's words as keywords: "element" took "end_header" for a
    // count, and its header parser looped, gigabytes in seconds (a fuzz campaign's input). A
    // "comment" ends the line for OpenMesh too.
    const std::string objInfoHeader =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\n";
    const std::string triangleBody = "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    expectFormatError("obj_info.ply",
                      objInfoHeader + "obj_info made with element x\n" + triangleBody,
                      "OpenMesh reads the words of an obj_info line as header keywords, and "
                      "'element' may not be one of them");
    EXPECT_EQ(
        loadDetailMesh(TempFile("obj_info_comment.ply",
                                objInfoHeader + "obj_info scan comment element\n" + triangleBody)
                           .path())
            .triangles.size(),
        1u);
    // Corners 1 and 4 are one point: the only face has no area once welded.
    expectFormatError("degenerate.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 0\nf 1 2 4\n",
                      "none of its 1 faces has three distinct corners");
    expectFormatError("truncated.stl", tetrahedronBinaryStl(30), "truncated");
    // OpenMesh drops a binary facet with a NaN corner: the mesh baked with a hole in it.
    for (const float bad : {std::numeric_limits<float>::quiet_NaN(), 3e9f}) {
        std::string stl = tetrahedronBinaryStl();
        std::memcpy(stl.data() + 84 + 50 + 12, &bad, 4);  // triangle 1, first corner's x
        expectFormatError("bad_corner.stl", stl, "triangle 1 (counting from 0) has the coordinate");
    }
    // OpenMesh reads the 3 lines after any line holding "outer" as corners.
    const std::string facet =
        "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
        "vertex 0 1 0\nendloop\nendfacet\n";
    EXPECT_EQ(
        loadDetailMesh(TempFile("ascii.stl", "solid a\n" + facet + facet + "endsolid a\n").path())
            .triangles.size(),
        2u);
    expectFormatError("outer_name.stl", "solid outer\n" + facet + "endsolid\n",
                      "line 2: 'facet normal 0 0 1' where a 'vertex x y z' line of the facet "
                      "whose 'outer loop' is line 1 must be");
    expectFormatError("short_facet.stl", "solid a\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n",
                      "ends inside the facet whose 'outer loop' is line 2");
    expectFormatError("float_range.stl",
                      "solid a\nouter loop\nvertex 0 0 0\nvertex 1e39 0 0\nvertex 0 1 0\n",
                      "line 4: '1e39' is not a finite decimal number within a float's range");
    expectFormatError("hex.stl", "solid a\nouter loop\nvertex 0 0 0\nvertex 0x1 0 0\n",
                      "'0x1' is not a finite decimal number");
    expectFormatError("truncated.ply",
                      "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
                      "property float y\nproperty float z\nelement face 4\n"
                      "property list uchar int vertex_indices\nend_header\n" +
                          std::string(20, '\0'),
                      "truncated");
    expectFormatError(
        "truncated_ascii.ply",
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 0\n1 0 0\n",
        "truncated");
    // Found by fuzzing (fuzz/corpus/mesh_ply/malformed_header.ply): OpenMesh's header parser
    // took gigabytes in seconds on header lines PLY does not define.
    expectFormatError("malformed_header.ply",
                      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                      "property float y\nproperty float z\nelement facproperty list2uchar int "
                      "vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
                      "not one PLY defines");
    expectFormatError("bad_format.ply",
                      "ply\nformat ascii ertex_indices\nelement vertex 1\nproperty float x\n"
                      "end_header\n0\n",
                      "format version 'ertex_indices' is not accepted");
    // Found by fuzzing (fuzz/corpus/mesh_ply/second_format_line.ply): OpenMesh's header parser
    // loops without end on a second format line.
    expectFormatError("second_format_line.ply",
                      "ply\nformat binary_little_endian ply\nformat binary_little_endian 1.0\n"
                      "element vertex 1\nproperty float x\nend_header\n" +
                          std::string(4, '\0'),
                      "the format line must come once");
    expectFormatError("format_not_first.ply",
                      "ply\nelement vertex 1\nformat ascii 1.0\nproperty float x\nend_header\n0\n",
                      "the format line must come once");
    expectFormatError("no_vertices.ply", "ply\nformat ascii 1.0\nend_header\n0 0 0\n",
                      "declares no vertex element");
    // OpenMesh reads an OFF file's counts from the line after the keyword's (it reserved 3.5 GB
    // for these, found by fuzzing).
    expectFormatError("counts_on_keyword_line.off", "OFF 0 0\n1  0877777777 0\n",
                      "the counts go on the next line");
    // OpenMesh reads an OFF body as a stream of numbers: a number too many or too few on a line
    // shifts all after it (a corner count of 4 billion read from a vertex: gigabytes of
    // indices, found by fuzzing).
    const std::string vertices = "0 0 0\n1 0 0\n0 1 0\n";
    expectFormatError("two_counts.off", "OFF\n3 1\n" + vertices + "3 0 1 2\n",
                      "OFF counts line has '0 0' after the vertex, face and edge counts (read as "
                      "3 1 0)");
    expectFormatError("extra_index.off", "OFF\n3 1 0\n" + vertices + "3 0 1 2 1\n",
                      "and nothing more (colours need a COFF)");
    EXPECT_EQ(loadDetailMesh(TempFile("colour.off",
                                      "COFF\n3 1 0\n0 0 0 255 0 0\n1 0 0 0 255 "
                                      "0\n0 1 0 0 0 255\n3 0 1 2 9 9 9\n")
                                 .path())
                  .triangles.size(),
              1u);
    expectFormatError("comment.off", "OFF\n3 1 0\n0 0 0\n# the second\n1 0 0\n0 1 0\n3 0 1 2\n",
                      "comment '# the second' in place of OFF vertex 1");
    expectFormatError("float_corners.off", "OFF\n3 1 0\n" + vertices + "3.0 0 1 2\n",
                      "OFF face 0 has the corner count '3.0'; expected 1 to 65536");
    expectFormatError("normals.off", "NOFF\n3 1 0\n" + vertices + "3 0 1 2\n",
                      "OFF vertex 0 has 3 numbers; each vertex's line holds at least its 3 "
                      "coordinates, 3 normal components");
    expectFormatError("uvs.off", "STOFF\n3 1 0\n0 0 0 0 0\n1 0 0 1\n0 1 0 0 1\n3 0 1 2\n",
                      "OFF vertex 1 has 4 numbers; each vertex's line holds at least its 3 "
                      "coordinates, 2 texture coordinates");
    expectFormatError("hex.off", "OFF\n3 1 0\n0x1 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                      "OFF vertex 0 has '0x1'; expected finite decimal numbers");
    const auto binaryOff = [](std::uint32_t corners, int indices) {
        std::string bytes = "OFF BINARY\n";
        const auto word = [&](std::uint32_t value) {
            bytes.append(reinterpret_cast<const char*>(&value), 4);  // little-endian here
        };
        word(3), word(1), word(0);
        for (float value : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f})
            word(std::bit_cast<std::uint32_t>(value));
        word(corners);
        for (int k = 0; k < indices; ++k) word(std::uint32_t(k));
        return bytes;
    };
    EXPECT_EQ(loadDetailMesh(TempFile("binary.off", binaryOff(3, 3)).path()).triangles.size(), 1u);
    expectFormatError("binary_corners.off", binaryOff(0xfffffff0u, 3),
                      "OFF face 0 has the corner count '4294967280'; expected 1 to 65536");
    expectFormatError("binary_truncated.off", binaryOff(3, 2), "binary OFF ends before its");
    expectFormatError("binary_index.off", binaryOff(4, 4),
                      "OFF face 0 has an invalid vertex index '3'; the file has 3 vertices");
    const std::string plyHeader =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    expectFormatError("float_count.ply", plyHeader + vertices + "3.0 0 1 2\n",
                      "PLY face 0 has '3.0'; expected a decimal integer");
    expectFormatError("hex.ply", plyHeader + "0 0 0\n0x1 0 0\n0 1 0\n3 0 1 2\n",
                      "PLY vertex 1 has '0x1'; expected a finite float number");
    expectFormatError("unprintable_header.ply",
                      "ply\nformat ascii 1.0\nelement ver\xf7"
                      "ex 3\nproperty float x\nend_header\n",
                      "not one PLY defines");
    expectFormatError("huge.obj", "v -1e30 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n", "within +-1e+09");
    expectFormatError("mesh.xyz", "", "unsupported mesh format");
    EXPECT_THROW(loadDetailMesh(std::filesystem::temp_directory_path() / "no_such_detail.stl"),
                 InputError);
}

// ---- polygons ------------------------------------------------------------------------------

using PolygonTriangles = std::vector<std::array<std::uint32_t, 3>>;

PolygonTriangles triangulated(const std::vector<glm::dvec3>& corners) {
    PolygonTriangles triangles;
    PolygonTriangulationBudget budget;
    EXPECT_TRUE(triangulatePolygon(corners, triangles, budget));
    return triangles;
}

/// Twice the signed area of the polygon `points` (x, y), positive counter-clockwise (shoelace).
double twiceSignedArea(const std::vector<glm::dvec2>& points) {
    double sum = 0.0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const glm::dvec2& a = points[i];
        const glm::dvec2& b = points[(i + 1) % points.size()];
        sum += a.x * b.y - a.y * b.x;
    }
    return sum;
}

/// Even-odd point-in-polygon test.
bool insidePolygon(const glm::dvec2& p, const std::vector<glm::dvec2>& points) {
    bool inside = false;
    for (std::size_t i = 0, j = points.size() - 1; i < points.size(); j = i++) {
        const glm::dvec2 &a = points[i], &b = points[j];
        if ((a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x)
            inside = !inside;
    }
    return inside;
}

/// Checks that `triangles` tile the simple polygon `points` (in the plane): n - 2 triangles, each
/// wound as the polygon (counter-clockwise), inside it, their areas adding up to its area.
void expectTiling(const std::vector<glm::dvec2>& points, const PolygonTriangles& triangles) {
    ASSERT_EQ(triangles.size(), points.size() - 2);
    double sum = 0.0;
    for (const auto& [a, b, c] : triangles) {
        const double twice = twiceSignedArea({points[a], points[b], points[c]});
        EXPECT_GT(twice, 0.0) << a << " " << b << " " << c;
        sum += std::abs(twice);
        const glm::dvec2 centroid = (points[a] + points[b] + points[c]) / 3.0;
        EXPECT_TRUE(insidePolygon(centroid, points)) << a << " " << b << " " << c;
    }
    const double area = twiceSignedArea(points);
    EXPECT_NEAR(sum, area, 1e-9 * area);
}

/// `points` placed in 3D: in the plane spanned by unit vectors u and v, offset by `origin`.
std::vector<glm::dvec3> placed(const std::vector<glm::dvec2>& points, const glm::dvec3& u,
                               const glm::dvec3& v, const glm::dvec3& origin) {
    std::vector<glm::dvec3> corners;
    for (const glm::dvec2& p : points) corners.push_back(origin + p.x * u + p.y * v);
    return corners;
}

/// A comb of `teeth` teeth 1 wide and 3 high, 1 apart on a bar 1 high, counter-clockwise from
/// the reflex corner right of the first tooth.
std::vector<glm::dvec2> comb(int teeth) {
    std::vector<glm::dvec2> points;
    for (int tooth = 0; tooth < teeth; ++tooth) {
        if (tooth > 0) {
            points.push_back({2.0 * tooth - 1.0, 1.0});
            points.push_back({2.0 * tooth, 1.0});
        }
        points.push_back({2.0 * tooth, 3.0});
        points.push_back({2.0 * tooth + 1.0, 3.0});
    }
    std::reverse(points.begin(), points.end());  // right to left along the top
    points.push_back({0.0, 0.0});
    points.push_back({2.0 * teeth - 1.0, 0.0});
    std::rotate(points.begin(), points.end() - 2, points.end());  // the bottom first
    std::rotate(points.begin(), points.begin() + 4, points.end());
    return points;
}

TEST(Polygon, ConvexPolygonsKeepTheFanFromTheirFirstCorner) {
    // What the loaders always did for convex faces, so their meshes load as before.
    std::vector<glm::dvec3> hexagon;
    for (int k = 0; k < 6; ++k)
        hexagon.push_back({std::cos(k * kPi / 3.0), std::sin(k * kPi / 3.0), 0.25 * (k % 2)});
    const PolygonTriangles expected{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 5}};
    EXPECT_EQ(triangulated(hexagon), expected);
    // Straight corners (a square with its edges' midpoints) still count as convex.
    const std::vector<glm::dvec3> square{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}};
    EXPECT_EQ(triangulated(square), (PolygonTriangles{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}}));
}

TEST(Polygon, AConcaveQuadIsSplitThroughItsReflexCorner) {
    // A dart: the fan from corner 0 gave (0, 1, 2), wound backwards outside the dart, and
    // (0, 2, 3), twice the dart's area.
    const std::vector<glm::dvec2> dart{{0, 0}, {2, 1}, {4, 0}, {2, 3}};
    const PolygonTriangles triangles = triangulated(placed(dart, {1, 0, 0}, {0, 1, 0}, {}));
    expectTiling(dart, triangles);
    for (const auto& triangle : triangles) {  // both sides of the diagonal 1-3
        EXPECT_NE(std::find(triangle.begin(), triangle.end(), 1u), triangle.end());
        EXPECT_NE(std::find(triangle.begin(), triangle.end(), 3u), triangle.end());
    }
}

TEST(Polygon, ConcavePolygonsInAnyPlaneAndEitherWindingAreTiled) {
    std::vector<std::vector<glm::dvec2>> shapes{
        // An L starting at its reflex side: the fan from corner 0 crossed outside.
        {{2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 0}, {2, 0}},
        comb(2),
        comb(9),
    };
    std::vector<glm::dvec2> star;  // starting at an inner (reflex) corner
    for (int k = 0; k < 14; ++k) {
        const double radius = k % 2 == 0 ? 0.35 : 1.0;
        star.push_back({radius * std::cos(k * kPi / 7.0), radius * std::sin(k * kPi / 7.0)});
    }
    shapes.push_back(star);
    // A curled band: many reflex corners in a row along its inner side.
    std::vector<glm::dvec2> band;
    for (int k = 0; k <= 20; ++k)
        band.push_back({(2.0 + k * 0.1) * std::cos(k * 0.3), (2.0 + k * 0.1) * std::sin(k * 0.3)});
    for (int k = 20; k >= 0; --k)
        band.push_back({(1.0 + k * 0.1) * std::cos(k * 0.3), (1.0 + k * 0.1) * std::sin(k * 0.3)});
    shapes.push_back(band);
    // Planes in general position, seen from either side (the corners' order in the plane's
    // coordinates is what the triangles are checked in).
    const glm::dvec3 u = glm::normalize(glm::dvec3(0.3, -0.8, 0.5));
    const glm::dvec3 v = glm::normalize(glm::cross(glm::dvec3(0.1, 0.7, 0.4), u));
    for (const auto& shape : shapes) {
        SCOPED_TRACE(shape.size());
        ASSERT_GT(twiceSignedArea(shape), 0.0);
        for (const auto& [first, second] : {std::pair{u, v}, std::pair{v, u},
                                            std::pair{glm::dvec3(0, 0, 1), glm::dvec3(1, 0, 0)}}) {
            expectTiling(shape, triangulated(placed(shape, first, second, {5.0, -3.0, 2.0})));
        }
    }
}

TEST(Polygon, SelfCrossingAndFlatPolygonsStillGiveTheirTriangles) {
    // Whatever the corners, n - 2 triangles of valid corners, and an end: random polygons mostly
    // cross themselves; some lie on a line or are one point.
    std::mt19937 random(7);
    std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
    for (int polygon = 0; polygon < 2000; ++polygon) {
        const int count = 4 + polygon % 13;
        std::vector<glm::dvec3> corners;
        for (int k = 0; k < count; ++k) {
            glm::dvec3 p(coordinate(random), coordinate(random), coordinate(random));
            if (polygon % 5 == 0) p = glm::dvec3(p.x, 2.0 * p.x, -p.x);  // on one line
            if (polygon % 7 == 0) p = glm::dvec3(0.5);                   // one point
            corners.push_back(p);
        }
        const PolygonTriangles triangles = triangulated(corners);
        ASSERT_EQ(triangles.size(), std::size_t(count - 2)) << polygon;
        for (const auto& triangle : triangles)
            for (const std::uint32_t corner : triangle) ASSERT_LT(corner, std::uint32_t(count));
    }
}

TEST(Polygon, EarClippingStopsAtItsBudget) {
    const std::vector<glm::dvec3> corners = placed(comb(200), {1, 0, 0}, {0, 1, 0}, {});
    PolygonTriangles triangles{{7, 8, 9}};
    PolygonTriangulationBudget budget{1000};
    EXPECT_FALSE(triangulatePolygon(corners, triangles, budget));
    EXPECT_EQ(triangles, (PolygonTriangles{{7, 8, 9}}));  // unchanged
    budget.testsLeft = std::uint64_t(1) << 28;
    EXPECT_TRUE(triangulatePolygon(corners, triangles, budget));
    EXPECT_EQ(triangles.size(), 1 + corners.size() - 2);
}

TEST(LoadBaseMesh, AConcaveFaceBecomesTrianglesInsideIt) {
    // An L whose first corner sees only part of it: the fan from there put a triangle outside
    // the L, wound against it (its detail would have shown from below).
    const TempFile file("l.obj",
                        "v 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\nv 2 0 0\n"
                        "vt 1 0.5\nvt 0.5 0.5\nvt 0.5 1\nvt 0 1\nvt 0 0\nvt 1 0\n"
                        "f 1/1 2/2 3/3 4/4 5/5 6/6\n");
    const BaseMesh mesh = loadBaseMesh(file.path());
    ASSERT_EQ(mesh.triangles.size(), 4u);
    double area = 0.0;
    for (const glm::uvec3& triangle : mesh.triangles) {
        const glm::vec3 normal =
            glm::cross(mesh.positions[triangle.y] - mesh.positions[triangle.x],
                       mesh.positions[triangle.z] - mesh.positions[triangle.x]);
        EXPECT_GT(normal.z, 0.0f);
        area += 0.5 * normal.z;
        // Each corner keeps its uv (here uv = position / 2).
        for (int corner = 0; corner < 3; ++corner) {
            EXPECT_EQ(mesh.uvs[triangle[corner]] * 2.0f,
                      glm::vec2(mesh.positions[triangle[corner]]));
        }
    }
    EXPECT_DOUBLE_EQ(area, 3.0);
    for (const glm::vec3& normal : mesh.normals) EXPECT_EQ(normal, glm::vec3(0, 0, 1));
}

TEST(DetailMesh, AConcaveFaceBecomesTrianglesInsideIt) {
    // The L as a prism 1 high: its caps are concave hexagons, its sides quads. Every triangle
    // of a cap faces as the cap does.
    const TempFile file("l_prism.obj",
                        "v 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\nv 2 0 0\n"
                        "v 2 1 1\nv 1 1 1\nv 1 2 1\nv 0 2 1\nv 0 0 1\nv 2 0 1\n"
                        "f 7 8 9 10 11 12\nf 6 5 4 3 2 1\n"
                        "f 1 2 8 7\nf 2 3 9 8\nf 3 4 10 9\nf 4 5 11 10\nf 5 6 12 11\nf 6 1 7 12\n");
    const TriangleSoup soup = loadDetailMesh(file.path());
    ASSERT_EQ(soup.triangles.size(), 4u + 4u + 12u);
    double volume = 0.0;
    for (const glm::uvec3& triangle : soup.triangles) {
        const glm::dvec3 &a = soup.positions[triangle.x], &b = soup.positions[triangle.y],
                         &c = soup.positions[triangle.z];
        const glm::dvec3 normal = glm::cross(b - a, c - a);
        if (a.z == b.z && b.z == c.z) {
            EXPECT_EQ(normal.z > 0.0, a.z == 1.0);
        }
        volume += glm::dot(a, glm::cross(b, c)) / 6.0;
    }
    EXPECT_DOUBLE_EQ(volume, 3.0);
}

TEST(LoadBaseMesh, AConcavePolygonBeyondTheSplittingBudgetIsAFormatError) {
    // A comb of 4000 teeth takes about 10^8 corner tests to split: refused within the budget's
    // fraction of a second, where a file of such faces would take minutes.
    std::string obj;
    const std::vector<glm::dvec2> teeth = comb(4000);
    for (const glm::dvec2& p : teeth)
        obj += "v " + std::to_string(p.x) + " " + std::to_string(p.y) + " 0\n";
    obj += "vt 0 0\nf";
    for (std::size_t corner = 1; corner <= teeth.size(); ++corner)
        obj += " " + std::to_string(corner) + "/1";
    const TempFile file("comb.obj", obj + "\n");
    const std::string message = messageOf<FormatError>([&] { loadBaseMesh(file.path()); });
    EXPECT_NE(message.find("face 0 (counting from 0) is a concave polygon of 16000 corners"),
              std::string::npos)
        << message;
    EXPECT_NE(message.find("split it into smaller polygons"), std::string::npos) << message;
    // A comb of 1000 teeth is well within it.
    PolygonTriangles triangles;
    PolygonTriangulationBudget budget;
    EXPECT_TRUE(
        triangulatePolygon(placed(comb(1000), {1, 0, 0}, {0, 1, 0}, {}), triangles, budget));
    EXPECT_GT(budget.testsLeft, PolygonTriangulationBudget{}.testsLeft / 2);
}

}  // namespace
}  // namespace distile
