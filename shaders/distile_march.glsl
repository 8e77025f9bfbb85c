// distile reference shader: distance mapping (GPU Gems 2, ch. 8) on a distile tile, GLSL ES 3.00
// (WebGL2; desktop GLSL 3.30+ takes it with its own #version line). Copy this file into a shader
// after the #version and precision lines; docs/shader.md describes the inputs and conventions.
//
// It does what `distile render` does by default for one ray in one tile: the budgeted sphere trace
// (steps of at least the path left to the floor over the samples left, and of the secant step
// where the distance falls, regula falsi once a step lands inside), epsilon 0.02 texel, a budget
// of 32 samples, trilinear distances for the march and the gradient of the tricubic B-spline for
// the shading normal.
//
// Texel space: x in [0, W), y in [0, H) across the tile (periodic), z in [0, D] from the floor
// (z = 0) to the base surface (z = D); texel (i, j, k) has its centre at (i + 0.5, j + 0.5, k + 0.5).
// Distances are signed, in texels, negative inside the detail.

// The tile as a W x H x D 3D texture, texel (x, y, z) at texelFetch(distileTile, ivec3(x, y, z), 0).
// Only texelFetch reads it: the filters below do their own addressing (periodic in x and y,
// extended linearly in z), so its sampler state does not matter. Its red channel holds
// distileDecode.x * value + distileDecode.y texels: (1, 0) for a half-float (R16F) or float
// (R32F) texture of distances; for the 16-bit PNG atlas read as unsigned normalised values in
// [0, 1]: (D, 0) for the clamped export, (2 R, -R) for the signed one of range R.
uniform highp sampler3D distileTile;
uniform vec2 distileDecode;

// The march's settings, as the command line's defaults.
const int kDistileBudget = 32;           // distance samples per ray at most
const float kDistileEpsilonTexels = 0.02; // closer than this to the surface is a hit
const float kDistileSecantReachTexels = 1.0; // a secant step's reach beyond the distance sampled
const float kDistileNever = 1e30;         // leaveTexels of a ray that meets no open border

float distileTexel(ivec3 texel) {
    return texelFetch(distileTile, texel, 0).r * distileDecode.x + distileDecode.y;
}

// Periodic axis of `extent` texels: the texels below and above `position` and the weight of the
// upper one.
void distilePeriodicAxis(float position, int extent, out int lower, out int upper,
                         out float weight) {
    float shifted = position - 0.5;
    float below = floor(shifted);
    weight = shifted - below;
    float periods = floor(below / float(extent));
    lower = int(below - float(extent) * periods);
    lower = clamp(lower, 0, extent - 1);  // rounding of huge coordinates
    upper = lower + 1 == extent ? 0 : lower + 1;
}

// The z axis: the edge cells extend linearly over the outer half texels up to the faces z = 0
// and z = D (weights from -0.5 to 1.5); positions beyond the faces take the value at the face.
void distileExtendedAxis(float position, int slices, out int lower, out float weight) {
    float shifted = clamp(position - 0.5, -0.5, float(slices) - 0.5);
    lower = clamp(int(floor(shifted)), 0, slices - 2);
    weight = shifted - float(lower);
}

// Trilinear distance (texels) at a texel-space point: the march's filter.
float distileDistance(vec3 position) {
    ivec3 size = textureSize(distileTile, 0);
    int x0, x1, y0, y1, z0;
    float wx, wy, wz;
    distilePeriodicAxis(position.x, size.x, x0, x1, wx);
    distilePeriodicAxis(position.y, size.y, y0, y1, wy);
    distileExtendedAxis(position.z, size.z, z0, wz);
    int z1 = z0 + 1;
    float c00 = mix(distileTexel(ivec3(x0, y0, z0)), distileTexel(ivec3(x1, y0, z0)), wx);
    float c10 = mix(distileTexel(ivec3(x0, y1, z0)), distileTexel(ivec3(x1, y1, z0)), wx);
    float c01 = mix(distileTexel(ivec3(x0, y0, z1)), distileTexel(ivec3(x1, y0, z1)), wx);
    float c11 = mix(distileTexel(ivec3(x0, y1, z1)), distileTexel(ivec3(x1, y1, z1)), wx);
    return mix(mix(c00, c10, wy), mix(c01, c11, wy), wz);
}

// Cubic B-spline weights of the four taps at fraction a, and of its derivative.
vec4 distileBSplineWeights(float a) {
    float b = 1.0 - a;
    return vec4(b * b * b, ((3.0 * a - 6.0) * a * a + 4.0), (((-3.0 * a + 3.0) * a + 3.0) * a + 1.0),
                a * a * a) / 6.0;
}
vec4 distileBSplineDerivativeWeights(float a) {
    float b = 1.0 - a;
    return vec4(-0.5 * b * b, 0.5 * a * (3.0 * a - 4.0), 0.5 * b * (3.0 * a + 1.0), 0.5 * a * a);
}

// Slice `slice` of column (x, y), for slices -2 .. D + 1: beyond the stored ones, a ghost texel on
// the line through the edge cell's two slices (slice -1 = 2 v0 - v1, slice D = 2 v[D-1] - v[D-2]).
float distileColumnTexel(int x, int y, int slice, int slices) {
    int cell = clamp(slice, 0, slices - 2);
    float beyond = float(slice - cell);
    float lower = distileTexel(ivec3(x, y, cell));
    if (beyond == 0.0) return lower;
    return lower + (distileTexel(ivec3(x, y, cell + 1)) - lower) * beyond;
}

// Gradient (texels per texel) of the tricubic B-spline at a texel-space point: the shading
// normal's direction in texel space (the 64-tap sum; the spline is smooth where trilinear is not).
vec3 distileGradient(vec3 position) {
    ivec3 size = textureSize(distileTile, 0);
    int x0, x1, y0, y1;
    float ax, ay;
    distilePeriodicAxis(position.x, size.x, x0, x1, ax);
    distilePeriodicAxis(position.y, size.y, y0, y1, ay);
    int xs[4] = int[4](x0 == 0 ? size.x - 1 : x0 - 1, x0, x1, x1 + 1 == size.x ? 0 : x1 + 1);
    int ys[4] = int[4](y0 == 0 ? size.y - 1 : y0 - 1, y0, y1, y1 + 1 == size.y ? 0 : y1 + 1);
    float shiftedZ = clamp(position.z - 0.5, -0.5, float(size.z) - 0.5);
    float belowZ = floor(shiftedZ);
    float az = shiftedZ - belowZ;
    int firstSlice = int(belowZ) - 1;
    vec4 wx = distileBSplineWeights(ax), dx = distileBSplineDerivativeWeights(ax);
    vec4 wy = distileBSplineWeights(ay), dy = distileBSplineDerivativeWeights(ay);
    vec4 wz = distileBSplineWeights(az), dz = distileBSplineDerivativeWeights(az);
    vec3 gradient = vec3(0.0);
    for (int k = 0; k < 4; ++k) {
        for (int j = 0; j < 4; ++j) {
            vec4 row = vec4(distileColumnTexel(xs[0], ys[j], firstSlice + k, size.z),
                            distileColumnTexel(xs[1], ys[j], firstSlice + k, size.z),
                            distileColumnTexel(xs[2], ys[j], firstSlice + k, size.z),
                            distileColumnTexel(xs[3], ys[j], firstSlice + k, size.z));
            float alongX = dot(row, wx);
            gradient += vec3(dot(row, dx) * wy[j] * wz[k], alongX * dy[j] * wz[k],
                             alongX * wy[j] * dz[k]);
        }
    }
    return gradient;
}

struct DistileMarch {
    vec3 position;      // where the march ended, texel space
    float travelTexels; // from the start along the direction
    int iterations;     // distance samples taken
    bool converged;     // within epsilon of the detail, or on the solid floor
    bool onFloor;       // stopped by the solid floor z = 0
    bool exitedFloor;   // open floor: left the shell through the bottom
};

// Ends a march on the floor z = 0, `toFloor` texels on from `travel`.
void distileEndOnFloor(inout DistileMarch result, vec3 start, vec3 direction, float travel,
                       float toFloor, bool solidFloor) {
    result.travelTexels = travel + toFloor;
    result.position = start + direction * result.travelTexels;
    result.position.z = 0.0;
    result.converged = solidFloor;
    result.onFloor = solidFloor;
    result.exitedFloor = !solidFloor;
}

// The budgeted sphere trace from `start` (texel space, z <= D) along `direction` (unit in texel
// space, direction.z < 0) with `budget` distance samples (>= 1), ending without a hit (as at an
// open floor) where the ray leaves the shell through an open border of the base mesh,
// `leaveTexels` along it, if that comes before the floor.
DistileMarch distileMarchUntil(vec3 start, vec3 direction, int budget, bool solidFloor,
                               float leaveTexels) {
    DistileMarch result = DistileMarch(start, 0.0, 0, false, false, false);
    float toFloorAtStart = start.z / -direction.z;
    if (leaveTexels < toFloorAtStart) {
        toFloorAtStart = max(leaveTexels, 0.0);
        solidFloor = false;
    }
    float travel = 0.0, safeRadius = 0.0, previousStep = 0.0;
    bool refining = false;
    float outside = 0.0, outsideDistance = 0.0, inside = 0.0, insideDistance = 0.0, estimate = 0.0;
    for (int iteration = 1; iteration <= budget; ++iteration) {
        result.iterations = iteration;
        if (refining) {
            // Regula falsi between the last point outside and the first inside.
            float distance = distileDistance(start + direction * estimate);
            if (abs(distance) < kDistileEpsilonTexels) break;
            if (distance > 0.0) {
                outside = estimate;
                outsideDistance = distance;
            } else {
                inside = estimate;
                insideDistance = distance;
            }
            estimate = outside + (inside - outside) * outsideDistance /
                                     (outsideDistance - insideDistance);
            continue;
        }
        vec3 position = start + direction * travel;
        float distance = distileDistance(position);
        if (distance < kDistileEpsilonTexels) {
            if (distance < 0.0 && previousStep > safeRadius) {
                // A budgeted step went past the surface: find the crossing in between.
                refining = true;
                outside = travel - previousStep;
                outsideDistance = safeRadius;
                inside = travel;
                insideDistance = distance;
                estimate = outside + (inside - outside) * outsideDistance /
                                         (outsideDistance - insideDistance);
                continue;
            }
            result.converged = true;
            result.position = position;
            result.travelTexels = travel;
            return result;
        }
        float toFloor = toFloorAtStart - travel;
        if (distance >= toFloor) {
            distileEndOnFloor(result, start, direction, travel, toFloor, solidFloor);
            return result;
        }
        float step = distance;
        if (previousStep > 0.0 && distance < safeRadius) {
            // The secant step: toward where the line through the last two samples' distances
            // reaches zero, at most kDistileSecantReachTexels beyond the distance sampled.
            float toZero = distance * previousStep / (safeRadius - distance);
            step = max(step, min(toZero, distance + kDistileSecantReachTexels));
        }
        if (iteration < budget) step = max(step, toFloor / float(budget - iteration));
        safeRadius = distance;
        previousStep = min(step, toFloor);
        travel += previousStep;
    }
    if (refining) {
        result.converged = true;
        result.travelTexels = estimate;
    } else {
        // Out of budget: back to the last point known to be outside.
        if (previousStep > safeRadius) travel -= previousStep - safeRadius;
        result.travelTexels = travel;
    }
    result.position = start + direction * result.travelTexels;
    return result;
}

// The whole ray in a tile: from its entry `entryTexels` on the top face (z = D) along
// `directionTexels` (unit, z < 0), skipping the empty path down to `highestTopTexels` (the
// highest top of the detail: no point above it is within epsilon; D when unknown), then the march
// with the whole budget, ending where the ray leaves the shell through an open border of the base
// mesh `leaveTexels` from the entry (as distileMarchUntil). travelTexels of the result counts
// from the entry.
DistileMarch distileTraceUntil(vec3 entryTexels, vec3 directionTexels, float highestTopTexels,
                               bool solidFloor, float leaveTexels) {
    float skipped = entryTexels.z > highestTopTexels
                        ? (entryTexels.z - highestTopTexels) / -directionTexels.z
                        : 0.0;
    vec3 start = entryTexels + directionTexels * skipped;
    DistileMarch result = distileMarchUntil(start, directionTexels, kDistileBudget, solidFloor,
                                            leaveTexels - skipped);
    result.travelTexels += skipped;
    return result;
}

// The same for a shell without open borders (a closed mesh), or whose rays never reach one.
DistileMarch distileMarch(vec3 start, vec3 direction, int budget, bool solidFloor) {
    return distileMarchUntil(start, direction, budget, solidFloor, kDistileNever);
}
DistileMarch distileTrace(vec3 entryTexels, vec3 directionTexels, float highestTopTexels,
                          bool solidFloor) {
    return distileTraceUntil(entryTexels, directionTexels, highestTopTexels, solidFloor,
                             kDistileNever);
}
