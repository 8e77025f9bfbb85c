/// @file
/// Eight rays entering one flat detail shell at a time with AVX2: SceneTracer's entry arithmetic
/// (render/tracer.cpp, SceneTracer::takeEntry) in SIMD lanes, with the scalar operations in their
/// order and precision (no FMA), so bit for bit as one ray at a time: the entry point and uv on the
/// shell's top, the ray's direction in texel space, its start in the tile (the uv wrapped in double
/// precision) and the jump over the empty layers above the highest occupied top. A flat shell's
/// frame is the same at every point of it, so it is one set of constants.
/// Built in its own translation unit with AVX2; plain types only, as sampler/trilinear_wide.h.
#pragma once

namespace distile::detail {

/// What the eight rays of one call share: their shell and the march's settings.
struct FlatShellConstants {
    float tangent[3], bitangent[3], normal[3];  ///< the shell's frame T, B, N (unit)
    float texelsPerWorld[3];                    ///< scale of the T, B, N components into texels
    float uvCorners[3][2];                      ///< the base triangle's corners' uv
    double uvScale[2];                          ///< the material's
    int tileWidth, tileHeight, tileDepth;       ///< texels
    /// The march starts no higher than this (TileOccupancy::highestTopTexels); +infinity: it
    /// starts at the top face.
    float highestTopTexels;
};

/// Eight rays: the inputs (each ray and where it meets the shell's top), then what the entry
/// computes for each. Lanes a call does not use may hold anything finite.
struct EntryLanes {
    float origin[3][8], direction[3][8];  ///< world, the direction unit
    float distanceWorld[8];               ///< the top's hit (TriangleHit)
    double b1[8], b2[8];                  ///< its barycentric weights
    float position[3][8];                 ///< out: the entry point, world
    float uv[2][8];                       ///< out: its uv (float interpolation)
    float directionTexels[3][8];          ///< out: unit, descending
    float texelsPerWorldAlongRay[8];      ///< out
    float startTexels[3][8];              ///< out: where the march starts
    float skippedTexels[8];               ///< out: the empty path before it
};

/// Fills the outputs of `lanes` for rays entering the flat shell `shell`. Precondition:
/// kSimdLevel >= SimdLevel::Avx2 (common/simd.h).
void enterFlatShell8(const FlatShellConstants& shell, EntryLanes& lanes);

}  // namespace distile::detail
