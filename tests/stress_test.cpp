// Numerical-stability stress suite: grazing rays, far UVs, far base meshes, broken UV
// layouts, a camera inside the shell, sub-texel wires, extreme shell depths and NaN/Inf rays. The
// cases themselves (scenes, known answers, checks) live in bench/stress/stress_cases.h, shared with
// `distile bench --stress`; here each family asserts its cases' error against the tolerance named
// below, no non-finite output and every check, and prints its measured figures with a
// "[ figures  ]" prefix. Small images and tiles, in-process: the whole file runs in seconds.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <set>
#include <string>
#include <vector>

#include "bench/stress/stress_cases.h"
#include "render/tracer.h"

namespace distile {
namespace {

/// Every case, run once per test program.
const std::vector<StressCase>& allCases() {
    static const std::vector<StressCase> cases = runStressCases();
    return cases;
}

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

/// Asserts the cases whose name starts with `prefix` (and contains `part`): there are `count` of
/// them, each with `toleranceTexels` as its bound, an error within it, no non-finite output and
/// every check held.
void expectCases(const std::string& prefix, const std::string& part, std::size_t count,
                 double toleranceTexels) {
    std::size_t found = 0;
    for (const StressCase& c : allCases()) {
        if (c.name.rfind(prefix, 0) != 0 || !contains(c.name, part)) continue;
        ++found;
        SCOPED_TRACE(c.name);
        std::printf("[ figures  ] %s: %s (error %.3g, tolerance %.3g texels)\n", c.name.c_str(),
                    c.measured.c_str(), c.errorTexels, c.toleranceTexels);
        EXPECT_DOUBLE_EQ(c.toleranceTexels, toleranceTexels);
        EXPECT_TRUE(std::isfinite(c.errorTexels));
        EXPECT_LE(c.errorTexels, c.toleranceTexels);
        EXPECT_EQ(c.nonFinitePixels, 0u);
        EXPECT_FALSE(c.checks.empty() && c.toleranceTexels == 0.0) << "a case that checks nothing";
        for (const StressCheck& check : c.checks) EXPECT_TRUE(check.held) << check.what;
        EXPECT_TRUE(c.passed);
    }
    EXPECT_EQ(found, count) << prefix << " ... " << part;
}

const double kEpsilonTexels = TraceOptions{}.march.epsilonTexels;

TEST(Stress, EveryCaseIsReportedOnceWithAFiniteErrorAndAVerdict) {
    // 10 grazing sphere-tracing, 6 budgeted grazing, far uvs, a triangle across many repeats, far
    // mesh, mirrored, degenerate, camera inside, wires, 4 shell depths, NaN/Inf rays.
    ASSERT_EQ(allCases().size(), 28u);
    std::set<std::string> names;
    for (const StressCase& c : allCases()) {
        EXPECT_TRUE(names.insert(c.name).second) << "duplicate case " << c.name;
        EXPECT_FALSE(c.expected.empty()) << c.name;
        EXPECT_FALSE(c.measured.empty()) << c.name;
        EXPECT_TRUE(std::isfinite(c.errorTexels)) << c.name;
        EXPECT_TRUE(c.passed) << c.name << ": " << c.measured;
    }
}

TEST(Stress, GrazingRaysStayAboveAFlatDetailPlaneWithABoundedError) {
    // Plain sphere tracing at 0.1 to 5 degrees, 16 and 4096 steps, against the march on the exact
    // plane computed in double: float rounding over the steps stays within 1e-3 texel of it.
    ASSERT_NO_FATAL_FAILURE(expectCases("grazing rays", "sphere tracing 16 steps", 5, 1e-3));
    ASSERT_NO_FATAL_FAILURE(expectCases("grazing rays", "sphere tracing 4096 steps", 5, 1e-3));
}

TEST(Stress, BudgetedMarchReachesAFlatDetailPlaneOnGrazingRaysWithinTheDefaultBudget) {
    // Float rounding of a secant over a path of up to 2300 texels (0.1 degree): 1e-3 past epsilon.
    ASSERT_NO_FATAL_FAILURE(
        expectCases("grazing rays",
                    "budgeted march " + std::to_string(MarchSettings{}.maxIterations) + " samples",
                    6, kEpsilonTexels + 1e-3));
}

TEST(Stress, UvsFarFromTheOriginRenderLikeSmallOnes) {
    // 1e-3 texel: well above the double-precision uv's rounding (1e-5), well below the 0.13 texel
    // of a float interpolation at 1e4.
    ASSERT_NO_FATAL_FAILURE(expectCases("uvs far from the origin (", "", 1, 1e-3));
}

TEST(Stress, ATriangleAcrossAMillionRepeatsRendersLikeASmallOne) {
    // The same bound: the entry's uv is wrapped from double barycentric weights.
    ASSERT_NO_FATAL_FAILURE(
        expectCases("uvs far from the origin across one triangle", "", 1, 1e-3));
}

TEST(Stress, BaseMeshFarFromTheWorldOriginRendersLikeNearIt) {
    // Depth may jump by the shell's 0.5 world units (16 texels) where a ray moved by float
    // rounding at 1e5 lands across a detail edge.
    ASSERT_NO_FATAL_FAILURE(expectCases("base mesh far from the world origin", "", 1, 16.0));
}

TEST(Stress, MirroredAndDegenerateUvTrianglesAndZeroAreaFacesStayFinite) {
    // Mirrored: straight down on an exact plane distance lands within epsilon. Degenerate: the bare
    // surface's hit 1 unit away is exact to float rounding (1e-4 texel).
    ASSERT_NO_FATAL_FAILURE(expectCases("mirrored uv triangles", "", 1, kEpsilonTexels));
    ASSERT_NO_FATAL_FAILURE(
        expectCases("degenerate uv triangles and zero-area faces", "", 1, 1e-4));
}

TEST(Stress, CameraInsideTheShellSeesBackFacesAndFinitePixels) {
    // Exact distances to the back face and the ground, to float rounding (1e-6 world, 32 texels
    // per world unit).
    ASSERT_NO_FATAL_FAILURE(expectCases("camera inside the shell", "", 1, 32e-6));
}

TEST(Stress, WiresThinnerThanATexelBakeAndRenderFinite) {
    // The conservative tile's overestimate of the analytic distance: rounding only (1e-3 texel).
    ASSERT_NO_FATAL_FAILURE(expectCases("wires thinner than a texel", "", 1, 1e-3));
}

TEST(Stress, ShellDepthsFrom1e4To1e2WorldUnitsStayFinite) {
    // Straight-down rays take exact steps at every depth: the hit is within epsilon.
    ASSERT_NO_FATAL_FAILURE(expectCases("shell depth", "", 4, kEpsilonTexels));
}

TEST(Stress, NanAndInfRaysMissOrStayFinite) {
    // No geometric truth for a NaN ray: finiteness and the march's rejections are the checks.
    ASSERT_NO_FATAL_FAILURE(expectCases("NaN and Inf rays", "", 1, 0.0));
}

}  // namespace
}  // namespace distile
