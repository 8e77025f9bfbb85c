# Finds distile's dependencies and works around the packaging pitfalls of Debian 12 (each noted
# where it is handled).

find_package(Threads REQUIRED)
find_package(TBB CONFIG REQUIRED)
find_package(glm CONFIG REQUIRED PATHS /usr/share/cmake/glm)

# OpenVDB ships a Find module, not a config; it lives outside the default module path.
list(APPEND CMAKE_MODULE_PATH /usr/lib/x86_64-linux-gnu/cmake/OpenVDB)
find_package(OpenVDB REQUIRED)

# CGAL's CMake modules include a FindOpenMesh that would shadow OpenMesh's own config.
find_package(OpenMesh CONFIG REQUIRED)
# CGAL (header-only) serves the ground truth in truth/ only.
find_package(CGAL CONFIG REQUIRED)

# Tiles are OpenEXR files, read and written with OpenEXR itself (sampler/tile_io.cpp); Imath's
# half gives the 16-bit floats of half tiles and of the tile page.
find_package(Imath CONFIG REQUIRED)
find_package(OpenEXR CONFIG REQUIRED)
# PNG files are written with libpng itself, deflated with zlib (common/detail/png_file.h).
find_package(PNG REQUIRED)
find_package(ZLIB REQUIRED)

# OpenImageIO reads every image and writes all but PNGs, from a module loaded on first use
# (common/image_files.h). Its 2.4 exported target lists /usr/include/opencv4 as an include folder
# even though nothing in its public headers needs OpenCV; CMake refuses to generate when the
# folder is missing.
# Drop the folder from the imported target instead of installing OpenCV's headers.
find_package(OpenImageIO CONFIG REQUIRED)
foreach(oiio_target OpenImageIO::OpenImageIO OpenImageIO::OpenImageIO_Util)
    if(TARGET ${oiio_target})
        foreach(property INTERFACE_INCLUDE_DIRECTORIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES)
            get_target_property(folders ${oiio_target} ${property})
            if(folders)
                list(FILTER folders EXCLUDE REGEX "opencv")
                set_target_properties(${oiio_target} PROPERTIES ${property} "${folders}")
            endif()
        endforeach()
    endif()
endforeach()

# Embree 3 traces the world-space ground truth (render/world_reference.cpp) and the bench peer.
find_package(embree 3 REQUIRED)

find_package(CLI11 CONFIG REQUIRED)
find_package(nlohmann_json CONFIG REQUIRED)
