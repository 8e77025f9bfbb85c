#include "common/detail/module_loader.h"

#include <dlfcn.h>
#include <link.h>

#include <algorithm>
#include <string>
#include <vector>

#include "common/error.h"

namespace distile::detail {

namespace fs = std::filesystem;

fs::path moduleFile(const ModuleName& module) {
    std::vector<fs::path> candidates;
    // The file this code was loaded from: a shared library by the path it was loaded by, the
    // program by /proc/self/exe. (dladdr names the program by argv[0], which a run through $PATH,
    // a symlink or `exec -a` leaves relative to some other folder, or anything at all.)
    Dl_info self{};
    link_map* loaded = nullptr;
    if (dladdr1(reinterpret_cast<const void*>(&moduleFile), &self,
                reinterpret_cast<void**>(&loaded), RTLD_DL_LINKMAP) &&
        loaded) {
        std::error_code error;
        const fs::path object = loaded->l_name && *loaded->l_name
                                    ? fs::absolute(loaded->l_name, error)
                                    : fs::read_symlink("/proc/self/exe", error);
        if (!error && !object.empty()) {
            // A program in <prefix>/bin: <prefix>/lib.
            candidates.push_back(
                (object.parent_path() / ".." / "lib" / module.fileName).lexically_normal());
            // The Python module installed in <prefix>/lib/python3.X/(dist|site)-packages/distile,
            // whatever prefix it was installed to: that lib.
            const fs::path packages = object.parent_path().parent_path();
            const fs::path python = packages.parent_path();
            if ((packages.filename() == "dist-packages" ||
                 packages.filename() == "site-packages") &&
                python.filename().string().starts_with("python") &&
                python.parent_path().filename() == "lib") {
                candidates.push_back(python.parent_path() / module.fileName);
            }
        }
    }
    candidates.push_back(fs::path(module.buildDir) / module.fileName);
    // Where cmake/DistileInstall.cmake installs every module.
    candidates.push_back(fs::path(DISTILE_MODULE_INSTALL_DIR) / module.fileName);
    std::vector<fs::path> folders;  // tried, each once
    for (const fs::path& candidate : candidates) {
        std::error_code error;
        if (fs::is_regular_file(candidate, error)) return candidate;
        if (std::find(folders.begin(), folders.end(), candidate.parent_path()) == folders.end())
            folders.push_back(candidate.parent_path());
    }
    std::string tried;
    for (const fs::path& folder : folders) tried += (tried.empty() ? "" : ", ") + folder.string();
    throw InternalError(std::string("distile's module ") + module.fileName + " is in none of " +
                        tried + "; the build or installation is incomplete (its target is " +
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
