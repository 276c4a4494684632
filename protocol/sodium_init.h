// libsodium must be initialised once before use (it picks its implementations and opens the
// system's random source); every protocol source that calls it calls this first. Stops the
// process with a message where the system has no randomness (secure_io.h says why).
#pragma once

namespace pc {

void ensureSodium();

}  // namespace pc
