// The scene's triangles as the lighting pass and the compute rasterizer read them: the packed
// vertex and index buffers (client/scene_pack.h) and the draw that owns a triangle id
// (client_frame.h, DrawData). Needs client_common.glsl first.
#ifndef PC_CLIENT_GEOMETRY_GLSL
#define PC_CLIENT_GEOMETRY_GLSL

layout(set = 0, binding = PC_CLIENT_BIND_VERTICES, std430) readonly buffer VertexBlock { float vertexData[]; };
layout(set = 0, binding = PC_CLIENT_BIND_INDICES, std430) readonly buffer IndexBlock { uint indexData[]; };

// The draw owning triangle id `triangle`: the last whose triangleBase is not above it.
int drawOfTriangle(uint triangle) {
  int lo = 0, hi = frame.drawCount;
  while (hi - lo > 1) {
    int mid = (lo + hi) / 2;
    if (uint(draws[mid].geometry.z) <= triangle) lo = mid;
    else hi = mid;
  }
  return lo;
}

struct VertexRecord {
  vec3 position;
  vec3 normal;
  vec2 uv;
  vec4 tangent;  // xyz, handedness w; zero where the mesh has none
};

VertexRecord vertexAt(uint v) {
  uint b = uint(PC_CLIENT_VERTEX_FLOATS) * v;
  VertexRecord r;
  r.position = vec3(vertexData[b], vertexData[b + 1u], vertexData[b + 2u]);
  r.normal = vec3(vertexData[b + 3u], vertexData[b + 4u], vertexData[b + 5u]);
  r.uv = vec2(vertexData[b + 6u], vertexData[b + 7u]);
  r.tangent = vec4(vertexData[b + 8u], vertexData[b + 9u], vertexData[b + 10u], vertexData[b + 11u]);
  return r;
}

// Vertex indices of the corners of triangle id `triangle` (0-based) of draw `d`.
void triangleVertices(DrawData d, uint triangle, out uint i0, out uint i1, out uint i2) {
  uint first = uint(d.geometry.x) + 3u * (triangle - uint(d.geometry.z));
  i0 = uint(int(indexData[first]) + d.geometry.y);
  i1 = uint(int(indexData[first + 1u]) + d.geometry.y);
  i2 = uint(int(indexData[first + 2u]) + d.geometry.y);
}

#endif
