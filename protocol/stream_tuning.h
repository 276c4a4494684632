// How much of the field's change a stream carries: one perceptual threshold T (a change of the
// gamma-encoded irradiance e) sets the publisher's dead zone and the sender's thresholds
// together, so the server and the bandwidth benchmark stream with the same rules.
// docs/BENCHMARKS.md ("Streaming bandwidth") has the trade-off of T against bandwidth and PSNR.
#pragma once

#include "protocol/field_publisher.h"
#include "protocol/stream_sender.h"

namespace pc {

struct StreamTuning {
  float threshold = 0.008f;      // T; 0: every version exactly (no dead zone, no skipping)
  float depthTolerance = 0.25f;  // dead zone of depth, x the texel's mean distance
  float occlusionTolerance = 0.02f;
};

// Sets the dead zone of `publisher` and the thresholds of `sender` from `tuning`; leaves
// everything else (rates, intervals, history) as it was.
void applyStreamTuning(const StreamTuning& tuning, PublisherOptions& publisher,
                       SenderOptions& sender);

}  // namespace pc
