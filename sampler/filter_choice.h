/// @file
/// The run-time choice of reconstruction filter, and the one place where it becomes a
/// compile-time filter type: hot loops (the march, tile checks) are templates over the filter.
#pragma once

#include "sampler/filters.h"
#include "sampler/tricubic.h"

namespace distile {

/// The reconstruction filters a renderer or a check can choose.
enum class FilterKind { Nearest, Trilinear, TricubicBSpline, CatmullRom };

/// Calls `function(filter)` with the filter of `kind` over `tile` and returns its result.
template <class Function>
decltype(auto) withFilter(FilterKind kind, const Tile& tile, Function&& function) {
    switch (kind) {
        case FilterKind::Nearest:
            return function(NearestFilter(tile));
        case FilterKind::TricubicBSpline:
            return function(TricubicBSplineFilter(tile));
        case FilterKind::CatmullRom:
            return function(CatmullRomFilter(tile));
        case FilterKind::Trilinear:
            break;
    }
    return function(TrilinearFilter(tile));
}

}  // namespace distile
