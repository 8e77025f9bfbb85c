// loadBaseMesh: OBJ / OFF / PLY through OpenMesh, with the checks OpenMesh does not make.
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <mutex>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/error.h"
#include "common/input_file.h"
#include "mesh/base_mesh.h"
#include "mesh/detail_mesh.h"
#include "mesh/polygon.h"

namespace distile {
namespace {

/// Memory one vertex or face of a mesh file takes once read, bytes: the faces and points as read
/// (with their uvs) and the loader's copies, with room to spare (an estimate, not a measurement). A
/// file's declared counts are checked against the memory budget with it.
constexpr std::uint64_t kBytesPerMeshElement = 256;

std::string lowercase(std::string text) {
    std::transform(text.begin(), text.end(), text.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return text;
}

/// The whitespace-separated tokens of `line`, into `tokens` (cleared first; reused from line to
/// line, so a long file is read without an allocation per line).
void splitWhitespace(std::string_view line, std::vector<std::string_view>& tokens) {
    // std::isspace's set in the C locale, inline (a library call per character was a tenth of
    // the check of a 1 M triangle OBJ).
    const auto space = [](char c) { return c == ' ' || (c >= '\t' && c <= '\r'); };
    tokens.clear();
    std::size_t start = 0;
    while (start < line.size()) {
        while (start < line.size() && space(line[start])) ++start;
        std::size_t end = start;
        while (end < line.size() && !space(line[end])) ++end;
        if (end > start) tokens.push_back(line.substr(start, end - start));
        start = end;
    }
}

std::vector<std::string_view> splitWhitespace(std::string_view line) {
    std::vector<std::string_view> tokens;
    splitWhitespace(line, tokens);
    return tokens;
}

/// Whether strtod reads the number `token` as hexadecimal ("0x1p3"), of which OpenMesh's streams
/// read only the leading "0" (and then the rest as the next value, or fail).
bool isHexadecimal(std::string_view token) {
    return token.find_first_of("xX") != std::string_view::npos;
}

/// What some Windows tools write at the start of a text file; OpenMesh's OBJ reader would take it
/// as part of the first line's keyword and skip the line.
constexpr std::string_view kUtf8ByteOrderMark = "\xEF\xBB\xBF";

/// OpenMesh's reader for `file` (its extension, lowercase, picks it) into `importer`; an OBJ is
/// read past a UTF-8 byte-order mark. False when the reader fails.
bool readWithOpenMesh(const std::filesystem::path& file, const std::string& extension,
                      OpenMesh::IO::BaseImporter& importer, OpenMesh::IO::Options& options) {
    if (extension != ".obj")
        return OpenMesh::IO::IOManager().read(file.string(), importer, options);
    std::ifstream in(file, std::ios::binary);
    if (!in) return false;
    char start[3] = {};
    in.read(start, 3);
    if (std::string_view(start, std::size_t(in.gcount())) != kUtf8ByteOrderMark) {
        in.clear();
        in.seekg(0);
    }
    return OpenMesh::IO::IOManager().read(in, ".obj", importer, options);
}

/// What the OBJ check learned that the OpenMesh result is compared against afterwards.
struct ObjFacts {
    std::size_t faceCount = 0;  ///< faces whose corners are distinct vertices (OpenMesh keeps)
};

/// OpenMesh's OBJ reader accepts some broken files without a word: an out-of-range `vt` index
/// or a face corner without `vt` leaves that corner's UV uninitialised; a `v nan ...` line
/// makes its stream parsing fail and then indexes past the vertex array; an out-of-range
/// vertex index drops the face with only a log line; a `v` line that its stream cannot read
/// whole (a hexadecimal number), or that starts with a form feed, is left out, so that the faces
/// after it index past the vertex array. So every line that matters is checked
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
    std::vector<std::string_view> tokens;
    std::vector<long long> vertices;
    for (std::size_t lineNumber = 1; std::getline(in, line); ++lineNumber) {
        if (lineNumber == 1 && line.starts_with(kUtf8ByteOrderMark)) line.erase(0, 3);
        splitWhitespace(line, tokens);
        if (tokens.empty()) continue;
        // Built only for a message: most lines of a large file have none.
        const auto where = [&] { return name + ": line " + std::to_string(lineNumber) + ": "; };
        const std::string_view keyword = tokens[0];
        if (keyword == "v" || keyword == "vt" || keyword == "f") {
            // OpenMesh skips a line whose first character after spaces and tabs is another
            // white-space one (a form feed, a vertical tab) as if it were a comment.
            const char first = line[line.find_first_not_of(" \t\r\n")];
            if (first == '\f' || first == '\v') {
                throw FormatError(where() + "the '" + std::string(keyword) +
                                  "' line starts with a form feed or vertical tab; OBJ lines "
                                  "start with their keyword");
            }
        }
        if (keyword == "v" || keyword == "vt") {
            const bool isPosition = keyword == "v";
            const std::size_t needed = isPosition ? 3 : 2;
            const auto what = [&] {
                return isPosition ? "vertex " + std::to_string(positionCount + 1)
                                  : "texture coordinate " + std::to_string(uvCount + 1);
            };
            if (tokens.size() < needed + 1) {
                throw FormatError(where() + what() + " has " + std::to_string(tokens.size() - 1) +
                                  " numbers; expected " + std::to_string(needed));
            }
            for (std::size_t k = 1; k <= needed; ++k) {
                // strtod reads from inside `line`, which is NUL-terminated and has whitespace or
                // its end after the token: it stops at the token's end if the token is a number.
                const std::string_view token = tokens[k];
                char* end = nullptr;
                const double value = std::strtod(token.data(), &end);
                // OpenMesh's stream drops a v line with a hexadecimal number.
                if (end != token.data() + token.size() || isHexadecimal(token)) {
                    throw FormatError(where() + what() + " has '" + quotedInput(token) +
                                      "'; expected a decimal number");
                }
                if (!std::isfinite(value) || std::abs(value) > std::numeric_limits<float>::max()) {
                    throw FormatError(where() + what() + " has the non-finite value '" +
                                      quotedInput(token) +
                                      "'; coordinates must be finite float numbers");
                }
            }
            (isPosition ? positionCount : uvCount) += 1;
        } else if (keyword == "f") {
            if (tokens.size() < 4) {
                throw FormatError(where() + "face has " + std::to_string(tokens.size() - 1) +
                                  " corners; faces need at least 3");
            }
            vertices.clear();
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
                        throw FormatError(where() + "face corner '" + quotedInput(corner) +
                                          "' has a bad " + kind +
                                          " index; expected a nonzero integer");
                    }
                    const long long resolved = index < 0 ? count + index + 1 : index;
                    if (resolved < 1 || resolved > count) {
                        throw FormatError(where() + "face corner '" + quotedInput(corner) +
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
                        cornerWithoutUv = where() + "face corner '" + quotedInput(corner) +
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
    requireWithinMemoryBudget(
        file,
        "OBJ of " + std::to_string(positionCount) + " vertices and " +
            std::to_string(facts.faceCount) + " faces",
        saturatingProduct(std::uint64_t(positionCount + uvCount) + facts.faceCount,
                          kBytesPerMeshElement));
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
                if (lower.find(word) != std::string::npos) return quotedInput(line, 160);
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

/// What OpenMesh's readers (OBJ, PLY, OFF, STL) find in a file, kept as they hand it over: the
/// points, each face's corners and, when asked, the texture coordinates, without the halfedge
/// connectivity a PolyMesh builds. Neither mesh needs it (it took 60% of the read of a 1 M
/// triangle OBJ), and building it fails on an edge of three faces or a face wound against its
/// neighbours: OpenMesh then re-adds the face on copies of its vertices, and hands that face's
/// corner uvs over rotated by one corner (OBJ) or not at all (PLY, OFF). Normals and colours are
/// dropped.
class SoupImporter final : public OpenMesh::IO::BaseImporter {
  public:
    explicit SoupImporter(bool keepUvs) : keepUvs_(keepUvs) {}

    std::vector<OpenMesh::Vec3f> points;
    std::vector<std::uint32_t> corners;         ///< the faces' vertex indices, face after face
    std::vector<std::size_t> faceStarts = {0};  ///< face f: corners [faceStarts[f], [f + 1])
    /// The first vertex index a face gave that is not a vertex of the file (the face is left out).
    std::optional<int> firstInvalidCorner;
    /// With keepUvs: each vertex's uv (PLY, OFF and OBJ give them; (0, 0) where none is given).
    std::vector<OpenMesh::Vec2f> vertexUvs;
    /// With keepUvs: each corner's uv, for the faces the file gives them to (OBJ `f v/vt`); the
    /// other faces take their vertices' uvs.
    std::vector<OpenMesh::Vec2f> cornerUvs;
    std::vector<bool> faceHasUvs;

    std::size_t faceCount() const { return faceStarts.size() - 1; }
    /// Face f's vertex indices, in order.
    std::span<const std::uint32_t> faceCorners(std::size_t face) const {
        return std::span(corners).subspan(faceStarts[face],
                                          faceStarts[face + 1] - faceStarts[face]);
    }

    OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3f& point) override {
        points.push_back(point);
        if (keepUvs_) {
            vertexUvs.emplace_back(0.0f, 0.0f);
        }
        return OpenMesh::VertexHandle(int(points.size() - 1));
    }
    OpenMesh::VertexHandle add_vertex() override { return add_vertex(OpenMesh::Vec3f(0.0f)); }
    OpenMesh::FaceHandle add_face(const VHandles& vertices) override {
        for (const OpenMesh::VertexHandle vertex : vertices) {
            if (!vertex.is_valid() || std::size_t(vertex.idx()) >= points.size()) {
                if (!firstInvalidCorner) firstInvalidCorner = vertex.idx();
                return OpenMesh::FaceHandle();
            }
        }
        for (const OpenMesh::VertexHandle vertex : vertices)
            corners.push_back(std::uint32_t(vertex.idx()));
        faceStarts.push_back(corners.size());
        if (keepUvs_) {
            cornerUvs.resize(corners.size(), OpenMesh::Vec2f(0.0f, 0.0f));
            faceHasUvs.push_back(false);
        }
        return OpenMesh::FaceHandle(int(faceCount() - 1));
    }
    void set_point(OpenMesh::VertexHandle vertex, const OpenMesh::Vec3f& point) override {
        if (vertex.is_valid() && std::size_t(vertex.idx()) < points.size())
            points[std::size_t(vertex.idx())] = point;
    }
    void reserve(unsigned int vertices, unsigned int, unsigned int faces) override {
        points.reserve(vertices);
        faceStarts.reserve(std::size_t(faces) + 1);
    }
    std::size_t n_vertices() const override { return points.size(); }
    std::size_t n_faces() const override { return faceCount(); }
    std::size_t n_edges() const override { return 0; }

    // What a detail mesh does not keep.
    OpenMesh::HalfedgeHandle add_edge(OpenMesh::VertexHandle, OpenMesh::VertexHandle) override {
        return OpenMesh::HalfedgeHandle();
    }
    OpenMesh::FaceHandle add_face(OpenMesh::HalfedgeHandle) override {
        return OpenMesh::FaceHandle();
    }
    /// The uvs of face `face`'s corners in order, from its corner at `first`.
    void add_face_texcoords(OpenMesh::FaceHandle face, OpenMesh::VertexHandle first,
                            const std::vector<OpenMesh::Vec2f>& uvs) override {
        if (!keepUvs_ || uvs.empty() || !face.is_valid() || std::size_t(face.idx()) >= faceCount())
            return;
        const std::size_t f = std::size_t(face.idx());
        const std::size_t begin = faceStarts[f], count = faceStarts[f + 1] - begin;
        const auto start =
            std::find(corners.begin() + std::ptrdiff_t(begin),
                      corners.begin() + std::ptrdiff_t(begin + count), std::uint32_t(first.idx()));
        // A vertex named at two corners of an OBJ face is left out of the face (its first corner
        // kept) but not out of the uvs: the face then takes its vertices' uvs.
        if (uvs.size() != count || start == corners.begin() + std::ptrdiff_t(begin + count)) return;
        const std::size_t offset = std::size_t(start - corners.begin()) - begin;
        for (std::size_t k = 0; k < count; ++k) cornerUvs[begin + (offset + k) % count] = uvs[k];
        faceHasUvs[f] = true;
    }
    void set_texcoord(OpenMesh::VertexHandle vertex, const OpenMesh::Vec2f& uv) override {
        if (!keepUvs_ || !vertex.is_valid() || std::size_t(vertex.idx()) >= points.size()) return;
        vertexUvs[std::size_t(vertex.idx())] = uv;
    }
    void add_face_texcoords(OpenMesh::FaceHandle, OpenMesh::VertexHandle,
                            const std::vector<OpenMesh::Vec3f>&) override {}
    void set_face_texindex(OpenMesh::FaceHandle, int) override {}
    void set_halfedge(OpenMesh::VertexHandle, OpenMesh::HalfedgeHandle) override {}
    void set_normal(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
    void set_normal(OpenMesh::VertexHandle, const OpenMesh::Vec3d&) override {}
    void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec3uc&) override {}
    void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec4uc&) override {}
    void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
    void set_color(OpenMesh::VertexHandle, const OpenMesh::Vec4f&) override {}
    void set_status(OpenMesh::VertexHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_next(OpenMesh::HalfedgeHandle, OpenMesh::HalfedgeHandle) override {}
    void set_face(OpenMesh::HalfedgeHandle, OpenMesh::FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(OpenMesh::HalfedgeHandle, const OpenMesh::Vec2f&) override {}
    void set_texcoord(OpenMesh::VertexHandle, const OpenMesh::Vec3f&) override {}
    void set_texcoord(OpenMesh::HalfedgeHandle, const OpenMesh::Vec3f&) override {}
    void set_status(OpenMesh::HalfedgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec3uc&) override {}
    void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec4uc&) override {}
    void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec3f&) override {}
    void set_color(OpenMesh::EdgeHandle, const OpenMesh::Vec4f&) override {}
    void set_status(OpenMesh::EdgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_normal(OpenMesh::FaceHandle, const OpenMesh::Vec3f&) override {}
    void set_normal(OpenMesh::FaceHandle, const OpenMesh::Vec3d&) override {}
    void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec3uc&) override {}
    void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec4uc&) override {}
    void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec3f&) override {}
    void set_color(OpenMesh::FaceHandle, const OpenMesh::Vec4f&) override {}
    void set_status(OpenMesh::FaceHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void add_texture_information(int, std::string) override {}

  private:
    bool keepUvs_;
};

/// Reads `file` with OpenMesh's reader for `extension` into `read` (`options` in and out), one
/// read at a time, with the checks every mesh file gets: a face naming a missing vertex (before
/// OpenMesh's own line for it, which says less), a failure OpenMesh logs, no face at all
/// (`noFacesHint` follows "has no faces OpenMesh could read"), and an OBJ of which OpenMesh read
/// fewer faces than the check counted (`objFacts`).
void readSoup(const std::filesystem::path& file, const std::string& extension,
              const ObjFacts& objFacts, const std::string& noFacesHint, SoupImporter& read,
              OpenMesh::IO::Options& options) {
    const std::string name = file.string();
    {
        std::lock_guard<std::mutex> lock(openMeshReadMutex());
        OpenMeshLogCapture log;
        const bool readOk = readWithOpenMesh(file, extension, read, options);
        const std::string failure = log.firstFailure();
        if (read.firstInvalidCorner) {
            throw FormatError(name + ": a face refers to vertex " +
                              std::to_string(*read.firstInvalidCorner) +
                              " (counting from 0); the file has " +
                              std::to_string(read.points.size()) + " vertices");
        }
        if (!readOk || !failure.empty()) {
            throw FormatError(name + ": OpenMesh cannot read it as " + extension.substr(1) +
                              (failure.empty() ? std::string() : " (" + failure + ")"));
        }
    }
    if (read.faceCount() == 0)
        throw FormatError(name + ": has no faces OpenMesh could read" + noFacesHint);
    if (extension == ".obj" && read.faceCount() < objFacts.faceCount) {
        throw FormatError(name + ": OpenMesh read only " + std::to_string(read.faceCount()) +
                          " of its " + std::to_string(objFacts.faceCount) + " faces");
    }
}

/// Splits the faces of one mesh file into triangles (triangulatePolygon), within one budget.
class PolygonSplitter {
  public:
    explicit PolygonSplitter(std::string fileName) : fileName_(std::move(fileName)) {}

    /// Face `face`'s triangles as triples of its corner numbers (0 ... corners.size() - 1);
    /// `corners` are indices into `points`. Valid until the next call.
    /// @throws FormatError a concave polygon beyond the budget (naming the face).
    const std::vector<std::array<std::uint32_t, 3>>& split(
        std::size_t face, const std::vector<OpenMesh::Vec3f>& points,
        std::span<const std::uint32_t> corners) {
        triangles_.clear();
        if (corners.size() == 3) {  // most faces: no positions to copy
            triangles_.push_back({0, 1, 2});
            return triangles_;
        }
        positions_.clear();
        for (const std::uint32_t corner : corners) {
            const OpenMesh::Vec3f& p = points[corner];
            positions_.emplace_back(p[0], p[1], p[2]);
        }
        if (!triangulatePolygon(positions_, triangles_, budget_)) {
            throw FormatError(fileName_ + ": face " + std::to_string(face) +
                              " (counting from 0) is a concave polygon of " +
                              std::to_string(corners.size()) +
                              " corners; splitting it into triangles (with the concave polygons "
                              "before it) takes more than the " +
                              std::to_string(PolygonTriangulationBudget{}.testsLeft) +
                              " corner tests distile spends on one file: split it into smaller "
                              "polygons");
        }
        return triangles_;
    }

  private:
    std::string fileName_;
    PolygonTriangulationBudget budget_;
    std::vector<glm::dvec3> positions_;
    std::vector<std::array<std::uint32_t, 3>> triangles_;
};

/// The most corners a polygon of a mesh file may have.
constexpr std::uint64_t kMaxPolygonCorners = 65536;

/// A token of a text mesh file, read without allocating more than a number needs.
class TextTokens {
  public:
    TextTokens(std::istream& in, const std::string& name) : in_(in), name_(name) {}

    /// The next whitespace-separated token; empty at the end of the file.
    std::string_view next() {
        token_.clear();
        int c = in_.get();
        while (c != EOF && std::isspace(c)) c = in_.get();
        while (c != EOF && !std::isspace(c)) {
            if (token_.size() == kMaxTokenLength) {
                throw FormatError(name_ + ": '" + quotedInput(token_) +
                                  "' is too long for a number; the file is corrupted");
            }
            token_ += char(c);
            c = in_.get();
        }
        endedLine_ = c == '\n';
        return token_;
    }

    /// Whether the character read after the last token ended its line.
    bool endedLine() const { return endedLine_; }

  private:
    static constexpr std::size_t kMaxTokenLength = 64;
    std::istream& in_;
    const std::string& name_;
    std::string token_;
    bool endedLine_ = false;
};

/// `token` as a decimal number, or nothing when it is not one (the whole token must be a number).
std::optional<double> numberIn(std::string_view token) {
    const std::string text(token);
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size() || isHexadecimal(text))
        return std::nullopt;
    return value;
}

/// A PLY property's value type: its size in a binary file and the range of its values.
struct PlyType {
    std::uint64_t bytes = 4;
    bool isFloat = false;
    bool isSigned = false;
};

PlyType plyType(std::string_view type, const std::string& name) {
    if (type == "char" || type == "int8") return {1, false, true};
    if (type == "uchar" || type == "uint8") return {1, false, false};
    if (type == "short" || type == "int16") return {2, false, true};
    if (type == "ushort" || type == "uint16") return {2, false, false};
    if (type == "int" || type == "int32") return {4, false, true};
    if (type == "uint" || type == "uint32") return {4, false, false};
    if (type == "float" || type == "float32") return {4, true, true};
    if (type == "double" || type == "float64") return {8, true, true};
    throw FormatError(name + ": PLY property type '" + quotedInput(type) + "' is unknown");
}

struct PlyProperty {
    PlyType value;
    bool isList = false;
    PlyType count;  ///< the type of a list's item count
};

struct PlyElement {
    std::string name;
    std::uint64_t count = 0;
    std::vector<PlyProperty> properties;
};

/// Reads PLY values, ASCII or binary, checking each against its type as OpenMesh would need it.
class PlyValues {
  public:
    PlyValues(std::istream& in, const std::string& name, bool ascii, bool bigEndian)
        : in_(in), name_(name), ascii_(ascii), bigEndian_(bigEndian), tokens_(in, name) {}

    /// The next value of `type` in element `element` (for messages); FormatError when the file
    /// ends, the value is not a number of that type, or a float is out of its type's range.
    double read(const PlyType& type, const PlyElement& element, std::uint64_t item) {
        return ascii_ ? readText(type, element, item) : readBinary(type, element, item);
    }

  private:
    double readText(const PlyType& type, const PlyElement& element, std::uint64_t item) {
        const std::string_view token = tokens_.next();
        if (token.empty()) truncated(element, item);
        const std::optional<double> value = numberIn(token);
        const double limit = type.bytes == 8 ? std::numeric_limits<double>::max()
                                             : double(std::numeric_limits<float>::max());
        if (!value || !std::isfinite(*value) || std::abs(*value) > limit) {
            throw FormatError(name_ + ": PLY " + where(element, item) + " has '" +
                              quotedInput(token) + "'; expected a finite " +
                              (type.bytes == 8 ? "double"
                               : type.isFloat  ? "float"
                                               : "integer") +
                              " number");
        }
        if (!type.isFloat) {
            // OpenMesh's stream reads "3.0" or "1e2" as an integer up to its '.' or 'e', and the
            // rest as the next value.
            if (token.find_first_of(".eE") != std::string_view::npos) {
                throw FormatError(name_ + ": PLY " + where(element, item) + " has '" +
                                  quotedInput(token) + "'; expected a decimal integer");
            }
            const double bits = double(type.bytes * 8);
            const double lowest = type.isSigned ? -std::exp2(bits - 1) : 0.0;
            const double highest = type.isSigned ? std::exp2(bits - 1) - 1 : std::exp2(bits) - 1;
            if (*value != std::floor(*value) || *value < lowest || *value > highest) {
                throw FormatError(name_ + ": PLY " + where(element, item) + " has '" +
                                  quotedInput(token) + "'; expected an integer in [" +
                                  std::to_string((long long)lowest) + ", " +
                                  std::to_string((long long)highest) + "]");
            }
        }
        return *value;
    }

    double readBinary(const PlyType& type, const PlyElement& element, std::uint64_t item) {
        unsigned char bytes[8] = {};
        in_.read(reinterpret_cast<char*>(bytes), std::streamsize(type.bytes));
        if (std::uint64_t(in_.gcount()) != type.bytes) truncated(element, item);
        if (bigEndian_) std::reverse(bytes, bytes + type.bytes);
        std::uint64_t bits = 0;
        for (std::uint64_t k = 0; k < type.bytes; ++k) bits |= std::uint64_t(bytes[k]) << (8 * k);
        if (type.isFloat) {
            return type.bytes == 8 ? std::bit_cast<double>(bits)
                                   : double(std::bit_cast<float>(std::uint32_t(bits)));
        }
        if (!type.isSigned) return double(bits);
        const std::uint64_t sign = std::uint64_t(1) << (type.bytes * 8 - 1);
        return bits & sign ? double(std::int64_t(bits) - std::int64_t(sign << 1)) : double(bits);
    }

    static std::string where(const PlyElement& element, std::uint64_t item) {
        return element.name + " " + std::to_string(item);
    }

    [[noreturn]] void truncated(const PlyElement& element, std::uint64_t item) const {
        throw FormatError(name_ + ": PLY data ends inside " + where(element, item) +
                          "; the file is truncated");
    }

    std::istream& in_;
    const std::string& name_;
    bool ascii_;
    bool bigEndian_;
    TextTokens tokens_;
};

/// PLY: reads the header, checks each element's declared count against the bytes after
/// `end_header` (in a binary file each item takes at least its fixed-size properties and list
/// counts, in an ASCII file a character and a separator per property) and against the memory
/// budget, in overflow-safe arithmetic, then reads every value: OpenMesh's ASCII reader leaves
/// uninitialised memory behind a number out of its type's range (a float coordinate of -1e308),
/// and a list's item count must be followed by that many values.
void checkPlyFile(const std::filesystem::path& file) {
    const std::string name = file.string();
    const std::uint64_t fileBytes = std::filesystem::file_size(file);
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(name + ": cannot open for reading");
    std::string line;
    std::getline(in, line);
    if (line.rfind("ply", 0) != 0) throw FormatError(name + ": does not start with 'ply'");
    std::string format, formatVersion;
    bool firstLine = true;
    std::vector<PlyElement> elements;
    bool headerEnded = false;
    // Header lines are short; a "line" of megabytes is not a PLY header.
    constexpr std::size_t kMaxHeaderLine = 4096;
    while (std::getline(in, line)) {
        if (line.size() > kMaxHeaderLine) {
            throw FormatError(name + ": PLY header line of " + std::to_string(line.size()) +
                              " bytes; the file is corrupted");
        }
        const std::vector<std::string_view> tokens = splitWhitespace(line);
        if (tokens.empty()) continue;
        // Only the header lines PLY defines, well formed and printable: OpenMesh's header parser
        // loops without end (gigabytes in seconds) on some malformed ones.
        const bool printable = std::all_of(line.begin(), line.end(), [](char c) {
            return (c >= 0x20 && c < 0x7f) || c == '\t' || c == '\r';
        });
        const bool wellFormed =
            tokens[0] == "comment" || tokens[0] == "obj_info" ||
            (tokens[0] == "end_header" && tokens.size() == 1) ||
            (tokens[0] == "format" && tokens.size() == 3) ||
            (tokens[0] == "element" && tokens.size() == 3) ||
            (tokens[0] == "property" &&
             (tokens.size() == 3 || (tokens.size() == 5 && tokens[1] == "list")));
        if (!printable || !wellFormed) {
            throw FormatError(name + ": PLY header line '" + quotedInput(line) +
                              "' is not one PLY defines (format, element, property, comment, "
                              "obj_info, end_header); the file is corrupted");
        }
        // OpenMesh reads the header as words, not lines: the words of an obj_info line are
        // keywords to it ("comment" ends the line, as the line ends here). An "element" there
        // took the next line's first word for its count and looped without end.
        if (tokens[0] == "obj_info") {
            for (std::size_t word = 1; word < tokens.size(); ++word) {
                if (tokens[word] == "element" || tokens[word] == "property" ||
                    tokens[word] == "end_header") {
                    throw FormatError(name + ": PLY header line '" + quotedInput(line) +
                                      "': OpenMesh reads the words of an obj_info line as header "
                                      "keywords, and '" +
                                      std::string(tokens[word]) + "' may not be one of them");
                }
                if (tokens[word] == "comment") break;
            }
        }
        if (tokens[0] == "end_header") {
            headerEnded = true;
            break;
        }
        // One format line, the first after "ply" as PLY places it: OpenMesh loops without end on
        // a second one.
        if ((tokens[0] == "format") != firstLine) {
            throw FormatError(name + ": PLY header line '" + quotedInput(line) +
                              "': the format line must come once, right after 'ply'");
        }
        firstLine = false;
        if (tokens[0] == "format") {
            format = std::string(tokens[1]);
            formatVersion = std::string(tokens[2]);
        }
        if (tokens[0] == "element" && tokens.size() >= 3) {
            PlyElement element;
            element.name = quotedInput(tokens[1]);
            const auto [end, error] = std::from_chars(
                tokens[2].data(), tokens[2].data() + tokens[2].size(), element.count);
            if (error != std::errc() || end != tokens[2].data() + tokens[2].size()) {
                throw FormatError(name + ": PLY element count '" + quotedInput(tokens[2]) +
                                  "' is not a number");
            }
            elements.push_back(std::move(element));
        }
        if (tokens[0] == "property" && tokens.size() >= 3) {
            if (elements.empty()) throw FormatError(name + ": PLY property before any element");
            PlyProperty property;
            if (tokens[1] == "list") {
                if (tokens.size() < 5)
                    throw FormatError(name + ": PLY list property needs two types");
                property.isList = true;
                property.count = plyType(tokens[2], name);
                property.value = plyType(tokens[3], name);
                if (property.count.isFloat) {
                    throw FormatError(name + ": PLY list count type '" + quotedInput(tokens[2]) +
                                      "' is not an integer type");
                }
            } else {
                property.value = plyType(tokens[1], name);
            }
            elements.back().properties.push_back(property);
        }
    }
    if (!headerEnded) throw FormatError(name + ": PLY header has no end_header");
    if (std::none_of(elements.begin(), elements.end(),
                     [](const PlyElement& element) { return element.name == "vertex"; })) {
        throw FormatError(name + ": PLY header declares no vertex element");
    }
    if (formatVersion != "1.0") {
        throw FormatError(name + ": PLY format version '" + quotedInput(formatVersion) +
                          "' is not accepted; only 1.0");
    }
    const bool ascii = format == "ascii";
    if (!ascii && format != "binary_little_endian" && format != "binary_big_endian") {
        throw FormatError(name + ": PLY format '" + quotedInput(format) +
                          "' is unknown; accepted: ascii, binary_little_endian, binary_big_endian");
    }
    const std::uint64_t dataStart = std::uint64_t(in.tellg());
    const std::uint64_t dataBytes = fileBytes - std::min(fileBytes, dataStart);
    std::uint64_t allElements = 0;
    for (const PlyElement& element : elements) {
        std::uint64_t leastBytes = 0;
        for (const PlyProperty& property : element.properties) {
            leastBytes += ascii ? 2 : property.isList ? property.count.bytes : property.value.bytes;
        }
        requireDeclaredCount(file, "PLY element '" + element.name + "'", element.count, leastBytes,
                             dataBytes, kBytesPerMeshElement);
        allElements = saturatingSum(allElements, element.count);
    }
    requireWithinMemoryBudget(file, "PLY elements, " + std::to_string(allElements) + " in all,",
                              saturatingProduct(allElements, kBytesPerMeshElement));

    PlyValues values(in, name, ascii, format == "binary_big_endian");
    for (const PlyElement& element : elements) {
        for (std::uint64_t item = 0; item < element.count; ++item) {
            for (const PlyProperty& property : element.properties) {
                if (!property.isList) {
                    values.read(property.value, element, item);
                    continue;
                }
                const double corners = values.read(property.count, element, item);
                if (!(corners >= 0.0 && corners <= double(kMaxPolygonCorners))) {
                    throw FormatError(name + ": PLY " + element.name + " " + std::to_string(item) +
                                      " has a list of " + std::to_string((long long)corners) +
                                      " values; accepted: 0 to " +
                                      std::to_string(kMaxPolygonCorners));
                }
                for (std::uint64_t k = 0; k < std::uint64_t(corners); ++k)
                    values.read(property.value, element, item);
            }
        }
    }
}

/// The unsigned 32-bit little-endian integer at `bytes`.
std::uint32_t littleEndianWord(const unsigned char* bytes) {
    return std::uint32_t(bytes[0]) | std::uint32_t(bytes[1]) << 8 | std::uint32_t(bytes[2]) << 16 |
           std::uint32_t(bytes[3]) << 24;
}

/// The next 4 bytes of `in` as a littleEndianWord, or nothing when the file ends before them.
std::optional<std::uint32_t> readLittleEndianWord(std::istream& in) {
    unsigned char bytes[4] = {};
    in.read(reinterpret_cast<char*>(bytes), 4);
    if (in.gcount() != 4) return std::nullopt;
    return littleEndianWord(bytes);
}

/// `token` as OpenMesh's stream reads an unsigned int, or nothing when it would read another
/// value or fail: decimal digits only, at most UINT32_MAX.
std::optional<std::uint32_t> unsignedIn(std::string_view token) {
    std::uint32_t value = 0;
    const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (token.empty() || error != std::errc() || end != token.data() + token.size())
        return std::nullopt;
    return value;
}

/// `token` as OpenMesh's stream reads a float, or nothing when it would read another value or
/// fail: a finite decimal number within a float's range.
std::optional<double> floatIn(std::string_view token) {
    const std::optional<double> number = numberIn(token);
    if (!number || !std::isfinite(*number) ||
        std::abs(*number) > double(std::numeric_limits<float>::max()))
        return std::nullopt;
    return number;
}

/// OFF, ASCII or "OFF BINARY", checked as OpenMesh's reader will read it, so that what it reads
/// is what was checked. First the counts, against the file's size and the memory budget, before
/// OpenMesh allocates for them. OpenMesh then reads an ASCII body as a stream of numbers, not
/// line by line: a vertex's 3 coordinates (and 3 normal components in an NOFF), the rest of its
/// line (colours, texture coordinates), then each face's corner count and that many indices (and
/// the rest of its line only for the colours of a COFF). A line with a number too many or too
/// few, or a comment, would shift every number after it (a corner count of 4 billion read from a
/// coordinate: gigabytes of indices); so here each must stand where OpenMesh looks for it:
/// - the counts: exactly the vertex, face and edge counts, the line ending after them;
/// - no comments in the body;
/// - a vertex: a line of at least 3 numbers (and 3 more in an NOFF, 2 more in an STOFF: its
///   texture coordinates, else left unset), all finite decimal numbers within a float's range
///   (OpenMesh's stream reads neither hexadecimal nor a float's overflow);
/// - a face: a line of a corner count and that many vertex indices, unsigned decimal integers,
///   and nothing more unless the file has colours (COFF).
/// A binary body is walked as OpenMesh reads it: 3 floats a vertex (and 3 for normals, 2 for
/// texture coordinates), a corner count and its indices a face; binary colours are refused
/// (OpenMesh reads them as floats or bytes by an option of the caller's, not of the file's).
void checkOffFile(const std::filesystem::path& file) {
    const std::string name = file.string();
    const std::uint64_t fileBytes = std::filesystem::file_size(file);
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(name + ": cannot open for reading");
    TextTokens tokens(in, name);
    const std::string keyword(tokens.next());
    if (keyword.size() < 3 || keyword.compare(keyword.size() - 3, 3, "OFF") != 0 ||
        keyword.find_first_of("4n") != std::string::npos) {
        throw FormatError(name + ": starts with '" + quotedInput(keyword) +
                          "'; expected an OFF header (OFF, COFF, NOFF, STOFF, ...)");
    }
    const std::string_view prefix = std::string_view(keyword).substr(0, keyword.size() - 3);
    const bool texcoords = prefix.starts_with("ST");
    const bool colours = prefix.find('C') != std::string_view::npos;
    const bool normals = prefix.find('N') != std::string_view::npos;
    // OpenMesh reads the counts from the line after the keyword's, whatever follows the keyword:
    // counts on the keyword's line would be checked here and ignored there.
    std::string rest;
    if (!tokens.endedLine()) std::getline(in, rest);
    const std::vector<std::string_view> restTokens = splitWhitespace(rest);
    const bool binary = restTokens.size() == 1 && restTokens[0] == "BINARY";
    if (!binary && !restTokens.empty()) {
        throw FormatError(name + ": OFF keyword line '" + quotedInput(keyword + " " + rest) +
                          "' has more than the keyword (and BINARY); the counts go on the next "
                          "line");
    }
    if (binary && colours) {
        throw FormatError(name + ": binary " + keyword +
                          " files (with colours) are not read; write it as ASCII OFF, or as PLY");
    }
    static constexpr const char* kCountNames[3] = {"vertex", "face", "edge"};
    std::uint32_t counts[3] = {0, 0, 0};
    for (int k = 0; k < 3; ++k) {
        if (binary) {
            const std::optional<std::uint32_t> count = readLittleEndianWord(in);
            if (!count) throw FormatError(name + ": OFF header ends before its counts");
            counts[k] = *count;
            continue;
        }
        const std::string_view token = tokens.next();
        const std::optional<std::uint32_t> count = unsignedIn(token);
        if (!count) {
            throw FormatError(name + ": OFF " + kCountNames[k] + " count '" + quotedInput(token) +
                              "' is not a number of at most 10 digits (vertex, face and edge "
                              "counts follow the keyword's line)");
        }
        counts[k] = *count;
    }
    // The least a vertex and a face take: "0 0 0" and "3 0 1 2" with a separator, or 3 floats
    // and a count with 3 indices in a binary file.
    requireDeclaredCount(file, "OFF vertex count", counts[0], binary ? 12 : 6, fileBytes,
                         kBytesPerMeshElement);
    requireDeclaredCount(file, "OFF face count", counts[1], binary ? 16 : 8, fileBytes,
                         kBytesPerMeshElement);
    requireDeclaredCount(file, "OFF vertex and face counts", std::uint64_t(counts[0]) + counts[1],
                         6, fileBytes, kBytesPerMeshElement);
    const auto badIndex = [&](const std::string& what, const std::string& index) {
        return FormatError(name + ": " + what + " has an invalid vertex index '" + index +
                           "'; the file has " + std::to_string(counts[0]) + " vertices (from 0)");
    };
    const auto badCornerCount = [&](const std::string& what, const std::string& count) {
        return FormatError(name + ": " + what + " has the corner count '" + count +
                           "'; expected 1 to " + std::to_string(kMaxPolygonCorners));
    };
    if (binary) {
        const std::uint64_t floatsPerVertex = 3 + (normals ? 3 : 0) + (texcoords ? 2 : 0);
        const auto truncated = [&] {
            return FormatError(name + ": binary OFF ends before its " + std::to_string(counts[0]) +
                               " vertices and " + std::to_string(counts[1]) +
                               " faces; the file is truncated");
        };
        const auto readWord = [&] {
            const std::optional<std::uint32_t> word = readLittleEndianWord(in);
            if (!word) throw truncated();
            return *word;
        };
        // The vertices' floats: their values are checked with the mesh (finite, in range).
        in.seekg(std::streamoff(4 * floatsPerVertex * counts[0]), std::ios::cur);
        if (!in || std::uint64_t(in.tellg()) > fileBytes) throw truncated();
        for (std::uint32_t face = 0; face < counts[1]; ++face) {
            const std::string what = "OFF face " + std::to_string(face);
            const std::uint32_t corners = readWord();
            if (corners < 1 || corners > kMaxPolygonCorners)
                throw badCornerCount(what, std::to_string(corners));
            for (std::uint32_t k = 0; k < corners; ++k) {
                const std::uint32_t index = readWord();
                if (index >= counts[0]) throw badIndex(what, std::to_string(index));
            }
        }
        return;
    }
    if (!tokens.endedLine()) {
        std::string countsRest;
        std::getline(in, countsRest);
        if (!splitWhitespace(countsRest).empty()) {
            throw FormatError(name + ": OFF counts line has '" + quotedInput(countsRest) +
                              "' after the vertex, face and edge counts (read as " +
                              std::to_string(counts[0]) + " " + std::to_string(counts[1]) + " " +
                              std::to_string(counts[2]) +
                              "); the three stand alone on one line before the vertices");
        }
    }
    const std::size_t numbersPerVertex = 3 + (normals ? 3 : 0) + (texcoords ? 2 : 0);
    const std::string vertexNumbers = std::string("3 coordinates") +
                                      (normals ? ", 3 normal components" : "") +
                                      (texcoords ? ", 2 texture coordinates" : "");
    std::string line;
    std::uint64_t vertices = 0, faces = 0;
    while (vertices + faces < std::uint64_t(counts[0]) + counts[1] && std::getline(in, line)) {
        const std::vector<std::string_view> values = splitWhitespace(line);
        if (values.empty()) continue;
        const bool isVertex = vertices < counts[0];
        const std::string what = isVertex ? "OFF vertex " + std::to_string(vertices)
                                          : "OFF face " + std::to_string(faces);
        if (values[0][0] == '#') {
            throw FormatError(name + ": comment '" + quotedInput(line) + "' in place of " + what +
                              "; OFF files have no comments after the keyword's line");
        }
        for (const std::string_view value : values) {
            if (!floatIn(value)) {
                throw FormatError(name + ": " + what + " has '" + quotedInput(value) +
                                  "'; expected finite decimal numbers within a float's range");
            }
        }
        if (isVertex) {
            if (values.size() < numbersPerVertex) {
                throw FormatError(name + ": " + what + " has " + std::to_string(values.size()) +
                                  " numbers; each vertex's line holds at least its " +
                                  vertexNumbers);
            }
            ++vertices;
            continue;
        }
        const std::optional<std::uint32_t> corners = unsignedIn(values[0]);
        if (!corners || *corners < 1 || *corners > kMaxPolygonCorners)
            throw badCornerCount(what, quotedInput(values[0]));
        if (values.size() < std::size_t(*corners) + 1 ||
            (!colours && values.size() > std::size_t(*corners) + 1)) {
            throw FormatError(name + ": " + what + " '" + quotedInput(line) +
                              "' is not a corner count followed by that many vertex indices" +
                              (colours ? "" : " and nothing more (colours need a COFF)"));
        }
        for (std::size_t k = 1; k <= std::size_t(*corners); ++k) {
            const std::optional<std::uint32_t> index = unsignedIn(values[k]);
            if (!index || *index >= counts[0]) throw badIndex(what, quotedInput(values[k]));
        }
        ++faces;
    }
    if (vertices < counts[0] || faces < counts[1]) {
        throw FormatError(name + ": OFF header promises " + std::to_string(counts[0]) +
                          " vertices and " + std::to_string(counts[1]) + " faces but only " +
                          std::to_string(vertices) + " and " + std::to_string(faces) +
                          " follow; the file is truncated");
    }
}

}  // namespace

BaseMesh loadBaseMesh(const std::filesystem::path& file) {
    const std::string name = file.string();
    requireRegularFile(file, "a mesh file");
    const std::string extension = lowercase(file.extension().string());
    if (extension != ".obj" && extension != ".off" && extension != ".ply") {
        throw FormatError(name + ": unsupported mesh format '" + file.extension().string() +
                          "'; accepted: .obj, .off, .ply");
    }
    ObjFacts objFacts;
    if (extension == ".obj") objFacts = checkObjFile(file);
    if (extension == ".ply") checkPlyFile(file);
    if (extension == ".off") checkOffFile(file);

    SoupImporter read(true);
    OpenMesh::IO::Options options =
        OpenMesh::IO::Options::VertexTexCoord | OpenMesh::IO::Options::FaceTexCoord;
    readSoup(file, extension, objFacts,
             " (in OBJ, f lines; a face needs three distinct corners); expected a mesh", read,
             options);
    const bool cornerUvs = options.face_has_texcoord();
    if (!cornerUvs && !options.vertex_has_texcoord()) {
        throw FormatError(name + ": has no texture coordinates" +
                          (extension == ".obj" ? std::string(" (vt lines)")
                           : extension == ".off"
                               ? std::string(" (STOFF header)")
                               : std::string(" (u, v or s, t vertex properties)")) +
                          "; base meshes need UVs");
    }
    for (std::size_t vertex = 0; vertex < read.points.size(); ++vertex) {
        const OpenMesh::Vec3f& p = read.points[vertex];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            throw FormatError(name + ": vertex " + std::to_string(vertex) +
                              " (counting from 0) has a NaN/Inf position; expected finite");
        }
    }

    // Split vertices per (file vertex, uv): each file vertex keeps a short list of the distinct
    // uvs seen at its corners and the BaseMesh vertex made for each. A corner takes its face's
    // uv where the file gives one (OBJ), else its vertex's.
    BaseMesh mesh;
    std::vector<std::vector<std::pair<glm::vec2, std::uint32_t>>> splits(read.points.size());
    auto baseVertex = [&](std::size_t face, std::size_t corner) {
        const std::uint32_t vertex = read.corners[corner];
        const OpenMesh::Vec2f& texcoord =
            read.faceHasUvs[face] ? read.cornerUvs[corner] : read.vertexUvs[vertex];
        const glm::vec2 uv(texcoord[0], texcoord[1]);
        if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) {
            throw FormatError(name + ": vertex " + std::to_string(vertex) +
                              " (counting from 0) has a NaN/Inf texture coordinate; expected "
                              "finite");
        }
        auto& seen = splits[vertex];
        for (const auto& [knownUv, index] : seen) {
            if (knownUv == uv) return index;
        }
        const auto index = static_cast<std::uint32_t>(mesh.positions.size());
        const OpenMesh::Vec3f& p = read.points[vertex];
        mesh.positions.emplace_back(p[0], p[1], p[2]);
        mesh.uvs.push_back(uv);
        seen.emplace_back(uv, index);
        return index;
    };
    std::vector<std::uint32_t> corners;
    PolygonSplitter splitter(name);
    for (std::size_t face = 0; face < read.faceCount(); ++face) {
        corners.clear();
        for (std::size_t corner = read.faceStarts[face]; corner < read.faceStarts[face + 1];
             ++corner)
            corners.push_back(baseVertex(face, corner));
        for (const auto& [a, b, c] : splitter.split(face, read.points, read.faceCorners(face)))
            mesh.triangles.emplace_back(corners[a], corners[b], corners[c]);
    }
    removeTrianglesWithoutArea(mesh);
    if (mesh.triangles.empty()) {
        throw FormatError(name + ": none of its " + std::to_string(read.faceCount()) +
                          " faces has an area; expected a mesh");
    }
    computeTangentFrames(mesh);
    return mesh;
}

namespace {

/// The corners of the `count` triangles of a binary STL, read from `in` (just past the header):
/// each coordinate finite and within kMaxDetailCoordinate. OpenMesh's reader drops a triangle
/// with a NaN corner without a word, leaving a hole in the mesh.
void checkBinaryStlCorners(std::istream& in, std::uint32_t count, const std::string& name) {
    constexpr std::size_t kTriangleBytes = 50, kBatch = 4096;
    std::vector<char> batch(kTriangleBytes * kBatch);
    for (std::uint32_t first = 0; first < count; first += std::uint32_t(kBatch)) {
        const std::size_t triangles = std::min<std::size_t>(kBatch, count - first);
        in.read(batch.data(), std::streamsize(triangles * kTriangleBytes));
        for (std::size_t t = 0; t < triangles; ++t) {
            // After the facet normal (3 floats): 3 corners of 3 little-endian floats each.
            for (int n = 3; n < 12; ++n) {
                const auto* bytes = reinterpret_cast<const unsigned char*>(
                    batch.data() + t * kTriangleBytes + 4 * std::size_t(n));
                const float value = std::bit_cast<float>(littleEndianWord(bytes));
                if (!std::isfinite(value) || std::abs(double(value)) > kMaxDetailCoordinate) {
                    std::ostringstream message;
                    message << name << ": triangle " << first + t << " (counting from 0) has the "
                            << "coordinate " << value << "; detail meshes need finite "
                            << "coordinates within +-" << kMaxDetailCoordinate;
                    throw FormatError(message.str());
                }
            }
        }
    }
}

/// Binary STL: 80-byte header, uint32 triangle count, 50 bytes per triangle. ASCII STL starts
/// with "solid" and is a text file; a binary file whose header happens to start with "solid" is
/// recognised by its exact size. Checks the size of binary files and, in ASCII files, what
/// OpenMesh's reader reads as corners: the 3 lines after each line that holds "outer" (or
/// "OUTER") anywhere, each read as a word and 3 floats (a number its stream cannot read leaves
/// the corner where the last one was, or unset). Those lines must be `vertex` and 3 finite
/// decimal numbers within a float's range, as must every other `vertex` line.
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
        count = littleEndianWord(reinterpret_cast<const unsigned char*>(header + 80));
    }
    const std::uintmax_t binarySize = 84 + 50 * std::uintmax_t(count);
    if (in.gcount() == 84 && size == binarySize) {  // a complete binary STL
        checkBinaryStlCorners(in, count, name);
        return;
    }
    if (!startsWithSolid) {
        throw FormatError(name + ": binary STL of " + std::to_string(size) + " bytes, but its " +
                          "header promises " + std::to_string(count) + " triangles (" +
                          std::to_string(binarySize) +
                          " bytes); the file is truncated or corrupted");
    }
    in.clear();
    in.seekg(0);
    std::string line;
    int cornersDue = 0;  // lines OpenMesh reads as corners after an "outer" line
    std::size_t outerLine = 0;
    for (std::size_t lineNumber = 1; std::getline(in, line); ++lineNumber) {
        const std::vector<std::string_view> tokens = splitWhitespace(line);
        // Built only for a message: most lines of a large file have none.
        const auto where = [&] { return name + ": line " + std::to_string(lineNumber) + ": "; };
        const bool corner = cornersDue > 0;
        if (corner) {
            --cornersDue;
        } else if (line.find("outer") != std::string::npos ||
                   line.find("OUTER") != std::string::npos) {
            cornersDue = 3;
            outerLine = lineNumber;
            continue;
        }
        if (!corner && (tokens.empty() || tokens[0] != "vertex")) continue;
        if (tokens.size() != 4 || tokens[0] != "vertex") {
            throw FormatError(where() + "'" + quotedInput(line) + "' where a 'vertex x y z' line " +
                              (corner ? "of the facet whose 'outer loop' is line " +
                                            std::to_string(outerLine) + " "
                                      : "") +
                              "must be (OpenMesh reads the 3 lines after any line holding "
                              "'outer' as a facet's corners)");
        }
        for (std::size_t k = 1; k < 4; ++k) {
            if (!floatIn(tokens[k])) {
                throw FormatError(where() + "'" + quotedInput(tokens[k]) +
                                  "' is not a finite decimal number within a float's range");
            }
        }
    }
    if (cornersDue > 0) {
        throw FormatError(name + ": ends inside the facet whose 'outer loop' is line " +
                          std::to_string(outerLine) + "; the file is truncated");
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
    requireRegularFile(file, "a mesh file");
    const std::string extension = lowercase(file.extension().string());
    ObjFacts objFacts;
    if (extension == ".obj") {
        objFacts = checkObjFile(file, /*requireUvs=*/false);
    } else if (extension == ".stl") {
        checkStlFile(file);
    } else if (extension == ".ply") {
        checkPlyFile(file);
    } else if (extension == ".off") {
        checkOffFile(file);
    } else {
        throw FormatError(name + ": unsupported mesh format '" + file.extension().string() +
                          "'; accepted: .obj, .ply, .off, .stl");
    }

    SoupImporter read(false);
    OpenMesh::IO::Options options;
    readSoup(file, extension, objFacts, "; expected a mesh (NaN/Inf numbers also end up here)",
             read, options);
    // Corners at identical positions become one vertex, whatever the format: OpenMesh merges
    // them for STL only, and an OBJ/PLY/OFF soup of unwelded corners would otherwise have no
    // shared edges at all.
    TriangleSoup soup;
    soup.positions.reserve(read.points.size());
    std::vector<std::uint32_t> weldedIndex(read.points.size());
    std::unordered_map<PositionKey, std::uint32_t, PositionKeyHash> firstAtPosition;
    firstAtPosition.reserve(read.points.size());
    for (std::size_t vertex = 0; vertex < read.points.size(); ++vertex) {
        const OpenMesh::Vec3f& p = read.points[vertex];
        for (int axis = 0; axis < 3; ++axis) {
            if (!std::isfinite(p[axis]) || std::abs(double(p[axis])) > kMaxDetailCoordinate) {
                std::ostringstream message;
                message << name << ": vertex " << vertex << " (counting from 0) has the "
                        << "coordinate " << p[axis] << "; detail meshes need finite coordinates "
                        << "within +-" << kMaxDetailCoordinate;
                throw FormatError(message.str());
            }
        }
        const auto [entry, isNew] = firstAtPosition.try_emplace(
            PositionKey{p[0], p[1], p[2]}, std::uint32_t(soup.positions.size()));
        if (isNew) soup.positions.emplace_back(p[0], p[1], p[2]);
        weldedIndex[vertex] = entry->second;
    }
    if (read.corners.size() > 2 * read.faceCount())
        soup.triangles.reserve(read.corners.size() - 2 * read.faceCount());
    PolygonSplitter splitter(name);
    for (std::size_t face = 0; face < read.faceCount(); ++face) {
        const std::span<const std::uint32_t> corners = read.faceCorners(face);
        for (const auto& [a, b, c] : splitter.split(face, read.points, corners)) {
            // A triangle whose corners merged has no area (OpenMesh drops such STL faces too).
            const glm::uvec3 triangle(weldedIndex[corners[a]], weldedIndex[corners[b]],
                                      weldedIndex[corners[c]]);
            if (triangle.x == triangle.y || triangle.y == triangle.z || triangle.z == triangle.x)
                continue;
            soup.triangles.push_back(triangle);
        }
    }
    if (soup.triangles.empty()) {
        throw FormatError(name + ": none of its " + std::to_string(read.faceCount()) +
                          " faces has three distinct corners; expected a mesh");
    }
    return soup;
}

}  // namespace distile
