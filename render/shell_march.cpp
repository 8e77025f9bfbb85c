#include "render/shell_march.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <tuple>
#include <utility>
#include <vector>

#include "common/position_weld.h"

namespace distile::detail {

SideWalk walkAcrossSide(const ShellPrisms& shell, const glm::dvec3& origin, CurvedCursor& cursor) {
    // A point on a shared side face belongs to both prisms: rounding may put it a hair outside
    // each, so a little outside counts as inside (no walk back and forth).
    constexpr double kOnFace = 1e-9;
    const double weights[3] = {cursor.point.b0(), cursor.point.b1, cursor.point.b2};
    // Inside the triangle (most samples): no need to know which weight is least, whose
    // comparisons the processor cannot predict.
    if (weights[0] >= -kOnFace && weights[1] >= -kOnFace && weights[2] >= -kOnFace)
        return SideWalk::Inside;
    int outside = 0;
    for (int corner = 1; corner < 3; ++corner)
        if (weights[corner] < weights[outside]) outside = corner;
    if (weights[outside] >= -kOnFace) return SideWalk::Inside;
    const std::uint32_t neighbour = shell.neighbours[cursor.prism][std::size_t(outside)];
    if (neighbour == ShellPrisms::kNoNeighbour) return SideWalk::OpenSide;
    // The guess in the neighbour, exact where the two triangles form a parallelogram: the far
    // corner takes the weight beyond the shared face, which its two corners (in reverse order)
    // give up.
    const int far = shell.neighbourCorners[cursor.prism][std::size_t(outside)];
    double across[3];
    across[far] = -weights[outside];
    across[(far + 1) % 3] = weights[(outside + 2) % 3] + weights[outside];
    across[(far + 2) % 3] = weights[(outside + 1) % 3] + weights[outside];
    cursor.prism = neighbour;
    cursor.originOffset = origin - shell.prisms[neighbour].corner0;
    cursor.point = {across[1], across[2], cursor.point.depthWorld};
    return SideWalk::Walked;
}

Located locate(const ShellPrisms& shell, const glm::dvec3& origin, const glm::dvec3& direction,
               double distanceWorld, CurvedCursor& cursor) {
    constexpr int kMaxWalk = 64;
    for (int walk = 0; walk < kMaxWalk; ++walk) {
        const ShellPrism& prism = shell.prisms[cursor.prism];
        if (!prism.invert(cursor.originOffset + distanceWorld * direction, cursor.point,
                          cursor.jacobian, 12))
            return Located::Lost;
        const bool aboveTop = cursor.point.depthWorld < 0.0;
        switch (walkAcrossSide(shell, origin, cursor)) {
            case SideWalk::Inside:
                return aboveTop ? Located::AboveTop : Located::Inside;
            case SideWalk::OpenSide:
                return aboveTop ? Located::AboveTop : Located::OpenSide;
            case SideWalk::Walked:
                break;
        }
    }
    return Located::Lost;
}

Chord chordStep(const ShellPrisms& shell, const glm::dvec3& origin, const glm::dvec3& direction,
                double distanceWorld, CurvedCursor& cursor) {
    const ShellPrism& prism = shell.prisms[cursor.prism];
    PrismPoint point = cursor.point;
    const glm::dvec3 change =
        prism.chordChange(cursor.originOffset + distanceWorld * direction, point, cursor.jacobian);
    point.b1 -= change.x;
    point.b2 -= change.y;
    point.depthWorld -= change.z;
    // Converged as a Newton step is (a move below 1e-3), and between the top and the floor.
    const double moved = std::max(std::abs(change.x), std::abs(change.y));
    const double movedTexelsZ = std::abs(change.z) * prism.texelsPerDepthWorld;
    if (!(moved < 1e-3 && movedTexelsZ < 1e-3 * prism.depthTexels && point.depthWorld >= 0.0 &&
          point.depthWorld <= prism.depthWorld))
        return Chord::Declined;
    const PrismPoint guess = cursor.point;
    cursor.point = point;
    switch (walkAcrossSide(shell, origin, cursor)) {
        case SideWalk::Inside:
            return Chord::Taken;
        case SideWalk::Walked:
            return Chord::Walked;
        case SideWalk::OpenSide:
            break;
    }
    cursor.point = guess;
    return Chord::Declined;
}

}  // namespace distile::detail

namespace distile {

using detail::Located;

ShellMesh buildShellMesh(const BaseMesh& mesh, const glm::vec2& uvScale, const Size3& tileSize,
                         double depthWorld) {
    ShellMesh shell;
    const std::size_t count = mesh.triangles.size();
    shell.prisms.resize(count);
    shell.neighbours.resize(count);
    shell.neighbourCorners.resize(count);
    buildShellMeshInto(mesh, uvScale, tileSize, depthWorld, 0, shell.prisms, shell.neighbours,
                       shell.neighbourCorners);
    return shell;
}

void buildShellMeshInto(const BaseMesh& mesh, const glm::vec2& uvScale, const Size3& tileSize,
                        double depthWorld, std::uint32_t firstIndex, std::span<ShellPrism> prisms,
                        std::span<std::array<std::uint32_t, 3>> neighbours,
                        std::span<std::array<std::uint8_t, 3>> neighbourCorners) {
    const std::size_t count = mesh.triangles.size();
    tbb::parallel_for(std::size_t(0), count, [&](std::size_t t) {
        glm::vec3 positions[3], normals[3];
        glm::vec2 uvs[3];
        for (int corner = 0; corner < 3; ++corner) {
            positions[corner] = mesh.positions[mesh.triangles[t][corner]];
            normals[corner] = mesh.normals[mesh.triangles[t][corner]];
            uvs[corner] = mesh.uvs[mesh.triangles[t][corner]];
        }
        prisms[t] = ShellPrism::make(positions, normals, uvs, uvScale, tileSize.width,
                                     tileSize.height, tileSize.depth, depthWorld);
    });
    buildNeighboursInto(mesh, firstIndex, neighbours, neighbourCorners);
}

void buildNeighboursInto(const BaseMesh& mesh, std::uint32_t firstIndex,
                         std::span<std::array<std::uint32_t, 3>> neighbours,
                         std::span<std::array<std::uint8_t, 3>> neighbourCorners) {
    const std::size_t count = mesh.triangles.size();
    std::fill(neighbours.begin(), neighbours.end(),
              std::array<std::uint32_t, 3>{ShellPrisms::kNoNeighbour, ShellPrisms::kNoNeighbour,
                                           ShellPrisms::kNoNeighbour});
    std::fill(neighbourCorners.begin(), neighbourCorners.end(), std::array<std::uint8_t, 3>{});
    // Vertices welded by position: the copies along a uv seam are one vertex of the surface.
    const std::vector<std::uint32_t> surfaceVertex =
        weldedPositionGroups(mesh.positions, mesh.triangles);
    // Directed edges (from, to), grouped by their undirected edge {lo, hi}, the edges from lo
    // first: the side opposite corner c of triangle t is 3 t + c.
    struct DirectedEdge {
        std::uint32_t lo, hi, from, side;
        bool operator<(const DirectedEdge& other) const {
            return std::tie(lo, hi, from, side) <
                   std::tie(other.lo, other.hi, other.from, other.side);
        }
    };
    std::vector<DirectedEdge> edges(3 * count);
    for (std::uint32_t t = 0; t < count; ++t) {
        const glm::uvec3 corners = mesh.triangles[t];
        for (std::uint32_t corner = 0; corner < 3; ++corner) {
            const std::uint32_t from = surfaceVertex[corners[(corner + 1) % 3]];
            const std::uint32_t to = surfaceVertex[corners[(corner + 2) % 3]];
            edges[3 * t + corner] = {std::min(from, to), std::max(from, to), from, 3 * t + corner};
        }
    }
    // Sides are unique, so the parallel sort's order is the one sorted order.
    tbb::parallel_sort(edges.begin(), edges.end());
    // An edge used once each way (a group of two, one from each end) joins its two triangles;
    // other edges join nothing, nor does a side whose ends are one vertex.
    const auto join = [&](const DirectedEdge& edge, const DirectedEdge& across) {
        neighbours[edge.side / 3][edge.side % 3] = firstIndex + across.side / 3;
        neighbourCorners[edge.side / 3][edge.side % 3] = std::uint8_t(across.side % 3);
    };
    for (std::size_t first = 0, next = 0; first < edges.size(); first = next) {
        for (next = first + 1; next < edges.size() && edges[next].lo == edges[first].lo &&
                               edges[next].hi == edges[first].hi;
             ++next) {
        }
        if (next - first == 2 && edges[first].from != edges[first + 1].from) {
            join(edges[first], edges[first + 1]);
            join(edges[first + 1], edges[first]);
        }
    }
}

void CurvedMarchRay::start(const ShellPrisms& shell, const Ray& ray, std::uint32_t entryPrism,
                           double b1, double b2, double entryDistanceWorld, Floor floor,
                           const MarchSettings& settings) {
    shell_ = &shell;
    origin_ = glm::dvec3(ray.origin);
    direction_ = glm::dvec3(ray.direction);
    cursor_.prism = entryPrism;
    cursor_.point = {b1, b2, 0.0};
    cursor_.originOffset = origin_ - shell.prisms[entryPrism].corner0;
    floor_ = floor;
    epsilonTexels_ = settings.epsilonTexels;
    budget_ = settings.maxIterations;
    budgeted_ = settings.method == MarchMethod::Budgeted;
    entryDistanceWorld_ = distanceWorld_ = outsideWorld_ = entryDistanceWorld;
    outsideDepthWorld_ = 0.0;
    outsideTexels_ = 0.0f;
    refining_ = false;
    end_ = CurvedMarchEnd{};
    // The entry itself, even where rounding puts it a hair above the top.
    const Located where = detail::locate(shell, origin_, direction_, distanceWorld_, cursor_);
    if (where == Located::AboveTop) {
        cursor_.point.depthWorld = 0.0;
    } else if (where != Located::Inside) {
        leave(distanceWorld_);
        return;
    }
    const ShellPrism& prism = shell.prisms[cursor_.prism];
    const glm::dvec3 velocity =
        detail::texelVelocity(prism, cursor_.jacobian, direction_, prismVelocity_);
    speed_ = glm::length(velocity);
    if (!(speed_ > 0.0 && std::isfinite(speed_))) {
        leave(distanceWorld_);
        return;
    }
    directionTexels_ = velocity * (1.0 / speed_);
    samplePosition_ = glm::vec3(prism.texelAt(cursor_.point));
    pathSinceNewtonTexels_ = 0.0;
    needsSample_ = true;
}

bool CurvedMarchRay::takeChordStep(double stepTexels) {
    if (pathSinceNewtonTexels_ + stepTexels > detail::kChordPathTexels) return false;
    if (detail::chordStep(*shell_, origin_, direction_, distanceWorld_, cursor_) !=
        detail::Chord::Taken)
        return false;
    pathSinceNewtonTexels_ += stepTexels;
    samplePosition_ = glm::vec3(shell_->prisms[cursor_.prism].texelAt(cursor_.point));
    return needsSample_ = true;
}

bool CurvedMarchRay::prepareSample(double stepTexels) {
    if (takeChordStep(stepTexels)) return true;
    const double startSpeed = speed_;
    for (int attempt = 0;; ++attempt) {
        const Located where = detail::locate(*shell_, origin_, direction_, distanceWorld_, cursor_);
        if (where == Located::AboveTop) {
            // Out through the top between the last two points: where the depth crosses 0.
            const double share =
                outsideDepthWorld_ / (outsideDepthWorld_ - cursor_.point.depthWorld);
            return leave(outsideWorld_ + (distanceWorld_ - outsideWorld_) * share);
        }
        if (where != Located::Inside) return leave(outsideWorld_);
        const ShellPrism& prism = shell_->prisms[cursor_.prism];
        const glm::dvec3 velocity =
            detail::texelVelocity(prism, cursor_.jacobian, direction_, prismVelocity_);
        speed_ = glm::length(velocity);
        if (!(speed_ > 0.0 && std::isfinite(speed_))) return leave(outsideWorld_);
        directionTexels_ = velocity * (1.0 / speed_);
        // The step was taken with the stretch at its start; where the stretch grows along it,
        // the texel-space path (by the trapezoid of the two speeds) is longer than the step and
        // may leave the safe sphere: shortened once to the step's length when it would leave it
        // by more than the hit threshold (the march resolves nothing finer anyway).
        const double meanSpeed = 0.5 * (startSpeed + speed_);
        const double stepWorld = distanceWorld_ - outsideWorld_;
        if (attempt > 0 || meanSpeed * stepWorld <= stepTexels + epsilonTexels_) {
            samplePosition_ = glm::vec3(prism.texelAt(cursor_.point));
            pathSinceNewtonTexels_ = 0.0;
            return needsSample_ = true;
        }
        const double shorter = stepTexels / meanSpeed;
        detail::moveAlong(cursor_.point, prismVelocity_, -(stepWorld - shorter));
        distanceWorld_ = outsideWorld_ + shorter;
    }
}

bool CurvedMarchRay::leave(double atWorld) {
    end_.leftShell = true;
    end_.march.exitedFloor = true;
    end_.distanceWorld = atWorld;
    end_.lastInsideWorld = std::min(outsideWorld_, atWorld);
    end_.firstOutsideWorld = std::max(distanceWorld_, atWorld);
    end_.prism = cursor_.prism;
    end_.point = cursor_.point;
    return needsSample_ = false;
}

bool CurvedMarchRay::stop(bool converged) {
    const ShellPrism& prism = shell_->prisms[cursor_.prism];
    end_.march.texelPosition = glm::vec3(prism.texelAt(cursor_.point));
    end_.march.converged = converged;
    end_.march.travelTexels = float((distanceWorld_ - entryDistanceWorld_) * speed_);
    end_.distanceWorld = distanceWorld_;
    end_.prism = cursor_.prism;
    end_.point = cursor_.point;
    end_.texelsPerWorldAlongRay = float(speed_);
    return needsSample_ = false;
}

bool CurvedMarchRay::reachFloor(double toFloorTexels) {
    // Newton in the distance along the ray for the depth of the floor, from the linear estimate.
    detail::CurvedCursor cursor = cursor_;
    double floorWorld = distanceWorld_ + toFloorTexels / speed_;
    glm::dvec3 prismVelocity;
    for (int step = 0; step < 8; ++step) {
        if (detail::locate(*shell_, origin_, direction_, floorWorld, cursor) != Located::Inside)
            return false;
        const ShellPrism& prism = shell_->prisms[cursor.prism];
        const glm::dvec3 velocity =
            detail::texelVelocity(prism, cursor.jacobian, direction_, prismVelocity);
        const double below = prism.depthWorld - cursor.point.depthWorld;
        if (std::abs(below) <= 1e-9 * prism.depthWorld) {
            cursor.point.depthWorld = prism.depthWorld;
            cursor_ = cursor;
            distanceWorld_ = floorWorld;
            speed_ = glm::length(velocity);
            if (floor_ == Floor::Open) return !leave(floorWorld);
            end_.march.onFloor = true;
            stop(true);
            end_.march.texelPosition.z = 0.0f;
            return true;
        }
        if (!(prismVelocity.z > 0.0)) return false;
        floorWorld += below / prismVelocity.z;
    }
    return false;
}

bool CurvedMarchRay::refineStep(float distance) {
    if (std::abs(distance) < epsilonTexels_) return stop(true);
    if (distance > 0.0f) {
        outsideWorld_ = distanceWorld_;
        outsideTexels_ = distance;
    } else {
        insideWorld_ = distanceWorld_;
        insideTexels_ = distance;
    }
    return toEstimate();
}

bool CurvedMarchRay::toEstimate() {
    const double estimate = outsideWorld_ + (insideWorld_ - outsideWorld_) * outsideTexels_ /
                                                (outsideTexels_ - insideTexels_);
    // The guess: the current point moved along the velocity to the estimate; a chord step
    // there while the last Newton step is near, else Newton. The crossing is within the
    // bracket; should the estimate fall outside the shell (a rounding at its faces), the march
    // ends at the current point.
    detail::CurvedCursor at = cursor_;
    const double stepWorld = estimate - distanceWorld_;
    detail::moveAlong(at.point, prismVelocity_, stepWorld);
    const double pathTexels = std::abs(stepWorld) * speed_;
    const bool chord =
        pathSinceNewtonTexels_ + pathTexels <= detail::kChordPathTexels &&
        detail::chordStep(*shell_, origin_, direction_, estimate, at) == detail::Chord::Taken;
    if (!chord && detail::locate(*shell_, origin_, direction_, estimate, at) != Located::Inside)
        return stop(true);
    cursor_ = at;
    distanceWorld_ = estimate;
    const ShellPrism& prism = shell_->prisms[cursor_.prism];
    if (chord) {
        pathSinceNewtonTexels_ += pathTexels;
    } else {
        pathSinceNewtonTexels_ = 0.0;
        speed_ =
            glm::length(detail::texelVelocity(prism, cursor_.jacobian, direction_, prismVelocity_));
    }
    if (end_.march.iterations >= budget_) return stop(true);  // at the estimate, unsampled
    samplePosition_ = glm::vec3(prism.texelAt(cursor_.point));
    return true;
}

bool CurvedMarchRay::advance(float distance) {
    ++end_.march.iterations;
    if (refining_) return refineStep(distance);
    if (std::isnan(distance)) return leave(outsideWorld_);
    if (distance < epsilonTexels_) {
        if (distance < 0.0f && end_.march.iterations > 1) {
            // A step went past the surface (a budgeted step longer than the distance, or the
            // map's stretch growing along it): regula falsi between the last outside point and
            // this one.
            refining_ = true;
            insideWorld_ = distanceWorld_;
            insideTexels_ = distance;
            return toEstimate();
        }
        return stop(true);
    }
    const ShellPrism& prism = shell_->prisms[cursor_.prism];
    const double zTexels = prism.depthTexels - prism.texelsPerDepthWorld * cursor_.point.depthWorld;
    const double toFloorTexels = directionTexels_.z < 0.0
                                     ? std::max(zTexels, 0.0) / -directionTexels_.z
                                     : std::numeric_limits<double>::infinity();
    if (double(distance) >= toFloorTexels) {
        // The floor is nearer than the detail: the march ends there if the ray reaches it
        // (it may bend away before).
        if (reachFloor(toFloorTexels)) return false;
    }
    if (end_.march.iterations >= budget_) return stop(false);
    double stepTexels = distance;
    if (budgeted_) {
        // Toward where the last two samples point (march_wide.h): the last step's path in texels
        // at the speed here.
        stepTexels = std::max(
            stepTexels, detail::secantStepLanes<detail::OneLaneOf<double>>(
                            distance, outsideTexels_, (distanceWorld_ - outsideWorld_) * speed_));
        // The path left in the shell: to the floor while the ray descends, to the top once it
        // rises again (a ray through a convex shell turns).
        const double pathLeftTexels = directionTexels_.z > 0.0
                                          ? (prism.depthTexels - zTexels) / directionTexels_.z
                                          : toFloorTexels;
        const double minimum = pathLeftTexels / double(budget_ - end_.march.iterations);
        if (minimum > stepTexels) {
            stepTexels = minimum;
        }
    }
    stepTexels = std::min(stepTexels, toFloorTexels);
    outsideWorld_ = distanceWorld_;
    outsideTexels_ = distance;
    outsideDepthWorld_ = cursor_.point.depthWorld;
    const double stepWorld = stepTexels / speed_;
    distanceWorld_ += stepWorld;
    // The next point's guess: the current one moved along the ray's prism-space velocity.
    detail::moveAlong(cursor_.point, prismVelocity_, stepWorld);
    return prepareSample(stepTexels);
}

bool ShellRayPath::start(const ShellPrisms& shell, const glm::dvec3& originWorld,
                         const glm::dvec3& direction, std::uint32_t prism,
                         const PrismPoint& guess) {
    shell_ = &shell;
    origin_ = originWorld;
    direction_ = direction;
    cursor_.prism = prism;
    cursor_.point = guess;
    cursor_.originOffset = origin_ - shell.prisms[prism].corner0;
    distanceWorld_ = 0.0;
    pathSinceNewtonTexels_ = std::numeric_limits<double>::infinity();  // no Jacobian yet
    return settle();
}

bool ShellRayPath::advance(double texels) {
    const double stepWorld = texels / speed_;
    distanceWorld_ += stepWorld;
    pathSinceNewtonTexels_ += texels;
    PrismPoint& point = cursor_.point;
    detail::moveAlong(point, prismVelocity_, stepWorld);
    // Between corrections the point moves along the path's tangent in the prism; a correction
    // (Newton, a new velocity) every kStepsPerSettle steps, and wherever the point may have left
    // the prism.
    const ShellPrism& prism = shell_->prisms[cursor_.prism];
    if (++stepsSinceSettle_ < kStepsPerSettle && point.b1 >= 0.0 && point.b2 >= 0.0 &&
        point.b0() >= 0.0 && point.depthWorld >= 0.0 && point.depthWorld <= prism.depthWorld) {
        texelPosition_ = glm::vec3(prism.texelAt(point));
        return true;
    }
    return settle();
}

bool ShellRayPath::settle() {
    stepsSinceSettle_ = 0;
    // A chord step while the last Newton step is near (its velocity kept), as the camera rays'
    // march takes them.
    if (pathSinceNewtonTexels_ <= detail::kChordPathTexels &&
        detail::chordStep(*shell_, origin_, direction_, distanceWorld_, cursor_) ==
            detail::Chord::Taken) {
        texelPosition_ = glm::vec3(shell_->prisms[cursor_.prism].texelAt(cursor_.point));
        return true;
    }
    pathSinceNewtonTexels_ = 0.0;
    if (detail::locate(*shell_, origin_, direction_, distanceWorld_, cursor_) != Located::Inside)
        return false;
    const ShellPrism& prism = shell_->prisms[cursor_.prism];
    const glm::dvec3 velocity =
        detail::texelVelocity(prism, cursor_.jacobian, direction_, prismVelocity_);
    speed_ = glm::length(velocity);
    if (!(speed_ > 0.0 && std::isfinite(speed_))) return false;
    directionTexels_ = velocity * (1.0 / speed_);
    texelPosition_ = glm::vec3(prism.texelAt(cursor_.point));
    return true;
}

}  // namespace distile
