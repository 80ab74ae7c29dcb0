// The implementations of tinygltf and stb_image / stb_image_write, compiled from Debian's
// headers (the same version as libtinygltf.so and libstb.so) so that sanitizer and fuzzing
// builds instrument the code that parses untrusted files (cmake/sanitize.cmake). tiny_gltf.h
// includes both stb headers once; their implementations come with the defines below.
#define TINYGLTF_IMPLEMENTATION
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <tiny_gltf.h>
