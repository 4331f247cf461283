# Plugin.ExampleBuildsAgainstInstalledTree (ctest, label "plugin"): installs this build into a
# temporary prefix, builds examples/plugin against it with find_package(Skelflow), runs the
# example's own test, and runs a pipeline that uses its module through the installed skelflow with
# SKELFLOW_PLUGIN_PATH set, checking the table it writes.
# Variables: BIN (this build), SRC (the source tree), WORK (a scratch folder), GENERATOR, LAUNCHER,
# SANITIZE (this build has ASan + UBSan, -DSKEL_SANITIZE=ON: the example is built with the same
# flags, since a program linking the instrumented libskelflow_core.so needs the ASan runtime first).
# Run by example_plugin_test.sh, which skips it (exit code 77) when no cmake program is at hand.

function(step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc}):\n${out}\n${err}")
  endif()
  set(step_output "${out}${err}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${WORK}")
set(prefix "${WORK}/prefix")
step("install" "${CMAKE_COMMAND}" --install "${BIN}" --prefix "${prefix}")
foreach(f include/skel/module.hpp include/skel/plugin.hpp include/skel/version.hpp bin/skelflow)
  if(NOT EXISTS "${prefix}/${f}")
    message(FATAL_ERROR "the install lacks ${f}")
  endif()
endforeach()
file(GLOB_RECURSE config "${prefix}/*/SkelflowConfig.cmake")
if(NOT config)
  message(FATAL_ERROR "the install lacks SkelflowConfig.cmake")
endif()

set(launcher)
if(LAUNCHER)
  set(launcher "-DCMAKE_CXX_COMPILER_LAUNCHER=${LAUNCHER}")
endif()
set(sanitize)
if(SANITIZE)
  set(flags "-fsanitize=address,undefined")
  set(sanitize "-DCMAKE_CXX_FLAGS=${flags} -fno-omit-frame-pointer" "-DCMAKE_EXE_LINKER_FLAGS=${flags}"
               "-DCMAKE_SHARED_LINKER_FLAGS=${flags}" "-DCMAKE_MODULE_LINKER_FLAGS=${flags}")
endif()
step("configuring examples/plugin" "${CMAKE_COMMAND}" -S "${SRC}/examples/plugin" -B "${WORK}/build" -G "${GENERATOR}"
     -DCMAKE_BUILD_TYPE=Release "-DCMAKE_PREFIX_PATH=${prefix}" ${launcher} ${sanitize})
step("building examples/plugin" "${CMAKE_COMMAND}" --build "${WORK}/build")
step("the example's test" "${CMAKE_CTEST_COMMAND}" --test-dir "${WORK}/build" --output-on-failure)
if(NOT EXISTS "${WORK}/build/example_voxel_count.so")
  message(FATAL_ERROR "examples/plugin built no example_voxel_count.so")
endif()

# The installed skelflow lists the module with its file and runs the example pipeline.
set(env "${CMAKE_COMMAND}" -E env "SKELFLOW_PLUGIN_PATH=${WORK}/build" "XDG_DATA_HOME=${WORK}/xdg")
step("skelflow modules" ${env} "${prefix}/bin/skelflow" modules)
if(NOT step_output MATCHES "example.voxel_count +Counts the voxels[^\n]*\\[plugin [^\n]*example_voxel_count.so\\]")
  message(FATAL_ERROR "skelflow modules does not list the plugin's module with its file:\n${step_output}")
endif()
step("skelflow run" ${env} "${prefix}/bin/skelflow" run --quiet --threads 2 "${SRC}/examples/plugin/pipeline.yaml"
     --output-dir "${WORK}/out")
file(READ "${WORK}/out/counts.csv" csv)
string(REGEX MATCH "^voxels,object_voxels,object_fraction,object_volume \\[[^]]+\\]\n32768,([0-9]+),([0-9.e-]+),([0-9.e+-]+)\n$" ok "${csv}")
if(NOT ok)
  message(FATAL_ERROR "unexpected counts.csv:\n${csv}")
endif()
if(CMAKE_MATCH_1 LESS 1 OR CMAKE_MATCH_1 GREATER 32767 OR NOT CMAKE_MATCH_1 EQUAL CMAKE_MATCH_3)
  message(FATAL_ERROR "object voxels ${CMAKE_MATCH_1} (volume ${CMAKE_MATCH_3}) in\n${csv}")
endif()
message(STATUS "example plugin: ${CMAKE_MATCH_1} of 32768 voxels in the object")
file(REMOVE_RECURSE "${WORK}")
