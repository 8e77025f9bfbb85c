// The AVX2 kernel of render/detail/entry_wide.h over Lanes8 (sampler/detail/simd_lanes.h).
// Compiled with -mavx2 and without FMA (see sampler/trilinear_wide.cpp: nothing here is shared
// with the SSE2 build of distile).
#include "render/detail/entry_wide.h"

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)
#include "render/march_wide.h"
#include "sampler/detail/simd_lanes.h"
#endif

namespace distile::detail {

#if defined(__x86_64__) && defined(__AVX2__) && !defined(__FMA__)

namespace {

using L = Lanes8;

/// (a x + b y) + c z: glm::dot's order.
L::F dot3(L::F x, L::F y, L::F z, float a, float b, float c) {
    return L::add(L::add(L::mul(x, L::set1(a)), L::mul(y, L::set1(b))), L::mul(z, L::set1(c)));
}

L::F lengthOf(L::F x, L::F y, L::F z) {
    return L::sqrt(L::add(L::add(L::mul(x, x), L::mul(y, y)), L::mul(z, z)));
}

/// Set where the lane is finite.
L::M finite(L::F value) {
    return L::greaterEqual(L::set1(3.40282347e38f), L::abs(value));
}

/// Four lanes of the uv wrapped into the tile, in double: corner 0 plus the weighted edge deltas,
/// times the scale, its fraction times the extent, as float. Double lanes are this kernel's alone,
/// so they stay AVX intrinsics rather than lanes operations.
__m128 wrappedTexels(__m256d b1, __m256d b2, float corner0, float corner1, float corner2,
                     double scale, int extent) {
    const double first = corner0;
    const __m256d value = _mm256_mul_pd(
        _mm256_add_pd(_mm256_add_pd(_mm256_set1_pd(first),
                                    _mm256_mul_pd(b1, _mm256_set1_pd(double(corner1) - first))),
                      _mm256_mul_pd(b2, _mm256_set1_pd(double(corner2) - first))),
        _mm256_set1_pd(scale));
    const __m256d fraction = _mm256_sub_pd(value, _mm256_floor_pd(value));
    return _mm256_cvtpd_ps(_mm256_mul_pd(fraction, _mm256_set1_pd(double(extent))));
}

L::F wrappedTexels8(const double (&b1)[8], const double (&b2)[8], const float (&corners)[3][2],
                    int axis, double scale, int extent) {
    const __m128 low = wrappedTexels(_mm256_loadu_pd(b1), _mm256_loadu_pd(b2), corners[0][axis],
                                     corners[1][axis], corners[2][axis], scale, extent);
    const __m128 high =
        wrappedTexels(_mm256_loadu_pd(b1 + 4), _mm256_loadu_pd(b2 + 4), corners[0][axis],
                      corners[1][axis], corners[2][axis], scale, extent);
    return _mm256_insertf128_ps(_mm256_castps128_ps256(low), high, 1);
}

/// Eight doubles rounded to float lanes.
L::F toFloat8(const double (&values)[8]) {
    return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm256_cvtpd_ps(_mm256_loadu_pd(values))),
                                _mm256_cvtpd_ps(_mm256_loadu_pd(values + 4)), 1);
}

}  // namespace

void enterFlatShell8(const FlatShellConstants& shell, EntryLanes& lanes) {
    const L::F ox = L::loadUnaligned(lanes.origin[0]), oy = L::loadUnaligned(lanes.origin[1]),
               oz = L::loadUnaligned(lanes.origin[2]);
    const L::F dx = L::loadUnaligned(lanes.direction[0]), dy = L::loadUnaligned(lanes.direction[1]),
               dz = L::loadUnaligned(lanes.direction[2]);
    const L::F t = L::loadUnaligned(lanes.distanceWorld);
    const L::F b1 = toFloat8(lanes.b1), b2 = toFloat8(lanes.b2);
    // The entry point and its uv (SceneTracer::shellEntry).
    L::storeUnaligned(lanes.position[0], L::add(ox, L::mul(dx, t)));
    L::storeUnaligned(lanes.position[1], L::add(oy, L::mul(dy, t)));
    L::storeUnaligned(lanes.position[2], L::add(oz, L::mul(dz, t)));
    const L::F b0 = L::sub(L::sub(L::set1(1.0f), b1), b2);
    for (int axis = 0; axis < 2; ++axis) {
        const L::F uv = L::add(L::add(L::mul(L::set1(shell.uvCorners[0][axis]), b0),
                                      L::mul(L::set1(shell.uvCorners[1][axis]), b1)),
                               L::mul(L::set1(shell.uvCorners[2][axis]), b2));
        L::storeUnaligned(lanes.uv[axis], uv);
    }
    // The direction in texel space (ShellEntry::toTexel), kept descending, made unit.
    const L::F x = L::mul(dot3(dx, dy, dz, shell.tangent[0], shell.tangent[1], shell.tangent[2]),
                          L::set1(shell.texelsPerWorld[0]));
    const L::F y =
        L::mul(dot3(dx, dy, dz, shell.bitangent[0], shell.bitangent[1], shell.bitangent[2]),
               L::set1(shell.texelsPerWorld[1]));
    L::F z = L::mul(dot3(dx, dy, dz, shell.normal[0], shell.normal[1], shell.normal[2]),
                    L::set1(shell.texelsPerWorld[2]));
    L::F length = lengthOf(x, y, z);
    const L::F steepest = L::mul(L::set1(-1e-3f), length);
    const L::M tooFlat = L::less(steepest, z);
    z = L::blend(z, steepest, tooFlat);
    length = L::blend(length, lengthOf(x, y, z), tooFlat);
    const L::F ux = L::div(x, length), uy = L::div(y, length), uz = L::div(z, length);
    L::storeUnaligned(lanes.directionTexels[0], ux);
    L::storeUnaligned(lanes.directionTexels[1], uy);
    L::storeUnaligned(lanes.directionTexels[2], uz);
    L::storeUnaligned(lanes.texelsPerWorldAlongRay, length);
    // The start: the uv wrapped into the tile in double precision, on the top face.
    const L::F sx =
        wrappedTexels8(lanes.b1, lanes.b2, shell.uvCorners, 0, shell.uvScale[0], shell.tileWidth);
    const L::F sy =
        wrappedTexels8(lanes.b1, lanes.b2, shell.uvCorners, 1, shell.uvScale[1], shell.tileHeight);
    const L::F sz = L::set1(float(shell.tileDepth));
    // TileOccupancy::emptyTravelTexels without the block walk: down to the highest top, for a
    // finite start and a finite, descending direction.
    const L::F descent = L::negate(uz);  // -direction.z
    const L::F top = L::set1(shell.highestTopTexels);
    const L::M jumps =
        L::both(L::both(L::both(finite(sx), finite(sy)), L::both(finite(sz), finite(ux))),
                L::both(L::both(finite(uy), L::less(uz, L::set1(0.0f))), L::greater(sz, top)));
    const L::F perDescent = L::div(L::set1(1.0f), descent);
    const L::F skipped = L::onlyWhere(jumps, L::mul(L::sub(sz, top), perDescent));
    L::storeUnaligned(lanes.skippedTexels, skipped);
    const L::F startZ = L::add(sz, L::mul(uz, skipped));
    L::storeUnaligned(lanes.startTexels[0], L::add(sx, L::mul(ux, skipped)));
    L::storeUnaligned(lanes.startTexels[1], L::add(sy, L::mul(uy, skipped)));
    L::storeUnaligned(lanes.startTexels[2], startZ);
    L::leave();
}

#else

void enterFlatShell8(const FlatShellConstants&, EntryLanes&) {}

#endif

}  // namespace distile::detail
