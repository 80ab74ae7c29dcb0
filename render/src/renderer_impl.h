// Renderer::Impl (private header of render/): the GL state of one renderer. One class with a file
// per phase, as pbrt-v4's wavefront integrator: renderer.cpp (programs, framebuffer, the frame
// as passes), scene_upload.cpp (instances, textures, probes), shadow_pass.cpp (shadow maps and
// the direct lights' uniforms) and background_pass.cpp.
#pragma once

#include <array>
#include <chrono>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "gl_objects.h"
#include "gl_program.h"
#include "prt/animation.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "shader_variants.h"

namespace prt::render {

struct ShadowPlan;

/// The uniforms of local_lighting.glsl for one frame (local_shading.cpp).
struct LocalFrameUniforms {
  std::vector<glm::vec4> pos, dir, up, color, shape;
  std::vector<glm::mat4> matrices;  // six per light
  bool shadowed = false;
  int mapSize = 0;
  float farPlane = 1.0f;
};

inline double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// What one frame draws and how, decided once per frame (Renderer::Impl::planFrame).
struct FramePlan {
  int width = 0, height = 0;
  bool flat = false;           // Shading::Flat
  bool drawReceivers = false;  // a probe grid and receivers to light from it
  // Direct lights per pixel (kVariantDirect) on the baked instances and on the receivers.
  bool bakedSplit = false, receiverSplit = false;
  int bakedExtra = 0, receiverExtra = 0;  // kVariantDirect where split, else 0
  bool reflections = false;               // the screen-space reflection pass (reflection_pass.cpp)
  glm::mat4 viewProj{1.0f};
};

/// An instance's glTF material as the MATERIAL variants read it (material_pass.cpp): the
/// uniforms of material_inputs.glsl, the slots' textures and the per-vertex inputs.
struct FullMaterial {
  glm::vec4 factors{0.0f, 1.0f, 1.0f, 1.0f};  // metallic, roughness, normal scale, occlusion strength
  glm::vec3 emissive{0.0f};
  glm::vec4 specularColor{0.0f};  // dielectric F0 colour, specular weight (0: Lambertian only)
  float diffuseScale = 1.0f;
  glm::ivec4 slots{-1};  // coordinate set per slot, -1 none
  std::array<GLuint, 4> textures{};
  GlBuffer tangents, texcoords1;
  int vertexInputs = 0;  // bit 0 tangents, bit 1 texcoords1, bit 2 the direct part (baked)
  int variantBits = 0;   // kVariantMaterialTextures | kVariantRoughSpecular: MATERIAL programs' only
};

struct Renderer::Impl {
  /// A baked instance or a receiver on the GPU.
  struct Instance {
    GlVertexArray vao;
    GlBuffer positions, texcoords, colors, indices, normals;
    GlBuffer transfer;      // MeshInstance::transfer (baked instances)
    GlBuffer transferBack;  // MeshInstance::transferBack (kVariantTwoSided); none if absent
    // MeshInstance::transferDirect and transferDirectBack; none if absent.
    GlBuffer transferDirect, transferDirectBack;
    // Frame::directBounce of this instance, front and back; with transferDirect.
    GlBuffer directBounce, directBounceBack;
    size_t mesh = 0;  // its Scene::meshes entry
    size_t vertices = 0;
    bool bounceZero = true;               // directBounce holds zeros
    glm::dvec3 restLo{0.0}, restHi{0.0};  // bounds of the (rest-pose, for receivers) vertices
    GLsizei indexCount = 0;
    size_t triangles = 0;
    glm::vec4 baseColor{1.0f};
    GLuint texture = 0;              // in Impl::textures
    GLuint transmissionTexture = 0;  // kVariantTransmission: bound to unit kTransmissionUnit
    bool hasColor = false;
    bool doubleSided = false;
    float alphaCutoff = 0.5f, opacity = 1.0f;  // MASK's cutoff; 1 − transmissionFactor
    bool blend = false;                        // drawn blended after the opaque pass (BLEND or transmission)
    int variant = 0;         // kVariantTexture | kVariantColor | ...: the shader variant it is drawn with
    MeshInstance placement;  // receivers: node and rest world only (no vertices), for the motion
    FullMaterial full;       // MaterialShading::Full
  };
  /// The program variant an instance is drawn with under a frame's bits `extra`: its own, and its
  /// material's where the frame draws the full material (a diffuse frame links no such program).
  static int variantOf(const Instance& in, int extra) {
    return in.variant | extra | ((extra & kVariantFullMaterial) ? in.full.variantBits : 0);
  }
  /// The probe grid's buffers, each read through a buffer texture: lattice index, static
  /// per-probe data, per-frame radiance.
  struct ProbeBuffers {
    GlBuffer lattice, statics, radiance;
    GlTexture latticeTexture, staticTexture, radianceTexture;
  };
  /// The shadow maps: a depth texture array (lights × cascades layers) and the framebuffer
  /// drawing it.
  struct ShadowMaps {
    GlTexture texture;
    GlFramebuffer framebuffer;
    int size = 0, layers = 0;
  };
  /// The framebuffer drawn into (multisampled when Frame::samples > 1) and, when it is, the
  /// single-sample one it is resolved into for the read-back.
  struct Target {
    GlFramebuffer framebuffer, resolveFramebuffer;
    GlRenderbuffer color, depth, resolveColor;
    int width = 0, height = 0, samples = 0, actualSamples = 1;
    // With reflections (reflection_pass.cpp): the depth as a texture instead of `depth`, the
    // lobes' four outputs (attachments 1–4, reflection_inputs.glsl), the copy of the bounced
    // radiance (attachment 4) with its mip levels, the framebuffer that copies it and the one
    // the pass draws into (`color` alone).
    bool reflections = false;
    GlTexture depthTexture, radianceCopy;
    std::array<GlTexture, 4> reflectionInputs;
    GlFramebuffer copyFramebuffer, reflectionFramebuffer;
  };
  /// The screen-space reflection pass's program and uniforms.
  struct Reflection {
    GlProgram id;
    GLint viewProj = -1, invViewProj = -1, viewport = -1, maxDistance = -1, perspective = -1, pixelsPerUnit = -1,
          steps = -1;
  };
  /// The background's program and uniforms, an empty vertex array for the full-screen
  /// triangle, and the environment maps uploaded so far, by image (kept alive while uploaded).
  struct Background {
    GlProgram id;
    GLint camera = -1, tan = -1, ortho = -1, viewport = -1, mapCount = -1, worldToMap = -1, mapScale = -1,
          capCount = -1, caps = -1, capRadiance = -1, uniformRadiance = -1;
    GlVertexArray emptyVao;
    std::map<const ImageRgb*, std::pair<std::shared_ptr<const ImageRgb>, GlTexture>> envTextures;
  };

  GlContext& context;
  const GlFunctions& gl;
  int bands = 0;
  glm::vec3 boundsMin{0.0f}, boundsMax{0.0f};
  std::vector<Instance> instances;  // baked
  std::vector<Instance> receivers;
  SceneAnimation animation;         // moves the receivers
  std::vector<GlTexture> textures;  // per Scene texture, none where unused
  // Per material variant (id 0: no instance needs it).
  std::array<Program, kVariants> programs;
  std::array<std::array<Program, kVariants>, 2> receiverPrograms;  // [ProbeLookup][variant]
  Program flatProgram, depthProgram;
  std::array<Program, kVariants> cutoutDepthPrograms;  // by material variant, linked on first use
  bool bakedDirect = false;                            // every baked instance holds the direct part of its transfer
  ShadowMaps shadowMaps;
  ShadowMaps localMaps;  // the lights inside the scene's cube faces, six layers per light
  bool warnedBakedDirect = false, warnedProbeDirect = false;
  const ProbeGrid* grid = nullptr;
  ProbeBuffers probes;
  Background background;
  Target target;
  Reflection reflection;
  std::vector<glm::vec4> readback;
  std::vector<glm::vec4> radiance;  // per-frame upload: c_p as RGBA (see uploadProbes)
  FrameStats stats;
  std::vector<std::string> warnings;
  // MaterialShading::Full (material_pass.cpp): the DFG table and the prefiltered maps, by image.
  GlTexture dfg;
  std::map<const ImageRgb*, std::pair<std::shared_ptr<const ImageRgb>, std::vector<ImageRgb>>> reflections;
  int envMaps = 0;                             // reflected maps the MATERIAL programs are compiled for
  GlTexture reflectionArray;                   // the frame's maps' levels as layers (bindReflections)
  std::vector<const ImageRgb*> reflectionKey;  // which maps it holds, in order

  explicit Impl(GlContext& c) : context(c), gl(c.gl()) {}
  void checkError(const char* where) const { checkGlError(gl, where); }

  // Programs (renderer.cpp), linked on first use (DIRECT variants are only needed once a frame
  // has direct lights).
  const Program& bakedProgram(int variant);
  const Program& receiverProgram(ProbeLookup lookup, int variant);
  const Program& cutoutDepthProgram(int variant);

  // The scene and the probes (scene_upload.cpp).
  void upload(const Scene& scene);
  void uploadReceiver(const Scene& scene, const MeshInstance& m);
  void uploadBaked(const Scene& scene, const MeshInstance& m, GLint maxSsbo);
  void setMaterial(const Scene& scene, const MeshInstance& m, Instance& in);
  GLuint sceneTexture(const Scene& scene, int index);
  /// A 2D float texture, bilinear, one level, the given wrap modes.
  GlTexture linearFloatTexture(GLenum internalFormat, GLenum format, int width, int height, const void* texels,
                               GLint wrapS, GLint wrapT) const;
  void uploadProbes(const ProbeGrid& grid);
  void releaseProbes();
  void uploadBounce(const std::vector<std::vector<glm::vec3>>* front, const std::vector<std::vector<glm::vec3>>* back);

  // The frame's passes (renderer.cpp).
  FramePlan planFrame(const Frame& frame);
  void updateLight(const Frame& frame, const FramePlan& plan);
  void updateBakedLight(const Frame& frame, const FramePlan& plan);
  void updateReceiverLight(const Frame& frame, const FramePlan& plan);
  void ensureFramebuffer(int width, int height, int samples, bool reflections);
  void beginFrame(const Frame& frame, FramePlan& plan);
  /// The material's uniforms and textures of `in` for `p`.
  void setMaterialUniforms(const Program& p, const Instance& in);
  void drawInstance(const Program& p, const Instance& in, bool mirrored, bool flat);
  void drawOpaque(const Frame& frame, const FramePlan& plan);
  void drawOpaqueList(const std::vector<Instance>& list, const std::array<Program, kVariants>& variants,
                      bool receiverList, int extra, const Frame& frame, const FramePlan& plan);
  void bindProbeTextures();
  void drawReceivers(const Frame& frame, const FramePlan& plan);
  void drawBlended(const Frame& frame, const FramePlan& plan);
  bool placeBaked(const Instance& in, const FramePlan& plan);
  bool placeReceiver(const Program& p, const Instance& in, const Frame& frame, bool flat);
  ImageRgb readBack(int width, int height);

  // Shadow maps and the direct lights' uniforms (shadow_pass.cpp).
  void ensureDepthArray(ShadowMaps& maps, int size, int layers, const char* what);
  void ensureShadowMaps(int size, int layers);
  /// The shadow maps of the frame's direct lights (when Frame::shadows.enabled) and the direct
  /// uniforms of the DIRECT programs the frame uses.
  void drawShadows(const Frame& frame, const FramePlan& plan);
  void shadowCasterBounds(const Frame& frame, bool withReceivers, glm::dvec3& lo, glm::dvec3& hi,
                          std::vector<glm::dmat4>& motions) const;
  void drawShadowMaps(const ShadowPlan& shadows, const std::vector<glm::dmat4>& motions, bool withReceivers,
                      int mapSize);
  void drawDepthLayers(const ShadowMaps& maps, int mapSize, const std::vector<glm::mat4>& viewProj,
                       const std::vector<glm::dmat4>& motions, bool withReceivers);
  void castShadow(const Instance& in, const glm::mat4& model, const glm::mat4& viewProj, GLuint& current);
  void setDirectUniforms(const Frame& frame, const FramePlan& plan, const ShadowPlan& shadows, bool maps);

  // The lights inside the scene per pixel (local_shading.cpp): their cube maps and uniforms.
  void drawLocalShadows(const Frame& frame, const FramePlan& plan);
  void ensureLocalMaps(int size, int layers);
  void setLocalUniforms(const Frame& frame, const FramePlan& plan, const LocalFrameUniforms& u);

  // The glTF material (material_pass.cpp).
  void setFullMaterial(const Scene& scene, const MeshInstance& m, Instance& in, bool receiver);
  /// The frame's MATERIAL uniforms (eye, reflected maps) on the programs it uses, and the
  /// environment's textures bound.
  void beginMaterialFrame(const Frame& frame, const FramePlan& plan);
  void setFullMaterialUniforms(const Program& p, const Instance& in);
  void bindMaterialBuffers(const Instance& in, bool direct);
  void bindReflections(const RigBackground* environment);

  // The background (background_pass.cpp).
  GLuint environmentTexture(const std::shared_ptr<const ImageRgb>& image);
  void linkBackground();
  void drawBackground(const RigBackground& b, const CameraView& camera, int width, int height);

  // Screen-space reflections (reflection_pass.cpp).
  void attachReflectionTargets(Target& t);
  /// Draws to the reflection pass's inputs too (reflection_inputs.glsl, zeroed) while `on`, to the
  /// colour alone after.
  void drawReflectionInputs(bool on);
  void drawReflections(const Frame& frame, const FramePlan& plan);
};

}  // namespace prt::render
