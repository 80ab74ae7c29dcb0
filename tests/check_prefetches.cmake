# The bake's gather kernels still prefetch once built (ctest -R BuildKernels.KeepTheirPrefetches).
#
# A prefetch changes no result, so no other test sees one go missing. GCC 12 deleted the calls of
# two helpers that did nothing but prefetch (it found them free of side effects), which left the
# probe bake's lit hits and the surface bake's bounces without their prefetches for days (docs/bake.md,
# "Probe bake: the prefetches that were not there"). This disassembles the bake's library and
# checks that every function whose name holds one of KERNELS has a prefetch instruction.
#
#   cmake -DOBJDUMP=objdump -DLIBRARY=libprt_bake.a -DKERNELS="litListedAvx512<;gatherChunkF16c<" -P check_prefetches.cmake
foreach(var OBJDUMP LIBRARY KERNELS)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "check_prefetches.cmake: ${var} is not set")
  endif()
endforeach()
execute_process(COMMAND "${OBJDUMP}" -d -C --no-show-raw-insn "${LIBRARY}" OUTPUT_VARIABLE listing
                RESULT_VARIABLE status ERROR_VARIABLE errors)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "${OBJDUMP} -d ${LIBRARY} failed: ${errors}")
endif()
# One function a block: objdump starts each with "<address> <name>:" and ends it with an empty line.
# What CMake's lists would read as separators or brackets, out of the way (names like [abi:cxx11]).
string(REPLACE ";" "_" listing "${listing}")
string(REPLACE "[" "_" listing "${listing}")
string(REPLACE "]" "_" listing "${listing}")
string(REPLACE "\n\n" ";" blocks "${listing}")
set(failed "")
foreach(kernel IN LISTS KERNELS)
  set(found 0)
  foreach(block IN LISTS blocks)
    string(FIND "${block}" ">:\n" header_end)
    if(header_end LESS 0)
      continue()
    endif()
    string(SUBSTRING "${block}" 0 ${header_end} header)
    string(FIND "${header}" "${kernel}" at)
    if(at LESS 0)
      continue()
    endif()
    math(EXPR found "${found} + 1")
    string(FIND "${block}" "prefetcht" prefetch)
    if(prefetch LESS 0)
      string(REGEX REPLACE "^[0-9a-f]+ <" "" name "${header}")
      list(APPEND failed "${name}")
    endif()
  endforeach()
  if(found EQUAL 0)
    message(FATAL_ERROR "no function named like ${kernel} in ${LIBRARY}: renamed? (tests/CMakeLists.txt lists the kernels)")
  endif()
  message(STATUS "${kernel}: ${found} function(s)")
endforeach()
if(failed)
  list(JOIN failed "\n  " names)
  message(FATAL_ERROR "without a prefetch instruction:\n  ${names}")
endif()
