# Embeds the GLSL files of render/src/shaders as C++ string constants (run by render/CMakeLists.txt):
#   cmake -DSHADER_DIR=dir -DOUTPUT=render_shaders.h -DNAMES="a.glsl;b.glsl" -P embed_shaders.cmake
# Per file: its leading block of `//` lines (the file's description) is dropped, so that a stage's
# `#version` line comes first, and each `#include "x.glsl"` line is replaced by x.glsl, embedded
# the same way (the shared maths are written once). a_b.glsl becomes prt::render::shaders::kAB.

function(load_glsl name out)
  file(READ "${SHADER_DIR}/${name}" text)
  string(FIND "${text}" "//" at)
  while(at EQUAL 0)
    string(FIND "${text}" "\n" eol)
    math(EXPR eol "${eol} + 1")
    string(SUBSTRING "${text}" ${eol} -1 text)
    string(FIND "${text}" "//" at)
  endwhile()
  string(REGEX MATCHALL "#include \"[a-z0-9_]+\\.glsl\"\n" includes "${text}")
  foreach(line IN LISTS includes)
    string(REGEX REPLACE "#include \"([a-z0-9_]+\\.glsl)\"\n" "\\1" included "${line}")
    load_glsl("${included}" inner)
    string(REPLACE "${line}" "${inner}" text "${text}")
  endforeach()
  set(${out} "${text}" PARENT_SCOPE)
endfunction()

set(header "// Generated from render/src/shaders/*.glsl by render/cmake/embed_shaders.cmake: edit those.\n")
string(APPEND header "#pragma once\n\n#include <string_view>\n\nnamespace prt::render::shaders {\n\n")
foreach(name IN LISTS NAMES)
  load_glsl("${name}" text)
  string(REGEX REPLACE "\\.glsl$" "" stem "${name}")
  string(REPLACE "_" ";" parts "${stem}")
  set(id "k")
  foreach(part IN LISTS parts)
    string(SUBSTRING "${part}" 0 1 first)
    string(TOUPPER "${first}" first)
    string(SUBSTRING "${part}" 1 -1 rest)
    string(APPEND id "${first}${rest}")
  endforeach()
  string(APPEND header "inline constexpr std::string_view ${id} = R\"glsl(${text})glsl\";\n\n")
endforeach()
string(APPEND header "}  // namespace prt::render::shaders\n")
# Rewritten only when it changes, so that an unchanged shader set rebuilds nothing.
file(WRITE "${OUTPUT}.tmp" "${header}")
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
