// Compiling and linking the renderer's programs (gl_program.h).
#include "gl_program.h"

#include "prt/error.h"

namespace prt::render {

namespace {

GlShader compile(const GlFunctions& gl, GLenum type, const char* source, const std::string& what) {
  GlShader s = createShader(gl, type);
  gl.ShaderSource(s, 1, &source, nullptr);
  gl.CompileShader(s);
  GLint ok = 0;
  gl.GetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetShaderInfoLog(s, sizeof log, nullptr, log);
    throw Error(cat("GL: ", what, " shader does not compile: ", log));
  }
  return s;
}

void findUniforms(const GlFunctions& gl, Program& p) {
  auto loc = [&](const char* name) { return gl.GetUniformLocation(p.id, name); };
  p.viewProj = loc("uViewProj");
  p.model = loc("uModel");
  p.normalMatrix = loc("uNormalMatrix");
  // The light: flat vec4 chunks (baked, attribute transfer), RGB per coefficient (baked, storage
  // transfer) or packed as the probes (receivers); a program has one of the three.
  p.light = loc("uLightFlat");
  if (p.light < 0) p.light = loc("uLight");
  if (p.light < 0) p.light = loc("uLightPacked");
  p.baseColor = loc("uBaseColor");
  p.origin = loc("uOrigin");
  p.spacing = loc("uSpacing");
  p.dims = loc("uDims");
  p.nearZero = loc("uNearZero");
  p.alphaCutoff = loc("uAlphaCutoff");
  p.opacity = loc("uOpacity");
  p.directSh = loc("uDirectSh");
  p.directCount = loc("uDirectCount");
  p.directDir = loc("uDirectDir");
  p.directIrradiance = loc("uDirectIrradiance");
  p.shadowed = loc("uShadowed");
  p.cascades = loc("uCascades");
  p.cascadeFar = loc("uCascadeFar");
  p.viewOrigin = loc("uViewOrigin");
  p.viewForward = loc("uViewForward");
  p.shadowSize = loc("uShadowSize");
  p.shadowMatrix = loc("uShadowMatrix");
  p.shadowParams = loc("uShadowParams");
  p.loopStep = loc("uLoopStep");
  p.material = loc("uMaterial");
  p.emissive = loc("uEmissive");
  p.specularColor = loc("uSpecularColor");
  p.diffuseScale = loc("uDiffuseScale");
  p.slots = loc("uSlots");
  p.vertexInputs = loc("uVertexInputs");
  p.eye = loc("uEye");
  p.envWorldToMap = loc("uEnvWorldToMap");
  p.envScale = loc("uEnvScale");
  p.envUniform = loc("uEnvUniform");
  p.envMaxLod = loc("uEnvMaxLod");
  p.skySh = loc("uSkySh");
  p.envOn = loc("uEnvOn");
}

}  // namespace

void checkGlError(const GlFunctions& gl, const char* where) {
  const GLenum e = gl.GetError();
  if (e != GL_NO_ERROR) throw Error(cat("GL: ", glErrorName(e), " ", where));
}

Program linkProgram(const GlFunctions& gl, const std::string& vertexSource, const std::string& fragmentSource,
                    const char* what) {
  Program p;
  {
    const GlShader vs = compile(gl, GL_VERTEX_SHADER, vertexSource.c_str(), cat(what, " vertex"));
    const GlShader fs = compile(gl, GL_FRAGMENT_SHADER, fragmentSource.c_str(), cat(what, " fragment"));
    p.id = createProgram(gl);
    gl.AttachShader(p.id, vs);
    gl.AttachShader(p.id, fs);
    gl.LinkProgram(p.id);
  }  // the shaders go; the program keeps what it linked
  GLint ok = 0;
  gl.GetProgramiv(p.id, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetProgramInfoLog(p.id, sizeof log, nullptr, log);
    throw Error(cat("GL: ", what, " shader program does not link: ", log));
  }
  findUniforms(gl, p);
  return p;
}

}  // namespace prt::render
