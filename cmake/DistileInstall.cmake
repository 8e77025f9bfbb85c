# Installs the libraries, their headers and the command, with an exported CMake package
# (find_package(distile) then link distile::render etc.).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(distile_libraries distile_common distile_vdb distile_sampler distile_mesh distile_truth distile_bake
                       distile_render distile_scene distile_check)
install(TARGETS ${distile_libraries} distile_warnings distile_sanitizers EXPORT distileTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS distile RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The modules loaded on first use (common/detail/module_loader.h), where the programs look for
# them: lib/ beside bin/.
install(TARGETS distile_image_files_oiio distile_vdb_openvdb LIBRARY DESTINATION lib)
if(TARGET distile-bench)  # next to distile, which runs it for `distile bench`
    install(TARGETS distile-bench RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
# The public headers: every header of a library's folder but those in its detail/ subfolder (the
# SIMD lanes and the kernels only its own sources include).
foreach(folder common vdb sampler mesh truth bake render scene check)
    install(DIRECTORY ${PROJECT_SOURCE_DIR}/${folder} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/distile
            FILES_MATCHING PATTERN "*.h" PATTERN "detail" EXCLUDE)
endforeach()
# The reference shader, for engines to copy (docs/shader.md).
install(FILES ${PROJECT_SOURCE_DIR}/shaders/distile_march.glsl DESTINATION ${CMAKE_INSTALL_DATADIR}/distile)
install(EXPORT distileTargets NAMESPACE distile:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/distile)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/distileConfig.cmake.in
    ${CMAKE_BINARY_DIR}/distileConfig.cmake INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/distile)
write_basic_package_version_file(${CMAKE_BINARY_DIR}/distileConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/distileConfig.cmake ${CMAKE_BINARY_DIR}/distileConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/distile)
