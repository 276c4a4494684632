#version 460
// Probe rays: report the closest hit; shading happens in ray generation.
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
#include "probe_trace_payload.glsl"

layout(location = 0) rayPayloadInEXT HitPayload hit;
hitAttributeEXT vec2 attribs;

void main() {
  hit.barycentric = attribs;
  hit.t = gl_HitTEXT;
  // Shading record: the static structure holds one geometry per static instance (custom index
  // 0); an animated instance's structure holds one geometry (custom index = its record).
  hit.instance = gl_InstanceCustomIndexEXT + gl_GeometryIndexEXT;
  hit.primitive = gl_PrimitiveID;
}
