// Receivers lit from a probe grid on the GPU (private header of render/): the GLSL port of
// prt::probeWeights + interpolateRadiance + sh::irradiance, and the packing of a ProbeGrid into
// the buffers the shader reads (docs/render.md, "Receivers").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/probe_grid.h"

namespace prt::render {

/// Texels per probe in the static buffer (probeStaticTexels).
constexpr int kProbeStaticTexels = 4;

/// Coefficient indices j < bands² whose band l has a non-zero clamped-cosine factor Â_l (odd
/// l > 1 contribute nothing to irradiance, so the shader never reads them).
std::vector<int> irradianceCoefficients(int bands);

/// RGBA texels per probe in the per-frame radiance buffer: ⌈3K/4⌉ for the K coefficients of
/// irradianceCoefficients(bands).
int radianceTexels(int bands);
/// Packs relit probes (relightProbes' layout: probe-major, bands² RGB) into that buffer: per
/// probe radianceTexels(bands) texels, coefficient irradianceCoefficients()[k] at floats 3k..3k+2.
void packRadiance(int bands, const std::vector<glm::vec3>& relit, std::vector<glm::vec4>& out);

/// The receivers' fragment shader for a grid of `bands` bands. Inputs: vWorld, vNormal,
/// vTexcoord, vColor; uniforms and bindings as set up by Renderer (renderer.cpp).
std::string receiverFragmentShader(int bands);

/// Per probe, kProbeStaticTexels RGBA texels: (position xyz, validity), then per axis x, y, z
/// (μ₊, σ²₊, μ₋, σ²₋) of the + and − faces, σ² = max(m₂ − μ², floor²) evaluated in double as
/// probeWeights does (a float shader would lose σ² to cancellation).
std::vector<glm::vec4> probeStaticTexels(const ProbeGrid& grid);

/// Dense lattice (index (z·dims.y + y)·dims.x + x) -> position in grid.coord, −1 for none.
std::vector<int32_t> latticeIndex(const ProbeGrid& grid);

/// (0.01 · min spacing)²: the variance floor of probeWeights.
double varianceFloor(const ProbeGrid& grid);
/// 10⁻⁶ · min spacing: below this distance from a probe, probeWeights drops the back-face term.
double nearZero(const ProbeGrid& grid);

}  // namespace prt::render
