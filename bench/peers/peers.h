/// @file
/// Peer renderers for `distile bench` (docs/reports.md): the same scene, camera rays and
/// thread count traced by other tools on the same detail, so distile's time and error can be put
/// next to theirs in one run.
///  - Embree 3 on the chain mail tessellated to a chosen error bound (vdb/chainmail.h
///    tessellateChainmail) and placed on the sheet in world space, with the solid floor as two
///    triangles; one ray per call or packets, triangles or quads, either BVH quality.
///  - OpenVDB's vdb_render (a separate program) on the chain mail's level set repeated over the
///    sheet (vdb/level_set.h), with its camera converted to the level set's texel space.
/// Both accept one kind of scene, a "sheet": one object, a planar base mesh with orthogonal,
/// right-handed uv axes carrying a procedural European 4-in-1 chain-mail tile
/// (its options read from the tile's provenance, bake/provenance.h). Anything else, or a peer that
/// is not installed, gives a PeerRender with available = false and the reason; errors of the peer
/// itself throw std::runtime_error.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "render/image.h"
#include "render/scene.h"

namespace distile {

struct PeerRender {
    std::string name;  ///< "embree", "vdb_render"
    bool available = false;
    std::string unavailableReason;  ///< "not available: ...", when !available
    double setupSeconds = 0.0;      ///< tessellation + BVH build / level set build + write + read
    double traceSeconds = 0.0;      ///< primary rays through every pixel centre, wall time
    /// Embree: what the device allocated (vertex and index buffers and the BVH), from its memory
    /// monitor; vdb_render: the level set's in-memory size (OpenVDB memUsage, file_mem_bytes).
    std::size_t memoryBytes = 0;
    /// Distance from the eye along the camera ray, world units, in all channels (0: miss): the
    /// convention of RenderAovs::depth (render/renderer.h).
    Image depth;
    /// Geometric (Embree) or level-set gradient (vdb_render) normal facing the camera, world
    /// space, n * 0.5 + 0.5 (0: miss).
    Image normal;
};

/// How the Embree peer builds and traces the sheet: a configuration a user of Embree could pick.
struct EmbreePeerOptions {
    /// Bound on the distance of every face from the analytic surface, texels (> 0): the rings'
    /// polygon counts follow from it (vdb/chainmail.h chainmailTessellationErrorTexels).
    double tessellationErrorTexels = 0.02;
    /// Rays traced per call: 1 (rtcIntersect1 per pixel), or 4, 8 or 16 (rtcIntersect4/8/16 on
    /// 2 x 2, 4 x 2 or 4 x 4 pixel tiles, with the coherent-ray hint Embree's documentation gives
    /// for camera rays).
    int raysPerPacket = 1;
    /// The rings as quads (each tessellation quad is planar: Embree intersects it as one
    /// primitive) rather than two triangles each.
    bool quads = false;
    /// RTC_BUILD_QUALITY_HIGH (spatial splits: a slower build, faster traces) rather than Embree's
    /// default medium quality.
    bool highQualityBvh = false;
    /// Traces of the one built scene (>= 1); traceSeconds is the fastest (the least disturbed).
    int traceRuns = 1;
    /// Called before each trace, untimed (may be empty): a caller times its own work there, so
    /// that a slow spell of a shared machine hits both alike.
    std::function<void()> beforeEachTrace;
};

/// Embree's native packet width on this machine and build (16, 8 or 4; 1 when Embree is missing
/// or has no packet support): the widest rtcIntersectN that runs without emulation.
int embreeNativePacketWidth();

/// Embree 3 on the sheet's chain mail, tessellated so that no face is more than
/// options.tessellationErrorTexels from the analytic surface (vdb/chainmail.h), every tile repeat
/// placed in world space, plus the solid floor at the bottom of the shell as two triangles. As in
/// distile, only rays entering the shell through the base mesh's uv rectangle can hit, and beyond
/// its edges the rings and the floor go on as far as those rays reach below the surface (distile's
/// march does not stop at the mesh's edge either). The renderer's camera rays through every pixel
/// centre (PinholeProjection), alone or in packets (options), on `threads` threads. Not available
/// when distile was built without Embree, the sheet would need more than 2^28 triangles, or the
/// packet width is not supported by the Embree build.
/// @throws InputError width, height or threads out of range ([1, 16384], [1, 16384], [1, 256]),
///   options out of range (tessellation error not > 0, rays per packet not 1, 4, 8 or 16, trace
///   runs < 1) or an invalid scene (validateScene); std::runtime_error when Embree fails.
PeerRender renderSheetWithEmbree(const Scene& scene, int width, int height, int threads,
                                 const EmbreePeerOptions& options = {});

/// A short label of an Embree configuration, e.g. "embree 16-wide packets, quads, high BVH,
/// 0.05 texel".
std::string embreePeerLabel(const EmbreePeerOptions& options);

/// /usr/bin/vdb_render on the sheet's chain-mail level set (half band 3 texels, the tile
/// repeated uv_scale times; texels must be cubes and the uv footprint whole tiles) written to
/// `workDir`, with its camera in texel space, shader "position" (for the depth) and "normal", on
/// `threads` threads. The trace time is what vdb_render reports for its ray tracing (-v); reading
/// the level set counts as setup. The level set has no floor (rays that reach distile's floor miss
/// here) and ends at the uv rectangle's edges. Writes sheet.vdb, position.exr, normal.exr and the
/// programs' output to `workDir`. Not available when vdb_render or vdb_print is missing.
/// @throws InputError bad sizes or threads (as above), an invalid scene, or `workDir` is not an
///   existing folder; std::runtime_error when vdb_render or vdb_print fails (stderr in the
///   message).
PeerRender renderSheetWithVdbRender(const Scene& scene, int width, int height, int threads,
                                    const std::filesystem::path& workDir);

/// Runs `program` with `arguments` (no shell), its stdout and stderr captured in files of
/// `workDir` named after `logName`; returns stdout. Throws std::runtime_error with the exit status
/// and stderr when the program fails.
std::string runProgram(const std::filesystem::path& program,
                       const std::vector<std::string>& arguments,
                       const std::filesystem::path& workDir, const std::string& logName);

}  // namespace distile
