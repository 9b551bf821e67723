// Direct volume rendering as a pass of the frame (private to the renderer):
// after the opaque geometry, each pixel's ray is marched through a volume's
// box, front to back, up to the nearest opaque surface or streamline (the
// frame's depth), each sample's value mapped through the object's transfer
// function (scene.hpp TransferFunction) to a colour and an opacity per
// millimetre, and the result composited over the picture (Levoy 1988;
// Engel et al., Real-Time Volume Graphics, 2006).
//
// Opacity is physical: a sample's over a step of s mm is 1 - (1 - a)^s, a
// the opacity of one millimetre, so that the picture does not depend on the
// step (the last step of a ray is as long as what is left of it, so a
// homogeneous volume gives exactly 1 - (1 - a)^L over a path of L mm).
// Colours are the transfer function's colormap entries (sRGB-encoded
// display values, as slices show them), composited as they are on a display
// picture, decoded to what the tone curve turns back into them on a linear
// one. With translucent surfaces or tractograms in the frame, each ray is
// marched in segments between their depth-peeled layers instead, so that a
// translucent object in front of a volume is in front of it.
//
// Threading: the GL context's thread.
#pragma once

#include "../gl.hpp"
#include "../gpu_object.hpp"
#include "frame_depth.hpp"

#include <glm/glm.hpp>

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace hz::core::render {

struct VolumeRayParams {
    glm::mat4 inv_view_proj{1.0f};  // clip -> world mm
    glm::vec3 eye{0.0f};
    glm::mat4 ras_to_tex{1.0f};  // world mm -> the volume's texture coordinates ([0, 1] inside)
    glm::vec2 window{0.0f, 1.0f};
    float step_mm = 0.5f;                  // the march's step (equal steps of at most this)
    float opacity = 1.0f;                  // the object's: multiplies what the ray gathered
    GLuint volume_tex = 0;                 // R32F 3D, linear
    GLuint transfer_tex = 0;               // 256 x 1 RGBA16F: colormap (display values), opacity of 1 mm
    int tone_curve = 0;                    // the scene's (glsl.hpp kDisplay), for a linear picture
    float exposure = 1.0f;                 // the scene's, likewise
    bool shade = false;                    // lit where the values change (TransferFunction::shade)
    glm::vec3 to_light{0.0f, 0.0f, 1.0f};  // the key light, world, unit
};

class VolumeRendering {
public:
    using MakeProgram = std::function<std::unique_ptr<Program>(const std::string &vs, const std::string &fs, const std::string &what)>;
    explicit VolumeRendering(MakeProgram make);
    ~VolumeRendering();
    VolumeRendering(const VolumeRendering &) = delete;
    VolumeRendering &operator=(const VolumeRendering &) = delete;

    // Composites the volume of `p` over the picture in `colour_fbo` (the
    // size of `depth`; display values if `encoded`, else linear radiance)
    // with rays ending at `depth`. `empty_vao`: a vertex array for a
    // full-screen triangle. Leaves depth testing and blending off.
    void apply(GLuint colour_fbo, const FrameDepth &depth, const VolumeRayParams &p, GLuint empty_vao, bool encoded);
    // The part of each ray between the window depths of the textures
    // `near_depth` (0: from the eye) and `far_depth` (1: unbounded), into
    // the bound framebuffer (linear radiance) as premultiplied colour, with
    // the blending the caller set: what lies between two layers of depth
    // peeling (transparency.hpp), composited under the layers in front.
    // The viewport is the caller's; the textures are its size.
    void apply_segment(GLuint near_depth, GLuint far_depth, const VolumeRayParams &p, GLuint empty_vao);

private:
    Program &program(bool encoded, int tone_curve, bool segment);
    void march(Program &prog, const VolumeRayParams &p, GLuint far_depth, GLuint near_depth, GLuint empty_vao);
    MakeProgram make_;
    std::map<int, std::unique_ptr<Program>> programs_;
};

// The transfer function's table as the pass reads it: 256 RGBA entries, the
// colormap's (sRGB-encoded) colour and the opacity of one millimetre at
// each of 256 fractions of the window (0 to 1).
std::vector<float> transfer_table(const TransferFunction &tf);

}  // namespace hz::core::render
