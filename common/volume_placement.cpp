// Volume placement from geometry: a surface voxelization, an exact Euclidean distance transform
// of it (Felzenszwalb and Huttenlocher's lower envelope of parabolas, one axis at a time), and
// per empty voxel what the six axis rays from it reach first (whether a surface, and which of
// its sides). See volume_placement.h for why.
#include "volume_placement.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>

#include "log.h"

namespace pc {

namespace {

// Squared distances are in voxel units; cells without a surface start at kFar.
constexpr float kFar = 1e20f;

struct Grid {
  glm::ivec3 n{0};
  glm::vec3 origin{0.0f};  // corner of voxel (0, 0, 0)
  float voxel = 0.0f;
  std::vector<std::uint8_t> solid;
  std::vector<glm::vec3> normal;  // summed surface normals of the triangles in each voxel
  std::size_t index(int x, int y, int z) const {
    return (std::size_t(z) * n.y + y) * std::size_t(n.x) + x;
  }
  std::size_t size() const { return std::size_t(n.x) * n.y * n.z; }
};

// Over the box [lo, hi]: the coarsest voxel that still resolves the largest extent in 256
// steps, grown until the grid fits the budget; one voxel of margin on every side so the box's
// faces are inside.
Grid makeGrid(glm::vec3 lo, glm::vec3 hi, std::size_t maxVoxels) {
  Grid g;
  const glm::vec3 extent = hi - lo;
  const float largest = std::max({extent.x, extent.y, extent.z});
  g.voxel = largest / 256.0f;
  for (;;) {
    g.n = glm::ivec3(glm::ceil(extent / g.voxel)) + 2;
    if (g.size() <= maxVoxels) break;
    g.voxel *= 1.1f;
  }
  g.origin = lo - g.voxel;
  g.solid.assign(g.size(), 0);
  g.normal.assign(g.size(), glm::vec3(0.0f));
  return g;
}

struct EdgeSample {
  float length, weight;
};

// Marks every voxel a triangle passes through by sampling it on a lattice finer than half a
// voxel along two of its edges. Returns the triangle's mean edge length and area for the
// feature-size statistics.
EdgeSample rasterize(Grid& g, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 normal) {
  const glm::vec3 ab = b - a, ac = c - a;
  const float area = 0.5f * glm::length(glm::cross(ab, ac));
  const float step = 0.5f * g.voxel;
  // A lattice of at most 1024 x 1024: a sliver longer than that is sampled sparsely rather
  // than costing millions of samples.
  const int ni = std::clamp(int(std::ceil(glm::length(ab) / step)), 1, 1024);
  const int nj = std::clamp(int(std::ceil(glm::length(ac) / step)), 1, 1024);
  for (int i = 0; i <= ni; ++i) {
    const float u = float(i) / float(ni);
    for (int j = 0; j <= nj; ++j) {
      const float w = float(j) / float(nj);
      if (u + w > 1.0f + 1e-6f) break;
      const glm::ivec3 v = glm::ivec3(glm::floor((a + u * ab + w * ac - g.origin) / g.voxel));
      if (glm::any(glm::lessThan(v, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(v, g.n)))
        continue;
      const std::size_t k = g.index(v.x, v.y, v.z);
      g.solid[k] = 1;
      g.normal[k] += normal;
    }
  }
  const float edges = (glm::length(ab) + glm::length(ac) + glm::length(c - b)) / 3.0f;
  return {edges, area};
}

std::vector<EdgeSample> voxelize(Grid& g, const Scene& scene) {
  std::vector<EdgeSample> edges;
  for (const Instance& inst : scene.instances) {
    if (inst.mesh < 0 || std::size_t(inst.mesh) >= scene.meshes.size()) continue;
    const Mesh& mesh = scene.meshes[inst.mesh];
    const glm::mat3 normalMatrix = glm::transpose(glm::inverse(glm::mat3(inst.transform)));
    const bool hasNormals = mesh.normals.size() == mesh.positions.size();
    for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const std::uint32_t i0 = mesh.indices[t], i1 = mesh.indices[t + 1], i2 = mesh.indices[t + 2];
      if (std::max({i0, i1, i2}) >= mesh.positions.size()) continue;
      glm::vec3 p[3];
      for (int k = 0; k < 3; ++k)
        p[k] = glm::vec3(inst.transform * glm::vec4(mesh.positions[mesh.indices[t + k]], 1.0f));
      // The shading normals say which side a surface shows (the file's winding may not).
      glm::vec3 n = hasNormals
                        ? normalMatrix * (mesh.normals[i0] + mesh.normals[i1] + mesh.normals[i2])
                        : glm::cross(p[1] - p[0], p[2] - p[0]);
      const float len = glm::length(n);
      n = len > 0.0f && std::isfinite(len) ? n / len : glm::vec3(0.0f);
      edges.push_back(rasterize(g, p[0], p[1], p[2], n));
    }
  }
  return edges;
}

// Squared distance to the nearest cell with f < kFar along one line of `count` cells `stride`
// apart, in place. `v` and `z` are scratch of count and count + 1 entries.
void distanceLine(float* f, std::size_t stride, int count, std::vector<int>& v,
                  std::vector<float>& z, std::vector<float>& out) {
  int k = -1;
  for (int q = 0; q < count; ++q) {
    const float fq = f[std::size_t(q) * stride];
    if (fq >= kFar) continue;
    float s = 0.0f;
    while (k >= 0) {
      const int p = v[k];
      const float fp = f[std::size_t(p) * stride];
      s = ((fq + float(q) * q) - (fp + float(p) * p)) / float(2 * (q - p));
      if (s > z[k]) break;
      --k;
    }
    ++k;
    v[k] = q;
    z[k] = k == 0 ? -kFar : s;
    z[k + 1] = kFar;
  }
  if (k < 0) return;  // nothing on this line: every cell stays far
  int j = 0;
  for (int q = 0; q < count; ++q) {
    while (z[j + 1] < float(q)) ++j;
    const float d = float(q - v[j]);
    out[q] = d * d + f[std::size_t(v[j]) * stride];
  }
  for (int q = 0; q < count; ++q) f[std::size_t(q) * stride] = out[q];
}

std::vector<float> distanceTransform(const Grid& g) {
  std::vector<float> d(g.size());
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = g.solid[i] ? 0.0f : kFar;
  const int longest = std::max({g.n.x, g.n.y, g.n.z});
  std::vector<int> v(longest);
  std::vector<float> z(longest + 1), out(longest);
  for (int zz = 0; zz < g.n.z; ++zz)
    for (int y = 0; y < g.n.y; ++y) distanceLine(&d[g.index(0, y, zz)], 1, g.n.x, v, z, out);
  for (int zz = 0; zz < g.n.z; ++zz)
    for (int x = 0; x < g.n.x; ++x)
      distanceLine(&d[g.index(x, 0, zz)], std::size_t(g.n.x), g.n.y, v, z, out);
  for (int y = 0; y < g.n.y; ++y)
    for (int x = 0; x < g.n.x; ++x)
      distanceLine(&d[g.index(x, y, 0)], std::size_t(g.n.x) * g.n.y, g.n.z, v, z, out);
  return d;
}

// Per empty voxel, what the six axis rays reach: `hits` surfaces in all, of which `front`
// show the side their normal points to and `back` the other; `below` whether the -Y ray hits.
struct Sight {
  std::vector<std::uint8_t> hits, front, back, below;
};

Sight sightLines(const Grid& g) {
  Sight s;
  s.hits.assign(g.size(), 0);
  s.front.assign(g.size(), 0);
  s.back.assign(g.size(), 0);
  s.below.assign(g.size(), 0);
  for (int axis = 0; axis < 3; ++axis) {
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    for (int i = 0; i < g.n[a1]; ++i)
      for (int j = 0; j < g.n[a2]; ++j)
        for (int dir : {1, -1}) {
          // Walking along +axis, the last surface passed lies in -axis from the current voxel:
          // it faces the voxel when its normal points along +axis (and the reverse walking back).
          bool seen = false;
          float facing = 0.0f;
          const int count = g.n[axis];
          for (int t = 0; t < count; ++t) {
            glm::ivec3 c;
            c[axis] = dir > 0 ? t : count - 1 - t;
            c[a1] = i;
            c[a2] = j;
            const std::size_t k = g.index(c.x, c.y, c.z);
            if (g.solid[k]) {
              seen = true;
              facing = g.normal[k][axis] * float(dir);
              continue;
            }
            if (!seen) continue;
            ++s.hits[k];
            if (facing > 1e-3f) ++s.front[k];
            if (facing < -1e-3f) ++s.back[k];
            if (axis == 1 && dir > 0) s.below[k] = 1;
          }
        }
  }
  return s;
}

// Index range [lo, hi] along each axis holding all but `trim` of the weight on either side.
void trimmedBox(const std::vector<std::vector<double>>& histograms, double trim, glm::ivec3& lo,
                glm::ivec3& hi) {
  for (int a = 0; a < 3; ++a) {
    const std::vector<double>& h = histograms[a];
    double total = 0.0;
    for (double c : h) total += c;
    double acc = 0.0;
    lo[a] = 0;
    for (int i = 0; i < int(h.size()); ++i) {
      acc += h[i];
      if (acc > trim * total) {
        lo[a] = i;
        break;
      }
    }
    acc = 0.0;
    hi[a] = int(h.size()) - 1;
    for (int i = int(h.size()) - 1; i >= 0; --i) {
      acc += h[i];
      if (acc > trim * total) {
        hi[a] = i;
        break;
      }
    }
  }
}

float weightedMedian(std::vector<EdgeSample> v) {
  if (v.empty()) return 0.0f;
  std::sort(v.begin(), v.end(), [](auto& a, auto& b) { return a.length < b.length; });
  double total = 0.0;
  for (const EdgeSample& e : v) total += e.weight;
  double acc = 0.0;
  for (const EdgeSample& e : v) {
    acc += e.weight;
    if (acc >= 0.5 * total) return e.length;
  }
  return v.back().length;
}

// The grid of spacing `s` over [lo, hi], probes half a spacing in from each face (as
// defaultVolumes places them), at least 2 along each axis.
ProbeVolume fitGrid(glm::vec3 lo, glm::vec3 hi, float s) {
  ProbeVolume v;
  v.spacing = s;
  const glm::vec3 extent = hi - lo;
  for (int a = 0; a < 3; ++a)
    v.counts[a] = std::clamp(int(std::ceil(extent[a] / s - 1e-3f)), 2, 4096);
  v.origin = 0.5f * (lo + hi) - 0.5f * s * glm::vec3(v.counts - 1);
  return v;
}

long long probeCount(const ProbeVolume& v) {
  return (long long)v.counts.x * v.counts.y * v.counts.z;
}

// Grows `s` by 5% steps until the grid over [lo, hi] holds at most `budget` probes.
ProbeVolume fitBudget(glm::vec3 lo, glm::vec3 hi, float s, long long budget) {
  ProbeVolume v = fitGrid(lo, hi, s);
  while (probeCount(v) > budget) v = fitGrid(lo, hi, v.spacing * 1.05f);
  return v;
}

std::string formatVolume(const ProbeVolume& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.3g (%dx%dx%d)", v.spacing, v.counts.x, v.counts.y, v.counts.z);
  return buf;
}

// One measurement over a box, and the box of its closed free space (four or more directions
// closed), which may be small where the measured space had to fall back to open free space.
struct Measurement {
  GeometryScale scale;
  bool hasClosed = false;
  glm::vec3 closedMin{0.0f}, closedMax{0.0f};
};

// The trimmed box of the voxels `pick` accepts and, when `distances` is given, their distances
// to the nearest surface (world units). Returns how many there are.
template <typename Pick>
std::size_t collect(const Grid& g, const std::vector<float>& dist, Pick pick, glm::vec3& lo,
                    glm::vec3& hi, std::vector<float>* distances) {
  std::vector<std::vector<double>> histograms{
      std::vector<double>(g.n.x), std::vector<double>(g.n.y), std::vector<double>(g.n.z)};
  std::size_t count = 0;
  for (int z = 0; z < g.n.z; ++z)
    for (int y = 0; y < g.n.y; ++y)
      for (int x = 0; x < g.n.x; ++x) {
        const std::size_t k = g.index(x, y, z);
        if (!pick(k)) continue;
        ++count;
        if (distances) distances->push_back(std::sqrt(dist[k]) * g.voxel);
        histograms[0][x] += 1;
        histograms[1][y] += 1;
        histograms[2][z] += 1;
      }
  if (count == 0) return 0;
  // Stray voxels (a gap inside a wall, a sealed cavity) do not stretch the box.
  glm::ivec3 ilo, ihi;
  trimmedBox(histograms, 0.002, ilo, ihi);
  lo = g.origin + glm::vec3(ilo) * g.voxel;
  hi = g.origin + glm::vec3(ihi + 1) * g.voxel;
  return count;
}

// The measurement over the box [lo, hi] (geometry outside it is left out).
Measurement measureIn(const Scene& scene, glm::vec3 boxLo, glm::vec3 boxHi, std::size_t maxVoxels) {
  Measurement m;
  GeometryScale& out = m.scale;
  Grid g = makeGrid(boxLo, boxHi, std::max<std::size_t>(maxVoxels, 4096));
  if (!(g.voxel >= std::numeric_limits<float>::min() * 1e6f)) return m;
  out.voxel = g.voxel;
  out.edgeLength = weightedMedian(voxelize(g, scene));
  const std::vector<float> dist = distanceTransform(g);
  const Sight sight = sightLines(g);
  // Free space: a surface below, and more of the surfaces around seen from their front than
  // from behind (behind: inside a solid). Closed: at least four of six directions hit.
  auto free = [&](std::size_t k, int minHits) {
    return !g.solid[k] && sight.below[k] && sight.hits[k] >= minHits &&
           sight.front[k] > sight.back[k];
  };
  std::size_t empty = 0;
  for (std::uint8_t s : g.solid) empty += s ? 0 : 1;
  std::vector<float> distances;
  std::size_t count = collect(
      g, dist, [&](std::size_t k) { return free(k, 4); }, m.closedMin, m.closedMax, &distances);
  m.hasClosed = count > 0;
  // Open levels (a yard under the sky) have little closed on four sides; then any free space
  // over a floor counts.
  if (count < 64 || double(count) < 0.005 * double(empty)) {
    distances.clear();
    count = collect(
        g, dist, [&](std::size_t k) { return free(k, 1); }, out.levelMin, out.levelMax, &distances);
  } else {
    out.levelMin = m.closedMin;
    out.levelMax = m.closedMax;
  }
  if (count < 8) return m;
  auto mid = distances.begin() + std::ptrdiff_t(distances.size() / 2);
  std::nth_element(distances.begin(), mid, distances.end());
  out.freeSpace = *mid;
  out.enclosedShare = empty ? double(count) / double(empty) : 0.0;
  out.valid = out.freeSpace > 0.0f;
  return m;
}

}  // namespace

GeometryScale measureGeometry(const Scene& scene, std::size_t maxVoxels) {
  const glm::vec3 extent = scene.boundsMax - scene.boundsMin;
  const float largest = std::max({extent.x, extent.y, extent.z});
  if (!(largest > 0.0f) || !std::isfinite(largest) || scene.triangleCount() == 0) return {};
  const Measurement first = measureIn(scene, scene.boundsMin, scene.boundsMax, maxVoxels);
  GeometryScale best = first.scale;
  // A level inside a much larger file (a ground plane, a skybox) leaves its free space a voxel
  // or two across: measure again over the closed space alone (else the free space), finer.
  if (best.freeSpace < 3.0f * best.voxel && (first.hasClosed || best.valid)) {
    const glm::vec3 boxLo = first.hasClosed ? first.closedMin : best.levelMin;
    const glm::vec3 boxHi = first.hasClosed ? first.closedMax : best.levelMax;
    const glm::vec3 lo = glm::max(boxLo - 2.0f * best.voxel, scene.boundsMin);
    const glm::vec3 hi = glm::min(boxHi + 2.0f * best.voxel, scene.boundsMax);
    const GeometryScale second = measureIn(scene, lo, hi, maxVoxels).scale;
    if (second.valid && second.voxel < best.voxel) best = second;
  }
  // Free space still under two voxels across is no measurement: the level is open (a slab
  // under the sky, all of its air outside the bounds) or thinner than the grid resolves.
  if (best.freeSpace < 2.0f * best.voxel) best.valid = false;
  return best;
}

float suggestedSpacing(const GeometryScale& scale) {
  // The distance field is only as fine as its voxels: never ask for less than two of them.
  return std::max(kSpacingPerFreeSpace * scale.freeSpace, 2.0f * scale.voxel);
}

VolumePlan autoVolumes(const Scene& scene, int probeBudget) {
  VolumePlan plan;
  plan.scale = measureGeometry(scene);
  if (!plan.scale.valid) {
    plan.volumes = defaultVolumes(scene);
  } else {
    const long long budget = std::max(probeBudget, 8);
    plan.wantedSpacing = suggestedSpacing(plan.scale);
    ProbeVolume fine =
        fitBudget(plan.scale.levelMin, plan.scale.levelMax, plan.wantedSpacing, budget);
    // The open ground around the rooms (a sunlit yard seen through a door) matters to what a
    // camera sees as much as the rooms do (rtxgi-two-rooms: 34.0 dB with the rooms' box alone,
    // 35.8 with NVIDIA's box, which reaches past them by 40% of their extent): at the same
    // spacing, the finest cascade takes the whole bounds, else reaches past the level by half,
    // a quarter or an eighth of its extent on each side, the most that the budget holds.
    const glm::vec3 extent = plan.scale.levelMax - plan.scale.levelMin;
    for (float reach : {1e30f, 0.5f, 0.25f, 0.125f}) {
      const glm::vec3 lo = glm::max(plan.scale.levelMin - reach * extent, scene.boundsMin);
      const glm::vec3 hi = glm::min(plan.scale.levelMax + reach * extent, scene.boundsMax);
      const ProbeVolume wider = fitGrid(glm::min(lo, plan.scale.levelMin),
                                        glm::max(hi, plan.scale.levelMax), fine.spacing);
      if (probeCount(wider) > budget) continue;
      if (probeCount(wider) > probeCount(fine)) fine = wider;
      break;
    }
    plan.volumes.push_back(fine);
    // Past the fine grid's reach (its probes plus half a spacing), a coarse cascade over the
    // whole scene gives distant surfaces and the fine grid's borders something to fall back on.
    const glm::vec3 reachLo = fine.origin - 0.5f * fine.spacing;
    const glm::vec3 reachHi = fine.origin + fine.spacing * (glm::vec3(fine.counts) - 0.5f);
    const bool beyond = glm::any(glm::lessThan(scene.boundsMin, reachLo - fine.spacing)) ||
                        glm::any(glm::greaterThan(scene.boundsMax, reachHi + fine.spacing));
    if (beyond) {
      ProbeVolume coarse = fitGrid(scene.boundsMin, scene.boundsMax, 2.0f * fine.spacing);
      while (probeCount(coarse) > budget / 4)
        coarse = fitGrid(scene.boundsMin, scene.boundsMax, 2.0f * coarse.spacing);
      plan.volumes.push_back(coarse);
    }
  }
  for (const ProbeVolume& v : plan.volumes) plan.probes += int(probeCount(v));
  return plan;
}

std::optional<std::string> spacingAdvice(const Scene& scene,
                                         const std::vector<ProbeVolume>& volumes,
                                         const GeometryScale& scale) {
  if (!scale.valid || volumes.empty()) return std::nullopt;
  const float wanted = suggestedSpacing(scale);
  const float spacing = volumes.front().spacing;
  if (!(spacing > 2.0f * wanted)) return std::nullopt;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "scene %s: probe spacing %.3g (finest cascade) is coarse for its geometry "
                "(median free space %.3g): suggested spacing %.3g; light may leak through "
                "walls and recesses come out too bright",
                scene.name.c_str(), spacing, scale.freeSpace, wanted);
  return std::string(buf);
}

std::string describePlan(const Scene& scene, const VolumePlan& plan) {
  std::string s = "scene " + scene.name + ": probe volumes from its geometry: ";
  for (std::size_t i = 0; i < plan.volumes.size(); ++i)
    s += (i ? ", then " : "spacing ") + formatVolume(plan.volumes[i]);
  char buf[200];
  if (plan.scale.valid) {
    std::snprintf(buf, sizeof buf,
                  "; %d probes; median free space %.3g, wanted spacing %.3g (voxels %.3g)",
                  plan.probes, plan.scale.freeSpace, plan.wantedSpacing, plan.scale.voxel);
  } else {
    std::snprintf(buf, sizeof buf, "; %d probes over the bounds (no enclosed space found)",
                  plan.probes);
  }
  return s + buf;
}

std::vector<ProbeVolume> sceneVolumes(const Scene& scene, bool automatic) {
  if (!automatic && !scene.volumes.empty()) {
    if (auto advice = spacingAdvice(scene, scene.volumes, measureGeometry(scene))) logWarn(*advice);
    return scene.volumes;
  }
  const VolumePlan plan = autoVolumes(scene);
  logInfo(describePlan(scene, plan));
  return plan.volumes;
}

}  // namespace pc
