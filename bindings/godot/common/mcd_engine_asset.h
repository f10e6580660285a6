/*
 * The opened asset both Godot bindings hold: a private copy of the bytes (the runtime reads an
 * asset in place, and the engine's array may change), the resident memory, one scratch buffer
 * and one pose buffer. Everything comes from the engine's allocator when the asset is loaded,
 * nothing while sampling.
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
    uint8_t *resident_block; /* 16 bytes of slack: the runtime wants 16-byte alignment */
    uint8_t *scratch_block;
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

/* A 16-byte aligned pointer inside a block allocated with 16 bytes of slack. */
void *mcd_engine_align16(void *p);

#endif
