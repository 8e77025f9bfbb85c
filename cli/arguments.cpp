#include "cli/arguments.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>
#include <utility>

#include "common/error.h"
#include "common/input_file.h"

namespace distile::cli {

namespace fs = std::filesystem;

Size3 parseSize(const std::string& text, const std::string& option) {
    const Size3 size = parseSize3(text, option);
    validateTileSize(size, option);
    return size;
}

CLI::Validator finiteRange(double lowest, double highest) {
    std::ostringstream range;
    range << "[" << lowest << ", " << highest << "]";
    return CLI::Validator(
        [lowest, highest, text = range.str()](std::string& value) -> std::string {
            double number = 0.0;
            if (CLI::detail::lexical_cast(value, number) && std::isfinite(number) &&
                number >= lowest && number <= highest)
                return {};
            return "value " + value + " is not accepted; give a finite number in " + text;
        },
        "FLOAT in " + range.str());
}

CLI::Validator integerRange(std::int64_t lowest, std::int64_t highest) {
    const std::string range = "[" + std::to_string(lowest) + ", " + std::to_string(highest) + "]";
    return CLI::Validator(
        [lowest, highest, range](std::string& value) -> std::string {
            std::int64_t number = 0;
            const char* end = value.data() + value.size();
            const auto [last, error] = std::from_chars(value.data(), end, number);
            if (error == std::errc() && last == end && number >= lowest && number <= highest)
                return {};
            return "'" + value + "' is not accepted; give an integer in " + range;
        },
        "INT in " + range);
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
