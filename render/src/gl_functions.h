// The GL entry points prt::render uses, loaded from the current context (private header).
//
// Why not call GL directly: a binary that links libGL or libOpenGL next to libOSMesa gets its
// direct GL calls dispatched to GLX/GLVND instead of OSMesa, where they silently do nothing
// (glGetString returns NULL). prt links only libEGL (libOSMesa is opened at run time, in
// gl_context.cpp) and fetches every entry point through OSMesaGetProcAddress / eglGetProcAddress
// of the context that is current (../../shared/notes/platform.md). glad is not packaged, libepoxy aborts under OSMesa,
// and GLEW
// misreports under EGL, so the table is ours: one line per function in PRT_GL_FUNCTIONS.
#pragma once

#include <string>

// Typedefs (PFNGL...PROC) and enums only: without GL_GLEXT_PROTOTYPES the header declares no
// functions, so a direct gl* call does not even compile.
#include <GL/glcorearb.h>

namespace prt::render {

// X(typedef, name): the member is `name`, the entry point "gl" #name.
#define PRT_GL_FUNCTIONS(X)                                                            \
  X(PFNGLGETSTRINGPROC, GetString)                                                     \
  X(PFNGLGETINTEGERVPROC, GetIntegerv)                                                 \
  X(PFNGLGETERRORPROC, GetError)                                                       \
  X(PFNGLFINISHPROC, Finish)                                                           \
  X(PFNGLVIEWPORTPROC, Viewport)                                                       \
  X(PFNGLENABLEPROC, Enable)                                                           \
  X(PFNGLDISABLEPROC, Disable)                                                         \
  X(PFNGLDEPTHFUNCPROC, DepthFunc)                                                     \
  X(PFNGLDEPTHMASKPROC, DepthMask)                                                     \
  X(PFNGLBLENDFUNCPROC, BlendFunc)                                                     \
  X(PFNGLCLIPCONTROLPROC, ClipControl)                                                 \
  X(PFNGLCULLFACEPROC, CullFace)                                                       \
  X(PFNGLFRONTFACEPROC, FrontFace)                                                     \
  X(PFNGLPIXELSTOREIPROC, PixelStorei)                                                 \
  X(PFNGLREADPIXELSPROC, ReadPixels)                                                   \
  X(PFNGLCREATEBUFFERSPROC, CreateBuffers)                                             \
  X(PFNGLNAMEDBUFFERSTORAGEPROC, NamedBufferStorage)                                   \
  X(PFNGLNAMEDBUFFERSUBDATAPROC, NamedBufferSubData)                                   \
  X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                                             \
  X(PFNGLBINDBUFFERBASEPROC, BindBufferBase)                                           \
  X(PFNGLCREATEVERTEXARRAYSPROC, CreateVertexArrays)                                   \
  X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)                                   \
  X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                                         \
  X(PFNGLVERTEXARRAYVERTEXBUFFERPROC, VertexArrayVertexBuffer)                         \
  X(PFNGLVERTEXARRAYELEMENTBUFFERPROC, VertexArrayElementBuffer)                       \
  X(PFNGLVERTEXARRAYATTRIBFORMATPROC, VertexArrayAttribFormat)                         \
  X(PFNGLVERTEXARRAYATTRIBBINDINGPROC, VertexArrayAttribBinding)                       \
  X(PFNGLENABLEVERTEXARRAYATTRIBPROC, EnableVertexArrayAttrib)                         \
  X(PFNGLDRAWELEMENTSPROC, DrawElements)                                               \
  X(PFNGLDRAWARRAYSPROC, DrawArrays)                                                   \
  X(PFNGLCREATETEXTURESPROC, CreateTextures)                                           \
  X(PFNGLDELETETEXTURESPROC, DeleteTextures)                                           \
  X(PFNGLTEXTURESTORAGE2DPROC, TextureStorage2D)                                       \
  X(PFNGLTEXTURESTORAGE3DPROC, TextureStorage3D)                                       \
  X(PFNGLTEXTURESUBIMAGE3DPROC, TextureSubImage3D)                                     \
  X(PFNGLNAMEDFRAMEBUFFERTEXTURELAYERPROC, NamedFramebufferTextureLayer)               \
  X(PFNGLTEXTURESUBIMAGE2DPROC, TextureSubImage2D)                                     \
  X(PFNGLTEXTUREPARAMETERIPROC, TextureParameteri)                                     \
  X(PFNGLTEXTUREBUFFERPROC, TextureBuffer)                                             \
  X(PFNGLBINDTEXTUREUNITPROC, BindTextureUnit)                                         \
  X(PFNGLCREATEFRAMEBUFFERSPROC, CreateFramebuffers)                                   \
  X(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers)                                   \
  X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)                                         \
  X(PFNGLNAMEDFRAMEBUFFERRENDERBUFFERPROC, NamedFramebufferRenderbuffer)               \
  X(PFNGLNAMEDFRAMEBUFFERREADBUFFERPROC, NamedFramebufferReadBuffer)                   \
  X(PFNGLNAMEDFRAMEBUFFERDRAWBUFFERPROC, NamedFramebufferDrawBuffer)                   \
  X(PFNGLNAMEDFRAMEBUFFERDRAWBUFFERSPROC, NamedFramebufferDrawBuffers)                 \
  X(PFNGLNAMEDFRAMEBUFFERTEXTUREPROC, NamedFramebufferTexture)                         \
  X(PFNGLGENERATETEXTUREMIPMAPPROC, GenerateTextureMipmap)                             \
  X(PFNGLBLENDFUNCSEPARATEPROC, BlendFuncSeparate)                                     \
  X(PFNGLCHECKNAMEDFRAMEBUFFERSTATUSPROC, CheckNamedFramebufferStatus)                 \
  X(PFNGLCLEARNAMEDFRAMEBUFFERFVPROC, ClearNamedFramebufferfv)                         \
  X(PFNGLCREATERENDERBUFFERSPROC, CreateRenderbuffers)                                 \
  X(PFNGLDELETERENDERBUFFERSPROC, DeleteRenderbuffers)                                 \
  X(PFNGLNAMEDRENDERBUFFERSTORAGEPROC, NamedRenderbufferStorage)                       \
  X(PFNGLNAMEDRENDERBUFFERSTORAGEMULTISAMPLEPROC, NamedRenderbufferStorageMultisample) \
  X(PFNGLBLITNAMEDFRAMEBUFFERPROC, BlitNamedFramebuffer)                               \
  X(PFNGLGETNAMEDRENDERBUFFERPARAMETERIVPROC, GetNamedRenderbufferParameteriv)         \
  X(PFNGLCREATESHADERPROC, CreateShader)                                               \
  X(PFNGLSHADERSOURCEPROC, ShaderSource)                                               \
  X(PFNGLCOMPILESHADERPROC, CompileShader)                                             \
  X(PFNGLGETSHADERIVPROC, GetShaderiv)                                                 \
  X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)                                       \
  X(PFNGLDELETESHADERPROC, DeleteShader)                                               \
  X(PFNGLCREATEPROGRAMPROC, CreateProgram)                                             \
  X(PFNGLATTACHSHADERPROC, AttachShader)                                               \
  X(PFNGLLINKPROGRAMPROC, LinkProgram)                                                 \
  X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                                               \
  X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)                                     \
  X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                                             \
  X(PFNGLUSEPROGRAMPROC, UseProgram)                                                   \
  X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)                                   \
  X(PFNGLPROGRAMUNIFORM1IPROC, ProgramUniform1i)                                       \
  X(PFNGLPROGRAMUNIFORM1FPROC, ProgramUniform1f)                                       \
  X(PFNGLPROGRAMUNIFORM3IVPROC, ProgramUniform3iv)                                     \
  X(PFNGLPROGRAMUNIFORM4IVPROC, ProgramUniform4iv)                                     \
  X(PFNGLPROGRAMUNIFORM3FVPROC, ProgramUniform3fv)                                     \
  X(PFNGLPROGRAMUNIFORM4FVPROC, ProgramUniform4fv)                                     \
  X(PFNGLPROGRAMUNIFORM2FVPROC, ProgramUniform2fv)                                     \
  X(PFNGLPROGRAMUNIFORMMATRIX3FVPROC, ProgramUniformMatrix3fv)                         \
  X(PFNGLPROGRAMUNIFORMMATRIX4FVPROC, ProgramUniformMatrix4fv)

/// The function table of one context. Pointers from one context must not be used with another
/// (OSMesa and EGL hand out different dispatch stubs).
struct GlFunctions {
#define PRT_GL_MEMBER(type, name) type name = nullptr;
  PRT_GL_FUNCTIONS(PRT_GL_MEMBER)
#undef PRT_GL_MEMBER

  /// Fills every pointer through `getProcAddress` ("glClear" -> address). Throws prt::Error
  /// naming the first missing function, prefixed by `who` ("OSMesa", "EGL").
  void load(void* (*getProcAddress)(const char*), const char* who);
};

/// "GL_INVALID_OPERATION" for the GL error codes, hex otherwise.
std::string glErrorName(GLenum error);

}  // namespace prt::render
