/* The parts of an RMAL payload both versions lay out alike (docs/FORMAT.md, RMAL versions 2
 * and 3): header, node modes, constants, descriptors and the zero end, the node plans built
 * from them, and a track's window of four keys and its curve. rmal_payload.h says how a
 * version's track reader plugs in. */
#include "rmal_payload.h"

enum { MODE_REST = 0, MODE_CONSTANT = 1, MODE_ANIMATED = 2 };

int mcd_rmal_zero_bits(const uint8_t* p, uint64_t from, uint64_t to) {
    for (; from < to; ++from)
        if (mcd_read_bits(p, from, 1)) return 0;
    return 1;
}

mcd_result mcd_rmal_parse_header(const uint8_t* p, size_t avail, mcd_rmal_header* H) {
    uint32_t i;
    /* Defined on every return: prepare reads validated bytes and ignores the result, which gcc
     * -O3 cannot see (maybe-uninitialized). */
    memset(H, 0, sizeof *H);
    if (avail < MCD_RMAL_PAYLOAD_HEADER) return MCD_ERROR_MALFORMED;
    H->size = mcd_rd_u32(p);
    H->frames = mcd_rd_u32(p + 4);
    H->nodes = mcd_rd_u32(p + 8);
    H->tracks = mcd_rd_u32(p + 12);
    H->constants = mcd_rd_u32(p + 16);
    if (H->size < MCD_RMAL_PAYLOAD_HEADER || H->size > avail || (H->size & 3u)) return MCD_ERROR_MALFORMED;
    if (mcd_rd_u32(p + 20) || mcd_rd_u32(p + 24) || mcd_rd_u32(p + 28)) return MCD_ERROR_MALFORMED;
    if (H->frames == 0 || H->nodes == 0 || H->nodes > MCD_MAX_NODES) return MCD_ERROR_MALFORMED;
    if (H->tracks > 3u * H->nodes || H->constants > 10u * H->nodes) return MCD_ERROR_MALFORMED;
    if ((uint64_t)MCD_RMAL_PAYLOAD_HEADER + mcd_align4(H->nodes) + 4u * (uint64_t)H->constants > H->size)
        return MCD_ERROR_MALFORMED;
    H->modes = p + MCD_RMAL_PAYLOAD_HEADER;
    H->consts = H->modes + mcd_align4(H->nodes);
    H->descs = H->consts + 4u * (size_t)H->constants;
    for (i = H->nodes; i < mcd_align4(H->nodes); ++i)
        if (H->modes[i]) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

mcd_result mcd_rmal_parse_desc(const uint8_t* d, uint32_t frames, mcd_rmal_desc* t) {
    uint32_t c;
    t->kind = d[0];
    if (!mcd_rmal_desc_size(t->kind)) return MCD_ERROR_MALFORMED;
    t->dims = t->kind == MCD_RMAL_TWIST ? 4u : 3u;
    t->split = d[1] & 1u;
    t->offset_bits = d[2];
    t->keys = mcd_rd_u32(d + 4);
    t->data_bytes = mcd_rd_u32(d + 8);
    if (t->offset_bits < 1 || t->offset_bits > 32) return MCD_ERROR_MALFORMED;
    if (t->keys < 1 || t->keys > frames || (frames > 1u && t->keys < 2u)) return MCD_ERROR_MALFORMED;
    if (t->data_bytes & 3u) return MCD_ERROR_MALFORMED;
    t->step[0] = t->step[1] = t->step[2] = t->step[3] = mcd_rd_f32(d + 12);
    if (t->kind == MCD_RMAL_TWIST) t->step[0] = mcd_rd_f32(d + 36);
    t->anchor_bits = 0;
    for (c = 0; c < 4; ++c) {
        t->abits[c] = d[16 + c];
        if (c < t->dims) {
            if (t->abits[c] < 1 || t->abits[c] > 31) return MCD_ERROR_MALFORMED;
            if (!mcd_in_bounds(t->step[c]) || t->step[c] < 0.0f) return MCD_ERROR_MALFORMED;
            t->anchor_bits += t->abits[c];
        } else if (t->abits[c]) {
            return MCD_ERROR_MALFORMED;
        }
    }
    return MCD_OK;
}

/* Where the tracks' data starts: after the descriptors (already checked), aligned to 4. */
static uint32_t data_start(const uint8_t* p, const mcd_rmal_header* H) {
    uint32_t i, off = 0;
    for (i = 0; i < H->tracks; ++i) off += mcd_rmal_desc_size(H->descs[off]);
    return (uint32_t)mcd_align4((size_t)(H->descs - p) + off);
}

mcd_result mcd_rmal_validate_payload(const mcd_clip_view* v, mcd_rmal_check_track check) {
    const uint8_t* p = v->payload;
    mcd_rmal_header H;
    mcd_result r;
    uint32_t i, m, k, off = 0, consts = 0, track = 0, at;
    static const uint8_t kinds[3][2] = {{MCD_RMAL_MRP, MCD_RMAL_TWIST}, {MCD_RMAL_TRANSLATION, 0}, {MCD_RMAL_SCALE, 0}};
    if ((size_t)(v->payload - v->section) < MCD_RMAL_SECTION_HEADER) return MCD_ERROR_MALFORMED;
    r = mcd_rmal_parse_header(p, v->payload_size, &H);
    if (r != MCD_OK) return r;
    if (H.size != v->payload_size || H.frames != v->frame_count || H.nodes != v->node_count) return MCD_ERROR_MALFORMED;
    for (i = 0; i < H.constants; ++i)
        if (!mcd_in_bounds(mcd_rd_f32(H.consts + 4u * i))) return MCD_ERROR_MALFORMED;
    /* Node modes: constants and tracks taken in node order, rotation, translation, scale. */
    for (i = 0; i < H.nodes; ++i) {
        uint32_t mode = H.modes[i];
        if (mode >> 6) return MCD_ERROR_MALFORMED;
        for (m = 0; m < 3; ++m) {
            uint32_t mm = (mode >> (2u * m)) & 3u, n = m == 0 ? 4u : 3u, kind;
            if (mm == 3u) return MCD_ERROR_MALFORMED;
            if (mm == MODE_CONSTANT) {
                if (consts + n > H.constants) return MCD_ERROR_MALFORMED;
                if (m == 0 && !mcd_unit_quat_at(H.consts + 4u * consts)) return MCD_ERROR_MALFORMED;
                consts += n;
            } else if (mm == MODE_ANIMATED) {
                if (track >= H.tracks || (size_t)(H.descs - p) + off + 4u > H.size) return MCD_ERROR_MALFORMED;
                kind = H.descs[off];
                if (kind == 0 || (kind != kinds[m][0] && kind != kinds[m][1])) return MCD_ERROR_MALFORMED;
                if ((size_t)(H.descs - p) + off + mcd_rmal_desc_size(kind) > H.size) return MCD_ERROR_MALFORMED;
                if ((kind == MCD_RMAL_MRP || kind == MCD_RMAL_TWIST) && mcd_rd_u16(H.descs + off + 26))
                    return MCD_ERROR_MALFORMED;
                if (kind == MCD_RMAL_TWIST) {
                    const uint8_t* a = H.descs + off + 28;
                    float ax = (float)(int16_t)mcd_rd_u16(a), ay = (float)(int16_t)mcd_rd_u16(a + 2);
                    float az = (float)(int16_t)mcd_rd_u16(a + 4);
                    if (mcd_rd_u16(a + 6)) return MCD_ERROR_MALFORMED;
                    if (ax * ax + ay * ay + az * az < 0.25f * 32767.0f * 32767.0f) return MCD_ERROR_MALFORMED;
                }
                off += mcd_rmal_desc_size(kind);
                track++;
            }
        }
    }
    if (track != H.tracks || consts != H.constants) return MCD_ERROR_MALFORMED;
    /* Track data back to back after the descriptors, then at least 8 zero bytes (the bit
     * readers' 64-bit loads), zero padding to the payload size. */
    at = (uint32_t)mcd_align4((size_t)(H.descs - p) + off);
    if ((uint64_t)at + 8u > H.size) return MCD_ERROR_MALFORMED;
    for (k = (uint32_t)((size_t)(H.descs - p) + off); k < at; ++k)
        if (p[k]) return MCD_ERROR_MALFORMED;
    for (i = 0, off = 0; i < H.tracks; ++i) {
        r = check(p, H.descs + off, H.frames, at, H.size - 8u, &at);
        if (r != MCD_OK) return r;
        off += mcd_rmal_desc_size(H.descs[off]);
    }
    if ((size_t)H.size != mcd_align4((size_t)at + 8u)) return MCD_ERROR_MALFORMED;
    for (k = at; k < H.size; ++k)
        if (p[k]) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

mcd_result mcd_rmal_validate_section(const uint8_t* s, uint32_t size) {
    uint32_t count;
    if (size < MCD_RMAL_SECTION_HEADER) return MCD_ERROR_MALFORMED;
    count = mcd_rd_u32(s);
    if (count == 0 || mcd_rd_u32(s + 4) || mcd_rd_u32(s + 8) || mcd_rd_u32(s + 12)) return MCD_ERROR_MALFORMED;
    return mcd_check_payload_run(s, size, MCD_RMAL_SECTION_HEADER, count, MCD_RMAL_PAYLOAD_HEADER);
}

/* ---------------------------------------------------------------- sampling */
size_t mcd_rmal_scratch_size(const mcd_clip_view* v, size_t track_size) {
    uint32_t nodes = mcd_rd_u32(v->payload + 8), tracks = mcd_rd_u32(v->payload + 12);
    return mcd_align16(sizeof(mcd_rmal_node) * nodes) + mcd_align16(track_size * tracks);
}

void mcd_rmal_prepare(const mcd_clip_view* v, void* scratch, size_t track_size, mcd_rmal_init_track init) {
    const uint8_t* p = v->payload;
    mcd_rmal_header H;
    const uint8_t* d;
    mcd_rmal_node* plans = (mcd_rmal_node*)scratch;
    uint8_t* tracks;
    uint32_t i, k, m, track = 0, consts = 0, at;
    mcd_rmal_parse_header(p, v->payload_size, &H); /* validated: cannot fail */
    tracks = (uint8_t*)scratch + mcd_align16(sizeof(mcd_rmal_node) * H.nodes);
    d = H.descs;
    at = data_start(p, &H);
    for (i = 0; i < H.tracks; ++i) {
        mcd_rmal_curve* w = (mcd_rmal_curve*)(tracks + track_size * i);
        memset(w, 0, track_size);
        w->kind = d[0];
        w->split = d[1] & 1u;
        if (w->kind == MCD_RMAL_MRP || w->kind == MCD_RMAL_TWIST) w->ref = mcd_reference_at(d + 20);
        if (w->kind == MCD_RMAL_TWIST) mcd_axis_at(d + 28, w->axis);
        at = init(p, d, H.frames, at, H.size - 8u, w);
        d += mcd_rmal_desc_size(w->kind);
    }
    for (i = 0; i < H.nodes; ++i) {
        mcd_rmal_node* np = &plans[i];
        uint32_t mode = H.modes[i];
        if (v->skeleton)
            mcd_skel_rest(v->skeleton, i, &np->base);
        else
            mcd_transform_identity(&np->base); /* curve sets of codec rma-pca have no skeleton */
        for (m = 0; m < 3; ++m) {
            uint32_t mm = (mode >> (2u * m)) & 3u, n = m == 0 ? 4u : 3u;
            float* field = m == 0 ? np->base.rotation : m == 1 ? np->base.translation : np->base.scale;
            np->track[m] = -1;
            if (mm == MODE_CONSTANT) {
                for (k = 0; k < n; ++k) field[k] = mcd_rd_f32(H.consts + 4u * (consts + k));
                consts += n;
            } else if (mm == MODE_ANIMATED) {
                np->track[m] = (int16_t)track++;
            }
        }
    }
}

void mcd_rmal_set_curve(mcd_rmal_curve* w) {
    w->t1 = w->t[1];
    w->t2 = w->t[2];
    /* A detached first segment (capture that jumps after frame 0): key 0 and key 1 are each
     * an end of their curves, so the first segment is the straight line between them and key
     * 0 takes no part in key 1's tangent. */
    if (w->split && w->i <= 1u) {
        float t[4], v[4][4];
        memcpy(t, w->t, sizeof t);
        memcpy(v, w->v, sizeof v);
        memcpy(v[0], v[1], sizeof v[0]);
        t[0] = t[1];
        if (w->i == 0) {
            memcpy(v[3], v[2], sizeof v[3]);
            t[3] = t[2];
        }
        w->inv_h = mcd_segment_coefficients(t, (const float(*)[4])v, 4u, w->coef);
    } else {
        w->inv_h = mcd_segment_coefficients(w->t, (const float(*)[4])w->v, 4u, w->coef);
    }
    w->valid = 1;
}
