/// @file
/// The numerical-stability stress cases: grazing rays (0.1 to 5 degrees above the
/// surface), UVs far from the origin, a base mesh far from the world origin, mirrored and
/// degenerate UV triangles and zero-area faces, a camera inside the shell, wires thinner than a
/// texel, shell depths from 1e-4 to 1e2 world units, and NaN/Inf rays. Each case states the
/// behaviour it expects, runs small in-process scenes and tiles, and reports its error against a
/// known answer (a plane's exact hit, the same scene near the origin, the analytic chain mail).
/// tests/stress_test.cpp asserts the results; `distile bench --stress` writes them as a report.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace distile {

/// One expectation of a stress case, with the measured figure it was judged on.
struct StressCheck {
    std::string what;  ///< "every ray converged: 18 of 18", "min hit error -2e-06 >= -1e-4 texel"
    bool held = false;
};

/// The outcome of one stress case.
struct StressCase {
    std::string name;              ///< "grazing rays 0.1 deg, sphere tracing 16 steps", ...
    std::string expected;          ///< the expected behaviour, one sentence
    std::string measured;          ///< what was measured, one line with units
    double errorTexels = 0.0;      ///< the case's error figure against its known answer, texels
    double toleranceTexels = 0.0;  ///< the bound on errorTexels
    std::uint64_t nonFinitePixels = 0;  ///< NaN/Inf pixels (or hit values, texels) produced
    std::vector<StressCheck> checks;    ///< every other expectation of the case
    /// errorTexels finite and within toleranceTexels, no non-finite output, every check held.
    bool passed = false;
};

/// Runs every stress case, in a fixed order (a few seconds on 2 cores; deterministic). Never
/// throws for a failing case: a failure (including an exception inside a case) is a case with
/// passed = false and the reason in its checks.
std::vector<StressCase> runStressCases();

}  // namespace distile
