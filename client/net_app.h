// probecast-client's network mode (--connect): the headless or windowed frame loop fed by a
// NetClient.
#pragma once

#include <string>

#include "client_app.h"
#include "net_client.h"

namespace pc::client {

struct NetRunConfig {
  NetClientOptions net;
  double duration = 0;       // wall-clock seconds to run; 0: ClientConfig::frames frames
  double maxFps = 0;         // frames per second at most (0: as fast as the renderer goes)
  int saveEvery = 1;         // write every Nth frame (0: only the last)
  std::string summary;       // JSON summary written here at exit
  std::string series;        // per-second CSV series (client_series.h); empty: none
  double startupWait = 3.0;  // s the first frame may wait for a layout when no baked field is given
};

// Renders until the duration or frame count is reached, whatever the network does, then
// renders one last frame (<prefix>_last[_left|_right]) and writes the summary. Exit codes as
// runHeadless.
int runNetHeadless(const ClientConfig& config, const NetRunConfig& run);
// The same stream into the window (window.cpp): the fly camera is the viewer; stops when the
// window closes, or after run.duration or ClientConfig::frames where set.
int runNetWindowed(const ClientConfig& config, const NetRunConfig& run);

}  // namespace pc::client
