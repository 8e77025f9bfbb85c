/// @file
/// What every reader of an input file checks before it reads: that the file is a regular file
/// (a device such as /dev/zero or a pipe never ends), and that the counts and sizes its header
/// declares fit in the file and in the memory budget, checked in overflow-safe arithmetic before
/// anything is allocated. Also the one way to quote a file's bytes in a one-line message.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace distile {

/// The most memory the decoded contents of one input file may take (pixels, mesh elements,
/// grids), bytes: 1 GiB, so a run stays within 2 GB with its own working memory.
inline constexpr std::uint64_t kInputMemoryBudgetBytes = std::uint64_t(1) << 30;

/// The file's extension, with its dot, in lower case ("Ring.OBJ" -> ".obj"; none: "").
std::string lowerExtension(const std::filesystem::path& file);

/// Throws InputError unless `file` exists and is a regular file (or a link to one): a folder, a
/// device, a pipe or a socket is refused with a message naming `expected` (e.g. "a tile .exr
/// file"). Returns the file's size in bytes.
std::uint64_t requireRegularFile(const std::filesystem::path& file, std::string_view expected);

/// From now on, keeps which files requireRegularFile accepts (by device and inode), forgetting
/// those kept before, so that a command's outputs can refuse to replace one of its own inputs
/// (common/atomic_file.h). Off until called: the command line calls it as each command starts; a
/// program using the library may mean to rewrite a file it read.
void recordInputFiles();

/// What requireRegularFile was told to expect of `file` (e.g. "a tile .exr file") if `file` is a
/// file it accepted since recordInputFiles(), under any name (links included); empty otherwise.
std::string recordedInputKind(const std::filesystem::path& file);

/// a * b, or UINT64_MAX when the product does not fit in 64 bits.
std::uint64_t saturatingProduct(std::uint64_t a, std::uint64_t b);

/// a + b, or UINT64_MAX when the sum does not fit in 64 bits.
std::uint64_t saturatingSum(std::uint64_t a, std::uint64_t b);

/// Throws FormatError unless `count` items that `file` declares (`what`, e.g. "PLY element
/// 'vertex'") fit: each takes at least `fileBytesEach` of the `fileBytes` bytes there are for
/// them, and all
/// of them, at `memoryBytesEach` bytes each once read, fit in kInputMemoryBudgetBytes.
void requireDeclaredCount(const std::filesystem::path& file, std::string_view what,
                          std::uint64_t count, std::uint64_t fileBytesEach, std::uint64_t fileBytes,
                          std::uint64_t memoryBytesEach);

/// Throws FormatError unless `bytes` of memory that reading `file` needs (`what`, e.g. "a
/// 65536x65536 image") fit in kInputMemoryBudgetBytes.
void requireWithinMemoryBudget(const std::filesystem::path& file, std::string_view what,
                               std::uint64_t bytes);

/// Throws FormatError if `file` starts with the PNG signature and its chunks are broken: a chunk
/// running past the end of the file, a chunk type that is not four letters, a CRC that does not
/// match, a first chunk other than IHDR, no IDAT or no IEND. libpng reports such files on stderr by
/// itself before OpenImageIO gets the error, so image readers check them first; other files pass
/// unchecked.
void checkPngChunks(const std::filesystem::path& file);

/// True when `file` starts with the PNG signature.
bool startsAsPng(const std::filesystem::path& file);

/// `bytes` from an input file as it can be quoted in a one-line message: control and non-ASCII
/// bytes become '?', and more than `maxCharacters` are cut to that many followed by "...".
std::string quotedInput(std::string_view bytes, std::size_t maxCharacters = 40);

}  // namespace distile
