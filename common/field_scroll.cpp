#include "field_scroll.h"

#include <cmath>
#include <cstdlib>

namespace pc {

using namespace pc::gpu;

namespace {

int wrap(int v, int n) { return ((v % n) + n) % n; }

}  // namespace

glm::ivec3 originShift(glm::vec3 from, glm::vec3 to, float spacing) {
  const glm::vec3 steps = (to - from) / spacing;
  return glm::ivec3(int(std::lround(steps.x)), int(std::lround(steps.y)),
                    int(std::lround(steps.z)));
}

std::vector<int> scrollCascade(Field& field, int k, glm::ivec3 shift) {
  std::vector<int> reset;
  if (shift == glm::ivec3(0)) return reset;
  CascadeDesc& c = field.desc.cascades[k];
  c.origin += glm::vec3(shift) * c.spacing;
  c.scroll = ivec3(wrap(c.scroll.x + shift.x, c.counts.x), wrap(c.scroll.y + shift.y, c.counts.y),
                   wrap(c.scroll.z + shift.z, c.counts.z));
  // In the new layout, logical coordinate l was inside the old cascade when l + shift lies in
  // [0, counts) on every axis; the others came in.
  for (int s = 0; s < pcSlotCount(c); ++s) {
    if (!pcSlotValid(c, s)) continue;
    const ivec3 was = pcLogicalCoord(c, pcSlotCoord(c, s)) + shift;
    if (was.x >= 0 && was.y >= 0 && was.z >= 0 && was.x < c.counts.x && was.y < c.counts.y &&
        was.z < c.counts.z)
      continue;
    ProbeRecord& r = field.probe(k, s);
    r = ProbeRecord{};
    if (!field.sh.empty()) field.shProbe(k, s) = ShCoefficients{};
    reset.push_back(s);
  }
  return reset;
}

glm::ivec3 followShift(const CascadeDesc& c, glm::vec3 center) {
  const glm::vec3 middle = c.origin + glm::vec3(c.counts - 1) * (0.5f * c.spacing);
  const glm::vec3 off = (center - middle) / c.spacing;
  // Truncation towards zero: a centre less than a spacing off stays; past it, the cascade
  // moves by the whole spacings it is off.
  return glm::ivec3(int(std::trunc(off.x)), int(std::trunc(off.y)), int(std::trunc(off.z)));
}

bool slotMatchesStamp(const CascadeDesc& current, glm::vec3 stampOrigin, glm::ivec3 physical) {
  const ivec3 d = originShift(stampOrigin, current.origin, current.spacing);
  if (d == ivec3(0)) return true;
  const ivec3 n = current.counts;
  for (int a = 0; a < 3; ++a) {
    // The stamp's scroll is the current one less the move; the slot's logical coordinate under
    // the stamp, less the move, is its coordinate now when that lies inside.
    if (std::abs(d[a]) >= n[a]) return false;
    const int stampScroll = wrap(current.scroll[a] - d[a], n[a]);
    const int logical = wrap(physical[a] - stampScroll, n[a]);
    const int now = logical - d[a];
    if (now < 0 || now >= n[a]) return false;
  }
  return true;
}

}  // namespace pc
