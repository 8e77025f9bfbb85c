# Installs the build (BUILD) into WORK/prefix, builds tests/install_consumer (the example
# render_scene, EXAMPLE_SOURCE) against it with find_package(distile), and renders SCENE with it
# and with `distile render` (DISTILE): both PNG files must be written and identical. CXX and
# GENERATOR are the build's compiler and CMake generator.
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
function(run what)
    execute_process(COMMAND ${ARGN} RESULT_VARIABLE status OUTPUT_VARIABLE out ERROR_VARIABLE err)
    if(NOT status EQUAL 0)
        message(FATAL_ERROR "${what} exited with ${status}:\n${out}\n${err}")
    endif()
endfunction()
run("cmake --install" ${CMAKE_COMMAND} --install ${BUILD} --prefix ${WORK}/prefix)
run("configuring the consumer" ${CMAKE_COMMAND} -S ${CONSUMER} -B ${WORK}/consumer -G ${GENERATOR}
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_PREFIX_PATH=${WORK}/prefix
    -DEXAMPLE_SOURCE=${EXAMPLE_SOURCE})
run("building the consumer" ${CMAKE_COMMAND} --build ${WORK}/consumer)
run("the consumer's render_scene" ${WORK}/consumer/render_scene ${SCENE} ${WORK}/consumer.png 160
    128)
run("distile render" ${DISTILE} render ${SCENE} --width 160 --height 128 -o ${WORK}/cli.png)
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/consumer.png ${WORK}/cli.png
                RESULT_VARIABLE differ)
if(NOT differ EQUAL 0)
    message(FATAL_ERROR "the installed example and distile render wrote different images of ${SCENE}")
endif()
