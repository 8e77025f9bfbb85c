# Renders SCENE at 160x128 with the example (EXAMPLE) and with `distile render` (DISTILE) in the
# folder WORK, and fails unless both PNG files are written and identical.
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
execute_process(COMMAND ${EXAMPLE} ${SCENE} ${WORK}/example.png 160 128 RESULT_VARIABLE status)
if(NOT status EQUAL 0)
    message(FATAL_ERROR "render_scene exited with ${status}")
endif()
execute_process(COMMAND ${DISTILE} render ${SCENE} --width 160 --height 128 -o ${WORK}/cli.png
                RESULT_VARIABLE status)
if(NOT status EQUAL 0)
    message(FATAL_ERROR "distile render exited with ${status}")
endif()
if(NOT EXISTS ${WORK}/example.png)
    message(FATAL_ERROR "render_scene wrote no ${WORK}/example.png")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/example.png ${WORK}/cli.png
                RESULT_VARIABLE differ)
if(NOT differ EQUAL 0)
    message(FATAL_ERROR "render_scene and distile render wrote different images of ${SCENE}")
endif()
