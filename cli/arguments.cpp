#include "cli/arguments.h"

#include <algorithm>
#include <sstream>

#include "common/error.h"

namespace distile::cli {

namespace fs = std::filesystem;

Size3 parseSize(const std::string& text, const std::string& option) {
    Size3 size{0, 0, 0};
    char x1 = 0, x2 = 0;
    std::string rest;
    std::istringstream in(text);
    if (!(in >> size.width >> x1 >> size.height >> x2 >> size.depth) || x1 != 'x' || x2 != 'x' ||
        (in >> rest)) {
        throw InputError(option + ": '" + text + "' is not a size; write WxHxD, e.g. 256x256x16");
    }
    validateTileSize(size, option);
    return size;
}

std::string lowerExtension(const fs::path& path) {
    std::string extension = path.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return extension;
}

void requireOutput(const fs::path& path, const std::string& option,
                   std::initializer_list<const char*> extensions) {
    const std::string extension = lowerExtension(path);
    bool accepted = false;
    std::string list;
    for (const char* candidate : extensions) {
        accepted = accepted || extension == candidate;
        list += std::string(list.empty() ? "" : ", ") + candidate;
    }
    if (!accepted) {
        throw InputError(option + ": '" + path.string() + "' has extension '" + extension +
                         "'; accepted: " + list);
    }
    const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!fs::is_directory(folder)) {
        throw InputError(option + ": folder '" + folder.string() + "' of '" + path.string() +
                         "' does not exist");
    }
}

}  // namespace distile::cli
