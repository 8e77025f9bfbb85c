// OpenVDB vdb_render peer (peers.h): the sheet's level set written to a .vdb, rendered by the
// vdb_render program with the scene's camera converted to texel space, read back as depth.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <glm/geometric.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/peers/peers.h"
#include "bench/peers/sheet.h"
#include "common/error.h"
#include "render/coverage.h"
#include "vdb/level_set.h"
#include "vdb/procedural.h"

extern char** environ;

namespace distile {

namespace {

namespace fs = std::filesystem;

const fs::path kVdbRender = "/usr/bin/vdb_render";
const fs::path kVdbPrint = "/usr/bin/vdb_print";
constexpr float kHalfBandTexels = 3.0f;  ///< OpenVDB's usual narrow band (LEVEL_SET_HALF_WIDTH)
constexpr double kPi = 3.14159265358979323846;

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string readText(const fs::path& file) {
    std::ifstream in(file);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

}  // namespace

std::string runProgram(const fs::path& program, const std::vector<std::string>& arguments,
                       const fs::path& workDir, const std::string& logName) {
    const fs::path out = workDir / (logName + ".stdout.txt");
    const fs::path err = workDir / (logName + ".stderr.txt");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<std::string> all{program.string()};
    all.insert(all.end(), arguments.begin(), arguments.end());
    std::vector<char*> argv;
    for (std::string& argument : all) argv.push_back(argument.data());
    argv.push_back(nullptr);
    pid_t child = 0;
    const int spawned =
        posix_spawn(&child, program.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (spawned != 0)
        throw std::runtime_error(program.string() + ": cannot start (" +
                                 std::string(std::strerror(spawned)) + ")");
    int status = 0;
    while (waitpid(child, &status, 0) < 0) {
        if (errno != EINTR) throw std::runtime_error(program.string() + ": waitpid failed");
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        std::string message = readText(err);
        while (!message.empty() && (message.back() == '\n' || message.back() == '\r'))
            message.pop_back();
        throw std::runtime_error(program.string() + " failed (" +
                                 (WIFEXITED(status)
                                      ? "exit status " + std::to_string(WEXITSTATUS(status))
                                      : std::string("killed by a signal")) +
                                 "): " + message);
    }
    return readText(out);
}

namespace {

/// The value after "key:" on a line of vdb_print's output, e.g. "file_bbox_min: [0, 0, -3]".
std::string printedValue(const std::string& printout, const std::string& key) {
    const std::size_t at = printout.find(key + ":");
    if (at == std::string::npos)
        throw std::runtime_error("vdb_print: no '" + key + "' in its output");
    const std::size_t begin = at + key.size() + 1;
    return printout.substr(begin, printout.find('\n', begin) - begin);
}

glm::dvec3 printedVector(const std::string& printout, const std::string& key) {
    std::string text = printedValue(printout, key);
    for (char& c : text)
        if (c == '[' || c == ']' || c == ',') c = ' ';
    std::istringstream in(text);
    glm::dvec3 value(0.0);
    if (!(in >> value.x >> value.y >> value.z))
        throw std::runtime_error("vdb_print: '" + key + "' is not a vector: " + text);
    return value;
}

/// Seconds vdb_render -v reports for the step announced by a line containing `step` ("reading",
/// "ray-tracing"): the "...completed in S sec" line that follows it.
double reportedSeconds(const std::string& verbose, const std::string& step) {
    const std::size_t announced = verbose.find(step);
    const std::string marker = "completed in ";
    const std::size_t completed =
        announced == std::string::npos ? announced : verbose.find(marker, announced);
    if (completed == std::string::npos)
        throw std::runtime_error("vdb_render -v: no time reported for " + step);
    return std::stod(verbose.substr(completed + marker.size()));
}

std::string vectorArgument(const glm::dvec3& v) {
    std::ostringstream text;
    text.precision(17);
    text << v.x << "," << v.y << "," << v.z;
    return text.str();
}

}  // namespace

PeerRender renderSheetWithVdbRender(const Scene& scene, int width, int height, int threads,
                                    const fs::path& workDir) {
    const std::string name = "vdb_render";
    detail::validatePeerRequest(width, height, threads);
    validateScene(scene);
    if (!fs::is_directory(workDir))
        throw InputError("vdb_render work folder '" + workDir.string() + "' is not a folder");
    for (const fs::path& program : {kVdbRender, kVdbPrint}) {
        if (access(program.c_str(), X_OK) != 0) {
            return detail::unavailablePeer(
                name, "not available: " + program.string() +
                          " is not installed (Debian package libopenvdb-tools)");
        }
    }
    auto found = detail::findSheet(scene);
    if (const auto* reason = std::get_if<std::string>(&found))
        return detail::unavailablePeer(name, *reason);
    const detail::SheetPlacement& sheet = std::get<detail::SheetPlacement>(found);
    const glm::dvec3 scale = sheet.texelsPerWorld;
    if (std::abs(scale.x - scale.z) > 1e-4 * scale.z ||
        std::abs(scale.y - scale.z) > 1e-4 * scale.z) {
        std::ostringstream reason;
        reason << "not available: texels are not cubes (" << scale.x << " x " << scale.y << " x "
               << scale.z << " texels per world unit along u, v, depth); a level set needs them";
        return detail::unavailablePeer(name, reason.str());
    }
    // The level set covers whole tiles: the uv rectangle must start and end on tile edges.
    const glm::dvec2 firstTile = sheet.uvMin * sheet.uvScale;
    const glm::dvec2 tileCount = (sheet.uvMax - sheet.uvMin) * sheet.uvScale;
    auto whole = [](double value) { return std::abs(value - std::round(value)) < 1e-4; };
    if (!whole(firstTile.x) || !whole(firstTile.y) || !whole(tileCount.x) || !whole(tileCount.y) ||
        std::round(tileCount.x) < 1 || std::round(tileCount.x) > 64 ||
        std::round(tileCount.y) < 1 || std::round(tileCount.y) > 64) {
        return detail::unavailablePeer(
            name, "not available: the base mesh's uv rectangle is not 1 to 64 whole tiles a side");
    }
    const int repeatX = int(std::round(tileCount.x));
    const int repeatY = int(std::round(tileCount.y));
    // Level-set texel space = sheet texel space shifted so the first tile starts at 0.
    const glm::dvec3 gridOrigin(std::round(firstTile.x) * sheet.tile.width,
                                std::round(firstTile.y) * sheet.tile.height, 0.0);

    PeerRender result;
    result.name = name;
    result.available = true;
    const auto setupStart = std::chrono::steady_clock::now();
    ProceduralOptions procedural;
    procedural.kind = ProceduralKind::Chainmail;
    procedural.chainmail = sheet.chainmail;
    const ProceduralDistance distance = proceduralDistance(procedural, sheet.tile);
    const fs::path levelSetFile = workDir / "sheet.vdb";
    LevelSet::fromDistance(distance.signedDistanceTexels, sheet.tile, kHalfBandTexels,
                           distance.source, distance.paramsJson)
        .repeated(repeatX, repeatY)
        .save(levelSetFile);
    result.setupSeconds = secondsSince(setupStart);

    // Position shader colour = (hit - bbox min) / bbox extent over the active voxels' bounding
    // box in the grid's world (= texel) space, where voxel (i, j, k) sits at (i, j, k) + 0.5.
    const std::string printout =
        runProgram(kVdbPrint, {"-m", levelSetFile.string()}, workDir, "vdb_print");
    const glm::dvec3 boxMin = printedVector(printout, "file_bbox_min") + 0.5;
    const glm::dvec3 boxExtent = printedVector(printout, "file_bbox_max") + 0.5 - boxMin;
    result.memoryBytes = std::stoull(printedValue(printout, "file_mem_bytes"));

    // The camera in texel space: a rotation and a uniform scale of the world, so angles and
    // pixel rays carry over; vdb_render's -fov is horizontal.
    const Camera& camera = scene.camera;
    auto toGrid = [&](const glm::vec3& world) {
        return sheet.texelFromWorld(glm::dvec3(world)) - gridOrigin;
    };
    const double tanHalfVertical = std::tan(0.5 * double(camera.fovDeg) * kPi / 180.0);
    const double horizontalFovDeg = 2.0 * std::atan(tanHalfVertical * width / height) * 180.0 / kPi;
    std::vector<std::string> arguments{levelSetFile.string(),
                                       "",
                                       "-res",
                                       std::to_string(width) + "x" + std::to_string(height),
                                       "-translate",
                                       vectorArgument(toGrid(camera.eye)),
                                       "-lookat",
                                       vectorArgument(toGrid(camera.target)),
                                       "-up",
                                       vectorArgument(sheet.texelDirection(glm::dvec3(camera.up))),
                                       "-fov",
                                       std::to_string(horizontalFovDeg),
                                       "-cpus",
                                       std::to_string(threads),
                                       "-compression",
                                       "none",
                                       "-shader",
                                       "position",
                                       "-v"};
    const fs::path positionFile = workDir / "position.exr";
    arguments[1] = positionFile.string();
    const std::string verbose = runProgram(kVdbRender, arguments, workDir, "vdb_render_position");
    result.setupSeconds += reportedSeconds(verbose, "reading");
    result.traceSeconds = reportedSeconds(verbose, "ray-tracing");
    const fs::path normalFile = workDir / "normal.exr";
    arguments[1] = normalFile.string();
    arguments[arguments.size() - 2] = "normal";
    runProgram(kVdbRender, arguments, workDir, "vdb_render_normal");

    const Image position = readImage(positionFile);
    const Image gridNormal = readImage(normalFile);
    if (position.width != width || position.height != height || gridNormal.width != width ||
        gridNormal.height != height) {
        throw std::runtime_error("vdb_render wrote images of another size than " +
                                 std::to_string(width) + "x" + std::to_string(height));
    }
    result.depth = Image(width, height);
    result.normal = Image(width, height);
    const glm::dvec3 eyeGrid = toGrid(camera.eye);
    const PinholeProjection projection(camera, width, height);
    const glm::dvec3 unitU = glm::normalize(sheet.worldPerU);
    const glm::dvec3 unitV = glm::normalize(sheet.worldPerV);
    for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
            const glm::dvec3 colour(position.at(x, y));
            if (colour == glm::dvec3(0.0)) continue;  // the background: a miss
            const glm::dvec3 hitGrid = boxMin + colour * boxExtent;
            result.depth.at(x, y) = glm::vec3(float(glm::length(hitGrid - eyeGrid) / scale.z));
            // Normal shader colour = n * 0.5 + 0.5 in texel space; texel axes are u, v, N.
            const glm::dvec3 n = glm::dvec3(gridNormal.at(x, y)) * 2.0 - 1.0;
            glm::vec3 normal(glm::normalize(unitU * n.x + unitV * n.y + sheet.normal * n.z));
            if (glm::dot(normal, projection.ray(x + 0.5f, y + 0.5f).direction) > 0.0f)
                normal = -normal;
            result.normal.at(x, y) = normal * 0.5f + 0.5f;
        }
    }
    return result;
}

}  // namespace distile
