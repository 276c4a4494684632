// Declarations every client shader shares: the descriptor set of shaders/interop/client_frame.h.
// Each shader includes this after its #version and extensions.
#include "../interop/client_frame.h"
#include "../interop/field_desc.h"

layout(set = 0, binding = PC_CLIENT_BIND_FRAME) uniform FrameBlock { FrameUniforms frame; };
layout(set = 0, binding = PC_CLIENT_BIND_DRAWS, std430) readonly buffer DrawBlock { DrawData draws[]; };
