#include "stream_tuning.h"

namespace pc {

void applyStreamTuning(const StreamTuning& tuning, PublisherOptions& publisher,
                       SenderOptions& sender) {
  if (tuning.threshold <= 0.0f) {
    publisher.deadZone = DeadZone{};
    sender.irradianceThreshold = 0.0f;
    sender.irradianceMeanThreshold = 0.0f;
    sender.depthThreshold = 0.0f;
    sender.occlusionThreshold = 0.0f;
    sender.offsetThreshold = 0.0f;
    return;
  }
  const float t = tuning.threshold;
  // Dead zone: a code keeps its previous value while the value moved by no more than T, so
  // ray noise leaves most codes alone between versions and residuals are mostly zeros.
  publisher.deadZone.irradiance = t;
  // Depth and occlusion follow static geometry: between versions their change is ray noise.
  // A quarter of a texel's mean distance does not move the visibility test's answer visibly
  // (the Chebyshev bound is flat where the mean is far from the shading point).
  publisher.deadZone.depth = tuning.depthTolerance;
  publisher.deadZone.occlusion = tuning.occlusionTolerance;
  // Relocation and classification jitter with fresh ray directions every update. Offsets
  // within 5% of the spacing and active <-> sleeping flips render the same.
  publisher.deadZone.offset = 0.05f;
  publisher.deadZone.sleepingAsActive = true;
  // A brick is sent when its mean irradiance change reaches T, or one texel moved by 8 T
  // (a small bright change). Depth, occlusion and offset jitter never force a send on their
  // own: they ride along with irradiance sends and refreshes, except a real relocation (a
  // quarter of the spacing) or a probe state change.
  sender.irradianceMeanThreshold = t;
  sender.irradianceThreshold = 8.0f * t;
  sender.depthThreshold = 1.0f;
  sender.occlusionThreshold = 1.0f;
  sender.offsetThreshold = 0.25f;
}

}  // namespace pc
