/*
 * What both Godot bindings hold: an opened asset (a private copy of the bytes, since the
 * runtime samples an asset in place and the engine's array may change; one scratch buffer and
 * one pose buffer), and a retargeting onto a rig (the runtime's map, its work buffer and the
 * rig pose). Everything comes from the engine's allocator when the asset is loaded or a rig
 * bound, nothing while sampling.
 */
#ifndef MCD_ENGINE_ASSET_H
#define MCD_ENGINE_ASSET_H

#include <stddef.h>
#include <stdint.h>

#include "mocodec.h"

typedef struct {
    void *(*alloc)(size_t bytes);
    void (*free)(void *p);
} mcd_engine_allocator;

typedef struct {
    uint8_t *bytes;
    uint8_t *scratch_block;  /* 16 bytes of slack: the runtime wants 16-byte alignment */
    void *scratch;           /* aligned, inside scratch_block */
    mcd_transform *pose;     /* asset.max_nodes entries */
    mcd_asset asset;
    uint32_t opened;         /* 1 once load succeeded */
} mcd_engine_asset;

/* Closes what `a` held, then validates and opens a copy of data[0 .. size). An empty buffer is
 * a truncated asset (not a missing one). On failure `a` is left closed. */
mcd_result mcd_engine_asset_load(mcd_engine_asset *a, const uint8_t *data, size_t size,
                                 const mcd_engine_allocator *mem);
void mcd_engine_asset_close(mcd_engine_asset *a, const mcd_engine_allocator *mem);

typedef struct {
    uint8_t *map_block, *work_block; /* 16 bytes of slack each, aligned inside */
    void *map, *work;
    mcd_transform *rig_pose;         /* bone_count entries, written by mcd_engine_rig_pose */
    mcd_retarget_info info;
    uint32_t skeleton;
    uint32_t bound;                  /* 1 once built */
} mcd_engine_rig;

/* Builds the retargeting of skeleton `skeleton` of `a` onto `bones` (see mocodec.h). On failure
 * the rig is left unbound and `issue` names the bone, pair or setting. */
mcd_result mcd_engine_rig_build(mcd_engine_rig *rig, const mcd_engine_asset *a, uint32_t skeleton,
                                const mcd_rig_bone *bones, uint32_t bone_count, const mcd_retarget_pair *pairs,
                                uint32_t pair_count, const mcd_retarget_config *config,
                                const mcd_engine_allocator *mem, mcd_retarget_issue *issue);
/* Samples clip `clip` of `a` (local; flags as mcd_sample, MCD_SAMPLE_WORLD refused) and
 * retargets it into rig->rig_pose. The clip must be of the rig's skeleton. */
mcd_result mcd_engine_rig_pose(mcd_engine_rig *rig, mcd_engine_asset *a, uint32_t clip, double time, uint32_t flags);
void mcd_engine_rig_close(mcd_engine_rig *rig, const mcd_engine_allocator *mem);

/* A rotation matrix given by its rows, as a unit quaternion x y z w (Shepperd's method: the
 * largest of the four squares first, so nothing is divided by a small number). */
void mcd_engine_rotation_from_rows(double rows[3][3], float out[4]); /* not const: C99 converts no double[3][3] to it */

/* A 16-byte aligned pointer inside a block allocated with 16 bytes of slack. */
void *mcd_engine_align16(void *p);

#endif
