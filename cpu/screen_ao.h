// Screen-space ambient occlusion of the indirect light for the CPU probe-lit render: the
// estimator of shaders/interop/screen_ao.h (GTAO), fed with a buffer of the view's surfaces
// through the pixel centres, as the client feeds it from its visibility buffer. The same
// buffer also tells which pixels lie near a contact (cpu/contact_band.h).
#pragma once

#include <glm/glm.hpp>
#include <vector>

#include "../common/field.h"
#include "camera.h"
#include "embree_scene.h"

namespace pc {

// The surface under each pixel centre (row 0 at the top).
struct ViewSurfaces {
  int width = 0, height = 0;
  glm::vec3 eye{0.0f};
  std::vector<glm::vec4> position;  // xyz relative to the eye; w 1, or 0 where the sky shows
  std::vector<glm::vec3> normal;    // shading normal, turned toward the eye
  std::vector<glm::vec3> albedo;
};

// Traces one ray through every pixel centre.
ViewSurfaces traceViewSurfaces(const EmbreeScene& scene, const PinholeCamera& camera, int width,
                               int height);

// Per pixel: the visibility (0..1) the shared estimator gives the surface under the pixel
// centre, with a radius of `radiusScale` x the probe spacing there; 1 where the sky shows.
std::vector<float> screenAmbientOcclusion(const ViewSurfaces& surfaces, const PinholeCamera& camera,
                                          const Field& field, float radiusScale);

}  // namespace pc
