/* Sampling entry point: argument checks, time mapping, codec dispatch, local -> world. */
#include <math.h>
#include <string.h>

#include "contacts.h"
#include "internal.h"

#define SCRATCH_MAGIC 0x5343444Du /* "MDCS" */

/* The first MCD_SCRATCH_HEADER_SIZE bytes of every scratch buffer. */
typedef struct scratch_header {
    uint32_t magic;
    uint32_t clip; /* clip the codec area holds state for, or UINT32_MAX */
    uint64_t size;
    const uint8_t* data; /* the asset it was initialised for */
    uint64_t asset_size;
    uint32_t crc;
    uint32_t reserved[3];
} scratch_header;

typedef char scratch_header_fits[sizeof(scratch_header) <= MCD_SCRATCH_HEADER_SIZE ? 1 : -1];

size_t mcd_scratch_size(const mcd_asset* asset) {
    return asset ? (size_t)asset->scratch_size : 0;
}

mcd_result mcd_scratch_init(const mcd_asset* asset, void* scratch, size_t scratch_size) {
    scratch_header* h = (scratch_header*)scratch;
    if (!asset || !asset->data || !scratch) return MCD_ERROR_INVALID_ARGUMENT;
    if (((uintptr_t)scratch & 15u) != 0) return MCD_ERROR_INVALID_ARGUMENT;
    /* Smaller than the asset's largest need is fine for an instance that plays smaller clips:
     * mcd_sample checks each clip's need. */
    if (scratch_size < MCD_SCRATCH_MIN_SIZE + asset->contacts_scratch) return MCD_ERROR_BUFFER_TOO_SMALL;
    memset(scratch, 0, MCD_SCRATCH_HEADER_SIZE + asset->contacts_scratch);
    h->magic = SCRATCH_MAGIC;
    h->clip = UINT32_MAX;
    h->size = scratch_size;
    h->data = asset->data;
    h->asset_size = asset->size;
    h->crc = mcd_rd_u32(asset->data + 20);
    return MCD_OK;
}

/* Frame position in [0, frame_count - 1] for a time in seconds, found in double so that late
 * frames of long clips are told apart, then held as the float the codecs take (exact for
 * integer frames: frame counts are at most 2^24). */
static float frame_position(double time_seconds, float rate, uint32_t frames, uint32_t flags) {
    double last = (double)(frames - 1u);
    double x = time_seconds * (double)rate, r;
    if (frames <= 1u) return 0.0f;
    if (flags & MCD_SAMPLE_LOOP) {
        x = fmod(x, last);
        if (x < 0.0) x += last;
        if (!(x < last)) x = 0.0; /* fmod rounding can land exactly on `last` */
    } else if (x < 0.0) {
        x = 0.0;
    } else if (x > last) {
        x = last;
    }
    if (flags & MCD_SAMPLE_NEAREST) {
        /* Rounded as runtime 0.2 rounded its float position (x + 0.5 in float), so that a time
         * at an exact half frame shows the frame it showed (the goldens record it). */
        x = (double)floorf((float)x + 0.5f);
    } else {
        /* Times computed as frame / rate land a few ulps off the frame: snap them. 4e-7 x covers
         * a float time's rounding (2^-24 of it, a few times over); the cap of 1/128 frame keeps
         * the poses between frames in reach of a double time two hours in (float times computed
         * as frame / rate still snap up to about 190,000 frames). */
        r = floor(x + 0.5);
        if (fabs(x - r) < fmin(1e-4 + 4e-7 * x, 1.0 / 128.0)) x = r;
    }
    /* Rounding (NEAREST or the snap) can land on `last`, which loop mode shows as frame 0. */
    if ((flags & MCD_SAMPLE_LOOP) ? !(x < last) : x > last) x = (flags & MCD_SAMPLE_LOOP) ? 0.0 : last;
    {
        /* Rounding to float can reach `last` too (a position just under it, on a long clip). */
        float xf = (float)x;
        if ((flags & MCD_SAMPLE_LOOP) && !(xf < (float)last)) xf = 0.0f;
        return xf;
    }
}

mcd_result mcd_sample(const mcd_asset* asset, uint32_t clip, double time_seconds, uint32_t flags,
                      mcd_transform* out_pose, uint32_t pose_capacity, void* scratch) {
    const uint32_t known = MCD_SAMPLE_WORLD | MCD_SAMPLE_LOOP | MCD_SAMPLE_NEAREST | MCD_SAMPLE_CONTACTS;
    scratch_header* h = (scratch_header*)scratch;
    mcd_clip_view view;
    const mcd_codec_ops* ops;
    mcd_result r;
    float x;
    int fresh;
    if (!asset || !asset->data || !out_pose || !scratch) return MCD_ERROR_INVALID_ARGUMENT;
    if ((flags & ~known) != 0 || !(time_seconds == time_seconds && time_seconds - time_seconds == 0.0))
        return MCD_ERROR_INVALID_ARGUMENT; /* not finite */
    if (h->magic != SCRATCH_MAGIC || h->data != asset->data || h->asset_size != asset->size ||
        h->crc != mcd_rd_u32(asset->data + 20))
        return MCD_ERROR_SCRATCH_MISMATCH;
    r = mcd_clip_view_get(asset, clip, &view, &ops);
    if (r != MCD_OK) return r;
    if (pose_capacity < view.node_count) return MCD_ERROR_BUFFER_TOO_SMALL;
    /* Scratch layout: header, the contact pass's area (assets with CNTC), the codec's area. */
    if (h->size < (uint64_t)MCD_SCRATCH_HEADER_SIZE + asset->contacts_scratch + view.scratch_need)
        return MCD_ERROR_BUFFER_TOO_SMALL;
    x = frame_position(time_seconds, view.frame_rate, view.frame_count, flags);
    fresh = h->clip != clip;
    h->clip = clip;
    ops->sample(&view, x, flags, out_pose, (uint8_t*)scratch + MCD_SCRATCH_HEADER_SIZE + asset->contacts_scratch,
                fresh);
    if ((flags & MCD_SAMPLE_CONTACTS) && asset->contacts)
        mcd_contacts_apply(asset->data + asset->contacts, asset->contacts_size, clip, &view, x, out_pose,
                           (uint8_t*)scratch + MCD_SCRATCH_HEADER_SIZE);
    if (flags & MCD_SAMPLE_WORLD) mcd_local_to_world(view.skeleton, view.node_count, out_pose);
    return MCD_OK;
}
