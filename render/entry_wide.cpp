// The AVX2 kernel of render/detail/entry_wide.h. Compiled with -mavx2 and without FMA (see
// sampler/trilinear_wide.cpp: nothing here is shared with the SSE2 build of distile).
#include "render/detail/entry_wide.h"

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)
#include <immintrin.h>
#endif

namespace distile::detail {

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)

namespace {

/// (a x + b y) + c z: glm::dot's order.
__m256 dot3(__m256 x, __m256 y, __m256 z, float a, float b, float c) {
    return _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(x, _mm256_set1_ps(a)), _mm256_mul_ps(y, _mm256_set1_ps(b))),
        _mm256_mul_ps(z, _mm256_set1_ps(c)));
}

__m256 lengthOf(__m256 x, __m256 y, __m256 z) {
    return _mm256_sqrt_ps(_mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(x, x), _mm256_mul_ps(y, y)),
                                        _mm256_mul_ps(z, z)));
}

/// All bits set where the lane is finite.
__m256 finite(__m256 value) {
    const __m256 magnitude =
        _mm256_and_ps(value, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff)));
    return _mm256_cmp_ps(magnitude, _mm256_set1_ps(3.40282347e38f), _CMP_LE_OQ);
}

/// Four lanes of the uv wrapped into the tile, in double: corner 0 plus the weighted edge deltas,
/// times the scale, its fraction times the extent, as float.
__m128 wrappedTexels(__m128 b1, __m128 b2, float corner0, float corner1, float corner2,
                     double scale, int extent) {
    const double first = corner0;
    const __m256d value = _mm256_mul_pd(
        _mm256_add_pd(_mm256_add_pd(_mm256_set1_pd(first),
                                    _mm256_mul_pd(_mm256_cvtps_pd(b1),
                                                  _mm256_set1_pd(double(corner1) - first))),
                      _mm256_mul_pd(_mm256_cvtps_pd(b2), _mm256_set1_pd(double(corner2) - first))),
        _mm256_set1_pd(scale));
    const __m256d fraction = _mm256_sub_pd(value, _mm256_floor_pd(value));
    return _mm256_cvtpd_ps(_mm256_mul_pd(fraction, _mm256_set1_pd(double(extent))));
}

__m256 wrappedTexels8(__m256 b1, __m256 b2, const float (&corners)[3][2], int axis, double scale,
                      int extent) {
    const __m128 low =
        wrappedTexels(_mm256_castps256_ps128(b1), _mm256_castps256_ps128(b2), corners[0][axis],
                      corners[1][axis], corners[2][axis], scale, extent);
    const __m128 high =
        wrappedTexels(_mm256_extractf128_ps(b1, 1), _mm256_extractf128_ps(b2, 1), corners[0][axis],
                      corners[1][axis], corners[2][axis], scale, extent);
    return _mm256_insertf128_ps(_mm256_castps128_ps256(low), high, 1);
}

}  // namespace

void enterFlatShell8(const FlatShellConstants& shell, EntryLanes& lanes) {
    const __m256 ox = _mm256_loadu_ps(lanes.origin[0]), oy = _mm256_loadu_ps(lanes.origin[1]),
                 oz = _mm256_loadu_ps(lanes.origin[2]);
    const __m256 dx = _mm256_loadu_ps(lanes.direction[0]), dy = _mm256_loadu_ps(lanes.direction[1]),
                 dz = _mm256_loadu_ps(lanes.direction[2]);
    const __m256 t = _mm256_loadu_ps(lanes.distanceWorld);
    const __m256 b1 = _mm256_loadu_ps(lanes.b1), b2 = _mm256_loadu_ps(lanes.b2);
    // The entry point and its uv (SceneTracer::shellEntry).
    _mm256_storeu_ps(lanes.position[0], _mm256_add_ps(ox, _mm256_mul_ps(dx, t)));
    _mm256_storeu_ps(lanes.position[1], _mm256_add_ps(oy, _mm256_mul_ps(dy, t)));
    _mm256_storeu_ps(lanes.position[2], _mm256_add_ps(oz, _mm256_mul_ps(dz, t)));
    const __m256 b0 = _mm256_sub_ps(_mm256_sub_ps(_mm256_set1_ps(1.0f), b1), b2);
    for (int axis = 0; axis < 2; ++axis) {
        const __m256 uv = _mm256_add_ps(
            _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(shell.uvCorners[0][axis]), b0),
                          _mm256_mul_ps(_mm256_set1_ps(shell.uvCorners[1][axis]), b1)),
            _mm256_mul_ps(_mm256_set1_ps(shell.uvCorners[2][axis]), b2));
        _mm256_storeu_ps(lanes.uv[axis], uv);
    }
    // The direction in texel space (ShellEntry::toTexel), kept descending, made unit.
    const __m256 x =
        _mm256_mul_ps(dot3(dx, dy, dz, shell.tangent[0], shell.tangent[1], shell.tangent[2]),
                      _mm256_set1_ps(shell.texelsPerWorld[0]));
    const __m256 y =
        _mm256_mul_ps(dot3(dx, dy, dz, shell.bitangent[0], shell.bitangent[1], shell.bitangent[2]),
                      _mm256_set1_ps(shell.texelsPerWorld[1]));
    __m256 z = _mm256_mul_ps(dot3(dx, dy, dz, shell.normal[0], shell.normal[1], shell.normal[2]),
                             _mm256_set1_ps(shell.texelsPerWorld[2]));
    __m256 length = lengthOf(x, y, z);
    const __m256 steepest = _mm256_mul_ps(_mm256_set1_ps(-1e-3f), length);
    const __m256 tooFlat = _mm256_cmp_ps(steepest, z, _CMP_LT_OQ);
    z = _mm256_blendv_ps(z, steepest, tooFlat);
    length = _mm256_blendv_ps(length, lengthOf(x, y, z), tooFlat);
    const __m256 ux = _mm256_div_ps(x, length), uy = _mm256_div_ps(y, length),
                 uz = _mm256_div_ps(z, length);
    _mm256_storeu_ps(lanes.directionTexels[0], ux);
    _mm256_storeu_ps(lanes.directionTexels[1], uy);
    _mm256_storeu_ps(lanes.directionTexels[2], uz);
    _mm256_storeu_ps(lanes.texelsPerWorldAlongRay, length);
    // The start: the uv wrapped into the tile in double precision, on the top face.
    const __m256 sx = wrappedTexels8(b1, b2, shell.uvCorners, 0, shell.uvScale[0], shell.tileWidth);
    const __m256 sy =
        wrappedTexels8(b1, b2, shell.uvCorners, 1, shell.uvScale[1], shell.tileHeight);
    const __m256 sz = _mm256_set1_ps(float(shell.tileDepth));
    // TileOccupancy::emptyTravelTexels without the block walk: down to the highest top, for a
    // finite start and a finite, descending direction.
    const __m256 signBit = _mm256_castsi256_ps(_mm256_set1_epi32(int(0x80000000u)));
    const __m256 descent = _mm256_xor_ps(uz, signBit);  // -direction.z
    const __m256 top = _mm256_set1_ps(shell.highestTopTexels);
    const __m256 jumps = _mm256_and_ps(
        _mm256_and_ps(_mm256_and_ps(finite(sx), finite(sy)), _mm256_and_ps(finite(sz), finite(ux))),
        _mm256_and_ps(_mm256_and_ps(finite(uy), _mm256_cmp_ps(uz, _mm256_setzero_ps(), _CMP_LT_OQ)),
                      _mm256_cmp_ps(sz, top, _CMP_GT_OQ)));
    const __m256 perDescent = _mm256_div_ps(_mm256_set1_ps(1.0f), descent);
    const __m256 skipped = _mm256_and_ps(jumps, _mm256_mul_ps(_mm256_sub_ps(sz, top), perDescent));
    _mm256_storeu_ps(lanes.skippedTexels, skipped);
    const __m256 startZ = _mm256_add_ps(sz, _mm256_mul_ps(uz, skipped));
    _mm256_storeu_ps(lanes.startTexels[0], _mm256_add_ps(sx, _mm256_mul_ps(ux, skipped)));
    _mm256_storeu_ps(lanes.startTexels[1], _mm256_add_ps(sy, _mm256_mul_ps(uy, skipped)));
    _mm256_storeu_ps(lanes.startTexels[2], startZ);
    // adaptiveBudget(budget, path to the floor): a sample per texel, in [budget / 4, budget].
    const __m256i budget = _mm256_set1_epi32(shell.budget);
    __m256i maxIterations = budget;
    if (shell.adaptiveBudget) {
        const __m256 samples = _mm256_ceil_ps(_mm256_div_ps(startZ, descent));
        const __m256 cut = _mm256_cmp_ps(samples, _mm256_set1_ps(float(shell.budget)), _CMP_LT_OQ);
        const int fewest = (shell.budget + 3) / 4 > 1 ? (shell.budget + 3) / 4 : 1;
        const __m256i atLeast = _mm256_max_epi32(_mm256_cvttps_epi32(_mm256_and_ps(cut, samples)),
                                                 _mm256_set1_epi32(fewest));
        maxIterations = _mm256_blendv_epi8(budget, atLeast, _mm256_castps_si256(cut));
    }
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(lanes.maxIterations), maxIterations);
    _mm256_zeroupper();
}

#else

void enterFlatShell8(const FlatShellConstants&, EntryLanes&) {}

#endif

}  // namespace distile::detail
