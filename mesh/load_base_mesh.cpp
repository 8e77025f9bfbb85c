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
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/error.h"
#include "mesh/base_mesh.h"
#include "mesh/detail_mesh.h"

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
/// `requireUvs` false (detail meshes): corners without `vt` and files without any are fine;
/// `vt` indices that are given must still be in range.
ObjFacts checkObjFile(const std::filesystem::path& file, bool requireUvs = true) {
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
                    if (!requireUvs) continue;
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
    if (!requireUvs) return facts;
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

/// Throws InputError unless `file` exists and is a regular file.
void requireMeshFile(const std::filesystem::path& file) {
    std::error_code error;
    if (!std::filesystem::exists(file, error)) throw InputError(file.string() + ": no such file");
    if (!std::filesystem::is_regular_file(file, error)) {
        throw InputError(file.string() + ": is not a regular file; expected a mesh file");
    }
}

/// OpenMesh's log streams are process globals: one read at a time.
std::mutex& openMeshReadMutex() {
    static std::mutex mutex;
    return mutex;
}

}  // namespace

BaseMesh loadBaseMesh(const std::filesystem::path& file) {
    const std::string name = file.string();
    requireMeshFile(file);
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

namespace {

/// Binary STL: 80-byte header, uint32 triangle count, 50 bytes per triangle. ASCII STL starts
/// with "solid" and is a text file; a binary file whose header happens to start with "solid" is
/// recognised by its exact size. Checks the size of binary files and the numbers of ASCII
/// `vertex` lines.
void checkStlFile(const std::filesystem::path& file) {
    const std::string name = file.string();
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(name + ": cannot open for reading");
    const std::uintmax_t size = std::filesystem::file_size(file);
    char header[84] = {};
    in.read(header, sizeof header);
    const bool startsWithSolid = in.gcount() >= 5 && std::string_view(header, 5) == "solid";
    std::uint32_t count = 0;
    if (in.gcount() == 84) {
        const auto* bytes = reinterpret_cast<const unsigned char*>(header + 80);
        count = std::uint32_t(bytes[0]) | std::uint32_t(bytes[1]) << 8 |
                std::uint32_t(bytes[2]) << 16 | std::uint32_t(bytes[3]) << 24;
    }
    const std::uintmax_t binarySize = 84 + 50 * std::uintmax_t(count);
    if (in.gcount() == 84 && size == binarySize) return;  // a complete binary STL
    if (!startsWithSolid) {
        throw FormatError(name + ": binary STL of " + std::to_string(size) + " bytes, but its " +
                          "header promises " + std::to_string(count) + " triangles (" +
                          std::to_string(binarySize) +
                          " bytes); the file is truncated or corrupted");
    }
    in.clear();
    in.seekg(0);
    std::string line;
    for (std::size_t lineNumber = 1; std::getline(in, line); ++lineNumber) {
        const std::vector<std::string_view> tokens = splitWhitespace(line);
        if (tokens.empty() || tokens[0] != "vertex") continue;
        if (tokens.size() != 4) {
            throw FormatError(name + ": line " + std::to_string(lineNumber) +
                              ": vertex needs 3 numbers");
        }
        for (std::size_t k = 1; k < 4; ++k) {
            const std::string token(tokens[k]);
            char* end = nullptr;
            const double value = std::strtod(token.c_str(), &end);
            if (end != token.c_str() + token.size() || !std::isfinite(value)) {
                throw FormatError(name + ": line " + std::to_string(lineNumber) + ": '" + token +
                                  "' is not a finite number");
            }
        }
    }
}

/// PLY: compares the data after `end_header` with what the header's elements promise: for
/// binary files at least the bytes of their fixed-size properties (lists counted with their
/// count field plus three entries, the least a face has), for ASCII files one line per element.
void checkPlyFile(const std::filesystem::path& file) {
    const std::string name = file.string();
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(name + ": cannot open for reading");
    const auto typeBytes = [&](std::string_view type) -> std::uintmax_t {
        if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
        if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
        if (type == "int" || type == "uint" || type == "int32" || type == "uint32" ||
            type == "float" || type == "float32") {
            return 4;
        }
        if (type == "double" || type == "float64") return 8;
        throw FormatError(name + ": PLY property type '" + std::string(type) + "' is unknown");
    };
    std::string line;
    std::getline(in, line);
    if (line.rfind("ply", 0) != 0) throw FormatError(name + ": does not start with 'ply'");
    bool ascii = false;
    std::uintmax_t elementCount = 0;  // all elements
    std::uintmax_t minimumBytes = 0;  // binary data the header promises at least
    std::uintmax_t currentCount = 0;
    bool headerEnded = false;
    while (std::getline(in, line)) {
        const std::vector<std::string_view> tokens = splitWhitespace(line);
        if (tokens.empty()) continue;
        if (tokens[0] == "end_header") {
            headerEnded = true;
            break;
        }
        if (tokens[0] == "format" && tokens.size() >= 2) ascii = tokens[1] == "ascii";
        if (tokens[0] == "element" && tokens.size() >= 3) {
            currentCount = 0;
            const auto [end, error] = std::from_chars(
                tokens[2].data(), tokens[2].data() + tokens[2].size(), currentCount);
            if (error != std::errc() || end != tokens[2].data() + tokens[2].size()) {
                throw FormatError(name + ": PLY element count '" + std::string(tokens[2]) +
                                  "' is not a number");
            }
            elementCount += currentCount;
        }
        if (tokens[0] == "property" && tokens.size() >= 3) {
            const std::uintmax_t bytes = tokens[1] == "list" && tokens.size() >= 5
                                             ? typeBytes(tokens[2]) + 3 * typeBytes(tokens[3])
                                             : typeBytes(tokens[1]);
            minimumBytes += bytes * currentCount;
        }
    }
    if (!headerEnded) throw FormatError(name + ": PLY header has no end_header");
    const std::uintmax_t dataStart = std::uintmax_t(in.tellg());
    const std::uintmax_t size = std::filesystem::file_size(file);
    if (!ascii) {
        if (size - dataStart < minimumBytes) {
            throw FormatError(name + ": PLY header promises " + std::to_string(elementCount) +
                              " elements (at least " + std::to_string(minimumBytes) +
                              " bytes) but only " + std::to_string(size - dataStart) +
                              " bytes follow it; the file is truncated");
        }
        return;
    }
    std::uintmax_t lines = 0;
    while (std::getline(in, line)) {
        if (!splitWhitespace(line).empty()) ++lines;
    }
    if (lines < elementCount) {
        throw FormatError(name + ": PLY header promises " + std::to_string(elementCount) +
                          " elements but only " + std::to_string(lines) +
                          " data lines follow it; the file is truncated");
    }
}

/// A vertex position exactly as read (positions are welded by exact equality).
struct PositionKey {
    float x, y, z;
    bool operator==(const PositionKey&) const = default;
};

struct PositionKeyHash {
    std::size_t operator()(const PositionKey& key) const {
        // +0.0 and -0.0 compare equal, so they must hash alike.
        const auto bits = [](float value) {
            return std::hash<float>{}(value == 0.0f ? 0.0f : value);
        };
        return bits(key.x) ^ (bits(key.y) * 0x9e3779b97f4a7c15ull) ^
               (bits(key.z) * 0xc2b2ae3d27d4eb4full);
    }
};

}  // namespace

TriangleSoup loadDetailMesh(const std::filesystem::path& file) {
    const std::string name = file.string();
    requireMeshFile(file);
    const std::string extension = lowercase(file.extension().string());
    ObjFacts objFacts;
    if (extension == ".obj") {
        objFacts = checkObjFile(file, /*requireUvs=*/false);
    } else if (extension == ".stl") {
        checkStlFile(file);
    } else if (extension == ".ply") {
        checkPlyFile(file);
    } else if (extension != ".off") {
        throw FormatError(name + ": unsupported mesh format '" + file.extension().string() +
                          "'; accepted: .obj, .ply, .off, .stl");
    }

    OpenMeshPolygons polygons;
    OpenMesh::IO::Options options;
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
        throw FormatError(name +
                          ": has no faces OpenMesh could read; expected a mesh "
                          "(NaN/Inf numbers also end up here)");
    }
    if (extension == ".obj" && polygons.n_faces() < objFacts.faceCount) {
        throw FormatError(name + ": OpenMesh read only " + std::to_string(polygons.n_faces()) +
                          " of its " + std::to_string(objFacts.faceCount) + " faces");
    }
    // Corners at identical positions become one vertex, whatever the format: OpenMesh merges
    // them for STL only, and an OBJ/PLY/OFF soup of unwelded corners would otherwise have no
    // shared edges at all.
    TriangleSoup soup;
    soup.positions.reserve(polygons.n_vertices());
    std::vector<std::uint32_t> weldedIndex(polygons.n_vertices());
    std::unordered_map<PositionKey, std::uint32_t, PositionKeyHash> firstAtPosition;
    firstAtPosition.reserve(polygons.n_vertices());
    for (const auto vertex : polygons.vertices()) {
        const auto& p = polygons.point(vertex);
        for (int axis = 0; axis < 3; ++axis) {
            if (!std::isfinite(p[axis]) || std::abs(double(p[axis])) > kMaxDetailCoordinate) {
                std::ostringstream message;
                message << name << ": vertex " << vertex.idx() << " (counting from 0) has the "
                        << "coordinate " << p[axis] << "; detail meshes need finite coordinates "
                        << "within +-" << kMaxDetailCoordinate;
                throw FormatError(message.str());
            }
        }
        const auto [entry, isNew] = firstAtPosition.try_emplace(
            PositionKey{p[0], p[1], p[2]}, std::uint32_t(soup.positions.size()));
        if (isNew) soup.positions.emplace_back(p[0], p[1], p[2]);
        weldedIndex[vertex.idx()] = entry->second;
    }
    std::vector<std::uint32_t> corners;
    for (const auto face : polygons.faces()) {
        corners.clear();
        for (const auto vertex : polygons.fv_range(face)) {
            corners.push_back(weldedIndex[vertex.idx()]);
        }
        for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
            // A triangle whose corners merged has no area (OpenMesh drops such STL faces too).
            const glm::uvec3 triangle(corners[0], corners[k], corners[k + 1]);
            if (triangle.x == triangle.y || triangle.y == triangle.z || triangle.z == triangle.x)
                continue;
            soup.triangles.push_back(triangle);
        }
    }
    return soup;
}

}  // namespace distile
