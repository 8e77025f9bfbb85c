/// @file
/// The run-time choice of reconstruction filter, and the one place where it becomes a
/// compile-time filter type: hot loops (the march, tile checks) are templates over the filter.
#pragma once

#include "sampler/filters.h"
#include "sampler/tricubic.h"

namespace distile {

/// The reconstruction filters a renderer or a check can choose.
enum class FilterKind { Nearest, Trilinear, TricubicBSpline, CatmullRom };
inline constexpr FilterKind kFilterKinds[] = {FilterKind::Nearest, FilterKind::Trilinear,
                                              FilterKind::TricubicBSpline, FilterKind::CatmullRom};

/// "nearest", "trilinear", "tricubic", "catmullrom": the names programs show and accept.
inline const char* filterKindName(FilterKind kind) {
    switch (kind) {
        case FilterKind::Nearest:
            return "nearest";
        case FilterKind::TricubicBSpline:
            return "tricubic";
        case FilterKind::CatmullRom:
            return "catmullrom";
        case FilterKind::Trilinear:
            break;
    }
    return "trilinear";
}

/// Calls `function(filter)` with the filter of `kind` reading `texels` (TileTexels or
/// ColumnTexels, sampler/filters.h) and returns its result.
template <class Texels, class Function>
decltype(auto) withFilterOn(FilterKind kind, const Texels& texels, Function&& function) {
    switch (kind) {
        case FilterKind::Nearest:
            return function(BasicNearestFilter<Texels>(texels));
        case FilterKind::TricubicBSpline:
            return function(BasicTricubicBSplineFilter<Texels>(texels));
        case FilterKind::CatmullRom:
            return function(BasicCatmullRomFilter<Texels>(texels));
        case FilterKind::Trilinear:
            break;
    }
    return function(BasicTrilinearFilter<Texels>(texels));
}

/// Calls `function(filter)` with the filter of `kind` over `tile` and returns its result.
template <class Function>
decltype(auto) withFilter(FilterKind kind, const Tile& tile, Function&& function) {
    return withFilterOn(kind, TileTexels(tile), function);
}

/// The same over a tile's columns (the renderer's layout).
template <class Function>
decltype(auto) withFilter(FilterKind kind, const TileColumns& columns, Function&& function) {
    return withFilterOn(kind, ColumnTexels(columns), function);
}

}  // namespace distile
