// Lets one header compile as C++ (with GLM) and as GLSL. Shared code follows a few rules so it
// means the same in both languages: float literals carry an `f` suffix, unsigned ones a `u`,
// no swizzles (build vectors with constructors), no references (use PC_INOUT), and functions
// are marked PC_FN.
#ifndef PC_INTEROP_H
#define PC_INTEROP_H

#ifdef __cplusplus
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/packing.hpp>
namespace pc::gpu {
using namespace glm;
using uint = std::uint32_t;
}  // namespace pc::gpu
#define PC_BEGIN namespace pc::gpu {
#define PC_END }
#define PC_FN inline
#define PC_CONST inline constexpr
#define PC_INOUT(T) T&
#define PC_IN(T) const T&
#else
#define PC_BEGIN
#define PC_END
#define PC_FN
#define PC_CONST const
#define PC_INOUT(T) inout T
#define PC_IN(T) in T
#endif

#endif
