# Every weak code symbol (nm type W) of a SIMD kernel object names that object's own instruction-
# set type: fsm::detail::simd::Avx2Evex (src/fsm/simd/evex_arch.hpp) in the *_avx512 objects,
# xsimd::fma3<xsimd::avx2> in the *_avx2 ones. Any other weak function may also be defined by
# another instruction set's objects or by the rest of the library, and the linker keeps one copy:
# if it keeps the wider one, a CPU without those instructions stops on an illegal instruction.
#   cmake -DNM=<nm> -DOBJECTS=<objects joined by |> -P check_simd_symbols.cmake
string(REPLACE "|" ";" objects "${OBJECTS}")
set(checked 0)
set(bad "")
foreach(obj IN LISTS objects)
  if(obj MATCHES "_avx512\\.cpp\\.o(bj)?$")
    set(own "Avx2Evex")  # (mangled: 8Avx2Evex)
  elseif(obj MATCHES "_avx2\\.cpp\\.o(bj)?$")
    set(own "4fma3IN[^E]*4avx2E")  # xsimd::fma3<xsimd::avx2>, mangled
  else()
    continue()
  endif()
  execute_process(COMMAND "${NM}" --defined-only "${obj}" OUTPUT_VARIABLE out
                  RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${NM} failed on ${obj}: ${err}")
  endif()
  math(EXPR checked "${checked} + 1")
  string(REPLACE "\n" ";" lines "${out}")
  foreach(line IN LISTS lines)
    if(line MATCHES "^[0-9a-fA-F]* *W (.+)$")
      set(name "${CMAKE_MATCH_1}")
      if(NOT name MATCHES "${own}")
        string(APPEND bad "\n  ${obj}: ${name}")
      endif()
    endif()
  endforeach()
endforeach()
if(checked EQUAL 0)
  message(FATAL_ERROR "no SIMD kernel object among: ${OBJECTS}")
endif()
if(bad)
  message(FATAL_ERROR "weak functions in SIMD kernel objects that other objects may define too:${bad}")
endif()
message(STATUS "${checked} SIMD kernel objects: every weak function is their own")
