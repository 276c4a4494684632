// Baked field files (protocol/baked_file.h): decodeBakedField on any bytes returns a field that
// passes validateField, or an Error. The input is tried as read, with its size prefix made
// to fit, and with that and its whole-file checksum made to fit (sealBakedChecksum), so that
// mutations reach the flatbuffer and atlas checks past the checksum. A decoded field survives
// re-encoding (float32, stored atlases) unchanged.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "fuzz_support.h"
#include "protocol/baked_file.h"

namespace {

using namespace pc;

void check(std::span<const std::uint8_t> bytes) {
  Result<Field> f = decodeBakedField(bytes, 0, "fuzz");
  if (!f) return;
  if (Status s = validateField(f.value()); !s) {
    std::fprintf(stderr, "decoded field fails validation: %s\n", s.error().message.c_str());
    std::abort();
  }
  BakedWriteOptions exact;
  exact.zstdLevel = 0;
  Result<std::vector<std::uint8_t>> bytes2 = encodeBakedField(f.value(), exact);
  if (!bytes2) {
    std::fprintf(stderr, "decoded field does not encode: %s\n", bytes2.error().message.c_str());
    std::abort();
  }
  Result<Field> g = decodeBakedField(bytes2.value(), f->sceneHash, "fuzz re-encoded");
  if (!g) {
    std::fprintf(stderr, "re-encoded field does not decode: %s\n", g.error().message.c_str());
    std::abort();
  }
  if (g->irradiance.texels != f->irradiance.texels || g->depth.texels != f->depth.texels ||
      g->occlusion.texels != f->occlusion.texels || g->probes.size() != f->probes.size() ||
      g->brickVersions != f->brickVersions || g->version != f->version ||
      g->cascadeCount() != f->cascadeCount())
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  check(std::span<const std::uint8_t>(data, size));
  std::vector<std::uint8_t> fitted = fuzz::withFittedPrefix(data, size);
  check(fitted);
  if (sealBakedChecksum(fitted)) check(fitted);
  return 0;
}
