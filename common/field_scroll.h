// Cascades that follow the viewers: a cascade moves by whole probe spacings and keeps its
// storage in place (toroidal addressing, CascadeDesc::scroll), so a move re-traces only the
// slab of probes that scrolled in, and a client that holds the cascade shifts its copy instead
// of downloading it again.
//
// Every brick a server quantizes carries the origin of its cascade at that moment (its layout
// stamp, QuantizedBrick::origin). A probe slot's data belongs to the grid point that the
// stamp's layout puts there; under another layout the same slot may stand for another grid
// point, and then its data is not shown (slotMatchesStamp). A client therefore never needs to
// see every move: whatever layouts it skipped, a slot is shown exactly when its data is for
// the grid point the client's layout puts there.
#pragma once

#include <glm/glm.hpp>
#include <vector>

#include "field.h"

namespace pc {

// Moves cascade k by `shift` probes per axis (origin += shift x spacing, scroll += shift mod
// counts). Probes whose grid point stays inside the cascade keep their slot and data; the
// slots of those that left now stand for the grid points that came in, and start over:
// uninitialized (never sampled), no relocation offset, no blend history. Their tiles keep the
// old values until traced (nothing samples them meanwhile). Returns those slots (cascade
// slot indices), every valid slot when a move is at least the cascade's size. Brick and
// field versions are not changed: the next update traces the reset probes, whose state
// changes, and that marks their bricks changed.
std::vector<int> scrollCascade(Field& field, int k, glm::ivec3 shift);

// The move that brings `center` back to within one spacing of the cascade's middle on each
// axis (0 where it is already; moving by whole spacings only, and only once the centre is a
// full spacing off, so that a viewer standing near a cell's edge does not make it scroll to
// and fro).
glm::ivec3 followShift(const gpu::CascadeDesc& cascade, glm::vec3 center);

// Whether the data of physical probe coordinate `physical`, quantized while the cascade's
// origin was `stampOrigin`, stands for the grid point that `current` puts at that coordinate.
// Both layouts must be of the same cascade (counts, spacing), origins a whole number of
// spacings apart as scrollCascade keeps them.
bool slotMatchesStamp(const gpu::CascadeDesc& current, glm::vec3 stampOrigin, glm::ivec3 physical);

// The integer move between two origins of one cascade (rounded to whole spacings).
glm::ivec3 originShift(glm::vec3 from, glm::vec3 to, float spacing);

}  // namespace pc
