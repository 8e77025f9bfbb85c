#include "common/image_files.h"

#include <dlfcn.h>

#include <cctype>
#include <future>
#include <mutex>
#include <stdexcept>

#include "common/detail/image_files_module.h"
#include "common/detail/png_file.h"
#include "common/error.h"

namespace distile::image_files {

namespace fs = std::filesystem;

namespace {

/// The module's file: beside the library holding this code (../lib from a program in bin/, as
/// the build lays them out), else where the build put it. Throws InternalError if neither exists.
fs::path moduleFile() {
    std::vector<fs::path> candidates;
    Dl_info self{};
    if (dladdr(reinterpret_cast<const void*>(&moduleFile), &self) && self.dli_fname) {
        const fs::path binary = fs::path(self.dli_fname).parent_path();
        candidates.push_back(
            (binary / ".." / "lib" / DISTILE_IMAGE_FILES_MODULE_NAME).lexically_normal());
    }
    candidates.push_back(fs::path(DISTILE_IMAGE_FILES_MODULE_DIR) /
                         DISTILE_IMAGE_FILES_MODULE_NAME);
    for (const fs::path& candidate : candidates) {
        std::error_code error;
        if (fs::is_regular_file(candidate, error)) return candidate;
    }
    throw InternalError(std::string("distile's OpenImageIO module ") +
                        DISTILE_IMAGE_FILES_MODULE_NAME + " is neither beside the program (" +
                        candidates.front().parent_path().string() + ") nor in " +
                        DISTILE_IMAGE_FILES_MODULE_DIR +
                        "; the build is incomplete (its target is distile_image_files_oiio)");
}

const detail::ModuleFunctions* loadModule() {
    const fs::path file = moduleFile();
    // Never closed: its libraries stay until the process ends.
    void* handle = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char* message = dlerror();
        throw InternalError("cannot load " + file.string() + ": " +
                            (message ? message : "unknown dlopen error"));
    }
    using Entry = const detail::ModuleFunctions* (*)();
    auto entry = reinterpret_cast<Entry>(dlsym(handle, detail::kModuleEntry));
    if (!entry) {
        throw InternalError(file.string() + " has no " + detail::kModuleEntry +
                            "; it is not distile's OpenImageIO module of this build");
    }
    return entry();
}

/// The module's load: started once, by loadInBackground or by the first use.
struct Loading {
    std::once_flag started;
    std::shared_future<const detail::ModuleFunctions*> functions;
};

Loading& loading() {
    static Loading state;
    return state;
}

void startLoading(std::launch policy) {
    Loading& state = loading();
    std::call_once(state.started,
                   [&] { state.functions = std::async(policy, loadModule).share(); });
}

const detail::ModuleFunctions& module() {
    startLoading(std::launch::deferred);
    return *loading().functions.get();
}

}  // namespace

void Spec::set(const std::string& name, std::variant<std::string, int, float> value) {
    for (Attribute& attribute : attributes) {
        if (attribute.name == name) {
            attribute.value = std::move(value);
            return;
        }
    }
    attributes.push_back({name, std::move(value)});
}

const Attribute* Spec::find(std::string_view name) const {
    for (const Attribute& attribute : attributes)
        if (attribute.name == name) return &attribute;
    return nullptr;
}

std::string Spec::text(std::string_view name) const {
    const Attribute* attribute = find(name);
    const auto* value = attribute ? std::get_if<std::string>(&attribute->value) : nullptr;
    return value ? *value : std::string();
}

std::unique_ptr<Input> open(const fs::path& file, std::string& error) {
    return module().open(file, error);
}

bool writesWithoutModule(const fs::path& file) {
    std::string extension = file.extension().string();
    for (char& c : extension) c = char(std::tolower((unsigned char)c));
    return extension == ".png";
}

void write(const fs::path& file, const fs::path& target, const Spec& spec, PixelType given,
           const void* pixels) {
    const std::string problem = writesWithoutModule(file)
                                    ? detail::writePng(file, spec, given, pixels)
                                    : module().write(file, spec, given, pixels);
    if (!problem.empty()) throw std::runtime_error(target.string() + ": " + problem);
}

bool drawText(std::span<float> rgb, int width, int height, int x, int baseline,
              const std::string& text, int fontPixels, const std::string& font,
              const float (&color)[3]) {
    return module().drawText(rgb, width, height, x, baseline, text, fontPixels, font, color);
}

void loadInBackground() {
    moduleFile();  // a missing module is reported now, not after the work that needs it
    startLoading(std::launch::async);
}

}  // namespace distile::image_files
