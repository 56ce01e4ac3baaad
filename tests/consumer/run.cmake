# CTest's package check (tests/CMakeLists.txt): installs the build tree BUILD_DIR into a fresh prefix under
# WORK_DIR, configures tests/consumer against it alone, builds both programs and runs them.
file(REMOVE_RECURSE ${WORK_DIR})
foreach(step
    "${CMAKE_COMMAND};--install;${BUILD_DIR};--prefix;${WORK_DIR}/prefix"
    "${CMAKE_COMMAND};-S;${SOURCE_DIR};-B;${WORK_DIR}/build;-DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix;-DCMAKE_BUILD_TYPE=Release"
    "${CMAKE_COMMAND};--build;${WORK_DIR}/build;-j2"
    "${WORK_DIR}/build/consumer_core"
    "${WORK_DIR}/build/consumer_lancer")
  execute_process(COMMAND ${step} RESULT_VARIABLE result)
  if(NOT result EQUAL 0)
    string(REPLACE ";" " " shown "${step}")
    message(FATAL_ERROR "package consumer: `${shown}` failed (${result})")
  endif()
endforeach()
