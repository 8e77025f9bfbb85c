/// @file
/// The shell map: the one map between a tile's texel space and world space over a base triangle,
/// shared by the renderer (render/shell_march.h), the world-space references
/// (vdb/displaced_level_set.h) and the docs (docs/shell_map.md).
///
/// A base triangle with corners P_i, unit vertex normals N_i and uvs uv_i (i = 0, 1, 2) carries a
/// *prism* of detail: its top is the triangle itself (texel z = D), its bottom the triangle moved
/// `depthWorld` along -N_i at each corner (z = 0). A point of the prism has barycentrics b (b_0 =
/// 1 - b_1 - b_2) and a depth h in [0, depthWorld] below the top:
///
///     world(b, h) = sum_i b_i (P_i - h N_i)
///     texel(b, h) = (uv(b).x uvScale.x W, uv(b).y uvScale.y H, D (1 - h / depthWorld)),
///     uv(b) = sum_i b_i uv_i.
///
/// texel(b, h) is affine; world(b, h) is linear in b for each h and in h for each b (the side faces
/// are bilinear patches, shared exactly by the prisms of neighbouring triangles). Where the three
/// normals are equal the prism is straight and the whole map is affine (ch. 8's planar march is
/// then exact); elsewhere rays bend in texel space and are followed prism by prism.
///
/// World positions are taken relative to P_0 (`offsetWorld`), in double precision, so a mesh far
/// from the origin keeps its sub-texel detail.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace distile {

/// Barycentrics (b1, b2) of corners 1 and 2 and the depth below the top, world units.
struct PrismPoint {
    double b1 = 0.0;
    double b2 = 0.0;
    double depthWorld = 0.0;
    double b0() const { return 1.0 - b1 - b2; }
};

/// The shell map of one base triangle (file note). Plain data: copyable, no references.
struct ShellPrism {
    glm::dvec3 corner0{0.0};                          ///< P_0, world units
    glm::dvec3 edge1{0.0}, edge2{0.0};                ///< P_1 - P_0, P_2 - P_0
    glm::dvec3 normal0{0.0};                          ///< N_0, unit
    glm::dvec3 normalDelta1{0.0}, normalDelta2{0.0};  ///< N_1 - N_0, N_2 - N_0
    double depthWorld = 1.0;                          ///< h of the bottom (z = 0)
    /// texel.xy = texelOrigin + b1 texelEdge1 + b2 texelEdge2; texelOrigin wrapped into
    /// [0, W) x [0, H) (the tile repeats: far uvs keep their fraction).
    glm::dvec2 texelOrigin{0.0}, texelEdge1{0.0}, texelEdge2{0.0};
    double depthTexels = 1.0;          ///< D: texel z = D (1 - h / depthWorld)
    double texelsPerDepthWorld = 1.0;  ///< D / depthWorld (texel z per world unit of depth)

    /// The prism of a triangle (corners, unit normals, uvs) carrying a tile of `width` x `height`
    /// x `depthTexels` texels repeated `uvScale` times per unit of uv, `depthWorld` deep.
    static ShellPrism make(const glm::vec3 corners[3], const glm::vec3 normals[3],
                           const glm::vec2 uvs[3], const glm::vec2& uvScale, int width, int height,
                           int depthTexels, double depthWorld);

    /// True when the three normals are equal: the map is affine.
    bool straight() const {
        return normalDelta1 == glm::dvec3(0.0) && normalDelta2 == glm::dvec3(0.0);
    }

    /// The interpolated (not normalised) vertex normal at barycentrics (b1, b2).
    glm::dvec3 normalAt(double b1, double b2) const {
        return normal0 + b1 * normalDelta1 + b2 * normalDelta2;
    }
    /// world(b, h) - P_0.
    glm::dvec3 offsetAt(const PrismPoint& point) const {
        return point.b1 * edge1 + point.b2 * edge2 -
               point.depthWorld * normalAt(point.b1, point.b2);
    }
    glm::dvec3 worldAt(const PrismPoint& point) const { return corner0 + offsetAt(point); }

    glm::dvec3 texelAt(const PrismPoint& point) const {
        const glm::dvec2 xy = texelOrigin + point.b1 * texelEdge1 + point.b2 * texelEdge2;
        return {xy.x, xy.y, depthTexels - texelsPerDepthWorld * point.depthWorld};
    }
    /// The inverse of texelAt (texel z to depth; x, y through the uv triangle). Precondition: the
    /// uv triangle is not degenerate.
    PrismPoint pointAtTexel(const glm::dvec3& texel) const;

    /// d world / d(b1, b2, h) at `point`: the columns of the map's Jacobian.
    struct Jacobian {
        glm::dvec3 column[3];
        /// Cofactor rows: inverse = rows / determinant (rows[k] = column[k+1] x column[k+2]).
        glm::dvec3 cofactor[3];
        double determinant = 0.0;
        double inverseDeterminant = 0.0;  ///< 1 / determinant (inf when singular)

        /// Solves J x = v.
        glm::dvec3 solve(const glm::dvec3& v) const {
            return glm::dvec3(glm::dot(cofactor[0], v), glm::dot(cofactor[1], v),
                              glm::dot(cofactor[2], v)) *
                   inverseDeterminant;
        }
        /// Solves J^T x = v: the world vector whose dot with each column is v's component.
        glm::dvec3 solveTransposed(const glm::dvec3& v) const {
            return (v.x * cofactor[0] + v.y * cofactor[1] + v.z * cofactor[2]) * inverseDeterminant;
        }
    };
    /// The columns of the map's Jacobian at `point`.
    void jacobianColumnsAt(const PrismPoint& point, glm::dvec3 column[3]) const {
        column[0] = edge1 - point.depthWorld * normalDelta1;
        column[1] = edge2 - point.depthWorld * normalDelta2;
        column[2] = -normalAt(point.b1, point.b2);
    }
    Jacobian jacobianAt(const PrismPoint& point) const {
        Jacobian jacobian;
        jacobianColumnsAt(point, jacobian.column);
        jacobian.cofactor[0] = glm::cross(jacobian.column[1], jacobian.column[2]);
        jacobian.cofactor[1] = glm::cross(jacobian.column[2], jacobian.column[0]);
        jacobian.cofactor[2] = glm::cross(jacobian.column[0], jacobian.column[1]);
        jacobian.determinant = glm::dot(jacobian.column[0], jacobian.cofactor[0]);
        jacobian.inverseDeterminant = 1.0 / jacobian.determinant;
        return jacobian;
    }

    /// jacobianAt(point).determinant, without the rest of the Jacobian.
    double determinantAt(const PrismPoint& point) const {
        glm::dvec3 column[3];
        jacobianColumnsAt(point, column);
        return glm::dot(column[0], glm::cross(column[1], column[2]));
    }

    /// d texel / d(b1, b2, h) applied to a vector of (b1, b2, h) changes.
    glm::dvec3 texelDelta(const glm::dvec3& change) const {
        const glm::dvec2 xy = change.x * texelEdge1 + change.y * texelEdge2;
        return {xy.x, xy.y, -texelsPerDepthWorld * change.z};
    }
    /// Its transpose: a texel-space gradient as a gradient over (b1, b2, h).
    glm::dvec3 texelGradientToPrism(const glm::dvec3& gradient) const {
        return {gradient.x * texelEdge1.x + gradient.y * texelEdge1.y,
                gradient.x * texelEdge2.x + gradient.y * texelEdge2.y,
                -texelsPerDepthWorld * gradient.z};
    }

    /// A chord step toward world offset `offset` (world - P_0) from `point`: the map's residual
    /// there solved with `jacobian`, kept from a Newton step nearby (subtract it from `point`).
    glm::dvec3 chordChange(const glm::dvec3& offset, const PrismPoint& point,
                           const Jacobian& jacobian) const {
        return jacobian.solve(offsetAt(point) - offset);
    }

    /// The prism point at world offset `offset` (world - P_0) by Newton's method from `guess`
    /// (the map is nearly affine: one step from a nearby guess). Converged when a step moves
    /// the barycentrics and the depth (relative to depthWorld) by less than 1e-3: the error left
    /// is then of the order of the square of that times the map's small nonlinearity. A longer
    /// step is followed by a chord step (its Jacobian kept), converged when its move is below
    /// 1e-3 and its move times the Newton step's below 1e-6 (the same order of error). `jacobian`
    /// receives the Jacobian of the last step (at the point before it). False when it does not
    /// converge within `maxSteps` (a fold of the map, a degenerate prism, non-finite input);
    /// `point` then holds the last iterate.
    bool invert(const glm::dvec3& offset, PrismPoint& point, Jacobian& jacobian,
                int maxSteps = 8) const;

    /// The smallest depth (world units) at which the map folds over this triangle (its
    /// Jacobian's determinant changes sign, looked at along the corners, edge midpoints and the
    /// centre), or +infinity when it does not fold at any depth up to 1e6 x depthWorld.
    double foldDepthWorld() const;
};

inline bool ShellPrism::invert(const glm::dvec3& offset, PrismPoint& point, Jacobian& jacobian,
                               int maxSteps) const {
    constexpr double kConverged = 1e-3;
    // Locals, written back once: the point and the Jacobian live in the caller's memory, and
    // stores to them in the loop would be reloaded.
    double b1 = point.b1, b2 = point.b2, depth = point.depthWorld;
    for (int step = 0; step < maxSteps; ++step) {
        const glm::dvec3 normal = normalAt(b1, b2);
        Jacobian at;
        at.column[0] = edge1 - depth * normalDelta1;
        at.column[1] = edge2 - depth * normalDelta2;
        at.column[2] = -normal;
        at.cofactor[0] = glm::cross(at.column[1], at.column[2]);
        at.cofactor[1] = glm::cross(at.column[2], at.column[0]);
        at.cofactor[2] = glm::cross(at.column[0], at.column[1]);
        at.determinant = glm::dot(at.column[0], at.cofactor[0]);
        if (!(at.determinant != 0.0)) break;
        at.inverseDeterminant = 1.0 / at.determinant;
        const glm::dvec3 residual = b1 * edge1 + b2 * edge2 - depth * normal - offset;
        glm::dvec3 change = at.solve(residual);
        b1 -= change.x;
        b2 -= change.y;
        depth -= change.z;
        const double moved = std::max(std::abs(change.x), std::abs(change.y));
        const double movedTexelsZ = std::abs(change.z) * texelsPerDepthWorld;
        if (moved < kConverged && movedTexelsZ < kConverged * depthTexels) {
            point = {b1, b2, depth};
            jacobian = at;
            return true;
        }
        if (!(moved < 1e6 && movedTexelsZ < 1e6 * depthTexels)) break;  // diverging, or NaN
        // A step too long to call converged left an error of the order of its square: a chord
        // step (the residual there, solved with the same Jacobian) takes most of it at a third
        // of a Newton step's cost. It falls short of the Newton step there by about its own move
        // times the Jacobian's change along the Newton step: converged when its move is below
        // 1e-3 and that product below 1e-6 (what a converged Newton step leaves), else Newton
        // goes on from the better point.
        const double newtonMove = std::max(moved, movedTexelsZ / depthTexels);
        change = chordChange(offset, {b1, b2, depth}, at);
        b1 -= change.x;
        b2 -= change.y;
        depth -= change.z;
        const double chordMove =
            std::max({std::abs(change.x), std::abs(change.y), std::abs(change.z) / depthWorld});
        if (chordMove < kConverged && chordMove * newtonMove < kConverged * kConverged) {
            point = {b1, b2, depth};
            jacobian = at;
            return true;
        }
        if (step + 1 == maxSteps) jacobian = at;
    }
    point = {b1, b2, depth};
    return false;
}

}  // namespace distile
