// Receivers lit from a probe grid on the GPU (private header of render/): the GLSL port of
// prt::probeWeights + interpolateRadiance + sh::irradiance, and the packing of a ProbeGrid into
// the buffers the shader reads (docs/render.md, "Receivers").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/probe_grid.h"
#include "prt/render/renderer.h"
#include "prt/sh.h"

namespace prt::render {

/// Texels per probe in the static buffer (probeStaticTexels).
constexpr int kProbeStaticTexels = 6;

/// Coefficient indices j < bands² whose band l has a non-zero clamped-cosine factor Â_l (odd
/// l > 1 contribute nothing to irradiance, so the shader never reads them).
std::vector<int> irradianceCoefficients(int bands);

/// RGBA texels per probe in the per-frame radiance buffer: ⌈3K/4⌉ for the K coefficients of
/// irradianceCoefficients(bands).
int radianceTexels(int bands);
/// Packs relit probes (relightProbes' layout: probe-major, bands² RGB) into that buffer: probe p
/// at texels (p + 1) · radianceTexels(bands) on (the null probe 0 is zero), coefficient
/// irradianceCoefficients()[k] at floats 3k..3k+2 of the probe's texels.
void packRadiance(int bands, const std::vector<glm::vec3>& relit, std::vector<glm::vec4>& out);

/// The receivers' shaders (shaders/receiver_*.glsl) for a grid of `bands` bands, to be compiled
/// through withMaterialDefines (shader_variants.h); uniforms and bindings as set up by Renderer (renderer.cpp). The
/// vertex
/// shader moves the rest-pose vertex by uModel / uNormalMatrix and passes vWorld, vNormal and the
/// material's varyings. ProbeLookup::PerPixel: the fragment shader does the probe lookup at the
/// interpolated x and n. PerVertex: the vertex shader does it at the vertex and passes the
/// normalised incident radiance (packed, radianceTexels vec4) on, interpolated; the fragment shader
/// applies the irradiance basis at the interpolated normal.
std::string receiverVertexShader(int bands, ProbeLookup lookup);
std::string receiverFragmentShader(int bands, ProbeLookup lookup, int envMaps);

/// The light packed as packRadiance packs one probe (radianceTexels(bands) texels).
std::vector<glm::vec4> packLight(int bands, const sh::ShRgb& light);

/// Per probe p, kProbeStaticTexels RGBA texels from texel (p + 1) · kProbeStaticTexels on (the
/// null probe 0 is all zero: validity 0): (position xyz, validity); then for the four sign pairs
/// (s_x, s_y), texel 1 + s_x + 2 s_y (s = 1 on the − side): (μ, σ²) of x's face of side s_x and
/// of y's face of side s_y; then (μ₊, σ²₊, μ₋, σ²₋) of z. The shader reads the position texel,
/// one x-y texel and the z texel: 3 fetches per probe instead of 4 with one texel per axis.
/// σ² = max(m₂ − μ², floor²) is evaluated in double as probeWeights does (a float shader would
/// lose σ² to cancellation).
std::vector<glm::vec4> probeStaticTexels(const ProbeGrid& grid);

/// Dense lattice (index (z·dims.y + y)·dims.x + x) -> position in grid.coord plus one, 0 for none.
std::vector<int32_t> latticeIndex(const ProbeGrid& grid);

/// (0.01 · min spacing)²: the variance floor of probeWeights.
double varianceFloor(const ProbeGrid& grid);
/// 10⁻⁶ · min spacing: below this distance from a probe, probeWeights drops the back-face term.
double nearZero(const ProbeGrid& grid);

}  // namespace prt::render
