# The version, written once in project(VERSION): configured into prt/version.h, which the
# tools include through prt::version.
configure_file(${CMAKE_CURRENT_LIST_DIR}/version.h.in ${PROJECT_BINARY_DIR}/generated/prt/version.h @ONLY)
add_library(prt_version INTERFACE)
add_library(prt::version ALIAS prt_version)
target_include_directories(prt_version INTERFACE ${PROJECT_BINARY_DIR}/generated)
