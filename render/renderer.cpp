#include "render/renderer.h"

#include <tbb/blocked_range2d.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <glm/geometric.hpp>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/image_blocks.h"
#include "common/thread_scratch.h"
#include "render/analytic_filter.h"
#include "render/coverage.h"
#include "render/shading.h"

namespace distile {

namespace {

constexpr float kPi = 3.14159265358979f;

/// A self-shadow ray takes a sample per this many texels of its path to the tile's top, so that
/// toward a low light (from the floor of a 16-texel tile toward a light 15 degrees above it, 62
/// texels through the rings) it steps no farther than about this (its steps are at least the path
/// left over the samples left): half the thickness of a default chain-mail wire. Not below the
/// options' budget, and not above kSelfShadowBudgetFactor times it, which paths longer than 192
/// texels take (from the floor of a 16-texel tile, a light less than 5 degrees above it in texel
/// space). Against the world reference, on the chain-mail sheet under a 2-degree light 15 degrees
/// high (320 x 256, mean signed sRGB codes over the image), 1 texel per sample was +0.41 codes
/// off, 2 texels +0.53, 4 +0.61 (the budget alone: those paths are at most 62 texels long), and
/// 256 samples for every ray +0.27; 24 samples and no floor on the steps (the rule before) +4.64.
constexpr float kSelfShadowPathTexelsPerSample = 2.0f;
constexpr int kSelfShadowBudgetFactor = 4;

/// Visibility in [0, 1] of a light of angular radius atan(tanHalfAngle) from a texel-space
/// point, by sphere tracing toward it until the ray leaves the top of the tile (in a curved
/// shell: along the world ray toward the light, through the shell map). The least of distance /
/// (travel x tanHalfAngle) along the ray, r, estimates how far the nearest blocker's edge lies
/// from the ray in radii of the light's disk: r >= 1 leaves the disk free, r = 0 (the ray grazes
/// the blocker) half covers it. So the ray goes on through the detail (steps of the distance's
/// magnitude, at least detail::kVisibilityMinStepTexels and the path left to the top over the
/// samples left, with a budget that grows with that path) until r reaches -1, where the blocker
/// covers the disk; the visible share is the smoothstep of (r + 1) / 2. Stopping at the first
/// contact (r = 0 as no light) darkened wide lights: the chain-mail sheet's mean sRGB value was 6%
/// low at 20 degrees and 19% at 89 against the world reference's shadow rays, and is now 0.3% low
/// and 2.3% high. Taken a sample at a time (samplePosition, advance), so the self-shadow rays of a
/// batch of camera rays are marched together (marchInterleaved) with the operations of a single
/// one.
class LightVisibilityRay {
  public:
    /// Starts at `start` toward `toLight` (unit, texel space) with a budget of `maxSamples`
    /// samples, more for a long path to the top (budgetForPath).
    void start(const glm::vec3& start, const glm::vec3& toLight, float depthTexels,
               float tanHalfAngle, int maxSamples) {
        begin(depthTexels, tanHalfAngle, maxSamples);
        for (int axis = 0; axis < 3; ++axis) {
            lane_.start[axis] = start[axis];
            lane_.direction[axis] = toLight[axis];
        }
        lane_.blocked = toLight.z <= 0.0f;  // the light is below the base surface
        curved_ = false;
        budgetForPath((depthTexels - start.z) / toLight.z, maxSamples);
        lane_.needsSample = !lane_.blocked && nextSampleInside();
    }
    /// start() for a hit in a curved shell: from world point `startWorld` (prism `prism`, near
    /// its point `guess`) toward the light along the world ray, its samples where that ray is in
    /// texel space (ShellRayPath); it ends where the ray leaves the shell.
    void startCurved(const ShellPrisms& shell, std::uint32_t prism, const PrismPoint& guess,
                     const glm::dvec3& startWorld, const glm::dvec3& toLightWorld,
                     float depthTexels, float tanHalfAngle, int maxSamples) {
        begin(depthTexels, tanHalfAngle, maxSamples);
        curved_ = true;
        lane_.blocked = false;
        lane_.needsSample = false;
        if (!path_.start(shell, startWorld, toLightWorld, prism, guess)) return;  // above it
        lane_.blocked = !(path_.directionTexels().z > 0.0);  // the light is below the base surface
        budgetForPath((depthTexels - path_.texelPosition().z) / float(path_.directionTexels().z),
                      maxSamples);
        lane_.needsSample = !lane_.blocked && lane_.samplesLeft > 0 && path_.advance(lane_.travel);
    }
    bool needsSample() const { return lane_.needsSample; }
    glm::vec3 samplePosition() const {
        return curved_ ? path_.texelPosition()
                       : straightStart() + straightDirection() * lane_.travel;
    }
    /// Takes the distance sampled at samplePosition(); false when no more samples are needed.
    /// (The wide kernel, detail::visibilitySteps, takes the same steps lane by lane.)
    bool advance(float distance) {
        ++lane_.samples;
        lane_.visibility =
            std::min(lane_.visibility, distance / (lane_.travel * lane_.tanHalfAngle));
        if (!(lane_.visibility > -1.0f)) {
            lane_.blocked = true;
            return lane_.needsSample = false;
        }
        float step = std::max(std::abs(distance), detail::kVisibilityMinStepTexels);
        --lane_.samplesLeft;
        // At least the path left to the top over the samples left (march_wide.h). On a curved
        // shell the path bends: its direction here gives the path to the top as if it went
        // straight on.
        const float climb = curved_ ? float(path_.directionTexels().z) : lane_.direction[2];
        if (lane_.samplesLeft > 0 && climb > 0.0f) {
            const float forced =
                (lane_.depthTexels - samplePosition().z) / climb / float(lane_.samplesLeft);
            if (step < forced) step = forced;
        }
        lane_.travel += step;
        if (curved_) return lane_.needsSample = lane_.samplesLeft > 0 && path_.advance(step);
        return lane_.needsSample = nextSampleInside();
    }
    /// Smoothstepped visibility, once needsSample() is false.
    float visibility() const {
        if (lane_.blocked) return 0.0f;
        const float share = 0.5f * (std::clamp(lane_.visibility, -1.0f, 1.0f) + 1.0f);
        return share * share * (3.0f - 2.0f * share);
    }
    std::uint64_t samples() const { return std::uint64_t(lane_.samples); }
    /// The ray's state for the wide kernel (marchInterleaved), or null for a curved ray, whose
    /// samples follow the shell map.
    detail::VisibilityLane* visibilityLane() { return curved_ ? nullptr : &lane_; }

  private:
    /// The samples of a ray whose path to the tile's top is `pathTexels` long: one per
    /// kSelfShadowPathTexelsPerSample of it, at least `maxSamples` (the options' budget) and at
    /// most kSelfShadowBudgetFactor times that. (A light below the base surface, no path: the
    /// budget, unused.)
    void budgetForPath(float pathTexels, int maxSamples) {
        const float wanted = pathTexels / kSelfShadowPathTexelsPerSample;
        lane_.samplesLeft =
            wanted > float(maxSamples)
                ? int(std::min(std::ceil(wanted), float(kSelfShadowBudgetFactor * maxSamples)))
                : maxSamples;
    }
    /// What start() and startCurved() set alike.
    void begin(float depthTexels, float tanHalfAngle, int maxSamples) {
        lane_.depthTexels = depthTexels;
        lane_.tanHalfAngle = tanHalfAngle;
        lane_.samplesLeft = maxSamples;
        lane_.visibility = 1.0f;
        lane_.travel = 0.1f;
        lane_.samples = 0;
    }
    glm::vec3 straightStart() const { return {lane_.start[0], lane_.start[1], lane_.start[2]}; }
    glm::vec3 straightDirection() const {
        return {lane_.direction[0], lane_.direction[1], lane_.direction[2]};
    }
    /// The next sample is within the budget and below the top of the tile (NaN: sampled, as a
    /// plain loop would).
    bool nextSampleInside() const {
        return lane_.samplesLeft > 0 && !(samplePosition().z >= lane_.depthTexels);
    }

    detail::VisibilityLane lane_{};  ///< the state; start and direction for straight rays only
    bool curved_ = false;            ///< startCurved: the samples follow path_
    ShellRayPath path_;
};

/// Position of sample `index` of `count` inside the pixel: the centre for one sample, else the
/// R2 low-discrepancy sequence (Roberts 2018), the same for every pixel.
glm::vec2 sampleOffset(int index, int count) {
    if (count == 1) return glm::vec2(0.5f);
    constexpr double kG = 1.32471795724474602596;  // plastic number
    const double x = 0.5 + (index + 1) / kG;
    const double y = 0.5 + (index + 1) / (kG * kG);
    return {float(x - std::floor(x)), float(y - std::floor(y))};
}

/// What one camera ray produced.
struct Sample {
    glm::vec3 color{0.0f};
    float depth = 0.0f;
    glm::vec3 normal{0.0f};
    int iterations = 0;
    std::uint64_t shadowSteps = 0;
    std::uint64_t shadowMapSamples = 0;
    float texelsPerWorldAlongRay = 0.0f;  ///< the hit's SurfaceHit::texelsPerWorldAlongRay
    float meanCurvature = 0.0f;           ///< 1/texel, when hasCurvature (AOVs only)
    bool hasCurvature = false;  ///< the ray hit detail (not the floor, not a bare base surface)
};

/// The seed of the shadow-map sample pattern of sample `index` of pixel (x, y): fixed per pixel,
/// so renders are repeatable, and different between neighbours, so the error is noise, not bands.
std::uint32_t shadowSeed(int x, int y, int index) {
    return std::uint32_t(x) * 0x9e3779b1U ^ std::uint32_t(y) * 0x85ebca77U ^
           std::uint32_t(index) * 0xc2b2ae3dU;
}

class Renderer {
  public:
    /// Camera rays traced together: a run of kRunRows rows of a screen tile, so that enough
    /// marches are in flight to hide the latency of their samples.
    static constexpr std::size_t kRunRays = 64;
    static constexpr int kRunRows = 4;
    /// Scenes with at most this many lights march their self-shadow rays together.
    static constexpr std::size_t kInterleavedLights = 4;

    /// Preconditions: `tracer` traces `scene` with `options` (PreparedScene).
    Renderer(const Scene& scene, const RenderOptions& options, const SceneTracer& tracer)
        : scene_(scene),
          options_(options),
          tracer_(tracer),
          projection_(scene.camera, options.width, options.height),
          shells_(tracer_, projection_) {
        for (int index = 0; index < options.samplesPerPixel; ++index)
            sampleOffsets_.push_back(sampleOffset(index, options.samplesPerPixel));
        for (const DirectionalLight& light : scene.lights) {
            toLights_.push_back(-unitDirection(light.direction));
            tanHalfAngles_.push_back(
                std::max(std::tan(0.5f * light.angleDeg * kPi / 180.0f), 1e-3f));
        }
        facingHits_ = std::make_unique<std::atomic<std::uint64_t>[]>(2 * scene.objects.size());
        shadowMaps_.resize(scene.lights.size());
        if (options.shadowFilter == ShadowFilter::None) return;
        if (options.skips.casterlessShadowMaps && !sceneCastsShadowsBetweenSurfaces(scene)) return;
        for (std::size_t light = 0; light < scene.lights.size(); ++light) {
            if (!lightReachesVisibleSurface(scene, scene.lights[light]))
                continue;  // no receiver would ask
            const int resolution =
                options.shadowMapResolution > 0
                    ? options.shadowMapResolution
                    : std::clamp(3 * std::max(options.width, options.height) / 2, 256, 4096);
            shadowMaps_[light] = std::make_unique<LightShadowMaps>(tracer_, scene.lights[light],
                                                                   resolution, &projection_);
        }
    }

    /// The tracer's warnings (folds), and one per object whose camera hits are mostly back
    /// faces: the sign of a mesh wound clockwise, whose detail would silently not show.
    std::vector<std::string> warnings() const {
        std::vector<std::string> all = tracer_.warnings();
        for (std::size_t object = 0; object < scene_.objects.size(); ++object) {
            const std::uint64_t back = facingHits_[2 * object + 1].load();
            const std::uint64_t hits = facingHits_[2 * object].load() + back;
            if (hits == 0 || 2 * back <= hits) continue;
            all.push_back("objects[" + std::to_string(object) + "]: " +
                          std::to_string(int(std::lround(100.0 * double(back) / double(hits)))) +
                          "% of the camera rays that reach it meet back faces, which show no "
                          "detail: the camera is inside the object or its detail shell (detail "
                          "is seen from outside only), or, if the mesh is closed, its faces are "
                          "wound clockwise (distile expects them counter-clockwise seen from "
                          "outside)");
        }
        return all;
    }

    /// Pixels x0 ... x1 - 1 of rows y0 ... y1 - 1 into `pixels` (row by row): each the mean
    /// colour of its samples, with the first sample's AOV values. The camera rays are traced in
    /// batches, their marches interleaved (ScreenShells::traceNearestBatch); each sample is what
    /// it would be alone.
    ///
    /// The camera hits on front and back faces are added to `facingHits` (per object: front,
    /// back), which addFacingHits takes once per block: per run, the threads' atomic adds on one
    /// cache line cost more than the counting.
    void renderRun(int y0, int y1, int x0, int x1, Sample* pixels, RenderStats& stats,
                   std::span<std::uint64_t> facingHits) const {
        constexpr std::size_t kBatch = kRunRays;
        static_assert(kBatch <= ScreenShells::kMaxBatchRays);
        // Self-shadow rays are marched together for scenes of a few lights (tile filters only).
        const bool batchSelfShadows = options_.selfShadows && !options_.reference &&
                                      scene_.lights.size() <= kInterleavedLights;
        // Working memory, once per thread: constructing these arrays for every run cost a few
        // percent of a render. Every element is set before it is read.
        struct Arrays {
            std::array<LightVisibilityRay, kInterleavedLights> selfShadows[kBatch];
            ScreenShells::PixelRay rays[kBatch];
            int sampleIndices[kBatch];
            SurfaceHit hits[kBatch];
            bool found[kBatch];
            TraceCounters counters[kBatch];
        };
        Arrays& arrays = threadScratch<Arrays>();
        auto& [selfShadows, rays, sampleIndices, hits, found, counters] = arrays;
        const int samplesPerPixel = options_.samplesPerPixel;
        const int runWidth = x1 - x0;
        const int total = runWidth * (y1 - y0) * samplesPerPixel;
        glm::vec3 sum(0.0f);
        for (int first = 0; first < total; first += int(kBatch)) {
            const std::size_t count = std::size_t(std::min(int(kBatch), total - first));
            // The camera rays' pixel positions, then their directions all at once.
            float xPixels[kBatch], yPixels[kBatch], directions[3][kBatch];
            // Sample `nextIndex` of pixel (nextX, nextY) first, then counted on: the samples of
            // a pixel, pixel by pixel along the run's rows.
            int nextIndex = first % samplesPerPixel;
            int nextX = x0 + (first / samplesPerPixel) % runWidth;
            int nextY = y0 + (first / samplesPerPixel) / runWidth;
            for (std::size_t k = 0; k < count; ++k) {
                const glm::vec2 offset = sampleOffsets_[std::size_t(nextIndex)];
                xPixels[k] = float(nextX) + offset.x;
                yPixels[k] = float(nextY) + offset.y;
                rays[k].x = nextX;
                rays[k].y = nextY;
                sampleIndices[k] = nextIndex;
                counters[k] = {};
                if (++nextIndex < samplesPerPixel) continue;
                nextIndex = 0;
                if (++nextX == x1) {
                    nextX = x0;
                    ++nextY;
                }
            }
            projection_.directions(xPixels, yPixels, count, directions[0], directions[1],
                                   directions[2]);
            for (std::size_t k = 0; k < count; ++k) {
                rays[k].ray = {projection_.eye(),
                               {directions[0][k], directions[1][k], directions[2][k]}};
            }
            ShellCounters shellCounters;
            shells_.traceNearestBatch(std::span(rays, count), options_.skips.shellCulling,
                                      std::span(hits, count), std::span(found, count),
                                      std::span(counters, count), shellCounters);
            stats.shellsTested += shellCounters.tested;
            stats.shellsTraced += shellCounters.traced;
            if (batchSelfShadows) marchSelfShadows(count, hits, found, selfShadows);
            countFacingHits(std::span(rays, count), std::span(hits, count), std::span(found, count),
                            facingHits);
            for (std::size_t k = 0; k < count; ++k) {
                const int x = rays[k].x;
                const int y = rays[k].y;
                const int index = sampleIndices[k];
                // The first sample straight into the pixel (its AOV values), the others aside.
                Sample& pixel = pixels[(y - y0) * runWidth + (x - x0)];
                Sample other;
                Sample& sample = index == 0 ? pixel : other;
                shadeSample(rays[k].ray, found[k], hits[k], counters[k], shadowSeed(x, y, index),
                            batchSelfShadows ? selfShadows[k].data() : nullptr, stats, sample);
                if (samplesPerPixel == 1) continue;
                sum = index == 0 ? sample.color : sum + sample.color;
                if (index == samplesPerPixel - 1) pixel.color = sum / float(samplesPerPixel);
            }
        }
    }

    /// Slots of renderRun's `facingHits`: two per object.
    std::size_t facingSlots() const { return 2 * scene_.objects.size(); }
    /// Adds a block's camera hits per object and facing (renderRun) to the render's.
    void addFacingHits(std::span<const std::uint64_t> facingHits) const {
        for (std::size_t slot = 0; slot < facingHits.size(); ++slot) {
            if (facingHits[slot] != 0) facingHits_[slot].fetch_add(facingHits[slot]);
        }
    }

    /// Texels of the shadow maps: traced so far, or `all` of them.
    std::uint64_t shadowMapTexels(bool all) const {
        std::uint64_t texels = 0;
        for (const std::unique_ptr<LightShadowMaps>& map : shadowMaps_) {
            if (!map) continue;
            texels += all ? map->texelCount() : map->tracedTexels();
        }
        return texels;
    }

  private:
    /// Counts the hits of `rays` (where `found`) into `facingHits` (per object: front, back). A
    /// back face the ray meets after the front of the same object (through an opening of its
    /// detail) counts as neither: only back faces met first say a mesh is wound inside out.
    /// In registers while consecutive hits share an object: one memory increment per hit would
    /// make a chain of store-to-load waits on one counter.
    void countFacingHits(std::span<const ScreenShells::PixelRay> rays,
                         std::span<const SurfaceHit> hits, std::span<const bool> found,
                         std::span<std::uint64_t> facingHits) const {
        std::size_t object = 0;
        std::uint64_t front = 0, back = 0;
        const auto add = [&] {
            if (front + back == 0) return;  // nothing counted (perhaps no object at all)
            facingHits[2 * object] += front;
            facingHits[2 * object + 1] += back;
        };
        for (std::size_t k = 0; k < hits.size(); ++k) {
            if (!found[k]) continue;
            if (hits[k].object != object) {
                add();
                object = hits[k].object;
                front = back = 0;
            }
            if (hits[k].entry.frontFacing) {
                ++front;
            } else if (!tracer_.entersFrontFirst(rays[k].ray, 0.0f, hits[k].object,
                                                 hits[k].distanceWorld)) {
                ++back;
            }
        }
        add();
    }

    /// One camera ray through the square of pixel (x, y), traced: its colour and AOV values into
    /// `sample`.
    void shadeSample(const Ray& ray, bool found, const SurfaceHit& hit,
                     const TraceCounters& counters, std::uint32_t seed,
                     const LightVisibilityRay* selfShadows, RenderStats& stats,
                     Sample& sample) const {
        ++stats.rays;
        sample = Sample{};
        stats.marchIterations += counters.marchIterations;
        // Per camera ray, from the march of its nearest hit.
        if (found && hit.onDetail) {
            ++stats.detailHits;
            if (hit.march.converged) ++stats.converged;
        }
        if (!found) {
            sample.color = skyColor(ray.direction);
            return;
        }
        ++stats.baseHits;
        sample.depth = hit.distanceWorld;
        sample.normal = hit.normal;
        sample.texelsPerWorldAlongRay = hit.texelsPerWorldAlongRay;
        sample.iterations = int(counters.marchIterations);
        const Material& material = scene_.objects[hit.object].material;
        if (!hit.entry.frontFacing) {
            sample.color = backFaceColor(material.color);
        } else if (!hit.onDetail) {
            sample.color = shadeBase(hit, material, ray.direction, seed, sample.shadowMapSamples);
        } else {
            sample.color = shadeDetail(hit, material, ray.direction, seed, selfShadows, sample);
        }
        stats.shadowSteps += sample.shadowSteps;
        stats.shadowMapSamples += sample.shadowMapSamples;
        if (options_.outputAovs && hit.entry.frontFacing && hit.onDetail && !hit.march.onFloor) {
            const BasicTricubicBSplineFilter<ColumnTexels> curvatureFilter(
                *tracer_.columns(hit.object));
            const glm::vec3 at = hit.march.texelPosition;
            sample.meanCurvature =
                curvatureFromDerivatives(curvatureFilter.gradient(at), curvatureFilter.hessian(at))
                    .mean;
            sample.hasCurvature = true;
        }
    }

    /// Fraction of light `lightIndex` reaching `receiver` past other surfaces. Precondition: the
    /// light has a shadow map (without one nothing is asked: the callers skip the receiver too).
    float castShadow(std::size_t lightIndex, const ShadowReceiver& receiver, std::uint32_t seed,
                     std::uint64_t& samples) const {
        return shadowMaps_[lightIndex]->visibility(
            receiver, options_.shadowFilter, seed ^ (0x27d4eb2fU * std::uint32_t(lightIndex + 1)),
            samples);
    }

    /// The smallest width of the hit's pixel on the light's plane, world units: the pixel spans
    /// at least distance x pixel angle on the surface in every direction, and the light's view
    /// shortens that by at most the cosine between the base normal and the light.
    float footprintWorld(const SurfaceHit& hit, const glm::vec3& toLight) const {
        return hit.distanceWorld * projection_.pixelAngleRadians() *
               std::max(glm::dot(hit.entry.normal, toLight), 0.0f);
    }

    glm::vec3 shadeBase(const SurfaceHit& hit, const Material& material, const glm::vec3& view,
                        std::uint32_t seed, std::uint64_t& shadowMapSamples) const {
        const glm::vec3 albedo = albedoAt(material, hit.entry.uv);
        glm::vec3 color = albedo * kAmbientStrength;
        for (std::size_t index = 0; index < scene_.lights.size(); ++index) {
            const DirectionalLight& light = scene_.lights[index];
            const glm::vec3& toLight = toLights_[index];
            const float facing = glm::dot(hit.entry.normal, toLight);
            if (facing <= 0.0f) continue;
            float visibility = lightDiskShareAboveHorizon(facing, tanHalfAngles_[index]);
            if (shadowMaps_[index]) {
                const ShadowReceiver receiver{hit.position, hit.entry.normal,
                                              footprintWorld(hit, toLight), hit.object};
                visibility *= castShadow(index, receiver, seed, shadowMapSamples);
                if (visibility <= 0.0f) continue;
            }
            color += directLight(hit.normal, toLight, view, albedo) * light.color * visibility;
        }
        return color;
    }

    /// Whether light `index` gets shading work at the detail hit `hit` (its direct light and
    /// shadows): its base faces the light, and the detail does too unless unlit shadows are not
    /// skipped (then detail facing away is shadowed only to measure the skip).
    bool shadesLight(const SurfaceHit& hit, std::size_t index) const {
        const glm::vec3& toLight = toLights_[index];
        if (glm::dot(hit.entry.normal, toLight) <= 0.0f) return false;
        return !(options_.skips.unlitShadows && glm::dot(hit.normal, toLight) <= 0.0f);
    }

    /// Starts the self-shadow ray toward light `index` from the detail hit `hit`: from just above
    /// the surface (along the filter's gradient) toward the light, in texel space.
    template <class Filter>
    void startSelfShadow(const Filter& filter, const SurfaceHit& hit, float depthTexels,
                         std::size_t index, LightVisibilityRay& ray) const {
        const glm::vec3 texelPosition = hit.march.texelPosition;
        glm::vec3 texelNormal(0.0f, 0.0f, 1.0f);
        if (!hit.march.onFloor) {
            const glm::vec3 gradient = filter.gradient(texelPosition);
            if (glm::length(gradient) > 1e-6f) texelNormal = glm::normalize(gradient);
        }
        const glm::vec3 start = texelPosition + texelNormal * (2.0f * options_.march.epsilonTexels);
        if (hit.entry.curved) {  // along the world ray toward the light, through the shell map
            const ShellPrisms& shell = tracer_.shellPrisms();
            const ShellPrism& prism = shell.prisms[hit.shellPrism];
            const PrismPoint startPoint = prism.pointAtTexel(glm::dvec3(start));
            ray.startCurved(shell, hit.shellPrism, startPoint, prism.worldAt(startPoint),
                            glm::dvec3(toLights_[index]), depthTexels, tanHalfAngles_[index],
                            options_.shadowIterations);
            return;
        }
        const glm::vec3 toLightTexel = glm::normalize(hit.entry.toTexel(toLights_[index]));
        // Beyond an open border of the base mesh the tile's repeats are not there.
        const float topTexels =
            tracer_.selfShadowTopTexels(hit, toLights_[index], start, toLightTexel, depthTexels);
        ray.start(start, toLightTexel, topTexels, tanHalfAngles_[index], options_.shadowIterations);
    }

    /// The self-shadow rays of a batch's detail hits (`rays[k][light]` for hits[k]), marched
    /// together a tile at a time (marchInterleaved): the same visibilities as one at a time.
    void marchSelfShadows(std::size_t count, const SurfaceHit* hits, const bool* found,
                          std::array<LightVisibilityRay, kInterleavedLights>* rays) const {
        LightVisibilityRay* pending[kRunRays * kInterleavedLights];
        const TileColumns* tiles[kRunRays * kInterleavedLights];
        std::size_t pendingCount = 0;
        for (std::size_t k = 0; k < count; ++k) {
            const SurfaceHit& hit = hits[k];
            if (!found[k] || !hit.entry.frontFacing || !hit.onDetail) continue;
            const TileColumns* tile = tracer_.columns(hit.object);
            const float depthTexels = float(tile->size().depth);
            withFilter(options_.filter, *tile, [&](const auto& filter) {
                for (std::size_t index = 0; index < scene_.lights.size(); ++index) {
                    if (!shadesLight(hit, index)) continue;
                    startSelfShadow(filter, hit, depthTexels, index, rays[k][index]);
                    if (!rays[k][index].needsSample()) continue;
                    pending[pendingCount] = &rays[k][index];
                    tiles[pendingCount++] = tile;
                }
            });
        }
        marchInterleavedByTile(options_.filter,
                               std::span<LightVisibilityRay* const>(pending, pendingCount),
                               std::span<const TileColumns* const>(tiles, pendingCount));
    }

    /// The detail hit's colour. `selfShadows`: per light, its self-shadow ray already marched
    /// (marchSelfShadows), or null to march them here.
    glm::vec3 shadeDetail(const SurfaceHit& hit, const Material& material, const glm::vec3& view,
                          std::uint32_t seed, const LightVisibilityRay* selfShadows,
                          Sample& sample) const {
        const float depthTexels = float(material.tile->size().depth);
        const glm::vec3 texelPosition = hit.march.texelPosition;
        // Cavities (low in the shell) see less of the sky.
        const glm::vec3 albedo = albedoAt(material, hit.entry.uv);
        glm::vec3 color = albedo * (kAmbientStrength * openness(texelPosition.z, depthTexels));
        for (std::size_t index = 0; index < scene_.lights.size(); ++index) {
            const DirectionalLight& light = scene_.lights[index];
            const glm::vec3& toLight = toLights_[index];
            // A base surface facing away from the light is in its own shadow, and detail facing
            // away from it gets no direct light: no work.
            if (!shadesLight(hit, index)) continue;
            const float facing = glm::dot(hit.entry.normal, toLight);
            float visibility = 1.0f;
            if (options_.selfShadows) {
                LightVisibilityRay own;
                const LightVisibilityRay* ray = selfShadows ? &selfShadows[index] : &own;
                if (!selfShadows) {
                    withMarchFilter(
                        options_.filter, material, tracer_.columns(hit.object), options_.reference,
                        [&](const auto& filter) {
                            startSelfShadow(filter, hit, depthTexels, index, own);
                            if (!own.needsSample()) return;
                            while (own.advance(filter.distanceTexels(own.samplePosition()))) {
                            }
                        });
                }
                sample.shadowSteps += ray->samples();
                visibility = ray->visibility();
                if (visibility <= 0.0f) continue;
            }
            // Other surfaces, from the shadow map, asked where the light ray leaves this shell
            // (its own detail is the self-shadow's job). The two sets of blockers are disjoint,
            // so their covered parts of the light's disk are uncorrelated: the visible share is
            // the product (min would assume they always overlap and under-darken penumbrae).
            if (shadowMaps_[index]) {
                const float belowSurfaceWorld =
                    (depthTexels - texelPosition.z) / depthTexels * material.depthWorld;
                const ShadowReceiver receiver{hit.position + toLight * (belowSurfaceWorld / facing),
                                              hit.entry.normal, footprintWorld(hit, toLight),
                                              hit.object};
                visibility *= castShadow(index, receiver, seed, sample.shadowMapSamples);
                if (visibility <= 0.0f) continue;
            }
            visibility *= lightDiskShareAboveHorizon(facing, tanHalfAngles_[index]);
            color += directLight(hit.normal, toLight, view, albedo) * light.color * visibility;
        }
        return color;
    }

    const Scene& scene_;
    const RenderOptions& options_;
    const SceneTracer& tracer_;
    std::vector<std::unique_ptr<LightShadowMaps>>
        shadowMaps_;  ///< per light; null: no map needed or wanted
    PinholeProjection projection_;
    std::vector<glm::vec3> toLights_;   ///< per light: unit direction toward it
    std::vector<float> tanHalfAngles_;  ///< per light: tan of its angular radius (at least 1e-3)
    std::vector<glm::vec2> sampleOffsets_;  ///< per sample of a pixel: sampleOffset()
    ScreenShells shells_;  ///< camera rays' shells per screen tile (the BVH serves the other rays)
    /// Per object: camera rays that hit a front face (2 i), a back face (2 i + 1).
    std::unique_ptr<std::atomic<std::uint64_t>[]> facingHits_;
};

void validateOptions(const RenderOptions& options) {
    auto reject = [](const std::string& field, const std::string& value,
                     const std::string& accepted) {
        throw InputError::inField(field, value + " is not accepted; " + accepted);
    };
    if (options.width < 1 || options.width > 16384)
        reject("width", std::to_string(options.width), "it must be in [1, 16384]");
    if (options.height < 1 || options.height > 16384)
        reject("height", std::to_string(options.height), "it must be in [1, 16384]");
    if (options.march.maxIterations < 1 || options.march.maxIterations > 4096) {
        reject("march.maxIterations", std::to_string(options.march.maxIterations),
               "it must be in [1, 4096]");
    }
    // Below 1e-5 texel (single precision's spacing at 256 texels is 1.5e-5) no sample can come
    // that close: every ray spends its whole budget (mean 12 samples at 0.02 and 17 at 1e-5 on the
    // sheet with a budget of 4096; 242 at 1e-6, 748 at 1e-30).
    if (!(options.march.epsilonTexels >= 1e-5f && options.march.epsilonTexels <= 1.0f)) {
        std::ostringstream value;
        value << options.march.epsilonTexels;
        reject("march.epsilonTexels", value.str(),
               "it must be in [1e-5, 1] texels (single precision resolves no closer hit)");
    }
    if (!(options.march.relaxation >= 1.0f && options.march.relaxation < 2.0f)) {
        reject("march.relaxation", numberText(options.march.relaxation), "it must be in [1, 2)");
    }
    if (!(options.march.reliefLinearShare > 0.0f && options.march.reliefLinearShare <= 1.0f)) {
        reject("march.reliefLinearShare", numberText(options.march.reliefLinearShare),
               "it must be in (0, 1]");
    }
    if (options.shadowIterations < 1 || options.shadowIterations > 4096) {
        reject("shadowIterations", std::to_string(options.shadowIterations),
               "it must be in [1, 4096]");
    }
    if (options.samplesPerPixel < 1 || options.samplesPerPixel > 256) {
        reject("samplesPerPixel", std::to_string(options.samplesPerPixel),
               "it must be in [1, 256]");
    }
    const std::int64_t pixels = std::int64_t(options.width) * options.height;
    if (pixels > kMaxRenderSamples) {  // no sample count fits: the size is what to change
        reject("width", std::to_string(options.width) + "x" + std::to_string(options.height),
               "width x height must be at most 2^24 pixels (16777216, e.g. 4096x4096; ~40 s on "
               "two cores)");
    }
    if (pixels * options.samplesPerPixel > kMaxRenderSamples) {
        reject("samplesPerPixel", std::to_string(options.samplesPerPixel),
               "width x height x samples per pixel must be at most 2^24 camera samples (" +
                   std::to_string(options.width) + " x " + std::to_string(options.height) +
                   " allows " +
                   std::to_string(std::max<std::int64_t>(1, kMaxRenderSamples / pixels)) +
                   " or less; ~40 s on two cores)");
    }
    if (options.outputAovs && pixels * kAovImages > kMaxRenderSamples * 2) {
        reject("outputAovs",
               "with a " + std::to_string(options.width) + "x" + std::to_string(options.height) +
                   " image",
               "the AOVs need width x height at most 2^22 pixels (8 float images in memory)");
    }
    if (options.shadowMapResolution != 0 &&
        (options.shadowMapResolution < 16 || options.shadowMapResolution > 16384)) {
        reject("shadowMapResolution", std::to_string(options.shadowMapResolution),
               "it must be 0 (automatic) or in [16, 16384] texels");
    }
}

}  // namespace

glm::vec3 heatColor(float value) {
    const float t = std::clamp(value, 0.0f, 1.0f) * 4.0f;
    const glm::vec3 stops[5] = {{0, 0, 1}, {0, 1, 1}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}};
    const int lower = std::min(int(t), 3);
    return glm::mix(stops[lower], stops[lower + 1], t - float(lower));
}

namespace {

/// Throws InputError for the first tiled object without the truth a reference render needs: an
/// analytic distance (the march, or the self-shadows when the material also has an exact hit).
void validateReference(const Scene& scene) {
    for (std::size_t index = 0; index < scene.objects.size(); ++index) {
        const Material& material = scene.objects[index].material;
        if (!material.tile || material.analyticDistance) continue;
        const std::string source =
            material.tile->provenance.source.empty() ? "unknown" : material.tile->provenance.source;
        std::string message =
            "objects[" + std::to_string(index) +
            "].material.tile: a reference render needs the detail's exact "
            "truth: procedural detail (chainmail, grating), a mesh or a level set "
            "(a scene's \"bake\": \"mesh\" or \"vdb\", or a tile file that "
            "records its source file); "
            "this tile's source '" +
            source + "' has none";
        if (source == "mesh") {
            message +=
                " (this tile file does not record its source mesh: bake it again with `distile "
                "bake mesh`, or bake it in the scene with {\"bake\": \"mesh\", \"file\": ...})";
        }
        throw InputError(message);
    }
}

/// The options a render runs with: `requested`, checked, with a reference render's march.
RenderOptions checkedOptions(const Scene& scene, const RenderOptions& requested) {
    validateOptions(requested);
    validateScene(scene);
    RenderOptions options = requested;
    if (options.reference) {
        validateReference(scene);
        options.march.method = MarchMethod::SphereTracing;
        options.march.maxIterations = RenderOptions::kReferenceIterations;
        options.march.epsilonTexels = RenderOptions::kReferenceEpsilonTexels;
    }
    return options;
}

}  // namespace

RenderAovs RenderAovs::blank(int width, int height) {
    const auto black = [&] { return Image(width, height); };  // filled in parallel, not copied
    return {black(), black(), black(), black(), black(), black(), black()};
}

struct PreparedScene::Parts {
    const Scene& scene;
    const RenderOptions options;
    const SceneTracer tracer;
};

PreparedScene::PreparedScene(const Scene& scene, const RenderOptions& requested) {
    const RenderOptions options = checkedOptions(scene, requested);
    parts_.reset(new Parts{
        scene, options,
        SceneTracer(scene, TraceOptions{options.march, options.filter, options.normalFilter,
                                        options.reference, options.skips, options.shellMapping})});
}

PreparedScene::~PreparedScene() = default;

RenderResult renderScene(const Scene& scene, const RenderOptions& options,
                         const ProgressCallback& progress) {
    return PreparedScene(scene, options).render(progress);
}

RenderResult PreparedScene::render(const ProgressCallback& progress) const {
    const Scene& scene = parts_->scene;
    const RenderOptions& options = parts_->options;
    const Renderer renderer(scene, options, parts_->tracer);
    RenderResult result;
    result.image = Image(options.width, options.height);
    if (options.outputAovs) {
        result.aovs.emplace(RenderAovs::blank(options.width, options.height));
    }
    const float shadowBudget =
        float(options.shadowIterations * std::max<std::size_t>(scene.lights.size(), 1));
    const float shadowMapBudget = float((kShadowRingSamples + kShadowDiskSamples) *
                                        std::max<std::size_t>(scene.lights.size(), 1));
    std::atomic<std::uint64_t> rays{0}, baseHits{0}, detailHits{0}, iterations{0}, converged{0},
        shadowSteps{0}, shadowMapSamples{0};
    std::atomic<std::uint64_t> shellsTested{0}, shellsTraced{0};
    // Blocks of 16 x 16 pixels shared among the threads; every pixel is computed on its own.
    constexpr int kBlock = 16;
    forEachImageBlock(
        options.width, options.height, kBlock, progress, 0.0, 1.0,
        [&](const tbb::blocked_range2d<int>& block) {
            RenderStats local;
            // Not threadScratch (a vector is not trivially destructible): one small allocation
            // a block.
            std::vector<std::uint64_t> facingHits(renderer.facingSlots(), 0);
            constexpr int kRows = Renderer::kRunRows;
            Sample run[kRows * kBlock];
            for (int y0 = block.rows().begin(); y0 < block.rows().end(); y0 += kRows) {
                const int y1 = std::min(y0 + kRows, block.rows().end());
                for (int x0 = block.cols().begin(); x0 < block.cols().end(); x0 += kBlock) {
                    const int x1 = std::min(x0 + kBlock, block.cols().end());
                    renderer.renderRun(y0, y1, x0, x1, run, local, facingHits);
                    for (int y = y0; y != y1; ++y)
                        for (int x = x0; x != x1; ++x) {
                            const Sample& pixel = run[(y - y0) * (x1 - x0) + (x - x0)];
                            result.image.at(x, y) = pixel.color;
                            if (!result.aovs) continue;
                            result.aovs->depth.at(x, y) = glm::vec3(pixel.depth);
                            result.aovs->normal.at(x, y) =
                                pixel.depth > 0.0f ? pixel.normal * 0.5f + 0.5f : glm::vec3(0.0f);
                            result.aovs->iterations.at(x, y) = heatColor(
                                float(pixel.iterations) / float(options.march.maxIterations));
                            result.aovs->shadowSamples.at(x, y) =
                                heatColor(float(pixel.shadowSteps) / shadowBudget);
                            result.aovs->shadowMapSamples.at(x, y) =
                                heatColor(float(pixel.shadowMapSamples) / shadowMapBudget);
                            result.aovs->texelScale.at(x, y) =
                                glm::vec3(pixel.texelsPerWorldAlongRay);
                            if (pixel.hasCurvature) {  // +-0.5 / texel over the heat map
                                result.aovs->curvature.at(x, y) =
                                    heatColor(0.5f + pixel.meanCurvature);
                            }
                        }
                }
            }
            renderer.addFacingHits(facingHits);
            rays += local.rays;
            baseHits += local.baseHits;
            detailHits += local.detailHits;
            iterations += local.marchIterations;
            converged += local.converged;
            shadowSteps += local.shadowSteps;
            shadowMapSamples += local.shadowMapSamples;
            shellsTested += local.shellsTested;
            shellsTraced += local.shellsTraced;
        });
    result.stats.rays = rays;
    result.stats.baseHits = baseHits;
    result.stats.detailHits = detailHits;
    result.stats.marchIterations = iterations;
    result.stats.converged = converged;
    result.stats.shadowSteps = shadowSteps;
    result.stats.shadowMapSamples = shadowMapSamples;
    result.stats.shellsTested = shellsTested;
    result.stats.shellsTraced = shellsTraced;
    result.stats.shadowMapTexels = renderer.shadowMapTexels(false);
    result.stats.shadowMapTexelsAll = renderer.shadowMapTexels(true);
    result.warnings = renderer.warnings();
    if (result.stats.rays > 0 && result.stats.baseHits == 0) {
        // Sky alone: a camera that looks past the scene, or one exactly on a base surface.
        result.warnings.push_back(
            "no camera ray meets any object, so the image is sky alone: check camera.eye, "
            "camera.target and camera.fov_deg against the objects' transforms (a camera exactly "
            "on a base surface sees neither it nor its detail)");
    }
    return result;
}

}  // namespace distile
