// The raster floor (Shading::Flat): one colour.
#version 450 core
out vec4 fragColor;
void main() { fragColor = vec4(0.5, 0.5, 0.5, 1.0); }
