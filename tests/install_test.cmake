# Installs the build (BUILD) into WORK/prefix, builds tests/install_consumer (the example
# render_scene, EXAMPLE_SOURCE) against it with find_package(distile), and renders SCENE with it
# and with `distile render` (DISTILE): both PNG files must be written and identical. CXX and
# GENERATOR are the build's compiler and CMake generator. With PYTHON (the interpreter the Python
# module is built for) and PYTHON_PACKAGE_DIR (where cmake --install puts the package, relative to
# the prefix), the installed package too renders SCENE, from outside the build tree, to the same
# PNG, and writes a TIFF with the image module, which it must load from the prefix's lib.
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

if(PYTHON)
    # Only the installed package on the path, run from WORK: nothing of the build tree is found.
    set(package ${WORK}/prefix/${PYTHON_PACKAGE_DIR})
    execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=DISTILE_BINARY PYTHONPATH=${package}
                            ${PYTHON} -c "
import os, sys, distile
module = os.path.realpath(distile.__file__)
if not module.startswith(os.path.realpath(sys.argv[1]) + os.sep):
    sys.exit('imported ' + module + ', not the installed package')
render = distile.render(sys.argv[2], width=160, height=128)
render.save(sys.argv[3])
render.save(sys.argv[4])
loaded = [line.split()[-1] for line in open('/proc/self/maps') if 'image_files_oiio' in line]
prefix = os.path.realpath(sys.argv[5])
if not loaded or not all(os.path.realpath(path).startswith(prefix + os.sep) for path in loaded):
    sys.exit('the image module was loaded from ' + repr(loaded) + ', not from ' + prefix)
" ${package} ${SCENE} ${WORK}/python.png ${WORK}/python.tif ${WORK}/prefix/lib
                    WORKING_DIRECTORY ${WORK}
                    RESULT_VARIABLE status OUTPUT_VARIABLE out ERROR_VARIABLE err)
    if(NOT status EQUAL 0)
        message(FATAL_ERROR "the installed Python package exited with ${status}:\n${out}\n${err}")
    endif()
    execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/python.png ${WORK}/cli.png
                    RESULT_VARIABLE differ)
    if(NOT differ EQUAL 0 OR NOT EXISTS ${WORK}/python.tif)
        message(FATAL_ERROR "the installed Python package and distile render wrote different "
                            "images of ${SCENE}, or no TIFF")
    endif()
endif()
