# fsm-build from the command line: builds the default data set with --json, refuses a missing
# scene with exit status 1 naming the file, and bad usage with 2.
foreach(v FSM_BUILD SOURCE_DIR WORK_DIR)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "${v} not set")
  endif()
endforeach()
file(MAKE_DIRECTORY ${WORK_DIR})
execute_process(COMMAND ${FSM_BUILD} ${SOURCE_DIR}/data/uterus/uterus.json -o ${WORK_DIR}/uterus.fsm --json --quiet
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "fsm-build failed (${rc}): ${err}")
endif()
string(JSON spheres GET "${out}" spheres)
string(JSON parts LENGTH "${out}" parts)
string(JSON first GET "${out}" parts 0 name)
if(spheres LESS 590 OR spheres GREATER 800 OR NOT parts EQUAL 8 OR NOT first STREQUAL "body")
  message(FATAL_ERROR "unexpected report: spheres=${spheres} parts=${parts} first=${first}")
endif()
if(NOT EXISTS ${WORK_DIR}/uterus.fsm)
  message(FATAL_ERROR "no model file written")
endif()
execute_process(COMMAND ${FSM_BUILD} ${WORK_DIR}/missing.json -o ${WORK_DIR}/x.fsm
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 1 OR NOT err MATCHES "missing.json")
  message(FATAL_ERROR "missing scene: exit ${rc}, message '${err}'")
endif()
execute_process(COMMAND ${FSM_BUILD} RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 2 OR NOT err MATCHES "usage")
  message(FATAL_ERROR "no arguments: exit ${rc}, message '${err}'")
endif()
# The resource budget from the command line: a limit below the model is refused naming the flag.
execute_process(COMMAND ${FSM_BUILD} ${SOURCE_DIR}/data/uterus/uterus.json -o ${WORK_DIR}/x.fsm
                        --quiet --max-spheres 100
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 1 OR NOT err MATCHES "more than the limit of 100" OR NOT err MATCHES "--max-spheres")
  message(FATAL_ERROR "--max-spheres 100: exit ${rc}, message '${err}'")
endif()
execute_process(COMMAND ${FSM_BUILD} ${SOURCE_DIR}/data/uterus/uterus.json -o ${WORK_DIR}/x.fsm
                        --max-spheres -3
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 2 OR NOT err MATCHES "positive number")
  message(FATAL_ERROR "--max-spheres -3: exit ${rc}, message '${err}'")
endif()
message(STATUS "fsm-build: ${spheres} spheres in ${parts} parts")
