#include <unistd.h>

#include <fstream>

#include "common/data_folders.h"
#include "context.h"

namespace pc::vk {

std::filesystem::path shaderPath(std::string_view name) {
  if (auto found = findDataFile("shaders", name)) return *found;
  // Where the build puts it, for a message: beside the executable.
  std::error_code ec;
  std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  std::filesystem::path dir = ec ? std::filesystem::current_path() : exe.parent_path();
  return dir / "shaders" / std::string(name);
}

Result<UniqueShaderModule> createShaderModule(const Context& ctx,
                                              std::span<const std::uint32_t> spirv) {
  VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  ci.codeSize = spirv.size_bytes();
  ci.pCode = spirv.data();
  VkShaderModule module = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateShaderModule(ctx.device(), &ci, nullptr, &module));
  return UniqueShaderModule(ctx.device(), module);
}

Result<UniqueDescriptorSetLayout> createDescriptorSetLayout(
    const Context& ctx, std::span<const VkDescriptorSetLayoutBinding> bindings,
    std::span<const VkDescriptorBindingFlags> flags) {
  VkDescriptorSetLayoutBindingFlagsCreateInfo fi{
      VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_BINDING_FLAGS_CREATE_INFO};
  fi.bindingCount = std::uint32_t(flags.size());
  fi.pBindingFlags = flags.data();
  VkDescriptorSetLayoutCreateInfo ci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  ci.pNext = flags.empty() ? nullptr : &fi;
  ci.bindingCount = std::uint32_t(bindings.size());
  ci.pBindings = bindings.data();
  VkDescriptorSetLayout layout = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateDescriptorSetLayout(ctx.device(), &ci, nullptr, &layout));
  return UniqueDescriptorSetLayout(ctx.device(), layout);
}

Result<UniquePipelineLayout> createPipelineLayout(const Context& ctx,
                                                  VkDescriptorSetLayout setLayout,
                                                  VkShaderStageFlags pushStages,
                                                  std::uint32_t pushBytes) {
  const VkPushConstantRange push{pushStages, 0, pushBytes};
  VkPipelineLayoutCreateInfo ci{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  ci.setLayoutCount = 1;
  ci.pSetLayouts = &setLayout;
  ci.pushConstantRangeCount = pushBytes > 0 ? 1 : 0;
  ci.pPushConstantRanges = pushBytes > 0 ? &push : nullptr;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreatePipelineLayout(ctx.device(), &ci, nullptr, &layout));
  return UniquePipelineLayout(ctx.device(), layout);
}

Result<UniqueShaderModule> loadShader(const Context& ctx, std::string_view name) {
  auto found = findDataFile("shaders", name);
  if (!found) return Error{"shader " + found.error().message};
  const std::filesystem::path path = *found;
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return Error{path.string() + ": cannot open shader"};
  const std::streamsize bytes = in.tellg();
  if (bytes <= 0 || bytes % 4 != 0) return Error{path.string() + ": not a SPIR-V file"};
  std::vector<std::uint32_t> words(std::size_t(bytes) / 4);
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(words.data()), bytes))
    return Error{path.string() + ": read failed"};
  if (words[0] != 0x07230203u) return Error{path.string() + ": not a SPIR-V file (bad magic)"};
  return createShaderModule(ctx, words);
}

Result<UniquePipeline> createComputePipeline(const Context& ctx, std::string_view name,
                                             VkPipelineLayout layout,
                                             std::span<const SpecConstant> constants,
                                             VkPipelineCreateFlags flags) {
  auto module = loadShader(ctx, name);
  if (!module) return module.error();
  VkComputePipelineCreateInfo cci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  cci.flags = flags;
  cci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  cci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  cci.stage.module = module->get();
  cci.stage.pName = "main";
  std::vector<VkSpecializationMapEntry> entries;
  std::vector<int> values;
  for (const SpecConstant& c : constants) {
    entries.push_back({c.id, std::uint32_t(values.size() * sizeof(int)), sizeof(int)});
    values.push_back(c.value);
  }
  const VkSpecializationInfo spec{std::uint32_t(entries.size()), entries.data(),
                                  values.size() * sizeof(int), values.data()};
  if (!constants.empty()) cci.stage.pSpecializationInfo = &spec;
  cci.layout = layout;
  VkPipeline p = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateComputePipelines(ctx.device(), VK_NULL_HANDLE, 1, &cci, nullptr, &p));
  return UniquePipeline(ctx.device(), p);
}

}  // namespace pc::vk
