#include "common/image_files.h"

#include <tbb/cache_aligned_allocator.h>
#include <tbb/parallel_for.h>

#include <cctype>
#include <future>
#include <mutex>
#include <stdexcept>

#include "common/detail/exr_file.h"
#include "common/detail/image_files_module.h"
#include "common/detail/module_loader.h"
#include "common/detail/png_file.h"
#include "common/error.h"
#include "common/exr_header.h"
#include "common/input_file.h"

namespace distile::image_files {

namespace fs = std::filesystem;

namespace {

constexpr distile::detail::ModuleName kModule{DISTILE_IMAGE_FILES_MODULE_NAME,
                                              DISTILE_IMAGE_FILES_MODULE_DIR, detail::kModuleEntry,
                                              "distile_image_files_oiio"};

const detail::ModuleFunctions* loadFunctions() {
    return static_cast<const detail::ModuleFunctions*>(distile::detail::loadModule(kModule));
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
                   [&] { state.functions = std::async(policy, loadFunctions).share(); });
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

std::unique_ptr<Input> open(const fs::path& file, std::string_view acceptedNote) {
    checkPngChunks(file);
    checkExrHeader(file);
    std::string error;
    std::unique_ptr<Input> input = module().open(file, error);
    if (!input) {
        throw FormatError(file.string() + ": not a readable image (" + firstLine(error) + ")" +
                          std::string(acceptedNote));
    }
    return input;
}

namespace {}  // namespace

bool writesWithoutModule(const fs::path& file) {
    const std::string extension = lowerExtension(file);
    return extension == ".png" || extension == ".exr";
}

void write(const fs::path& file, const fs::path& target, const Spec& spec, PixelType given,
           const void* pixels) {
    const std::string extension = lowerExtension(file);
    const std::string problem = extension == ".png"   ? detail::writePng(file, spec, given, pixels)
                                : extension == ".exr" ? detail::writeExr(file, spec, given, pixels)
                                                      : module().write(file, spec, given, pixels);
    if (!problem.empty()) throw std::runtime_error(target.string() + ": " + problem);
}

bool drawText(std::span<float> rgb, int width, int height, int x, int baseline,
              const std::string& text, int fontPixels, const std::string& font,
              const float (&color)[3]) {
    return module().drawText(rgb, width, height, x, baseline, text, fontPixels, font, color);
}

void loadInBackground() {
    // A missing module is reported now, not after the work needing it.
    distile::detail::moduleFile(kModule);
    // The dynamic loader holds its lock for the whole load, and work beside it that asks for
    // the lock waits as long: TBB opens a library on its first allocation and starts its
    // workers on its first parallel loop, so both happen here first. (The work must not
    // register thread_local objects with destructors either: common/thread_scratch.h.)
    tbb::cache_aligned_allocator<char> allocator;
    allocator.deallocate(allocator.allocate(1), 1);
    tbb::parallel_for(0, 2, [](int) {});
    startLoading(std::launch::async);
}

}  // namespace distile::image_files
