// OpenGL entry points for the renderer: GLVND's libOpenGL exports every core
// function and dispatches to whichever context (EGL or GLX) is current, so no
// loader is needed and one binary serves the window and the headless path.
#pragma once

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>
