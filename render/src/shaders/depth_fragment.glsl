// Shadow maps of opaque casters: depth only.
#version 450 core
void main() {}
