#include "tools/inspect/slice_images.h"

#include <algorithm>
#include <cmath>

#include "common/image.h"
#include "shaders/interop/probe_update.h"

namespace pc::inspect {

using namespace pc::gpu;

namespace {

// The atlas slot of the probe at logical (x, y, z) of cascade k, through the field's scroll.
int sliceSlot(const CascadeDesc& c, int x, int y, int z) {
  return pcProbeSlot(c, pcPhysicalCoord(c, ivec3(x, y, z)));
}

// Calls put(px, py, texel) for every image pixel of the slice's tiles: tile (x, z) at column x,
// row z, each of its n x n interior texels upscaled to scale x scale pixels.
template <typename Put>
void forEachSlicePixel(const Atlas& atlas, const CascadeDesc& c, int y, int n, int scale,
                       Put&& put) {
  for (int z = 0; z < c.counts.z; ++z) {
    for (int x = 0; x < c.counts.x; ++x) {
      const ivec2 origin = pcAtlasTileOrigin(c, sliceSlot(c, x, y, z), n + 2);
      for (int py = 0; py < n * scale; ++py) {
        for (int px = 0; px < n * scale; ++px) {
          put(x * n * scale + px, z * n * scale + py,
              atlas.at(origin.x + 1 + px / scale, origin.y + 1 + py / scale));
        }
      }
    }
  }
}

Image8 blankImage8(const CascadeDesc& c, int n, int scale) {
  Image8 image;
  image.width = c.counts.x * n * scale;
  image.height = c.counts.z * n * scale;
  image.rgb.assign(std::size_t(image.width) * image.height * 3, 0);
  return image;
}

void putGrey(Image8& image, int px, int py, float value) {
  const auto v = static_cast<unsigned char>(std::lround(std::clamp(value, 0.0f, 1.0f) * 255.0f));
  unsigned char* p = &image.rgb[(std::size_t(py) * image.width + px) * 3];
  p[0] = p[1] = p[2] = v;
}

}  // namespace

StateColour stateColour(int state) {
  switch (state) {
    case PC_PROBE_ACTIVE:
      return {60, 200, 80};  // green
    case PC_PROBE_SLEEPING:
      return {70, 120, 230};  // blue
    case PC_PROBE_INSIDE:
      return {220, 60, 50};  // red
  }
  return {40, 40, 40};  // uninitialized: dark grey
}

Result<std::vector<std::filesystem::path>> writeSliceImages(const Field& field, int k, int y,
                                                            const std::filesystem::path& dir,
                                                            const SliceOptions& options) {
  const CascadeDesc& c = field.cascade(k);
  const int scale = options.scale;
  const std::string suffix = "_y" + std::to_string(y) + ".png";
  const std::string stem = "cascade" + std::to_string(k) + "_";
  std::vector<std::filesystem::path> written;
  auto write = [&](const std::string& what, auto&&... image) -> Status {
    const std::filesystem::path path = dir / (stem + what + suffix);
    if (Status s = writePng(path, image...); !s) return s;
    written.push_back(path);
    return Status::success();
  };

  // Irradiance, decoded, divided by pi: what a white diffuse surface facing that way reflects.
  constexpr int ni = PC_IRRADIANCE_TEXELS;
  Image irradiance(c.counts.x * ni * scale, c.counts.z * ni * scale);
  forEachSlicePixel(field.irradiance, c, y, ni, scale, [&](int px, int py, const float* t) {
    irradiance.at(px, py) = pcDecodeIrradiance(vec3(t[0], t[1], t[2])) / PC_PI;
  });
  if (Status s = write("irradiance", irradiance, options.exposure); !s) return s.error();

  // Depth: the mean hit distance as a share of the cascade's max ray distance.
  Image8 depth = blankImage8(c, PC_DEPTH_TEXELS, scale);
  forEachSlicePixel(field.depth, c, y, PC_DEPTH_TEXELS, scale, [&](int px, int py, const float* t) {
    putGrey(depth, px, py, c.maxRayDistance > 0.0f ? t[0] / c.maxRayDistance : 0.0f);
  });
  if (Status s = write("depth", depth); !s) return s.error();

  Image8 occlusion = blankImage8(c, PC_OCCLUSION_TEXELS, scale);
  forEachSlicePixel(field.occlusion, c, y, PC_OCCLUSION_TEXELS, scale,
                    [&](int px, int py, const float* t) { putGrey(occlusion, px, py, t[0]); });
  if (Status s = write("occlusion", occlusion); !s) return s.error();

  // One block per probe, the size of its irradiance tile, so the map lies over that image.
  const int block = ni * scale;
  Image8 states = blankImage8(c, ni, scale);
  for (int z = 0; z < c.counts.z; ++z) {
    for (int x = 0; x < c.counts.x; ++x) {
      const StateColour colour = stateColour(field.probe(k, sliceSlot(c, x, y, z)).state);
      for (int py = z * block; py < (z + 1) * block; ++py) {
        for (int px = x * block; px < (x + 1) * block; ++px) {
          unsigned char* p = &states.rgb[(std::size_t(py) * states.width + px) * 3];
          p[0] = colour.r;
          p[1] = colour.g;
          p[2] = colour.b;
        }
      }
    }
  }
  if (Status s = write("states", states); !s) return s.error();
  return written;
}

}  // namespace pc::inspect
