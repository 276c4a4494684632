// Spherical-harmonics probes (PC_ENCODING_SH1, PC_ENCODING_SH2): the real SH basis up to band 2,
// the cosine lobe's zonal coefficients that turn radiance coefficients into irradiance
// (Ramamoorthi and Hanrahan, "An efficient representation for irradiance environment maps",
// 2001), and the stored size of a probe. Shared by the Embree path (projection), the CPU
// sampling and, later, the shaders.
//
// A probe's coefficients are L_i = integral over the sphere of L(w) Y_i(w), estimated from its
// rays as (4 pi / rays) * sum L(w_r) Y_i(w_r) (the ray directions are uniform on the sphere).
// Irradiance toward n is E(n) = sum_i A(l_i) L_i Y_i(n), clamped at 0 (a truncated series can
// ring below zero). Every constant is written as its closed form; tests/test_sh_probes.cpp
// checks each against its integral and against the paper's five combined constants.
#ifndef PC_SH_PROBE_H
#define PC_SH_PROBE_H

#include "field_desc.h"

PC_BEGIN

PC_CONST int PC_SH_MAX_COEFFICIENTS = 9;  // band 2: 1 + 3 + 5

// Basis normalisations, so that each Y_i integrates to 1 squared over the sphere:
PC_CONST float PC_SH_K0 = 0.282094791774f;   // 1/2 sqrt(1/pi)
PC_CONST float PC_SH_K1 = 0.488602511903f;   // sqrt(3/(4 pi))
PC_CONST float PC_SH_K2 = 1.092548430592f;   // 1/2 sqrt(15/pi): xy, yz, xz
PC_CONST float PC_SH_K20 = 0.315391565253f;  // 1/4 sqrt(5/pi): 3z^2 - 1
PC_CONST float PC_SH_K22 = 0.546274215296f;  // 1/4 sqrt(15/pi): x^2 - y^2

// Zonal coefficients of the clamped cosine, A_l = 2 pi * integral_0^1 t P_l(t) dt:
PC_CONST float PC_SH_A0 = PC_PI;                // 2 pi * 1/2
PC_CONST float PC_SH_A1 = 2.0f * PC_PI / 3.0f;  // 2 pi * 1/3
PC_CONST float PC_SH_A2 = PC_PI / 4.0f;         // 2 pi * 1/8

// Halves stored per probe: L2 has 27 coefficients (54 bytes), padded to 28 (56 bytes) so a
// probe starts on a 4-byte boundary; L1 has 12 (24 bytes).
PC_CONST int PC_SH2_STORED_HALVES = 28;
PC_CONST int PC_SH1_STORED_HALVES = 12;

PC_FN bool pcEncodingIsSh(int encoding) {
  return encoding == PC_ENCODING_SH1 || encoding == PC_ENCODING_SH2;
}

// Coefficients per colour channel (0 for octahedral).
PC_FN int pcShCoefficientCount(int encoding) {
  if (encoding == PC_ENCODING_SH2) return 9;
  if (encoding == PC_ENCODING_SH1) return 4;
  return 0;
}

PC_FN int pcShStoredHalves(int encoding) {
  if (encoding == PC_ENCODING_SH2) return PC_SH2_STORED_HALVES;
  if (encoding == PC_ENCODING_SH1) return PC_SH1_STORED_HALVES;
  return 0;
}

// Y_i(d) for unit d, in the order (l, m) = (0,0), (1,-1), (1,0), (1,1), (2,-2) .. (2,2).
PC_FN float pcShBasis(int i, vec3 d) {
  if (i == 0) return PC_SH_K0;
  if (i == 1) return PC_SH_K1 * d.y;
  if (i == 2) return PC_SH_K1 * d.z;
  if (i == 3) return PC_SH_K1 * d.x;
  if (i == 4) return PC_SH_K2 * d.x * d.y;
  if (i == 5) return PC_SH_K2 * d.y * d.z;
  if (i == 6) return PC_SH_K20 * (3.0f * d.z * d.z - 1.0f);
  if (i == 7) return PC_SH_K2 * d.x * d.z;
  return PC_SH_K22 * (d.x * d.x - d.y * d.y);
}

// The cosine lobe's factor for coefficient i (its band's A_l).
PC_FN float pcShCosineLobe(int i) {
  if (i == 0) return PC_SH_A0;
  if (i < 4) return PC_SH_A1;
  return PC_SH_A2;
}

PC_END

#endif
