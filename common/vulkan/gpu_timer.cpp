#include "../log.h"
#include "context.h"

namespace pc::vk {

Result<GpuTimer> GpuTimer::create(const Context& ctx, std::uint32_t maxPasses) {
  GpuTimer t;
  t.ctx_ = &ctx;
  t.capacity_ = maxPasses * 2;
  t.periodNs_ = ctx.properties().limits.timestampPeriod;
  std::uint32_t count = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(ctx.physicalDevice(), &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  vkGetPhysicalDeviceQueueFamilyProperties(ctx.physicalDevice(), &count, families.data());
  t.supported_ = families[ctx.queueFamily()].timestampValidBits > 0 && t.periodNs_ > 0.0;
  if (!t.supported_) return t;  // results() then reports nothing
  VkQueryPoolCreateInfo qci{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  qci.queryType = VK_QUERY_TYPE_TIMESTAMP;
  qci.queryCount = t.capacity_;
  VkQueryPool pool = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateQueryPool(ctx.device(), &qci, nullptr, &pool));
  t.pool_ = UniqueQueryPool(ctx.device(), pool);
  return t;
}

void GpuTimer::reset(VkCommandBuffer cmd) {
  used_ = 0;
  names_.clear();
  if (supported_) vkCmdResetQueryPool(cmd, pool_.get(), 0, capacity_);
}

void GpuTimer::begin(VkCommandBuffer cmd, std::string name) {
  if (!supported_ || used_ + 2 > capacity_) return;
  names_.push_back(std::move(name));
  vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, pool_.get(), used_++);
}

void GpuTimer::end(VkCommandBuffer cmd) {
  if (!supported_ || used_ % 2 == 0) return;
  vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, pool_.get(), used_++);
}

std::vector<std::pair<std::string, double>> GpuTimer::results() const {
  std::vector<std::pair<std::string, double>> out;
  if (!supported_ || used_ == 0) return out;
  std::vector<std::uint64_t> ticks(used_);
  const VkResult r = vkGetQueryPoolResults(
      ctx_->device(), pool_.get(), 0, used_, ticks.size() * sizeof(std::uint64_t), ticks.data(),
      sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
  if (r != VK_SUCCESS) {
    // Timings are diagnostics: without them the work itself still stands (a lost device shows
    // at the caller's next submission, which reports it).
    pc::logWarn("GPU timestamps: " + vkErrorMessage("vkGetQueryPoolResults", r));
    return out;
  }
  for (std::uint32_t i = 0; i + 1 < used_; i += 2) {
    const double ms = double(ticks[i + 1] - ticks[i]) * periodNs_ * 1e-6;
    out.emplace_back(names_[i / 2], ms);
  }
  return out;
}

}  // namespace pc::vk
