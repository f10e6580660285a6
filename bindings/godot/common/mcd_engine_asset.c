#include "mcd_engine_asset.h"

#include <math.h>
#include <string.h>

void *mcd_engine_align16(void *p) {
    return (void *)(((uintptr_t)p + 15u) & ~(uintptr_t)15u);
}

static void release(const mcd_engine_allocator *mem, void *p) {
    if (p) mem->free(p); /* some engines' free complains about NULL */
}

void mcd_engine_asset_close(mcd_engine_asset *a, const mcd_engine_allocator *mem) {
    release(mem, a->bytes);
    release(mem, a->scratch_block);
    release(mem, a->pose);
    memset(a, 0, sizeof *a);
}

static mcd_result open_copy(mcd_engine_asset *a, const uint8_t *data, size_t size, const mcd_engine_allocator *mem) {
    static const uint8_t empty = 0;
    size_t scratch_size;
    mcd_result r;
    if (size == 0) data = &empty;
    a->bytes = mem->alloc(size + 1);
    if (!a->bytes) return MCD_ERROR_BUFFER_TOO_SMALL;
    memcpy(a->bytes, data, size);
    r = mcd_open(a->bytes, size, 0, &a->asset);
    if (r != MCD_OK) return r;
    scratch_size = mcd_scratch_size(&a->asset);
    a->scratch_block = mem->alloc(scratch_size + 16);
    a->pose = mem->alloc(a->asset.max_nodes * sizeof(mcd_transform) + 1);
    if (!a->scratch_block || !a->pose) return MCD_ERROR_BUFFER_TOO_SMALL;
    a->scratch = mcd_engine_align16(a->scratch_block);
    return mcd_scratch_init(&a->asset, a->scratch, scratch_size);
}

mcd_result mcd_engine_asset_load(mcd_engine_asset *a, const uint8_t *data, size_t size,
                                 const mcd_engine_allocator *mem) {
    mcd_result r;
    mcd_engine_asset_close(a, mem);
    r = open_copy(a, data, size, mem);
    if (r == MCD_OK)
        a->opened = 1;
    else
        mcd_engine_asset_close(a, mem);
    return r;
}

void mcd_engine_rig_close(mcd_engine_rig *rig, const mcd_engine_allocator *mem) {
    release(mem, rig->map_block);
    release(mem, rig->work_block);
    release(mem, rig->rig_pose);
    memset(rig, 0, sizeof *rig);
}

mcd_result mcd_engine_rig_build(mcd_engine_rig *rig, const mcd_engine_asset *a, uint32_t skeleton,
                                const mcd_rig_bone *bones, uint32_t bone_count, const mcd_retarget_pair *pairs,
                                uint32_t pair_count, const mcd_retarget_config *config,
                                const mcd_engine_allocator *mem, mcd_retarget_issue *issue) {
    size_t size = 0;
    mcd_result r;
    mcd_engine_rig_close(rig, mem);
    if (issue) issue->where = MCD_RETARGET_ISSUE_CONFIG, issue->index = 0;
    if (!a->opened) return MCD_ERROR_INVALID_ARGUMENT;
    r = mcd_retarget_size(&a->asset, skeleton, bone_count, &size);
    if (r != MCD_OK) return r;
    rig->map_block = mem->alloc(size + 16);
    if (!rig->map_block) return MCD_ERROR_BUFFER_TOO_SMALL;
    rig->map = mcd_engine_align16(rig->map_block);
    r = mcd_retarget_init(&a->asset, skeleton, bones, bone_count, pairs, pair_count, config, rig->map, size, issue);
    if (r == MCD_OK) r = mcd_retarget_get_info(rig->map, &rig->info);
    if (r == MCD_OK) {
        rig->work_block = mem->alloc(rig->info.work_size + 16);
        rig->rig_pose = mem->alloc(rig->info.bone_count * sizeof(mcd_transform));
        if (!rig->work_block || !rig->rig_pose) r = MCD_ERROR_BUFFER_TOO_SMALL;
    }
    if (r != MCD_OK) {
        mcd_engine_rig_close(rig, mem);
        return r;
    }
    rig->work = mcd_engine_align16(rig->work_block);
    rig->skeleton = skeleton;
    rig->bound = 1;
    return MCD_OK;
}

mcd_result mcd_engine_rig_pose(mcd_engine_rig *rig, mcd_engine_asset *a, uint32_t clip, double time, uint32_t flags) {
    mcd_clip_info info;
    mcd_result r;
    if (!rig->bound || !a->opened || (flags & MCD_SAMPLE_WORLD)) return MCD_ERROR_INVALID_ARGUMENT;
    r = mcd_get_clip_info(&a->asset, clip, &info);
    if (r != MCD_OK) return r;
    if (info.skeleton != rig->skeleton) return MCD_ERROR_INVALID_ARGUMENT;
    r = mcd_sample(&a->asset, clip, time, flags, a->pose, a->asset.max_nodes, a->scratch);
    if (r != MCD_OK) return r;
    return mcd_retarget_pose(rig->map, a->pose, info.node_count, rig->rig_pose, rig->info.bone_count, rig->work,
                             rig->info.work_size);
}

void mcd_engine_rotation_from_rows(double m[3][3], float out[4]) {
    double tr = m[0][0] + m[1][1] + m[2][2], q[4], n;
    int k;
    if (tr > 0) {
        double s = 2.0 * sqrt(tr + 1.0);
        q[3] = 0.25 * s, q[0] = (m[2][1] - m[1][2]) / s, q[1] = (m[0][2] - m[2][0]) / s, q[2] = (m[1][0] - m[0][1]) / s;
    } else if (m[0][0] > m[1][1] && m[0][0] > m[2][2]) {
        double s = 2.0 * sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]);
        q[3] = (m[2][1] - m[1][2]) / s, q[0] = 0.25 * s, q[1] = (m[0][1] + m[1][0]) / s, q[2] = (m[0][2] + m[2][0]) / s;
    } else if (m[1][1] > m[2][2]) {
        double s = 2.0 * sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]);
        q[3] = (m[0][2] - m[2][0]) / s, q[0] = (m[0][1] + m[1][0]) / s, q[1] = 0.25 * s, q[2] = (m[1][2] + m[2][1]) / s;
    } else {
        double s = 2.0 * sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]);
        q[3] = (m[1][0] - m[0][1]) / s, q[0] = (m[0][2] + m[2][0]) / s, q[1] = (m[1][2] + m[2][1]) / s, q[2] = 0.25 * s;
    }
    n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (k = 0; k < 4; k++) out[k] = (float)(q[k] / n);
}
