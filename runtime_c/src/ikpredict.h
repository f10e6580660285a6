/* Codec `ik-predict`: the encoder-support entry points (docs/FORMAT.md, IKPR). The encoder
 * runs its closed loop through these functions (via the cffi binding), so its reconstruction
 * is computed by the very prediction step the decoder runs. Not installed. */
#ifndef MCD_IKPREDICT_H
#define MCD_IKPREDICT_H

#include <stddef.h>
#include <stdint.h>

#include "mocodec.h"

/* Bytes of work memory mcd_ikp_closed_loop needs for the payload head `head` (the payload's
 * header, node table and chain tables: everything before the block table) over the skeleton
 * records `skeleton` (a SKEL section's first 16 + 32 x node_count bytes). 0 when the head is
 * not valid for that skeleton. */
size_t mcd_ikp_work_size(const uint8_t* head, size_t head_size, const uint8_t* skeleton,
                         size_t skeleton_size);

/* Closed-loop encode of a clip's `frames` coded frames (frame_count when frame_stride is 1;
 * coded frame g is frame min(g frame_stride, frame_count - 1)). For every coded frame f (intra
 * when f is a multiple of the block length): the effector codes (root-relative effector positions `effectors` (F x 3C), coded
 * against the forward kinematics of the decoded frame f - 1), the prediction of the decoder,
 * and the residual codes of `targets` (F x (3J + 3T): phi, varphi, psi per coded joint, then
 * x, y, z per coded translation) are written to `codes` (F x (3C + 3J + 3T); the effector
 * part of intra rows is 0). `poses` (F x N transforms, or NULL) receives the local pose the
 * runtime samples at each integer frame, bit for bit. `work` is 16-aligned, `work_size` bytes
 * (mcd_ikp_work_size). Returns MCD_ERROR_INVALID_ARGUMENT on a bad head or argument and
 * MCD_ERROR_OUT_OF_RANGE when a code would exceed the entropy coder's range (steps too fine). */
mcd_result mcd_ikp_closed_loop(const uint8_t* head, size_t head_size, const uint8_t* skeleton,
                               size_t skeleton_size, uint32_t frames, const double* targets,
                               const double* effectors, int32_t* codes, mcd_transform* poses,
                               void* work, size_t work_size);

#endif /* MCD_IKPREDICT_H */
