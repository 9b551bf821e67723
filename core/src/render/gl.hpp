// OpenGL entry points for the renderer: GLVND's libOpenGL exports every core
// function and dispatches to whichever context (EGL or GLX) is current, so no
// loader is needed and one binary serves the window and the headless path.
#pragma once

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>

namespace hz::core::render {
// The bound 2D texture's filter (min and mag) and edges clamped: the
// renderer's targets and lookup tables.
inline void clamped_texture_2d(GLint filter) {
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filter);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filter);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}
}  // namespace hz::core::render
