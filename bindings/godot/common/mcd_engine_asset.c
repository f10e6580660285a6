#include "mcd_engine_asset.h"

#include <string.h>

void *mcd_engine_align16(void *p) {
    return (void *)(((uintptr_t)p + 15u) & ~(uintptr_t)15u);
}

static void release(const mcd_engine_allocator *mem, void *p) {
    if (p) mem->free(p); /* some engines' free complains about NULL */
}

void mcd_engine_asset_close(mcd_engine_asset *a, const mcd_engine_allocator *mem) {
    release(mem, a->bytes);
    release(mem, a->resident_block);
    release(mem, a->scratch_block);
    release(mem, a->pose);
    memset(a, 0, sizeof *a);
}

static mcd_result open_copy(mcd_engine_asset *a, const uint8_t *data, size_t size, const mcd_engine_allocator *mem) {
    static const uint8_t empty = 0;
    size_t resident_size = 0, scratch_size;
    mcd_result r;
    if (size == 0) data = &empty;
    r = mcd_resident_size(data, size, 0, &resident_size);
    if (r != MCD_OK) return r;
    a->bytes = mem->alloc(size + 1);
    a->resident_block = mem->alloc(resident_size + 16);
    if (!a->bytes || !a->resident_block) return MCD_ERROR_BUFFER_TOO_SMALL;
    memcpy(a->bytes, data, size);
    r = mcd_open(a->bytes, size, 0, mcd_engine_align16(a->resident_block), resident_size, &a->asset);
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
