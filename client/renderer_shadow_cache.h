// Which shadow map layers a frame must redraw. A layer keeps its depth from the frame that
// last drew it; it is redrawn only when its light's view changed, or when a draw whose
// transform changed since the previous frame could cast into it (its world bounds, before or
// after the change, touch the layer's frustum). Static scenes draw every layer once.
#pragma once

#include <glm/glm.hpp>
#include <span>
#include <vector>

#include "light_pack.h"

namespace pc::client {

// Object-space bounds of a draw's mesh.
struct LocalBounds {
  glm::vec3 lo{0.0f}, hi{0.0f};
};

// True when the box `lo..hi` (world) may touch the clip volume of `viewProj` (Vulkan depth
// 0..1). Conservative: false only when all corners lie outside one clip plane.
bool boxTouchesFrustum(const glm::mat4& viewProj, glm::vec3 lo, glm::vec3 hi);

// World bounds of an object-space box under `m`.
void worldBox(const glm::mat4& m, const LocalBounds& b, glm::vec3& lo, glm::vec3& hi);

class ShadowCache {
 public:
  // Forgets everything: the next frame draws every layer.
  void reset(std::span<const int> layersPerArray);
  // The views of `views` that must be drawn this frame, for draws at `models` (one per draw;
  // `bounds` per draw too). Assumes the caller draws them: they count as current afterwards.
  std::vector<ShadowView> select(const std::vector<ShadowView>& views,
                                 std::span<const glm::mat4> models,
                                 std::span<const LocalBounds> bounds);
  // True until a frame has drawn into the arrays (they start in an undefined layout).
  bool fresh() const { return fresh_; }

 private:
  struct Layer {
    bool valid = false;
    glm::mat4 viewProj{0.0f};
  };
  std::vector<Layer> layers_[kShadowArrays];  // [array][layer]
  std::vector<glm::mat4> models_;             // the previous frame's draw transforms
  bool fresh_ = true;
};

}  // namespace pc::client
