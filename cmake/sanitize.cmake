# Sanitizer and fuzzing builds (docs/robustness.md).
#
# PRT_SANITIZE=address,undefined instruments every target of the project (libraries, tools,
# tests): compile and link flags are global, because a sanitizer runtime must be in the
# executable and every object that shares a heap should be instrumented. Errors halt:
# -fno-sanitize-recover makes UBSan fatal like ASan. Third-party libraries (Debian's OpenVDB,
# OpenEXR, Embree, TBB, Mesa) stay uninstrumented; only tinygltf and stb_image, which parse
# untrusted bytes, are rebuilt from their headers with the same flags (PRT_INSTRUMENT_PARSERS).
#
# PRT_FUZZ builds the libFuzzer targets in tests/fuzz (clang only): the objects a fuzzer runs get
# coverage instrumentation (PRT_FUZZ_COVERAGE, -fsanitize=fuzzer-no-link): the probes/
# libraries (probes/CMakeLists.txt), the parsers below and the fuzz targets; the fuzz executables
# link libFuzzer. bake/, render/, tools/ and the tests are linked into no fuzzer and go without.
set(PRT_SANITIZE "" CACHE STRING "Sanitizers for every target, e.g. address,undefined (empty: none)")
option(PRT_FUZZ "Build the libFuzzer targets in tests/fuzz (clang only)" OFF)

if(PRT_FUZZ AND NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR "PRT_FUZZ needs clang (libFuzzer): configure with -DCMAKE_CXX_COMPILER=clang++ "
                      "-DCMAKE_C_COMPILER=clang")
endif()

if(PRT_SANITIZE)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang|GNU")
    message(FATAL_ERROR "PRT_SANITIZE needs clang or gcc")
  endif()
  # -O1 (after the build type's flags, so it wins): sanitizer-friendly stacks, quick builds.
  add_compile_options(-fsanitize=${PRT_SANITIZE} -fno-sanitize-recover=all -fno-omit-frame-pointer -O1
                      $<IF:$<CXX_COMPILER_ID:Clang>,-gline-tables-only,-g1>)
  add_link_options(-fsanitize=${PRT_SANITIZE} -fno-sanitize-recover=all)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    # Third-party header code that is compiled into our objects but whose reports are not
    # ours to fix (each entry says why).
    # The list is an input of every object that neither the generated build nor ccache sees:
    # a copy named by its hash changes the flags, so an edit rebuilds everything (configure_file
    # also reruns CMake when the list changes).
    set(prt_ignorelist ${PROJECT_SOURCE_DIR}/cmake/sanitizer_ignorelist.txt)
    file(MD5 ${prt_ignorelist} prt_ignorelist_md5)
    set(prt_ignorelist_copy ${CMAKE_BINARY_DIR}/sanitizer_ignorelist_${prt_ignorelist_md5}.txt)
    configure_file(${prt_ignorelist} ${prt_ignorelist_copy} COPYONLY)
    add_compile_options(-fsanitize-ignorelist=${prt_ignorelist_copy})
  endif()
endif()

set(PRT_FUZZ_COVERAGE "")
if(PRT_FUZZ)
  set(PRT_FUZZ_COVERAGE -fsanitize=fuzzer-no-link)
endif()

if(PRT_SANITIZE OR PRT_FUZZ)
  set(prt_instrument_default ON)
else()
  set(prt_instrument_default OFF)
endif()
option(PRT_INSTRUMENT_PARSERS "Compile tinygltf and stb_image from their headers (instrumented)"
       ${prt_instrument_default})

# tinygltf and stb_image parse the untrusted bytes of a scene. Debian ships them compiled
# (libtinygltf.so, libstb.so), invisible to sanitizers and to the fuzzer's coverage; here the
# same headers are compiled into one instrumented static library that stands in for
# TinyGLTF::TinyGLTF (its stb_image symbols take precedence over libstb.so's).
function(prt_add_instrumented_parsers)
  add_library(prt_parsers STATIC ${PROJECT_SOURCE_DIR}/cmake/parsers.cpp)
  target_compile_options(prt_parsers PRIVATE ${PRT_FUZZ_COVERAGE})
  target_link_libraries(prt_parsers PRIVATE PkgConfig::STB nlohmann_json::nlohmann_json)
  # Third-party code: compiled without the project's warnings.
  add_library(TinyGLTF::TinyGLTF INTERFACE IMPORTED)
  target_link_libraries(TinyGLTF::TinyGLTF INTERFACE prt_parsers)
endfunction()
