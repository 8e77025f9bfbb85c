// loadBaseMesh: OBJ / OFF / PLY through OpenMesh, with the checks OpenMesh does not make.
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/error.h"
#include "mesh/base_mesh.h"

namespace distile {
namespace {

using OpenMeshPolygons = OpenMesh::PolyMesh_ArrayKernelT<>;

std::string lowercase(std::string text) {
    std::transform(text.begin(), text.end(), text.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return text;
}

std::vector<std::string_view> splitWhitespace(std::string_view line) {
    std::vector<std::string_view> tokens;
    std::size_t start = 0;
    while (start < line.size()) {
        while (start < line.size() && std::isspace(static_cast<unsigned char>(line[start]))) {
            ++start;
        }
        std::size_t end = start;
        while (end < line.size() && !std::isspace(static_cast<unsigned char>(line[end]))) ++end;
        if (end > start) tokens.push_back(line.substr(start, end - start));
        start = end;
    }
    return tokens;
}

/// What the OBJ check learned that the OpenMesh result is compared against afterwards.
struct ObjFacts {
    std::size_t faceCount = 0;  ///< faces whose corners are distinct vertices (OpenMesh keeps)
};

/// OpenMesh's OBJ reader accepts some broken files without a word: an out-of-range `vt` index
/// or a face corner without `vt` leaves that corner's UV uninitialised; a `v nan ...` line
/// makes its stream parsing fail and then indexes past the vertex array; an out-of-range
/// vertex index drops the face with only a log line. So every line that matters is checked
/// here first, with OBJ's rules (1-based indices, negative = relative to the end so far).
ObjFacts checkObjFile(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(file.string() + ": cannot open for reading");
    const std::string name = file.string();
    ObjFacts facts;
    long long positionCount = 0;
    long long uvCount = 0;
    std::string cornerWithoutUv;
    std::string line;
    for (std::size_t lineNumber = 1; std::getline(in, line); ++lineNumber) {
        const std::vector<std::string_view> tokens = splitWhitespace(line);
        if (tokens.empty()) continue;
        const std::string where = name + ": line " + std::to_string(lineNumber) + ": ";
        const std::string_view keyword = tokens[0];
        if (keyword == "v" || keyword == "vt") {
            const bool isPosition = keyword == "v";
            const std::size_t needed = isPosition ? 3 : 2;
            const std::string what = isPosition
                                         ? "vertex " + std::to_string(positionCount + 1)
                                         : "texture coordinate " + std::to_string(uvCount + 1);
            if (tokens.size() < needed + 1) {
                throw FormatError(where + what + " has " + std::to_string(tokens.size() - 1) +
                                  " numbers; expected " + std::to_string(needed));
            }
            for (std::size_t k = 1; k <= needed; ++k) {
                const std::string token(tokens[k]);
                char* end = nullptr;
                const double value = std::strtod(token.c_str(), &end);
                if (end != token.c_str() + token.size()) {
                    throw FormatError(where + what + " has '" + token + "'; expected a number");
                }
                if (!std::isfinite(value) || std::abs(value) > std::numeric_limits<float>::max()) {
                    throw FormatError(where + what + " has the non-finite value '" + token +
                                      "'; coordinates must be finite float numbers");
                }
            }
            (isPosition ? positionCount : uvCount) += 1;
        } else if (keyword == "f") {
            if (tokens.size() < 4) {
                throw FormatError(where + "face has " + std::to_string(tokens.size() - 1) +
                                  " corners; faces need at least 3");
            }
            std::vector<long long> vertices;
            for (std::size_t k = 1; k < tokens.size(); ++k) {
                const std::string_view corner = tokens[k];
                // Corner forms: v, v/vt, v//vn, v/vt/vn.
                const std::size_t slash = corner.find('/');
                const std::string_view vertexText = corner.substr(0, slash);
                std::string_view uvText;
                if (slash != std::string_view::npos) {
                    const std::size_t slash2 = corner.find('/', slash + 1);
                    uvText = corner.substr(slash + 1, slash2 == std::string_view::npos
                                                          ? std::string_view::npos
                                                          : slash2 - slash - 1);
                }
                auto resolve = [&](std::string_view text, long long count, const char* kind) {
                    long long index = 0;
                    const auto [end, error] =
                        std::from_chars(text.data(), text.data() + text.size(), index);
                    if (error != std::errc() || end != text.data() + text.size() || index == 0) {
                        throw FormatError(where + "face corner '" + std::string(corner) +
                                          "' has a bad " + kind +
                                          " index; expected a nonzero integer");
                    }
                    const long long resolved = index < 0 ? count + index + 1 : index;
                    if (resolved < 1 || resolved > count) {
                        throw FormatError(where + "face corner '" + std::string(corner) +
                                          "' refers to " + kind + " " + std::to_string(index) +
                                          "; only " + std::to_string(count) +
                                          " are defined above it");
                    }
                    return resolved;
                };
                vertices.push_back(resolve(vertexText, positionCount, "vertex"));
                if (uvText.empty()) {
                    // Reported at the end: a file without any vt gets the plainer message.
                    if (cornerWithoutUv.empty()) {
                        cornerWithoutUv = where + "face corner '" + std::string(corner) +
                                          "' has no texture coordinate; every corner needs v/vt";
                    }
                } else {
                    resolve(uvText, uvCount, "texture coordinate");
                }
            }
            std::sort(vertices.begin(), vertices.end());
            if (std::adjacent_find(vertices.begin(), vertices.end()) == vertices.end()) {
                ++facts.faceCount;
            }
        }
    }
    if (in.bad()) throw InputError(name + ": read error");
    if (uvCount == 0) {
        throw FormatError(name + ": has no texture coordinates (vt lines); base meshes need UVs");
    }
    if (!cornerWithoutUv.empty()) throw FormatError(cornerWithoutUv);
    return facts;
}

/// Redirects OpenMesh's global log streams for one read: omlog and omout are muted, and omerr's
/// output goes into a string so its complaints can become one FormatError; restored afterwards.
/// omerr is re-pointed at another stream buffer rather than reconnected: OpenMesh's
/// mostream::disconnect never frees the target connect allocated (a leak per load).
class OpenMeshLogCapture {
  public:
    OpenMeshLogCapture()
        : logWasEnabled_(omlog().is_enabled()),
          outWasEnabled_(omout().is_enabled()),
          previousErrBuffer_(omerr().rdbuf(&captured_)) {
        omlog().disable();
        omout().disable();
    }
    ~OpenMeshLogCapture() {
        omerr().rdbuf(previousErrBuffer_);
        if (logWasEnabled_) omlog().enable();
        if (outWasEnabled_) omout().enable();
    }
    OpenMeshLogCapture(const OpenMeshLogCapture&) = delete;
    OpenMeshLogCapture& operator=(const OpenMeshLogCapture&) = delete;

    /// The first captured line that reports a real failure. Non-manifold notices (OpenMesh then
    /// duplicates the vertices), dropped faces with repeated corners and material warnings are
    /// not failures.
    std::string firstFailure() const {
        std::istringstream lines(captured_.str());
        std::string line;
        while (std::getline(lines, line)) {
            const std::string lower = lowercase(line);
            for (const char* word : {"invalid", "error", "could not", "cannot", "can't"}) {
                if (lower.find(word) != std::string::npos) return line;
            }
        }
        return {};
    }

  private:
    std::stringbuf captured_;
    bool logWasEnabled_;
    bool outWasEnabled_;
    std::streambuf* previousErrBuffer_;
};

/// OpenMesh's log streams are process globals: one read at a time.
std::mutex& openMeshReadMutex() {
    static std::mutex mutex;
    return mutex;
}

}  // namespace

BaseMesh loadBaseMesh(const std::filesystem::path& file) {
    const std::string name = file.string();
    std::error_code error;
    if (!std::filesystem::exists(file, error)) throw InputError(name + ": no such file");
    if (!std::filesystem::is_regular_file(file, error)) {
        throw InputError(name + ": is not a regular file; expected a mesh file");
    }
    const std::string extension = lowercase(file.extension().string());
    if (extension != ".obj" && extension != ".off" && extension != ".ply") {
        throw FormatError(name + ": unsupported mesh format '" + file.extension().string() +
                          "'; accepted: .obj, .off, .ply");
    }
    ObjFacts objFacts;
    if (extension == ".obj") objFacts = checkObjFile(file);

    OpenMeshPolygons polygons;
    polygons.request_vertex_texcoords2D();
    polygons.request_halfedge_texcoords2D();
    OpenMesh::IO::Options options =
        OpenMesh::IO::Options::VertexTexCoord | OpenMesh::IO::Options::FaceTexCoord;
    {
        std::lock_guard<std::mutex> lock(openMeshReadMutex());
        OpenMeshLogCapture log;
        const bool readOk = OpenMesh::IO::read_mesh(polygons, name, options);
        const std::string failure = log.firstFailure();
        if (!readOk || !failure.empty()) {
            throw FormatError(name + ": OpenMesh cannot read it as " + extension.substr(1) +
                              (failure.empty() ? std::string() : " (" + failure + ")"));
        }
    }
    if (polygons.n_faces() == 0) {
        throw FormatError(name + (extension == ".obj"
                                      ? ": has no faces (f lines); expected a mesh"
                                      : ": has no faces OpenMesh could read; expected a mesh "
                                        "(NaN/Inf numbers also end up here)"));
    }
    if (extension == ".obj" && polygons.n_faces() < objFacts.faceCount) {
        throw FormatError(name + ": OpenMesh read only " + std::to_string(polygons.n_faces()) +
                          " of its " + std::to_string(objFacts.faceCount) + " faces");
    }
    const bool cornerUvs = options.face_has_texcoord();
    if (!cornerUvs && !options.vertex_has_texcoord()) {
        throw FormatError(name + ": has no texture coordinates" +
                          (extension == ".obj"   ? std::string(" (vt lines)")
                           : extension == ".off" ? std::string(" (STOFF header)")
                                                 : std::string(" (u, v vertex properties)")) +
                          "; base meshes need UVs");
    }
    for (const auto vertex : polygons.vertices()) {
        const auto& p = polygons.point(vertex);
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            throw FormatError(name + ": vertex " + std::to_string(vertex.idx()) +
                              " (counting from 0) has a NaN/Inf position; expected finite");
        }
    }

    // Split vertices per (OpenMesh vertex, uv): each OpenMesh vertex keeps a short list of the
    // distinct uvs seen at its corners and the BaseMesh vertex made for each.
    BaseMesh mesh;
    std::vector<std::vector<std::pair<glm::vec2, std::uint32_t>>> splits(polygons.n_vertices());
    auto baseVertex = [&](OpenMeshPolygons::HalfedgeHandle halfedge) {
        const auto vertex = polygons.to_vertex_handle(halfedge);
        const auto& texcoord =
            cornerUvs ? polygons.texcoord2D(halfedge) : polygons.texcoord2D(vertex);
        const glm::vec2 uv(texcoord[0], texcoord[1]);
        if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) {
            throw FormatError(name + ": vertex " + std::to_string(vertex.idx()) +
                              " (counting from 0) has a NaN/Inf texture coordinate; expected "
                              "finite");
        }
        auto& seen = splits[static_cast<std::size_t>(vertex.idx())];
        for (const auto& [knownUv, index] : seen) {
            if (knownUv == uv) return index;
        }
        const auto index = static_cast<std::uint32_t>(mesh.positions.size());
        const auto& p = polygons.point(vertex);
        mesh.positions.emplace_back(p[0], p[1], p[2]);
        mesh.uvs.push_back(uv);
        seen.emplace_back(uv, index);
        return index;
    };
    std::vector<std::uint32_t> corners;
    for (const auto face : polygons.faces()) {
        corners.clear();
        for (const auto halfedge : polygons.fh_range(face)) corners.push_back(baseVertex(halfedge));
        for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
            mesh.triangles.emplace_back(corners[0], corners[k], corners[k + 1]);
        }
    }
    computeTangentFrames(mesh);
    return mesh;
}

}  // namespace distile
