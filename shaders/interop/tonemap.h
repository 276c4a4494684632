// Exposure, tone curve and sRGB encoding used by every image probecast writes, so PSNR
// between renderers compares like with like.
#ifndef PC_TONEMAP_H
#define PC_TONEMAP_H

#include "pc_interop.h"

PC_BEGIN

// Narkowicz's fit of the ACES filmic curve: linear radiance (after exposure) -> [0,1].
PC_FN vec3 pcToneCurve(vec3 x) {
  const float a = 2.51f, b = 0.03f, c = 2.43f, d = 0.59f, e = 0.14f;
  vec3 y = (x * (a * x + vec3(b))) / (x * (c * x + vec3(d)) + vec3(e));
  return clamp(y, vec3(0.0f), vec3(1.0f));
}

PC_FN float pcSrgbEncode(float v) {
  return v <= 0.0031308f ? 12.92f * v : 1.055f * pow(v, 1.0f / 2.4f) - 0.055f;
}
PC_FN float pcSrgbDecode(float v) {
  return v <= 0.04045f ? v / 12.92f : pow((v + 0.055f) / 1.055f, 2.4f);
}

// Linear radiance -> display sRGB in [0,1].
PC_FN vec3 pcTonemap(vec3 radiance, float exposure) {
  vec3 t = pcToneCurve(max(radiance * exposure, vec3(0.0f)));
  return vec3(pcSrgbEncode(t.x), pcSrgbEncode(t.y), pcSrgbEncode(t.z));
}

PC_END

#endif
