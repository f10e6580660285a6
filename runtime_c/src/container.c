/* The container: header, section table, skeletons and clip directory (docs/FORMAT.md), and the
 * queries on an opened asset. Validation is written for hostile input: every size is checked
 * before it is used, and all arithmetic on sizes is done in 64 bits so it cannot wrap. */
#include <string.h>

#include "contacts.h"
#include "internal.h"
#include "offline.h"

static const uint8_t k_magic[8] = {0x89, 0x4D, 0x43, 0x44, 0x0D, 0x0A, 0x1A, 0x0A};

#define KIND_SKEL mcd_fourcc('S', 'K', 'E', 'L')
#define KIND_CLIP mcd_fourcc('C', 'L', 'I', 'P')
#define KIND_META mcd_fourcc('M', 'E', 'T', 'A')
#define KIND_CNTC mcd_fourcc('C', 'N', 'T', 'C')

float mcd_rd_f32(const uint8_t* p) {
    uint32_t u = mcd_rd_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static uint64_t align16(uint64_t x) {
    return (x + 15u) & ~(uint64_t)15u;
}

uint32_t mcd_version(void) {
    return (uint32_t)MCD_VERSION;
}

const char* mcd_result_string(mcd_result result) {
    switch (result) {
    case MCD_OK: return "ok";
    case MCD_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case MCD_ERROR_TRUNCATED: return "asset is truncated";
    case MCD_ERROR_BAD_MAGIC: return "not a mocodec asset (bad magic)";
    case MCD_ERROR_VERSION_TOO_NEW: return "asset format version is newer than this runtime";
    case MCD_ERROR_VERSION_TOO_OLD: return "asset format version is older than this runtime reads";
    case MCD_ERROR_CHECKSUM: return "checksum mismatch (asset corrupted)";
    case MCD_ERROR_MALFORMED: return "asset is malformed";
    case MCD_ERROR_UNSUPPORTED: return "asset uses a codec or section version this runtime does not support";
    case MCD_ERROR_BUFFER_TOO_SMALL: return "buffer too small";
    case MCD_ERROR_OUT_OF_RANGE: return "index out of range";
    case MCD_ERROR_SCRATCH_MISMATCH: return "scratch buffer was not initialised for this asset";
    case MCD_ERROR_TRAILING_DATA: return "buffer is longer than the asset (trailing data)";
    case MCD_ERROR_NOT_FOUND: return "not found";
    }
    return "unknown result code";
}

/* ---------------------------------------------------------------- header + section table */

/* Checks the header and, when `table_too`, the section table layout. Fills the section
 * count. */
static mcd_result check_header(const uint8_t* d, size_t size, uint32_t* out_sections) {
    uint32_t total, count;
    if (size < MCD_HEADER_SIZE) return memcmp(d, k_magic, size < 8 ? size : 8) == 0 ? MCD_ERROR_TRUNCATED : MCD_ERROR_BAD_MAGIC;
    if (memcmp(d, k_magic, 8) != 0) return MCD_ERROR_BAD_MAGIC;
    if (mcd_rd_u16(d + 8) > MCD_FORMAT_MAJOR) return MCD_ERROR_VERSION_TOO_NEW;
    if (mcd_rd_u16(d + 8) < MCD_FORMAT_MAJOR) return MCD_ERROR_VERSION_TOO_OLD;
    if (mcd_rd_u32(d + 12) != MCD_HEADER_SIZE) return MCD_ERROR_MALFORMED;
    total = mcd_rd_u32(d + 16);
    if (total < MCD_HEADER_SIZE || (total & 15u) != 0) return MCD_ERROR_MALFORMED;
    if ((uint64_t)size < total) return MCD_ERROR_TRUNCATED;
    if ((uint64_t)size > total) return MCD_ERROR_TRAILING_DATA;
    count = mcd_rd_u32(d + 24);
    if (count < 2 || count > MCD_MAX_SECTIONS) return MCD_ERROR_MALFORMED;
    if (mcd_rd_u32(d + 28) != 0) return MCD_ERROR_MALFORMED;
    if ((uint64_t)MCD_HEADER_SIZE + (uint64_t)count * MCD_SECTION_ENTRY_SIZE > total) return MCD_ERROR_MALFORMED;
    *out_sections = count;
    return MCD_OK;
}

static int all_zero(const uint8_t* p, uint64_t n) {
    uint64_t i;
    for (i = 0; i < n; ++i)
        if (p[i] != 0) return 0;
    return 1;
}

/* Sections packed in table order, 16-aligned, total = align16(end of last); with `full`, the
 * gaps are zero too (they lie among the codec payloads, which a prevalidated open never reads). */
static mcd_result check_section_table(const uint8_t* d, uint32_t count, int full) {
    uint32_t total = mcd_rd_u32(d + 16);
    uint64_t expect = align16((uint64_t)MCD_HEADER_SIZE + (uint64_t)count * MCD_SECTION_ENTRY_SIZE);
    uint64_t prev_end = (uint64_t)MCD_HEADER_SIZE + (uint64_t)count * MCD_SECTION_ENTRY_SIZE;
    uint32_t i;
    for (i = 0; i < count; ++i) {
        const uint8_t* e = d + MCD_HEADER_SIZE + (size_t)i * MCD_SECTION_ENTRY_SIZE;
        uint64_t off = mcd_rd_u32(e + 8), sz = mcd_rd_u32(e + 12);
        if (off != expect) return MCD_ERROR_MALFORMED;
        if (off + sz > total) return MCD_ERROR_MALFORMED;
        if (full && !all_zero(d + prev_end, off - prev_end)) return MCD_ERROR_MALFORMED;
        prev_end = off + sz;
        expect = align16(prev_end);
    }
    if (expect != total) return MCD_ERROR_MALFORMED;
    if (full && !all_zero(d + prev_end, total - prev_end)) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* ---------------------------------------------------------------- validation */

typedef struct table_scan {
    uint32_t skeleton_count;
    uint32_t skeleton_offsets[16];
    uint32_t clip_section; /* index */
    uint32_t clip_count_sections;
    uint32_t meta_count;
    uint32_t contacts_section; /* index + 1, 0 = none */
    uint32_t codec_sections[MCD_MAX_CODEC_ID + 1]; /* per codec id: section index + 1, 0 = none */
} table_scan;

/* Section kinds and versions; with `full`, every SKEL and each codec section as a whole is
 * checked too (a prevalidated open reads only what it needs). */
static mcd_result scan_sections(const uint8_t* d, uint32_t count, int full, table_scan* t) {
    uint32_t i;
    memset(t, 0, sizeof *t);
    for (i = 0; i < count; ++i) {
        const uint8_t* e = d + MCD_HEADER_SIZE + (size_t)i * MCD_SECTION_ENTRY_SIZE;
        uint32_t kind = mcd_rd_u32(e), version = mcd_rd_u32(e + 4);
        uint32_t off = mcd_rd_u32(e + 8), sz = mcd_rd_u32(e + 12);
        mcd_result r;
        if (kind == KIND_SKEL) {
            if (version != 2) return MCD_ERROR_UNSUPPORTED;
            r = mcd_skel_check(d + off, sz);
            if (r != MCD_OK) return r;
            if (t->skeleton_count < 16) t->skeleton_offsets[t->skeleton_count] = off;
            t->skeleton_count++;
        } else if (kind == KIND_CLIP) {
            if (version != 2) return MCD_ERROR_UNSUPPORTED;
            t->clip_section = i;
            t->clip_count_sections++;
        } else if (kind == KIND_META) {
            if (version != 1) return MCD_ERROR_UNSUPPORTED;
            t->meta_count++;
        } else if (kind == KIND_CNTC) {
            /* Checked after the clip directory, which it refers to. At most one. */
            if (version != 1) return MCD_ERROR_UNSUPPORTED;
            if (t->contacts_section) return MCD_ERROR_MALFORMED;
            t->contacts_section = i + 1;
        } else {
            const mcd_codec_ops* ops = mcd_find_codec_by_kind(kind);
            if (ops) {
                /* One section per codec: clips name it by index, the format keeps it unique. */
                if (t->codec_sections[ops->codec]) return MCD_ERROR_MALFORMED;
                ops = mcd_find_codec_version(ops->codec, version);
                if (!ops) return MCD_ERROR_UNSUPPORTED;
                t->codec_sections[ops->codec] = i + 1;
                if (full && ops->validate_section) {
                    r = ops->validate_section(d + off, sz);
                    if (r != MCD_OK) return r;
                }
            }
        }
    }
    if (t->skeleton_count < 1 || t->clip_count_sections != 1 || t->meta_count > 1) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* Resolve a clip record against its skeleton and codec section. Checks everything the clip
 * record promises; the codec checks its payload afterwards. */
static mcd_result resolve_clip(const mcd_asset* a, uint32_t clip, mcd_clip_view* v,
                               const mcd_codec_ops** ops_out) {
    const uint8_t* r = a->data + a->clip_records + (size_t)clip * MCD_CLIP_RECORD_SIZE;
    uint32_t skel = mcd_rd_u32(r + 4), codec = mcd_rd_u32(r + 8), section = mcd_rd_u32(r + 12);
    uint32_t poff = mcd_rd_u32(r + 16), psize = mcd_rd_u32(r + 20);
    const mcd_codec_ops* ops;
    const uint8_t* e;
    uint32_t skel_off;
    if (skel >= a->skeleton_count || section >= a->section_count) return MCD_ERROR_MALFORMED;
    ops = mcd_find_codec(codec);
    if (!ops) return MCD_ERROR_UNSUPPORTED;
    e = a->data + a->section_table + (size_t)section * MCD_SECTION_ENTRY_SIZE;
    if (mcd_rd_u32(e) != ops->section_kind) return MCD_ERROR_MALFORMED;
    ops = mcd_find_codec_version(codec, mcd_rd_u32(e + 4));
    if (!ops) return MCD_ERROR_UNSUPPORTED;
    if ((poff & 3u) != 0 || (uint64_t)poff + psize > mcd_rd_u32(e + 12)) return MCD_ERROR_MALFORMED;
    skel_off = mcd_skeleton_offset(a, skel);
    v->section = a->data + mcd_rd_u32(e + 8);
    v->section_size = mcd_rd_u32(e + 12);
    v->payload = v->section + poff;
    v->payload_size = psize;
    v->scratch_need = mcd_rd_u32(r + 40);
    v->frame_count = mcd_rd_u32(r + 24);
    v->frame_rate = mcd_rd_f32(r + 28);
    v->skeleton = a->data + skel_off;
    v->node_count = mcd_rd_u32(v->skeleton);
    *ops_out = ops;
    return MCD_OK;
}

mcd_result mcd_clip_view_get(const mcd_asset* asset, uint32_t clip, mcd_clip_view* out,
                             const mcd_codec_ops** out_ops) {
    if (clip >= asset->clip_count) return MCD_ERROR_OUT_OF_RANGE;
    return resolve_clip(asset, clip, out, out_ops);
}

/* The largest clip scratch the format allows: far above any real skeleton's need. */
#define MAX_CLIP_SCRATCH 0x4000000u

/* The clip directory; with `full`, every payload through its codec as well. */
static mcd_result check_clips(mcd_asset* a, uint32_t clip_section, int full) {
    const uint8_t* d = a->data;
    const uint8_t* e = d + a->section_table + (size_t)clip_section * MCD_SECTION_ENTRY_SIZE;
    uint32_t off = mcd_rd_u32(e + 8), size = mcd_rd_u32(e + 12);
    const uint8_t* s = d + off;
    uint32_t count, strings, i, scratch = 0;
    if (size < 8) return MCD_ERROR_MALFORMED;
    count = mcd_rd_u32(s);
    strings = mcd_rd_u32(s + 4);
    if (count < 1 || count > MCD_MAX_CLIPS) return MCD_ERROR_MALFORMED;
    if ((uint64_t)strings != 8u + (uint64_t)count * MCD_CLIP_RECORD_SIZE || strings > size) return MCD_ERROR_MALFORMED;
    a->clip_count = count;
    a->clip_records = off + 8;
    a->clip_strings = off + strings;
    a->clip_strings_size = size - strings;
    for (i = 0; i < count; ++i) {
        const uint8_t* r = d + a->clip_records + (size_t)i * MCD_CLIP_RECORD_SIZE;
        mcd_clip_view v;
        const mcd_codec_ops* ops;
        float rate = mcd_rd_f32(r + 28), duration = mcd_rd_f32(r + 32), expect, tol;
        uint32_t need = mcd_rd_u32(r + 40);
        mcd_result res;
        if (!mcd_valid_name(d + a->clip_strings, a->clip_strings_size, mcd_rd_u32(r), 1)) return MCD_ERROR_MALFORMED;
        if (mcd_rd_u32(r + 24) < 1 || mcd_rd_u32(r + 24) > MCD_MAX_FRAMES) return MCD_ERROR_MALFORMED;
        if (!mcd_finite(rate) || !(rate > 0.0f) || rate > MCD_MAX_FRAME_RATE) return MCD_ERROR_MALFORMED;
        expect = (float)((double)(mcd_rd_u32(r + 24) - 1u) / (double)rate);
        tol = 1e-4f * (expect > 1.0f ? expect : 1.0f);
        /* expect overflows to inf for a tiny rate: then no finite duration matches (and tol is inf). */
        if (!mcd_finite(expect) || !mcd_finite(duration) || duration < expect - tol || duration > expect + tol) return MCD_ERROR_MALFORMED;
        if (mcd_rd_u32(r + 36) != 0 || mcd_rd_u32(r + 44) != 0) return MCD_ERROR_MALFORMED;
        if ((need & 15u) != 0 || need > MAX_CLIP_SCRATCH) return MCD_ERROR_MALFORMED;
        res = resolve_clip(a, i, &v, &ops);
        if (res != MCD_OK) return res;
        if (full) {
            res = ops->validate(&v);
            if (res != MCD_OK) return res;
            /* The record states what the codec needs, so a prevalidated open need not ask it. */
            if (ops->scratch_size(&v) != need) return MCD_ERROR_MALFORMED;
        }
        if (need > scratch) scratch = need;
    }
    a->scratch_size = MCD_SCRATCH_HEADER_SIZE + a->contacts_scratch + scratch;
    return MCD_OK;
}

static mcd_result validate_into(const void* data, size_t size, uint32_t flags, int full, mcd_asset* a) {
    const uint8_t* d = (const uint8_t*)data;
    uint32_t count, i;
    table_scan t;
    mcd_result r;
    if (!data) return MCD_ERROR_INVALID_ARGUMENT;
    r = check_header(d, size, &count);
    if (r != MCD_OK) return r;
    if (full && !(flags & MCD_VALIDATE_SKIP_CHECKSUM) &&
        mcd_crc32(d + 24, (size_t)mcd_rd_u32(d + 16) - 24u) != mcd_rd_u32(d + 20))
        return MCD_ERROR_CHECKSUM;
    r = check_section_table(d, count, full);
    if (r != MCD_OK) return r;
    r = scan_sections(d, count, full, &t);
    if (r != MCD_OK) return r;
    memset(a, 0, sizeof *a);
    a->data = d;
    a->size = size;
    a->section_table = MCD_HEADER_SIZE;
    a->section_count = count;
    a->skeleton_count = t.skeleton_count;
    for (i = 0; i < 16; ++i) a->skeleton_offsets[i] = t.skeleton_offsets[i];
    for (i = 0; i < t.skeleton_count; ++i) {
        uint32_t n = mcd_rd_u32(d + mcd_skeleton_offset(a, i));
        if (n > a->max_nodes) a->max_nodes = n;
    }
    if (t.contacts_section) {
        const uint8_t* e = d + MCD_HEADER_SIZE + (size_t)(t.contacts_section - 1u) * MCD_SECTION_ENTRY_SIZE;
        a->contacts = mcd_rd_u32(e + 8);
        a->contacts_size = mcd_rd_u32(e + 12);
        /* The contact pass keeps a world pose between the header and the codec's area. */
        a->contacts_scratch = (uint32_t)mcd_contacts_scratch_size(a->max_nodes);
    }
    r = check_clips(a, t.clip_section, full);
    if (r != MCD_OK) return r;
    /* The contact section refers to clips, so it is checked after the directory. */
    if (full && a->contacts) return mcd_contacts_validate(a, d + a->contacts, a->contacts_size);
    return MCD_OK;
}

mcd_result mcd_validate(const void* data, size_t size, uint32_t flags) {
    mcd_asset scratch_asset;
    if ((flags & ~MCD_VALIDATE_SKIP_CHECKSUM) != 0) return MCD_ERROR_INVALID_ARGUMENT;
    return validate_into(data, size, flags, 1, &scratch_asset);
}

mcd_result mcd_open(const void* data, size_t size, uint32_t flags, mcd_asset* out_asset) {
    mcd_asset a;
    mcd_result r;
    if (!out_asset || (flags & ~(MCD_VALIDATE_SKIP_CHECKSUM | MCD_OPEN_PREVALIDATED)) != 0) return MCD_ERROR_INVALID_ARGUMENT;
    r = validate_into(data, size, flags, !(flags & MCD_OPEN_PREVALIDATED), &a);
    if (r != MCD_OK) return r;
    *out_asset = a;
    return MCD_OK;
}

/* ---------------------------------------------------------------- queries */

uint32_t mcd_clip_count(const mcd_asset* asset) {
    return asset ? asset->clip_count : 0;
}

uint32_t mcd_skeleton_count(const mcd_asset* asset) {
    return asset ? asset->skeleton_count : 0;
}

mcd_result mcd_get_clip_info(const mcd_asset* asset, uint32_t clip, mcd_clip_info* out) {
    const uint8_t* r;
    if (!asset || !asset->data || !out) return MCD_ERROR_INVALID_ARGUMENT;
    if (clip >= asset->clip_count) return MCD_ERROR_OUT_OF_RANGE;
    r = asset->data + asset->clip_records + (size_t)clip * MCD_CLIP_RECORD_SIZE;
    out->name = (const char*)(asset->data + asset->clip_strings + mcd_rd_u32(r));
    out->skeleton = mcd_rd_u32(r + 4);
    out->codec = mcd_rd_u32(r + 8);
    out->frame_count = mcd_rd_u32(r + 24);
    out->frame_rate = mcd_rd_f32(r + 28);
    out->duration = mcd_rd_f32(r + 32);
    out->node_count = mcd_rd_u32(asset->data + mcd_skeleton_offset(asset, out->skeleton));
    out->scratch_size = MCD_SCRATCH_HEADER_SIZE + asset->contacts_scratch + mcd_rd_u32(r + 40);
    {
        const uint8_t* e = asset->data + asset->section_table + (size_t)mcd_rd_u32(r + 12) * MCD_SECTION_ENTRY_SIZE;
        out->data_offset = mcd_rd_u32(e + 8) + mcd_rd_u32(r + 16);
        out->data_size = mcd_rd_u32(r + 20);
    }
    return MCD_OK;
}

mcd_result mcd_find_clip(const mcd_asset* asset, const char* name, uint32_t* out_clip) {
    uint32_t i;
    if (!asset || !asset->data || !name || !out_clip) return MCD_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < asset->clip_count; ++i) {
        const uint8_t* r = asset->data + asset->clip_records + (size_t)i * MCD_CLIP_RECORD_SIZE;
        if (strcmp((const char*)(asset->data + asset->clip_strings + mcd_rd_u32(r)), name) == 0) {
            *out_clip = i;
            return MCD_OK;
        }
    }
    return MCD_ERROR_NOT_FOUND;
}

mcd_result mcd_get_skeleton_info(const mcd_asset* asset, uint32_t skeleton, mcd_skeleton_info* out) {
    const uint8_t* s;
    if (!asset || !asset->data || !out) return MCD_ERROR_INVALID_ARGUMENT;
    if (skeleton >= asset->skeleton_count) return MCD_ERROR_OUT_OF_RANGE;
    s = asset->data + mcd_skeleton_offset(asset, skeleton);
    out->node_count = mcd_rd_u32(s);
    out->cm_per_unit = mcd_rd_f32(s + 8);
    return MCD_OK;
}

mcd_result mcd_get_node_info(const mcd_asset* asset, uint32_t skeleton, uint32_t node, mcd_node_info* out) {
    const uint8_t *s, *r;
    uint32_t k;
    if (!asset || !asset->data || !out) return MCD_ERROR_INVALID_ARGUMENT;
    if (skeleton >= asset->skeleton_count) return MCD_ERROR_OUT_OF_RANGE;
    s = asset->data + mcd_skeleton_offset(asset, skeleton);
    if (node >= mcd_rd_u32(s)) return MCD_ERROR_OUT_OF_RANGE;
    r = mcd_skel_record(s, node);
    out->name = (const char*)(s + mcd_rd_u32(s + 12) + mcd_rd_u32(r + 4));
    out->parent = mcd_rd_i32(r);
    out->kind = r[20];
    {
        mcd_transform rest;
        mcd_skel_rest(s, node, &rest);
        for (k = 0; k < 3; ++k) out->rest_translation[k] = rest.translation[k];
        for (k = 0; k < 4; ++k) out->rest_rotation[k] = rest.rotation[k];
        for (k = 0; k < 3; ++k) out->rest_scale[k] = rest.scale[k];
    }
    out->channel_count = r[21];
    for (k = 0; k < 6; ++k) out->channels[k] = r[22 + k];
    out->reserved[0] = out->reserved[1] = 0;
    return MCD_OK;
}

/* ---------------------------------------------------------------- encoder support */

mcd_result mcd_offline_clip_scratch(uint32_t codec, const uint8_t* section, size_t section_size,
                                    size_t payload_offset, size_t payload_size, const uint8_t* skeleton,
                                    size_t skeleton_size, uint32_t frame_count, float frame_rate,
                                    size_t* out_size) {
    const mcd_codec_ops* ops = mcd_find_codec(codec);
    mcd_clip_view v;
    mcd_result r;
    if (!section || !skeleton || !out_size || section_size > 0xFFFFFFFFu || skeleton_size > 0xFFFFFFFFu)
        return MCD_ERROR_INVALID_ARGUMENT;
    if (!ops) return MCD_ERROR_UNSUPPORTED;
    if (payload_offset > section_size || payload_size > section_size - payload_offset || (payload_offset & 3u))
        return MCD_ERROR_MALFORMED;
    r = mcd_skel_check(skeleton, (uint32_t)skeleton_size);
    if (r != MCD_OK) return r;
    if (ops->validate_section) {
        r = ops->validate_section(section, (uint32_t)section_size);
        if (r != MCD_OK) return r;
    }
    memset(&v, 0, sizeof v);
    v.section = section;
    v.section_size = (uint32_t)section_size;
    v.payload = section + payload_offset;
    v.payload_size = (uint32_t)payload_size;
    v.frame_count = frame_count;
    v.frame_rate = frame_rate;
    v.skeleton = skeleton;
    v.node_count = mcd_rd_u32(skeleton);
    r = ops->validate(&v);
    if (r != MCD_OK) return r;
    *out_size = ops->scratch_size(&v);
    return MCD_OK;
}
