// Baked probe field files (.probes): a whole pc::Field in one flatbuffer (baked_field.fbs),
// the fallback a client renders with before the server has sent anything. PROTOCOL.md
// specifies the format and the rules for bumping its version.
//
// Decoding treats every byte as hostile: size caps before reading, the flatbuffers Verifier,
// then checks that every count, size and value agrees with the shared field layout. A file
// that fails any check gives an Error naming the file and the problem, never a crash.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>
#include <vector>

#include "common/field.h"
#include "common/result.h"

namespace pc {

// The version this code writes, and the oldest it still reads. Version 2 added the whole-file
// checksum; version 1 files, which have none, are refused (PROTOCOL.md, Versioning).
inline constexpr std::uint32_t kBakedFormatVersion = 2;
inline constexpr std::uint32_t kBakedMinFormatVersion = 2;

// Files larger than this are rejected before they are read (flatbuffers' 2 GiB limit with
// room to spare).
inline constexpr std::uint64_t kMaxBakedFileBytes = 2'000'000'000;
// Decompressed atlases may not add up to more than this, so a small hostile file cannot ask
// for a huge allocation.
inline constexpr std::uint64_t kMaxBakedAtlasBytes = 4'000'000'000;

struct BakedWriteOptions {
  // float16 irradiance and occlusion (about half the size; relative error < 1e-3) instead of
  // exact float32. Depth is always float32: its mean-square channel needs the range.
  bool halfPrecision = false;
  // zstd level for the atlases; 0 stores them uncompressed.
  int zstdLevel = 3;
};

Result<std::vector<std::uint8_t>> encodeBakedField(const Field& field,
                                                   const BakedWriteOptions& options = {});
// Writes the whole-file checksum into encoded bytes (encodeBakedField does so itself); for
// tests and fuzzers that change a file on purpose so that the checks past the checksum see it.
// False where the bytes hold no root table with a checksum field.
bool sealBakedChecksum(std::span<std::uint8_t> bytes);

// `name` only labels error messages. expectedSceneHash 0 accepts any scene.
Result<Field> decodeBakedField(std::span<const std::uint8_t> bytes, std::uint64_t expectedSceneHash,
                               std::string_view name = "<memory>");

// Writes through a temporary file in the same folder and renames it into place, so readers
// never see a partial file, whatever happens during the write.
Status writeBakedField(const std::filesystem::path& path, const Field& field,
                       const BakedWriteOptions& options = {});
Result<Field> readBakedField(const std::filesystem::path& path, std::uint64_t expectedSceneHash);

// The checks decodeBakedField applies to what it decoded, for fields from anywhere: layout
// consistent with the shared layout functions, finite values, valid probe states. Messages
// start with what is wrong (no file name).
Status validateField(const Field& field);

}  // namespace pc
