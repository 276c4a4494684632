// Image files: tone-mapped 8-bit PNG (stb), linear EXR (tinyexr) and linear PFM (own code,
// the format is a short text header followed by raw floats).
#include "image.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <system_error>

#include "../shaders/interop/tonemap.h"

// The stb and tinyexr headers do not build warning-free under -Wall -Wextra -Wpedantic.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wall"
#pragma GCC diagnostic ignored "-Wextra"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb_image_write.h>
// Declarations only: the stb_image implementation is compiled once, in scene_model.cpp.
#include <stb_image.h>
#include <tinyexr.h>
#pragma GCC diagnostic pop

namespace pc {

namespace {

// Pixel counts above this are rejected when reading, so a corrupt header cannot ask for an
// absurd allocation (16k x 16k).
constexpr std::int64_t kMaxPixels = std::int64_t(1) << 28;

std::string describe(const std::filesystem::path& path) { return path.string(); }

Error fileError(const std::filesystem::path& path, const std::string& problem) {
  return Error{"image " + describe(path) + ": " + problem};
}

// Distinguishes "missing" from "not a regular file" before a decoder gives a vaguer reason.
Status checkReadable(const std::filesystem::path& path) {
  std::error_code ec;
  auto st = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(st)) return fileError(path, "file not found");
  if (!std::filesystem::is_regular_file(st)) return fileError(path, "not a regular file");
  return Status::success();
}

std::string lowerExtension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

bool validSize(int w, int h) { return w > 0 && h > 0 && std::int64_t(w) * h <= kMaxPixels; }

unsigned char toByte(float v) {
  return static_cast<unsigned char>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

struct StbFree {
  void operator()(unsigned char* p) const { stbi_image_free(p); }
};
struct ExrFree {
  void operator()(float* p) const { std::free(p); }
};
// tinyexr allocates its messages; this frees one whatever way the function leaves.
struct ExrMessage {
  const char* text = nullptr;
  ~ExrMessage() {
    if (text) FreeEXRErrorMessage(text);
  }
  std::string str() const { return text ? text : "unknown error"; }
};

float fromLittleEndian(const unsigned char* p, bool littleEndian) {
  std::uint32_t bits;
  std::memcpy(&bits, p, 4);
  if ((std::endian::native == std::endian::little) != littleEndian) {
    bits = (bits >> 24) | ((bits >> 8) & 0xff00u) | ((bits << 8) & 0xff0000u) | (bits << 24);
  }
  float v;
  std::memcpy(&v, &bits, 4);
  return v;
}

void appendLittleEndian(std::string& out, float v) {
  std::uint32_t bits;
  std::memcpy(&bits, &v, 4);
  if constexpr (std::endian::native != std::endian::little) {
    bits = (bits >> 24) | ((bits >> 8) & 0xff00u) | ((bits << 8) & 0xff0000u) | (bits << 24);
  }
  char b[4];
  std::memcpy(b, &bits, 4);
  out.append(b, 4);
}

Result<Image> readPfm(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fileError(path, std::string("cannot open: ") + std::strerror(errno));
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return fileError(path, "read error");

  // Header: "PF" (rgb) or "Pf" (grey), width, height, scale; each separated by whitespace
  // and the last followed by exactly one whitespace byte before the pixels.
  std::size_t pos = 0;
  auto token = [&]() -> std::string {
    while (pos < data.size() && std::isspace(static_cast<unsigned char>(data[pos]))) ++pos;
    std::size_t start = pos;
    while (pos < data.size() && !std::isspace(static_cast<unsigned char>(data[pos]))) ++pos;
    return data.substr(start, pos - start);
  };
  std::string magic = token();
  int channels = magic == "PF" ? 3 : magic == "Pf" ? 1 : 0;
  if (channels == 0) return fileError(path, "not a PFM file (magic '" + magic.substr(0, 8) + "')");
  std::string ws = token(), hs = token(), ss = token();
  if (ss.empty() || pos >= data.size()) {
    return fileError(path, "truncated PFM header (" + std::to_string(data.size()) + " bytes)");
  }
  ++pos;  // the single whitespace byte that ends the header
  char* end = nullptr;
  long w = std::strtol(ws.c_str(), &end, 10);
  bool ok = *end == '\0';
  long h = std::strtol(hs.c_str(), &end, 10);
  ok = ok && *end == '\0';
  double scale = std::strtod(ss.c_str(), &end);
  ok = ok && *end == '\0' && std::isfinite(scale) && scale != 0.0;
  if (!ok || w <= 0 || h <= 0 || w > (1 << 20) || h > (1 << 20) || !validSize(int(w), int(h))) {
    return fileError(path, "bad PFM header (size '" + ws + " " + hs + "', scale '" + ss + "')");
  }
  const std::size_t need = std::size_t(w) * std::size_t(h) * channels * 4;
  const std::size_t have = data.size() - pos;
  if (have < need) {
    return fileError(path, "truncated: " + std::to_string(have) + " bytes of pixel data, " +
                               std::to_string(w) + "x" + std::to_string(h) + " needs " +
                               std::to_string(need));
  }
  const bool little = scale < 0.0;  // the sign of the scale gives the byte order
  Image img{int(w), int(h)};
  const auto* p = reinterpret_cast<const unsigned char*>(data.data()) + pos;
  for (int row = 0; row < img.height; ++row) {
    // PFM stores rows bottom to top.
    const int y = img.height - 1 - row;
    for (int x = 0; x < img.width; ++x) {
      glm::vec3& px = img.at(x, y);
      if (channels == 3) {
        px = glm::vec3(fromLittleEndian(p, little), fromLittleEndian(p + 4, little),
                       fromLittleEndian(p + 8, little));
      } else {
        px = glm::vec3(fromLittleEndian(p, little));
      }
      p += channels * 4;
    }
  }
  return img;
}

Result<Image> readExr(const std::filesystem::path& path) {
  float* rgba = nullptr;
  int w = 0, h = 0;
  ExrMessage err;
  int rc = LoadEXR(&rgba, &w, &h, path.c_str(), &err.text);
  std::unique_ptr<float, ExrFree> owned(rgba);
  if (rc != TINYEXR_SUCCESS || !rgba) return fileError(path, "cannot read EXR: " + err.str());
  if (!validSize(w, h)) {
    return fileError(path,
                     "EXR has unsupported size " + std::to_string(w) + "x" + std::to_string(h));
  }
  Image img(w, h);
  for (std::size_t i = 0; i < img.pixels.size(); ++i) {
    img.pixels[i] = glm::vec3(rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2]);
  }
  return img;
}

}  // namespace

Image boxDownsample(const Image& image, int k) {
  if (k <= 1) return image;
  Image out(image.width / k, image.height / k);
  const float scale = 1.0f / float(k * k);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      glm::vec3 sum(0.0f);
      for (int dy = 0; dy < k; ++dy)
        for (int dx = 0; dx < k; ++dx) sum += image.at(x * k + dx, y * k + dy);
      out.at(x, y) = sum * scale;
    }
  return out;
}

Image8 tonemap(const Image& image, float exposure) {
  Image8 out;
  out.width = image.width;
  out.height = image.height;
  out.rgb.resize(image.pixels.size() * 3);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    glm::vec3 v = gpu::pcTonemap(image.pixels[i], exposure);
    out.rgb[3 * i] = toByte(v.x);
    out.rgb[3 * i + 1] = toByte(v.y);
    out.rgb[3 * i + 2] = toByte(v.z);
  }
  return out;
}

Status writePng(const std::filesystem::path& path, const Image8& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgb.size() != std::size_t(image.width) * image.height * 3) {
    return fileError(path, "cannot write PNG: image is empty or its size is inconsistent");
  }
  errno = 0;
  int ok =
      stbi_write_png(path.c_str(), image.width, image.height, 3, image.rgb.data(), image.width * 3);
  if (!ok) {
    return fileError(path, std::string("cannot write PNG: ") +
                               (errno ? std::strerror(errno) : "encoder failed"));
  }
  return Status::success();
}

Status writePng(const std::filesystem::path& path, const Image& image, float exposure) {
  return writePng(path, tonemap(image, exposure));
}

Status writeExr(const std::filesystem::path& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.pixels.size() != std::size_t(image.width) * image.height) {
    return fileError(path, "cannot write EXR: image is empty or its size is inconsistent");
  }
  // Full float: the files are references that metrics compare, so they stay lossless.
  static_assert(sizeof(glm::vec3) == 3 * sizeof(float));
  ExrMessage err;
  int rc = SaveEXR(reinterpret_cast<const float*>(image.pixels.data()), image.width, image.height,
                   3, /*save_as_fp16=*/0, path.c_str(), &err.text);
  if (rc != TINYEXR_SUCCESS) return fileError(path, "cannot write EXR: " + err.str());
  return Status::success();
}

Status writePfm(const std::filesystem::path& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.pixels.size() != std::size_t(image.width) * image.height) {
    return fileError(path, "cannot write PFM: image is empty or its size is inconsistent");
  }
  std::string out = "PF\n" + std::to_string(image.width) + " " + std::to_string(image.height) +
                    "\n-1.0\n";  // negative scale: little-endian floats
  out.reserve(out.size() + image.pixels.size() * 12);
  for (int y = image.height - 1; y >= 0; --y) {
    for (int x = 0; x < image.width; ++x) {
      const glm::vec3& p = image.at(x, y);
      appendLittleEndian(out, p.x);
      appendLittleEndian(out, p.y);
      appendLittleEndian(out, p.z);
    }
  }
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) return fileError(path, std::string("cannot write PFM: ") + std::strerror(errno));
  f.write(out.data(), std::streamsize(out.size()));
  f.close();
  if (!f) return fileError(path, "cannot write PFM: write failed");
  return Status::success();
}

Result<Image8> readPng(const std::filesystem::path& path) {
  if (Status s = checkReadable(path); !s) return s.error();
  int w = 0, h = 0, n = 0;
  std::unique_ptr<unsigned char, StbFree> data(stbi_load(path.c_str(), &w, &h, &n, 3));
  if (!data) {
    const char* why = stbi_failure_reason();
    return fileError(path, std::string("cannot read PNG: ") + (why ? why : "decoder failed"));
  }
  if (!validSize(w, h)) {
    return fileError(path,
                     "PNG has unsupported size " + std::to_string(w) + "x" + std::to_string(h));
  }
  Image8 img;
  img.width = w;
  img.height = h;
  img.rgb.assign(data.get(), data.get() + std::size_t(w) * h * 3);
  return img;
}

Result<Image> readImage(const std::filesystem::path& path) {
  if (Status s = checkReadable(path); !s) return s.error();
  const std::string ext = lowerExtension(path);
  if (ext == ".exr") return readExr(path);
  if (ext == ".pfm") return readPfm(path);
  if (ext == ".png") {
    Result<Image8> png = readPng(path);
    if (!png) return png.error();
    Image img(png->width, png->height);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) {
      const unsigned char* p = &png->rgb[3 * i];
      img.pixels[i] = glm::vec3(gpu::pcSrgbDecode(p[0] / 255.0f), gpu::pcSrgbDecode(p[1] / 255.0f),
                                gpu::pcSrgbDecode(p[2] / 255.0f));
    }
    return img;
  }
  return fileError(path, "unsupported image format '" + ext + "' (expected .exr, .pfm or .png)");
}

}  // namespace pc
