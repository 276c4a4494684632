#include "split_sum_table.h"

#include <algorithm>
#include <cmath>

namespace pc {
namespace {

// Van der Corput radical inverse in base 2: the second Hammersley coordinate.
float radicalInverse(unsigned bits) {
  bits = (bits << 16u) | (bits >> 16u);
  bits = ((bits & 0x55555555u) << 1u) | ((bits & 0xAAAAAAAAu) >> 1u);
  bits = ((bits & 0x33333333u) << 2u) | ((bits & 0xCCCCCCCCu) >> 2u);
  bits = ((bits & 0x0F0F0F0Fu) << 4u) | ((bits & 0xF0F0F0F0u) >> 4u);
  bits = ((bits & 0x00FF00FFu) << 8u) | ((bits & 0xFF00FF00u) >> 8u);
  return float(bits) * 2.3283064365386963e-10f;
}

constexpr int kTableSamples = 1024;

}  // namespace

glm::vec2 integrateSplitSum(float NdotV, float roughness, int samples) {
  using namespace gpu;
  const float alpha = pcGgxAlpha(roughness);
  // View in the frame where N is +Z.
  const glm::vec3 V(std::sqrt(std::max(0.0f, 1.0f - NdotV * NdotV)), 0.0f, NdotV);
  glm::dvec2 sum(0.0);
  for (int s = 0; s < samples; ++s) {
    const float u1 = (float(s) + 0.5f) / float(samples);
    const float u2 = radicalInverse(unsigned(s));
    const glm::vec3 H = pcSampleGgxVndf(V, alpha, u1, u2);
    const float VdotH = glm::dot(V, H);
    const glm::vec3 L = 2.0f * VdotH * H - V;
    const float NdotL = L.z;
    if (!(NdotL > 0.0f)) continue;
    const float pdf = pcGgxVndfPdf(NdotV, std::max(H.z, 0.0f), alpha);
    if (!(pdf > 0.0f)) continue;
    // f / F x N.L / pdf: D and the visibility term of pcGgxSpecular without its Fresnel.
    const float w =
        pcGgxD(std::max(H.z, 0.0f), alpha) * pcSmithVisibility(NdotL, NdotV, alpha) * NdotL / pdf;
    const float fc = pcSchlickWeight(VdotH);
    sum += glm::dvec2(w * (1.0f - fc), w * fc);
  }
  return glm::vec2(sum / double(samples));
}

const SplitSumTable& splitSumTable() {
  static const SplitSumTable table = [] {
    SplitSumTable t{};
    for (int j = 0; j < gpu::PC_SPLIT_SUM_SIZE; ++j) {
      for (int i = 0; i < gpu::PC_SPLIT_SUM_SIZE; ++i) {
        t[std::size_t(i + gpu::PC_SPLIT_SUM_SIZE * j)] =
            integrateSplitSum(gpu::pcSplitSumNdotV(i), gpu::pcSplitSumRoughness(j), kTableSamples);
      }
    }
    return t;
  }();
  return table;
}

glm::vec2 lookupSplitSum(const SplitSumTable& table, float NdotV, float roughness) {
  const glm::vec2 c = gpu::pcSplitSumCoord(NdotV, roughness);
  const int last = gpu::PC_SPLIT_SUM_SIZE - 1;
  const int i0 = std::min(int(c.x), last - 1), j0 = std::min(int(c.y), last - 1);
  const glm::vec2 f = c - glm::vec2(float(i0), float(j0));
  auto at = [&](int i, int j) { return table[std::size_t(i + gpu::PC_SPLIT_SUM_SIZE * j)]; };
  return glm::mix(glm::mix(at(i0, j0), at(i0 + 1, j0), f.x),
                  glm::mix(at(i0, j0 + 1), at(i0 + 1, j0 + 1), f.x), f.y);
}

}  // namespace pc
