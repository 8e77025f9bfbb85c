/// @file
/// Modules: parts of distile that bring a heavy library (OpenImageIO, OpenVDB) are built as
/// shared objects of their own and loaded on first use, so that a process which never needs
/// them does not link them at start-up (dynamic linking of OpenVDB alone was 0.05-0.07 s of every
/// process on a 2.4 GHz core). Each exports one function returning its table of functions; both
/// sides are built together, so C++ types cross freely.
#pragma once

#include <filesystem>

namespace distile::detail {

/// Where a module is and what it exports.
struct ModuleName {
    const char* fileName;  ///< e.g. libdistile_vdb_openvdb.so
    const char* buildDir;  ///< the build's folder holding it (after those beside the code)
    const char* entry;     ///< the exported C function returning its table
    const char* target;    ///< its CMake target, named in errors (the build is incomplete)
};

/// The module's file: beside the library holding this code (../lib from a program in bin/, as
/// the build and an installation lay them out; <prefix>/lib from the Python module installed in
/// <prefix>/lib/python3.X/dist-packages/distile), else in `module.buildDir`, else in the
/// installation's lib/, where `cmake --install` puts every module (a program elsewhere linking
/// the installed libraries). Throws InternalError if none holds it.
std::filesystem::path moduleFile(const ModuleName& module);

/// Loads the module (never unloaded) and returns what its entry function returns. Throws
/// InternalError when it is missing, cannot be loaded or lacks its entry.
const void* loadModule(const ModuleName& module);

}  // namespace distile::detail
