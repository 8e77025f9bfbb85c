/// @file
/// The truth as a filter: a material's exact (analytic) signed distance, evaluated in double
/// precision, behind the same interface as the tile filters of sampler/filters.h, so the march and
/// the shading of reference renders (RenderOptions::reference) are the ones of ordinary renders.
/// withMarchFilter() is the single place where a render picks between the tile and the truth.
#pragma once

#include <functional>
#include <glm/vec3.hpp>

#include "render/scene.h"
#include "sampler/filter_choice.h"

namespace distile {

/// An exact signed distance (texels, texel space, periodic in x and y) as a filter. Holds a
/// reference to the function, which must outlive the filter and be safe to call from several
/// threads. Results are computed in double and rounded to float only when returned.
class AnalyticFilter {
  public:
    using DistanceFunction = std::function<double(const glm::dvec3& texelPosition)>;

    /// Central-difference step of gradient(), in texels: small against any feature of the detail
    /// (wires are several texels thick), large against double rounding (~1e-13 relative error).
    static constexpr double kGradientStepTexels = 1e-5;

    /// Precondition: `distance` is not empty.
    explicit AnalyticFilter(const DistanceFunction& distance) : distance_(distance) {}

    float distanceTexels(const glm::vec3& texelPosition) const {
        return float(distance_(glm::dvec3(texelPosition)));
    }

    /// The gradient of the exact distance by central differences in double precision (unit length
    /// away from the medial axis).
    glm::vec3 gradient(const glm::vec3& texelPosition) const {
        const glm::dvec3 at(texelPosition);
        const double h = kGradientStepTexels;
        const glm::dvec3 dx(h, 0.0, 0.0), dy(0.0, h, 0.0), dz(0.0, 0.0, h);
        return glm::vec3((distance_(at + dx) - distance_(at - dx)) / (2.0 * h),
                         (distance_(at + dy) - distance_(at - dy)) / (2.0 * h),
                         (distance_(at + dz) - distance_(at - dz)) / (2.0 * h));
    }

  private:
    const DistanceFunction& distance_;
};

/// Calls `function(filter)` with the filter a render uses for `material`: its analytic distance
/// when `reference` is set, else withFilter(kind, columns, ...) over the material's tile in the
/// renderer's layout. Preconditions: an analyticDistance when `reference` is set, else `columns`
/// not null (the renderer checks).
template <class Function>
decltype(auto) withMarchFilter(FilterKind kind, const Material& material,
                               const TileColumns* columns, bool reference, Function&& function) {
    if (reference) return function(AnalyticFilter(material.analyticDistance));
    return withFilter(kind, *columns, function);
}

}  // namespace distile
