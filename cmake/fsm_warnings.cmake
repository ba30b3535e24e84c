# Warnings as an interface target, linked privately so users never inherit them.
add_library(fsm_warnings INTERFACE)
if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
  target_compile_options(fsm_warnings INTERFACE
    -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Wcast-align
    -Woverloaded-virtual -Wconversion -Wno-sign-conversion -Wdouble-promotion
    $<$<BOOL:${FSM_WARNINGS_AS_ERRORS}>:-Werror>)
endif()
