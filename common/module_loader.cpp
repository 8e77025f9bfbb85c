#include "common/detail/module_loader.h"

#include <dlfcn.h>

#include <string>
#include <vector>

#include "common/error.h"

namespace distile::detail {

namespace fs = std::filesystem;

fs::path moduleFile(const ModuleName& module) {
    std::vector<fs::path> candidates;
    Dl_info self{};
    if (dladdr(reinterpret_cast<const void*>(&moduleFile), &self) && self.dli_fname) {
        const fs::path binary = fs::path(self.dli_fname).parent_path();
        candidates.push_back((binary / ".." / "lib" / module.fileName).lexically_normal());
    }
    candidates.push_back(fs::path(module.buildDir) / module.fileName);
    for (const fs::path& candidate : candidates) {
        std::error_code error;
        if (fs::is_regular_file(candidate, error)) return candidate;
    }
    throw InternalError(std::string("distile's module ") + module.fileName +
                        " is neither beside the program (" +
                        candidates.front().parent_path().string() + ") nor in " +
                        module.buildDir + "; the build is incomplete (its target is " +
                        module.target + ")");
}

const void* loadModule(const ModuleName& module) {
    const fs::path file = moduleFile(module);
    // Never closed: its libraries stay until the process ends.
    void* handle = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char* message = dlerror();
        throw InternalError("cannot load " + file.string() + ": " +
                            (message ? message : "unknown dlopen error"));
    }
    using Entry = const void* (*)();
    auto entry = reinterpret_cast<Entry>(dlsym(handle, module.entry));
    if (!entry) {
        throw InternalError(file.string() + " has no " + module.entry +
                            "; it is not the distile module of this build");
    }
    return entry();
}

}  // namespace distile::detail
