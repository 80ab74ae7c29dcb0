// The glTF 2.0 metallic-roughness BRDF (glTF 2.0 specification, Appendix B) as CPU maths: the
// reference that the bake's material rule and the renderer's shaders are measured against.
//
// Conventions. Directions are unit vectors pointing away from the surface: l towards the light,
// v towards the viewer, n the shading normal, h = normalize(l + v). α = roughness² (the
// specification's perceptual roughness squared). A BRDF value f(l, v) is per steradian; the
// light reflected towards v is ∫ f(l, v) L(l) (n·l) dl.
//
// References (numbered in comments as [n]):
//   [1] The Khronos Group, glTF 2.0 Specification, Appendix B "BRDF Implementation"
//       (specular_brdf = V·D, fresnel_mix, conductor_fresnel, material = mix(dielectric, metal, metallic)).
//   [2] KHR_materials_specular (ratified): fresnel_mix(f0_color, ior, weight, base, layer) =
//       (1 − weight·max(F)) base + weight·F·layer, F0 = min(f0(ior)·specularColor, 1).
//       KHR_materials_ior: f0(ior) = ((ior − 1)/(ior + 1))², ior 1.5 by default (f0 = 0.04).
//   [3] B. Walter et al., "Microfacet Models for Refraction through Rough Surfaces", EGSR 2007
//       (the GGX distribution and its sampling).
//   [4] E. Heitz, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs",
//       JCGT 3(2), 2014 (the height-correlated Smith G2).
//   [5] B. Karis, "Real Shading in Unreal Engine 4", SIGGRAPH 2013 course notes (the split
//       sum: the environment's specular as prefiltered light × (F0·A + B)).
//   [6] R. Guy, M. Agopian, Filament documentation, "Physically Based Rendering in Filament",
//       sections 4.4 (the BRDF in this form) and 5.3.4 (the DFG term).
#pragma once

#include <vector>

#include <glm/glm.hpp>

namespace prt::brdf {

/// GGX (Trowbridge-Reitz) distribution of normals [1, 3]: D(h) = α² / (π ((n·h)²(α² − 1) + 1)²)
/// for n·h > 0, 0 otherwise. α > 0 (callers clamp roughness; α = 0 is a mirror, no function).
double ggxD(double nDotH, double alpha);

/// Height-correlated Smith visibility V = G2 / (4 |n·l| |n·v|) [1, 4]:
/// V = 0.5 / (n·l √((n·v)²(1 − α²) + α²) + n·v √((n·l)²(1 − α²) + α²)); 0 where either
/// cosine is ≤ 0.
double smithVisibility(double nDotL, double nDotV, double alpha);

/// Smith's Λ(θ) for GGX [4]: (−1 + √(1 + α² tan²θ)) / 2, cosTheta ∈ (0, 1]. The visibility
/// above is 1 / (4 |n·l||n·v| (1 + Λ(l) + Λ(v))): the tests derive it from this one.
double smithLambda(double cosTheta, double alpha);

/// Schlick's Fresnel F = f0 + (f90 − f0)(1 − |v·h|)⁵ [1].
double schlick(double f0, double vDotH, double f90 = 1.0);
glm::dvec3 schlick(const glm::dvec3& f0, double vDotH, double f90 = 1.0);

/// F0 of a dielectric of index `ior` against air (KHR_materials_ior) [2]: ((ior − 1)/(ior + 1))².
double dielectricF0(double ior);

/// Schlick's F averaged over the cosine-weighted hemisphere, 2 ∫₀¹ F(μ) μ dμ: since
/// 2 ∫₀¹ (1 − μ)⁵ μ dμ = 2 B(2, 6) = 1/21, it is f0 + (f90 − f0)/21 (0.0857143 at f0 = 0.04).
double schlickCosineAverage(double f0, double f90 = 1.0);

/// The glTF metallic-roughness inputs at a point, after the textures: what [1] and [2] take.
struct MetallicRoughness {
  glm::dvec3 baseColor{1.0};
  double metallic = 1.0;          // glTF default
  double roughness = 1.0;         // perceptual; α = roughness²
  double ior = 1.5;               // KHR_materials_ior
  double specular = 1.0;          // KHR_materials_specular: specularFactor × specularTexture.a
  glm::dvec3 specularColor{1.0};  // specularColorFactor × specularColorTexture.rgb
  /// The dielectric's F0 colour [2]: min(f0(ior) · specularColor, 1) per channel.
  glm::dvec3 dielectricF0Color() const;
};

/// The two lobes of f(l, v), so that callers can weigh them apart (the bake keeps only the
/// first): diffuse = (1 − metallic)(1 − specular·max(F_d)) baseColor/π, specular = the rest.
struct Lobes {
  glm::dvec3 diffuse{0.0};
  glm::dvec3 specular{0.0};
  glm::dvec3 sum() const { return diffuse + specular; }
};

/// f(l, v) of the glTF metallic-roughness material [1] with KHR_materials_ior and
/// KHR_materials_specular [2]: mix(dielectric, metal, metallic), where
///   metal      = V·D · (baseColor + (1 − baseColor)(1 − |v·h|)⁵)
///   dielectric = (1 − s·max(F_d)) baseColor/π + s·F_d·V·D,  F_d = F0_d + (1 − F0_d)(1 − |v·h|)⁵.
/// Zero where n·l ≤ 0 or n·v ≤ 0. roughness is clamped below at kMinRoughness.
Lobes evaluate(const MetallicRoughness& m, const glm::dvec3& n, const glm::dvec3& l, const glm::dvec3& v);

/// The smallest perceptual roughness evaluate() and the samplers use (α = 1e-6): below it
/// GGX's peak overflows doubles' useful range. Shaders clamp higher (their floats).
inline constexpr double kMinRoughness = 1e-3;

/// E[(1 − |v·h|)⁵] for l and v drawn independently from the cosine-weighted hemisphere: the
/// mean of Schlick's angular term in Appendix B's own variable, v·h. By quadrature (test
/// BrdfEnergy.HalfVectorFresnelMean; 400³ midpoint cells in (θ_v, θ_l, φ), Richardson-
/// extrapolated). Far below 1/21, the same mean in n·l: the half vector of two cosine-
/// distributed directions lies close to both.
inline constexpr double kHalfVectorFresnelMean = 0.0036845;

/// The dielectric's diffuse weight 1 − s·max(F_d(v·h)) [2], averaged over light and view
/// directions both cosine-weighted: 1 − specular · (F0 + (1 − F0)·kHalfVectorFresnelMean), F0
/// the largest channel of the dielectric's F0 colour (F is increasing in F0, so max(F) is the
/// F of the largest F0). 0.956463 for the default dielectric (ior 1.5, F0 = 0.04).
double dielectricDiffuseWeight(double ior, double specular, const glm::dvec3& specularColor);

// ---- GGX importance sampling, as a triplet (sample / pdf / invert) in the local frame where
// n = (0, 0, 1). Half vectors are drawn with density D(h)(n·h) over solid angle [3], which
// integrates to 1 over the hemisphere (the projected-area normalisation of D).

/// The half vector for u ∈ [0, 1)²: cos²θ = (1 − u₀)/(1 + (α² − 1)u₀), φ = 2π u₁.
glm::dvec3 sampleGgxHalfVector(const glm::dvec2& u, double alpha);
/// Its density over solid angle: D(h) (n·h); 0 below the horizon.
double pdfGgxHalfVector(const glm::dvec3& h, double alpha);
/// The u that sampleGgxHalfVector maps to h.
glm::dvec2 invertGgxHalfVector(const glm::dvec3& h, double alpha);

/// A light direction for view v (local frame): v mirrored about a sampled half vector,
/// l = 2(v·h)h − v. May fall below the horizon (then the caller's integrand is 0).
glm::dvec3 sampleGgxReflection(const glm::dvec2& u, const glm::dvec3& v, double alpha);
/// Its density over solid angle: D(h)(n·h) / (4 |v·h|), h = normalize(l + v) [3].
double pdfGgxReflection(const glm::dvec3& l, const glm::dvec3& v, double alpha);

// ---- The split-sum DFG table [5, 6]

/// The environment's specular under the split sum: ∫ f_spec(l, v) L(l) (n·l) dl ≈
/// prefiltered L × (F0 · A + f90 · B), with A = ∫ V D (1 − F_c) (n·l) dl and
/// B = ∫ V D F_c (n·l) dl, F_c = (1 − |v·h|)⁵, functions of n·v and roughness only.
struct DfgTable {
  int size = 0;                // size × size entries
  std::vector<glm::dvec2> ab;  // (A, B) at [row · size + column], row: roughness, column: n·v
  /// Entry centres: n·v = (column + 0.5)/size, roughness = (row + 0.5)/size (perceptual).
  static double coordinate(int i, int size) { return (i + 0.5) / size; }
  /// Bilinear lookup (clamped to the entry centres at the edges).
  glm::dvec2 lookup(double nDotV, double roughness) const;
};

/// (A, B) at one (n·v, roughness) by importance sampling the GGX half vectors
/// (`samples` Hammersley points): each sample weighs 4 V (n·l)(v·h)/(n·h) [5, 6].
glm::dvec2 integrateDfg(double nDotV, double roughness, int samples);
/// The whole table, size × size entries of `samples` each.
DfgTable computeDfgTable(int size, int samples);
/// (Ā, B̄) = 2 ∫₀¹ (A, B)(μ) μ dμ: the split-sum terms averaged over cosine-weighted views,
/// so that a lobe of Schlick F0 sends back F0 · Ā + f90 · B̄ of the light that a uniform
/// radiance brings it (its hemispherical-hemispherical albedo; the bake bounces a metal's
/// specular lobe as a diffuse reflector of that albedo, docs/bake.md, "Materials"). Tabulated
/// once (65 roughness nodes × 64 midpoint μ nodes × 512 samples, each by integrateDfg) and
/// interpolated linearly in perceptual roughness, clamped to [0, 1].
glm::dvec2 cosineAveragedDfg(double roughness);

}  // namespace prt::brdf
