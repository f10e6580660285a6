/* Contact trajectories (docs/FORMAT.md "Contacts — CNTC section") and the IK that rectifies
 * a sampled pose with them. Internal to the runtime; the tests include it for the solvers. */
#ifndef MCD_CONTACTS_H
#define MCD_CONTACTS_H

#include <stddef.h>
#include <stdint.h>

#include "internal.h"

#define MCD_CONTACTS_MAX_EFFECTORS 16u
#define MCD_CONTACTS_MAX_SEGMENT 1024u /* frames: bounds the delta walk of one sample */
#define MCD_CONTACTS_MAX_CHAIN 4u
#define MCD_CONTACTS_SOLVER_TWO_BONE 1u
#define MCD_CONTACTS_SOLVER_DLS 2u
#define MCD_CONTACTS_DLS_ITERATIONS 16u /* at most: it stops once converged */

/* Scratch bytes the contact pass needs (per-effector offset caches and a world pose), multiple
 * of 16. */
size_t mcd_contacts_scratch_size(uint32_t max_nodes);

/* Check every byte of a CNTC section against an asset whose clip directory is already valid. */
mcd_result mcd_contacts_validate(const mcd_asset* asset, const uint8_t* section, uint32_t size);

/* Rectify the local pose `local` of clip `clip` at frame position x with the clip's contacts
 * (no-op when the section has none for it). `scratch`: mcd_contacts_scratch_size bytes. */
void mcd_contacts_apply(const uint8_t* section, uint32_t size, uint32_t clip, const mcd_clip_view* view,
                        float x, mcd_transform* local, void* scratch);

/* Analytic two-bone IK in world space. a (hip), b (knee), c (ankle) are joint positions, t the
 * target. Outputs world rotations: `da` about a, applied to the whole limb, and `db` about b,
 * applied to the lower bone first (c' = a + da((b - a) + db(c - b))). The knee stays in the
 * plane of a, b, c; an unreachable target gives the straight limb pointing at it. */
void mcd_ik_two_bone(const float a[3], const float b[3], const float c[3], const float t[3], mcd_quat* da,
                     mcd_quat* db);

/* Damped least squares over a chain of `count` (1 ... MCD_CONTACTS_MAX_CHAIN) ball joints at
 * `joints` (root-most first) moving effector `e` towards `t`, a fixed number of iterations.
 * Writes each joint's accumulated world rotation `d[j]` (joint j's new world rotation is
 * d[j] ⊗ old) and the effector's final position `e_out`. */
void mcd_ik_dls(uint32_t count, const float joints[][3], const float e[3], const float t[3], mcd_quat* d,
                float e_out[3]);

#endif /* MCD_CONTACTS_H */
