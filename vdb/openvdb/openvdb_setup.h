/// @file
/// Internal to vdb/: OpenVDB's one-time setup and distile's texel-space transform.
#pragma once

#include <openvdb/openvdb.h>

#include <mutex>

namespace distile::detail {

/// Registers OpenVDB's grid types, once per process.
inline void initializeOpenVdb() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

/// Texel space: voxel (i, j, k) centred at (i + 0.5, j + 0.5, k + 0.5), voxel size 1 texel.
inline openvdb::math::Transform::Ptr texelTransform() {
    auto transform = openvdb::math::Transform::createLinearTransform(1.0);
    transform->postTranslate(openvdb::Vec3d(0.5));
    return transform;
}

}  // namespace distile::detail
