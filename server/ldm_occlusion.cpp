// LDM occlusion on the GPU (ldm_occlusion.h): three compute passes, ldm_raster.comp (every
// triangle into every LDM, a linked list of layers per pixel), ldm_sort.comp (each list by
// depth) and ldm_occlusion.comp (each probe's tile from the lists).
#include "ldm_occlusion.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "../shaders/interop/probe_math.h"
#include "../shaders/interop/probe_update.h"

namespace pc {

using namespace pc::gpu;

// std430 layouts, as the shaders read them.
static_assert(sizeof(LdmParams) == 48 && sizeof(LdmTriangle) == 48 && sizeof(LdmNode) == 8 &&
              sizeof(LdmCounters) == 16);
static_assert(sizeof(LdmParams) <= 128, "push constants: the guaranteed 128 bytes");
static_assert(PC_LDM_TRACE_THREADS == PC_OCCLUSION_TEXELS * PC_OCCLUSION_TEXELS,
              "ldm_occlusion.comp runs a thread per occlusion texel");

namespace {

constexpr VkBufferUsageFlags kStorage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
// The lists are filled and read back (layers()) by copies too.
constexpr VkBufferUsageFlags kCopyable =
    VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
constexpr VkPipelineStageFlags2 kCompute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
constexpr VkAccessFlags2 kShaderRW =
    VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;
constexpr VkPipelineStageFlags2 kCopy = VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT;
constexpr VkAccessFlags2 kTransferWrite = VK_ACCESS_2_TRANSFER_WRITE_BIT;

std::uint32_t groups(std::uint64_t items, std::uint32_t size) {
  return std::uint32_t((items + size - 1) / size);
}

}  // namespace

struct LdmOcclusion::Impl {
  const vk::Context* ctx = nullptr;
  LdmOptions options;
  vk::CommandPool pool;
  vk::UniqueDescriptorSetLayout setLayout;
  vk::UniquePipelineLayout layout;
  vk::UniqueDescriptorPool descriptorPool;
  VkDescriptorSet set = VK_NULL_HANDLE;
  vk::UniquePipeline raster, sort, trace;
  vk::Buffer triangles, heads, nodes, counters, countersReadback, probes, tiles;
  LdmParams params{};
  bool built = false;

  Result<vk::UniquePipeline> pipeline(const char* name) {
    return vk::createComputePipeline(*ctx, name, layout.get());
  }

  // Points the set's bindings at the current buffers (after any was made again).
  void writeDescriptors() {
    const vk::Buffer* buffers[PC_LDM_BINDINGS] = {&triangles, &heads,  &nodes,
                                                  &counters,  &probes, &tiles};
    VkDescriptorBufferInfo infos[PC_LDM_BINDINGS];
    VkWriteDescriptorSet writes[PC_LDM_BINDINGS];
    for (int b = 0; b < PC_LDM_BINDINGS; ++b) {
      infos[b] = buffers[b]->descriptor();
      writes[b] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      writes[b].dstSet = set;
      writes[b].dstBinding = std::uint32_t(b);
      writes[b].descriptorCount = 1;
      writes[b].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      writes[b].pBufferInfo = &infos[b];
    }
    vkUpdateDescriptorSets(ctx->device(), PC_LDM_BINDINGS, writes, 0, nullptr);
  }

  void bind(VkCommandBuffer cmd, const vk::UniquePipeline& p) const {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.get());
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout.get(), 0, 1, &set, 0,
                            nullptr);
    vkCmdPushConstants(cmd, layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof params, &params);
  }
};

LdmOcclusion::LdmOcclusion(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
LdmOcclusion::~LdmOcclusion() = default;

Result<std::unique_ptr<LdmOcclusion>> LdmOcclusion::create(const vk::Context& ctx,
                                                           const LdmOptions& options) {
  if (options.directions < 1 || options.directions > PC_LDM_MAX_DIRECTIONS)
    return Error{"ldm: directions must be 1.." + std::to_string(PC_LDM_MAX_DIRECTIONS) + ", not " +
                 std::to_string(options.directions)};
  if (options.resolution < 8 || options.resolution > 2048)
    return Error{"ldm: resolution must be 8..2048 pixels, not " +
                 std::to_string(options.resolution)};
  auto impl = std::make_unique<Impl>();
  impl->ctx = &ctx;
  impl->options = options;
  // Whole groups of 8: a row of pixels is then whole sort workgroups.
  impl->options.resolution = (options.resolution + 7) / 8 * 8;
  auto pool = vk::CommandPool::create(ctx);
  if (!pool) return pool.error();
  impl->pool = std::move(pool).value();
  std::vector<VkDescriptorSetLayoutBinding> bindings;
  for (int b = 0; b < PC_LDM_BINDINGS; ++b)
    bindings.push_back({std::uint32_t(b), VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
                        VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  auto setLayout = vk::createDescriptorSetLayout(ctx, bindings);
  if (!setLayout) return setLayout.error();
  impl->setLayout = std::move(setLayout).value();
  auto layout = vk::createPipelineLayout(ctx, impl->setLayout.get(), VK_SHADER_STAGE_COMPUTE_BIT,
                                         sizeof(LdmParams));
  if (!layout) return layout.error();
  impl->layout = std::move(layout).value();
  const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, PC_LDM_BINDINGS};
  VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  dpi.maxSets = 1;
  dpi.poolSizeCount = 1;
  dpi.pPoolSizes = &size;
  VkDescriptorPool dp = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateDescriptorPool(ctx.device(), &dpi, nullptr, &dp));
  impl->descriptorPool = vk::UniqueDescriptorPool(ctx.device(), dp);
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = dp;
  ai.descriptorSetCount = 1;
  VkDescriptorSetLayout sl = impl->setLayout.get();
  ai.pSetLayouts = &sl;
  PC_VK_TRY(vkAllocateDescriptorSets(ctx.device(), &ai, &impl->set));
  for (auto [p, name] : {std::pair{&impl->raster, "ldm_raster.comp.spv"},
                         std::pair{&impl->sort, "ldm_sort.comp.spv"},
                         std::pair{&impl->trace, "ldm_occlusion.comp.spv"}}) {
    auto made = impl->pipeline(name);
    if (!made) return made.error();
    *p = std::move(made).value();
  }
  // Every binding holds a buffer from the start; build() and occlusion() make their own.
  for (vk::Buffer* b : {&impl->triangles, &impl->heads, &impl->nodes, &impl->probes}) {
    auto made = vk::Buffer::create(ctx, 64, kStorage, vk::MemoryUsage::DeviceLocal);
    if (!made) return made.error();
    *b = std::move(made).value();
  }
  auto counters = vk::Buffer::create(
      ctx, sizeof(LdmCounters),
      kStorage | VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
      vk::MemoryUsage::DeviceLocal);
  if (!counters) return counters.error();
  impl->counters = std::move(counters).value();
  auto readback = vk::Buffer::create(ctx, sizeof(LdmCounters), VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                     vk::MemoryUsage::Readback);
  if (!readback) return readback.error();
  impl->countersReadback = std::move(readback).value();
  auto tiles = vk::Buffer::create(ctx, 64, kStorage, vk::MemoryUsage::Readback);
  if (!tiles) return tiles.error();
  impl->tiles = std::move(tiles).value();
  impl->writeDescriptors();
  return std::unique_ptr<LdmOcclusion>(new LdmOcclusion(std::move(impl)));
}

glm::vec3 LdmOcclusion::direction(int i) const {
  return pcLdmDirection(i, impl_->options.directions);
}

Status LdmOcclusion::build(std::span<const LdmTriangle> triangles, glm::vec3 lo, glm::vec3 hi) {
  Impl& m = *impl_;
  const vk::Context& ctx = *m.ctx;
  const int n = m.options.resolution, dirs = m.options.directions;
  const std::uint64_t maxGroups = ctx.properties().limits.maxComputeWorkGroupCount[0];
  if (groups(triangles.size(), PC_LDM_RASTER_THREADS) > maxGroups)
    return Error{"ldm: " + std::to_string(triangles.size()) +
                 " triangles are more than one rasterizer dispatch holds (" +
                 std::to_string(maxGroups * PC_LDM_RASTER_THREADS) + ")"};
  LdmParams& p = m.params;
  p.center = 0.5f * (lo + hi);
  // The bounding sphere's radius: the square covers the box seen along any direction.
  p.halfExtent = std::max(0.5f * glm::length(hi - lo), 1e-3f);
  p.resolution = n;
  p.directions = dirs;
  p.triangleCount = int(triangles.size());
  stats_ = {};
  stats_.directions = dirs;
  stats_.resolution = n;
  stats_.triangles = int(triangles.size());
  stats_.pixel = 2.0f * p.halfExtent / float(n);

  const std::size_t pixels = std::size_t(n) * std::size_t(n) * std::size_t(dirs);
  const std::size_t triangleBytes = std::max<std::size_t>(triangles.size_bytes(), 64);
  if (!triangles.empty()) {
    auto uploaded = vk::uploadBuffer(ctx, triangles.data(), triangles.size_bytes(), kStorage);
    if (!uploaded) return uploaded.error();
    m.triangles = std::move(uploaded).value();
  } else if (m.triangles.size() < triangleBytes) {
    auto made = vk::Buffer::create(ctx, triangleBytes, kStorage, vk::MemoryUsage::DeviceLocal);
    if (!made) return made.error();
    m.triangles = std::move(made).value();
  }
  if (m.heads.size() != pixels * 4) {
    auto made =
        vk::Buffer::create(ctx, pixels * 4, kStorage | kCopyable, vk::MemoryUsage::DeviceLocal);
    if (!made) return made.error();
    m.heads = std::move(made).value();
  }
  // A first guess of the layers: 4 a pixel on average; a build that appends more grows the
  // node buffer to what it appended and runs again.
  std::uint64_t capacity = std::max<std::uint64_t>(m.nodes.size() / sizeof(LdmNode), pixels * 4);
  for (int attempt = 1;; ++attempt) {
    const std::uint64_t maxNodes =
        std::min<std::uint64_t>(ctx.properties().limits.maxStorageBufferRange / sizeof(LdmNode),
                                std::uint64_t(PC_LDM_NONE) - 1);
    capacity = std::min(capacity, maxNodes);
    if (m.nodes.size() < capacity * sizeof(LdmNode)) {
      m.nodes = vk::Buffer{};
      auto made = vk::Buffer::create(ctx, capacity * sizeof(LdmNode), kStorage | kCopyable,
                                     vk::MemoryUsage::DeviceLocal);
      if (!made) return made.error();
      m.nodes = std::move(made).value();
    }
    p.nodeCapacity = std::uint32_t(m.nodes.size() / sizeof(LdmNode));
    m.writeDescriptors();
    Status done = m.pool.submitAndWait([&](VkCommandBuffer cmd) {
      vkCmdFillBuffer(cmd, m.heads.get(), 0, VK_WHOLE_SIZE, PC_LDM_NONE);
      vkCmdFillBuffer(cmd, m.counters.get(), 0, VK_WHOLE_SIZE, 0u);
      vk::memoryBarrier(cmd, kCopy, kTransferWrite, kCompute, kShaderRW);
      m.bind(cmd, m.raster);
      if (!triangles.empty())
        vkCmdDispatch(cmd, groups(triangles.size(), PC_LDM_RASTER_THREADS), std::uint32_t(dirs), 1);
      vk::memoryBarrier(cmd, kCompute, kShaderRW, kCompute, kShaderRW);
      m.bind(cmd, m.sort);
      vkCmdDispatch(cmd, groups(std::uint64_t(n) * n, PC_LDM_SORT_THREADS), std::uint32_t(dirs), 1);
      vk::memoryBarrier(cmd, kCompute, kShaderRW, kCopy, VK_ACCESS_2_TRANSFER_READ_BIT);
      const VkBufferCopy copy{0, 0, sizeof(LdmCounters)};
      vkCmdCopyBuffer(cmd, m.counters.get(), m.countersReadback.get(), 1, &copy);
      vk::memoryBarrier(cmd, kCopy, kTransferWrite, VK_PIPELINE_STAGE_2_HOST_BIT,
                        VK_ACCESS_2_HOST_READ_BIT);
    });
    if (!done) return done.error();
    if (VkResult r = m.countersReadback.invalidate(); r != VK_SUCCESS)
      return Error{vk::vkErrorMessage("vkInvalidateMappedMemoryRanges", r)};
    LdmCounters c{};
    std::memcpy(&c, m.countersReadback.mapped(), sizeof c);
    stats_.attempts = attempt;
    if (c.nodeCount <= p.nodeCapacity) {
      stats_.layers = c.nodeCount;
      stats_.maxLayers = int(c.maxLayers);
      stats_.longLists = int(c.longLists);
      stats_.bytes = m.heads.size() + m.nodes.size();
      m.built = true;
      return Status::success();
    }
    if (capacity >= maxNodes)
      return Error{"ldm: " + std::to_string(c.nodeCount) + " depth layers at " + std::to_string(n) +
                   "^2 pixels x " + std::to_string(dirs) +
                   " directions are more than one storage buffer holds (" +
                   std::to_string(maxNodes) + "): use fewer pixels or directions"};
    capacity = std::uint64_t(c.nodeCount) + c.nodeCount / 8;
  }
}

Result<std::vector<float>> LdmOcclusion::occlusion(std::span<const glm::vec3> positions,
                                                   float dmax) {
  Impl& m = *impl_;
  if (!m.built) return Error{"ldm: occlusion asked for before the LDMs were built"};
  constexpr int texels = PC_OCCLUSION_TEXELS * PC_OCCLUSION_TEXELS;
  std::vector<float> out(positions.size() * texels);
  if (positions.empty()) return out;
  const vk::Context& ctx = *m.ctx;
  const std::size_t probeBytes = positions.size() * sizeof(glm::vec4);
  const std::size_t tileBytes = out.size() * sizeof(float);
  if (m.probes.size() < probeBytes || !m.probes.mapped()) {
    auto made = vk::Buffer::create(ctx, probeBytes, kStorage, vk::MemoryUsage::Upload);
    if (!made) return made.error();
    m.probes = std::move(made).value();
  }
  if (m.tiles.size() < tileBytes) {
    auto made = vk::Buffer::create(ctx, tileBytes, kStorage, vk::MemoryUsage::Readback);
    if (!made) return made.error();
    m.tiles = std::move(made).value();
  }
  m.writeDescriptors();
  std::vector<glm::vec4> points(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) points[i] = glm::vec4(positions[i], 1.0f);
  m.probes.write(points.data(), probeBytes);
  m.params.dmax = dmax;
  Status done = m.pool.submitAndWait([&](VkCommandBuffer cmd) {
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_WRITE_BIT, kCompute,
                      kShaderRW);
    for (std::size_t base = 0; base < positions.size(); base += PC_LDM_MAX_PROBES_PER_DISPATCH) {
      m.params.probeBase = int(base);
      m.params.probeCount =
          int(std::min<std::size_t>(positions.size() - base, PC_LDM_MAX_PROBES_PER_DISPATCH));
      m.bind(cmd, m.trace);
      vkCmdDispatch(cmd, std::uint32_t(m.params.probeCount), 1, 1);
    }
    vk::memoryBarrier(cmd, kCompute, kShaderRW, VK_PIPELINE_STAGE_2_HOST_BIT,
                      VK_ACCESS_2_HOST_READ_BIT);
  });
  if (!done) return done.error();
  if (VkResult r = m.tiles.invalidate(); r != VK_SUCCESS)
    return Error{vk::vkErrorMessage("vkInvalidateMappedMemoryRanges", r)};
  std::memcpy(out.data(), m.tiles.mapped(), tileBytes);
  return out;
}

Result<std::vector<std::vector<float>>> LdmOcclusion::layers(int direction) {
  Impl& m = *impl_;
  if (!m.built) return Error{"ldm: layers asked for before the LDMs were built"};
  if (direction < 0 || direction >= m.options.directions)
    return Error{"ldm: no direction " + std::to_string(direction)};
  const vk::Context& ctx = *m.ctx;
  auto read = [&](const vk::Buffer& src) -> Result<vk::Buffer> {
    auto rb = vk::Buffer::create(ctx, src.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                 vk::MemoryUsage::Readback);
    if (!rb) return rb.error();
    Status copied = ctx.submitAndWait([&](VkCommandBuffer cmd) {
      const VkBufferCopy copy{0, 0, src.size()};
      vkCmdCopyBuffer(cmd, src.get(), rb->get(), 1, &copy);
    });
    if (!copied) return copied.error();
    if (VkResult r = rb->invalidate(); r != VK_SUCCESS)
      return Error{vk::vkErrorMessage("vkInvalidateMappedMemoryRanges", r)};
    return std::move(rb).value();
  };
  auto heads = read(m.heads);
  if (!heads) return heads.error();
  auto nodes = read(m.nodes);
  if (!nodes) return nodes.error();
  const int n = m.options.resolution;
  const std::uint32_t* h = heads->as<std::uint32_t>() + std::size_t(direction) * n * n;
  const LdmNode* nd = nodes->as<LdmNode>();
  std::vector<std::vector<float>> out(std::size_t(n) * n);
  for (std::size_t px = 0; px < out.size(); ++px)
    for (std::uint32_t i = h[px]; i != PC_LDM_NONE; i = nd[i].next & PC_LDM_NONE)
      out[px].push_back(nd[i].depth);
  return out;
}

std::vector<LdmTriangle> ldmSceneTriangles(const Scene& scene, const SceneState& state,
                                           glm::vec3 lo, glm::vec3 hi) {
  std::vector<LdmTriangle> out;
  for (std::size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    const glm::mat4 t =
        i < state.instanceTransforms.size() ? state.instanceTransforms[i] : inst.transform;
    const Mesh& mesh = scene.meshes[std::size_t(inst.mesh)];
    // Cut-outs' backs are surface to the tracers (pcBackfaceIsSurface); the winding is fixed
    // by the time-0 transform, as the Embree scene and the Vulkan tracer fix it.
    const bool twoSided =
        mesh.material >= 0 && std::size_t(mesh.material) < scene.materials.size() &&
        pcBackfaceIsSurface(scene.materials[std::size_t(mesh.material)].alphaCutoff);
    const bool mirrored = glm::determinant(glm::mat3(inst.transform)) < 0.0f;
    for (std::size_t k = 0; k < mesh.triangleCount(); ++k) {
      LdmTriangle tri;
      tri.p0 = t * glm::vec4(mesh.positions[mesh.indices[3 * k]], 1.0f);
      tri.p1 = t * glm::vec4(mesh.positions[mesh.indices[3 * k + 1]], 1.0f);
      tri.p2 = t * glm::vec4(mesh.positions[mesh.indices[3 * k + 2]], 1.0f);
      if (mirrored) std::swap(tri.p1, tri.p2);
      tri.p0.w = twoSided ? 1.0f : 0.0f;
      const glm::vec3 a(tri.p0), b(tri.p1), c(tri.p2);
      const glm::vec3 tlo = glm::min(a, glm::min(b, c)), thi = glm::max(a, glm::max(b, c));
      if (glm::any(glm::lessThan(thi, lo)) || glm::any(glm::greaterThan(tlo, hi))) continue;
      out.push_back(tri);
    }
  }
  return out;
}

void ldmFieldBounds(const Field& field, glm::vec3& lo, glm::vec3& hi) {
  lo = glm::vec3(std::numeric_limits<float>::max());
  hi = -lo;
  for (int k = 0; k < field.cascadeCount(); ++k) {
    const CascadeDesc& c = field.cascade(k);
    const glm::vec3 a = pcProbeGridPosition(c, glm::ivec3(0));
    const glm::vec3 b = pcProbeGridPosition(c, c.counts - 1);
    const float reach = PC_RELOCATE_MAX_OFFSET * c.spacing * std::sqrt(3.0f);
    lo = glm::min(lo, glm::min(a, b) - reach);
    hi = glm::max(hi, glm::max(a, b) + reach);
  }
  lo -= glm::vec3(field.desc.occlusionDistance);
  hi += glm::vec3(field.desc.occlusionDistance);
}

std::vector<glm::vec3> ldmProbePositions(const Field& field, std::span<const ProbeRef> probes) {
  std::vector<glm::vec3> out;
  out.reserve(probes.size());
  for (const ProbeRef& p : probes) out.push_back(field.probePosition(p.cascade, p.slot));
  return out;
}

void writeLdmOcclusion(Field& field, std::span<const ProbeRef> probes,
                       std::span<const float> tiles) {
  constexpr int n = PC_OCCLUSION_TEXELS;
  for (std::size_t i = 0; i < probes.size() && (i + 1) * n * n <= tiles.size(); ++i) {
    const ProbeRef& p = probes[i];
    if (field.probe(p.cascade, p.slot).state == PC_PROBE_INSIDE) continue;
    const glm::ivec2 o = pcAtlasTileOrigin(field.cascade(p.cascade), p.slot, n + 2);
    for (int t = 0; t < n * n; ++t)
      field.occlusion.at(o.x + 1 + t % n, o.y + 1 + t / n)[0] = tiles[i * n * n + std::size_t(t)];
    field.fixBorders(p.cascade, p.slot);
  }
}

}  // namespace pc
