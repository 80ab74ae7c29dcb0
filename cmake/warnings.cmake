# One INTERFACE target carries the project's warning flags (pbrt-v4's pbrt_warnings).
add_library(prt_warnings INTERFACE)
add_library(prt::warnings ALIAS prt_warnings)
target_compile_options(prt_warnings INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wno-missing-field-initializers>
  # clang has no -Wshadow=local (sanitizer and fuzzing builds use clang).
  $<$<CXX_COMPILER_ID:GNU>:-Wshadow=local>
  $<$<AND:$<CXX_COMPILER_ID:GNU,Clang>,$<BOOL:${PRT_WERROR}>>:-Werror>)
