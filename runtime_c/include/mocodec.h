/*
 * mocodec runtime: validate, open and sample compressed motion assets (.mcd).
 *
 * C99, libc and libm only. No global state, no allocation: the caller owns every buffer
 * (the asset bytes, the mcd_asset struct, the scratch memory) and asks the library how much
 * it needs. Every entry point that can fail returns an mcd_result. The asset format is
 * specified in docs/FORMAT.md.
 *
 * Typical use:
 *
 *     mcd_asset asset;
 *     if (mcd_open(bytes, size, 0, &asset) != MCD_OK) ...;   // validates, decodes nothing
 *     size_t n = mcd_scratch_size(&asset);
 *     void* scratch = aligned_alloc(16, n);      // one per playing instance; 16-aligned
 *     mcd_scratch_init(&asset, scratch, n);
 *     mcd_transform pose[64];
 *     mcd_sample(&asset, clip, t, MCD_SAMPLE_LOOP, pose, 64, scratch);
 *
 * Memory: the runtime samples the asset's own bytes in place. What an engine holds is the
 * asset plus one scratch buffer per playing instance (a few KB; it caches the decoder state
 * that makes sequential playback O(1) per frame). Opening decodes nothing.
 *
 * Thread safety: an opened mcd_asset is read-only and may be shared by any number of
 * threads; a scratch buffer is used by one thread at a time.
 */
#ifndef MOCODEC_H
#define MOCODEC_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(_WIN32) && defined(MCD_BUILD_SHARED)
#define MCD_API __declspec(dllexport)
#elif defined(__GNUC__) && defined(MCD_BUILD_SHARED)
#define MCD_API __attribute__((visibility("default")))
#else
#define MCD_API
#endif

/* Library version: major << 16 | minor << 8 | patch. */
#define MCD_VERSION_MAJOR 0
#define MCD_VERSION_MINOR 3
#define MCD_VERSION_PATCH 0
#define MCD_VERSION ((MCD_VERSION_MAJOR << 16) | (MCD_VERSION_MINOR << 8) | MCD_VERSION_PATCH)

/* Asset format version this runtime reads (docs/FORMAT.md). Format 1 assets (mocodec 0.1,
 * decoded into resident memory at open) are refused with MCD_ERROR_VERSION_TOO_OLD. */
#define MCD_FORMAT_MAJOR 2
#define MCD_FORMAT_MINOR 0

/* Result codes. The values never change: the Python, C# and Godot bindings copy them. */
typedef enum mcd_result {
    MCD_OK = 0,
    MCD_ERROR_INVALID_ARGUMENT = 1,  /* NULL pointer, NaN time, unknown flag bits */
    MCD_ERROR_TRUNCATED = 2,         /* the buffer is shorter than the asset says */
    MCD_ERROR_BAD_MAGIC = 3,         /* not a mocodec asset */
    MCD_ERROR_VERSION_TOO_NEW = 4,   /* format major version newer than this runtime */
    MCD_ERROR_VERSION_TOO_OLD = 5,   /* format major version older than this runtime reads */
    MCD_ERROR_CHECKSUM = 6,          /* CRC-32 mismatch */
    MCD_ERROR_MALFORMED = 7,         /* a structural rule of docs/FORMAT.md is broken */
    MCD_ERROR_UNSUPPORTED = 8,       /* a codec or section version this runtime does not know */
    MCD_ERROR_BUFFER_TOO_SMALL = 9,  /* output or scratch buffer smaller than needed */
    MCD_ERROR_OUT_OF_RANGE = 10,     /* clip, skeleton or node index past the end */
    MCD_ERROR_SCRATCH_MISMATCH = 11, /* scratch not initialised for this asset */
    MCD_ERROR_TRAILING_DATA = 12,    /* the buffer is longer than the asset */
    MCD_ERROR_NOT_FOUND = 13         /* no clip or node of that name */
} mcd_result;

/* mcd_validate / mcd_open flags. */
#define MCD_VALIDATE_SKIP_CHECKSUM 0x1u /* structural checks only (still safe to sample) */
/* mcd_open only: the bytes passed mcd_validate before (at import or cook time), so open reads
 * just the header, section table, skeletons and clip directory: O(clips + sections), no
 * payload byte touched. Sampling bytes that did not pass mcd_validate is then undefined. */
#define MCD_OPEN_PREVALIDATED 0x2u

/* mcd_sample flags. All zero: local transforms, clamp to the clip, cubic between frames. */
#define MCD_SAMPLE_WORLD 0x1u   /* output model-space transforms instead of local ones */
#define MCD_SAMPLE_LOOP 0x2u    /* wrap time into the clip instead of clamping */
#define MCD_SAMPLE_NEAREST 0x4u /* round to the nearest frame instead of interpolating */
/* Rectify the pose with the clip's contact trajectories (CNTC section, docs/FORMAT.md): feet
 * (and hands) in contact are pulled to their stored targets by IK, blended in and out at the
 * ends of each contact. Changes local rotations only. A no-op for clips without contacts. */
#define MCD_SAMPLE_CONTACTS 0x8u

/* Codec identifiers (clip directory). */
typedef enum mcd_codec {
    MCD_CODEC_SPLINE = 1,
    MCD_CODEC_RMA = 2,
    MCD_CODEC_IK_PREDICT = 3,
    MCD_CODEC_FK_WAVELET = 4,
    MCD_CODEC_NEURAL = 5,
    MCD_CODEC_RMA_PCA = 6
} mcd_codec;

/* BVH channel codes (skeleton channel layout). */
typedef enum mcd_channel {
    MCD_CHANNEL_XPOSITION = 0,
    MCD_CHANNEL_YPOSITION = 1,
    MCD_CHANNEL_ZPOSITION = 2,
    MCD_CHANNEL_XROTATION = 3,
    MCD_CHANNEL_YROTATION = 4,
    MCD_CHANNEL_ZROTATION = 5
} mcd_channel;

/* One node's transform. Quaternion x y z w (unit), translation in the file's units, scale
 * (1 1 1 where the source has none). Applied as scale, then rotation, then translation. */
typedef struct mcd_transform {
    float rotation[4];
    float translation[3];
    float scale[3];
} mcd_transform;

typedef struct mcd_clip_info {
    const char* name;      /* NUL-terminated, points into the asset bytes */
    uint32_t skeleton;     /* skeleton index */
    uint32_t codec;        /* mcd_codec */
    uint32_t frame_count;
    float frame_rate;      /* frames per second */
    float duration;        /* seconds, (frame_count - 1) / frame_rate */
    uint32_t node_count;   /* transforms one sample writes */
    uint32_t scratch_size; /* scratch bytes sampling this clip needs (mcd_scratch_size covers all) */
    /* The byte range [data_offset, data_offset + data_size) of the asset that sampling this
     * clip reads besides the header, section table, SKEL and CLIP sections (and the CNTC
     * section with MCD_SAMPLE_CONTACTS; for rma-pca also its section's shared part, see
     * docs/FORMAT.md RMAP): a game may page or stream clips by these ranges. */
    uint32_t data_offset;
    uint32_t data_size;
} mcd_clip_info;

typedef struct mcd_skeleton_info {
    uint32_t node_count;   /* joints and end sites */
    float cm_per_unit;     /* centimetres per file unit */
} mcd_skeleton_info;

/* Node kinds (mcd_node_info.kind). */
#define MCD_NODE_JOINT 0u
#define MCD_NODE_END_SITE 1u /* a BVH End Site: no channels, no children */
#define MCD_NODE_VIRTUAL 2u  /* a point the encoder added at a leaf joint (glTF has no end sites) so
                                the error metric sees the leaf's rotation; not in the source file */

typedef struct mcd_node_info {
    const char* name;         /* NUL-terminated, points into the asset bytes */
    int32_t parent;           /* -1 for a root */
    uint32_t kind;            /* MCD_NODE_JOINT, MCD_NODE_END_SITE or MCD_NODE_VIRTUAL */
    float rest_translation[3];/* BVH OFFSET, glTF rest translation */
    float rest_rotation[4];   /* x y z w; identity for BVH */
    float rest_scale[3];      /* 1 1 1 for BVH */
    uint32_t channel_count;   /* BVH channels, 0 ... 6 (0 for glTF) */
    uint8_t channels[6];      /* mcd_channel codes in file order */
    uint8_t reserved[2];
} mcd_node_info;

/*
 * An opened asset: offsets into the caller's bytes, filled by mcd_open. Treat the fields as
 * private; use the functions below. Plain data: copy it, put it on the stack, share it.
 */
typedef struct mcd_asset {
    const uint8_t* data;
    size_t size;
    uint32_t skeleton_count;
    uint32_t clip_count;
    uint32_t clip_records;      /* offset of the first clip record */
    uint32_t clip_strings;      /* offset of the clip string block */
    uint32_t clip_strings_size;
    uint32_t max_nodes;         /* largest node_count of any skeleton */
    uint32_t scratch_size;      /* bytes mcd_scratch_size returns */
    uint32_t contacts;          /* offset of the CNTC section, 0 when there is none */
    uint32_t contacts_size;
    uint32_t contacts_scratch;  /* bytes of the contact pass's scratch area (0 without CNTC) */
    uint32_t skeleton_offsets[16]; /* offsets of the first 16 SKEL sections */
    uint32_t section_table;     /* offset of the section table */
    uint32_t section_count;
} mcd_asset;

/* Runtime library version (MCD_VERSION of the build). Bindings check it at load time. */
MCD_API uint32_t mcd_version(void);

/* A short English description of a result code ("checksum mismatch"). Never NULL. */
MCD_API const char* mcd_result_string(mcd_result result);

/*
 * Check that `data[0 .. size)` is a complete, well-formed asset this runtime can sample:
 * header, checksum (unless MCD_VALIDATE_SKIP_CHECKSUM), section table, skeletons, clip
 * directory and every byte of every codec payload (entropy streams included). Safe on any
 * bytes: never reads outside the buffer, never crashes. After it returns MCD_OK, sampling
 * cannot fail, cannot read out of bounds and never produces a non-finite float. Cost: linear
 * in the asset size. Thread-safe.
 */
MCD_API mcd_result mcd_validate(const void* data, size_t size, uint32_t flags);

/*
 * Open the asset for sampling: fills `out_asset` with offsets into the caller's bytes, which
 * must stay alive and unchanged while it is used. Validates first (see mcd_validate; `flags`
 * as there) unless MCD_OPEN_PREVALIDATED says the bytes passed mcd_validate already; then only
 * the container is read (header, section table, skeletons, clip directory). Decodes nothing
 * and does not allocate.
 */
MCD_API mcd_result mcd_open(const void* data, size_t size, uint32_t flags, mcd_asset* out_asset);

MCD_API uint32_t mcd_clip_count(const mcd_asset* asset);
MCD_API uint32_t mcd_skeleton_count(const mcd_asset* asset);
MCD_API mcd_result mcd_get_clip_info(const mcd_asset* asset, uint32_t clip, mcd_clip_info* out);
/* Index of the clip called `name` (exact, case-sensitive) or MCD_ERROR_NOT_FOUND. */
MCD_API mcd_result mcd_find_clip(const mcd_asset* asset, const char* name, uint32_t* out_clip);
MCD_API mcd_result mcd_get_skeleton_info(const mcd_asset* asset, uint32_t skeleton,
                                     mcd_skeleton_info* out);
MCD_API mcd_result mcd_get_node_info(const mcd_asset* asset, uint32_t skeleton, uint32_t node,
                                 mcd_node_info* out);

/*
 * Scratch memory that samples any clip of the asset (a few KB; the largest clip's need, see
 * mcd_clip_info.scratch_size for one clip): it caches the decoder state of the clip it last
 * sampled, so give each playing instance its own to make sequential playback O(1) per frame.
 * One scratch shared by several instances or clips works too, but every switch of clip costs
 * a re-preparation (a random access). Initialise it once with mcd_scratch_init (16-byte
 * aligned, at least MCD_SCRATCH_MIN_SIZE bytes); it may then be used for any clip whose need
 * it covers. The size is a multiple of 16.
 */
#define MCD_SCRATCH_MIN_SIZE 64u
MCD_API size_t mcd_scratch_size(const mcd_asset* asset);
MCD_API mcd_result mcd_scratch_init(const mcd_asset* asset, void* scratch, size_t scratch_size);

/*
 * Sample clip `clip` at `time_seconds` into `out_pose[0 .. node_count)` (node_count of the
 * clip's skeleton; `pose_capacity` is the caller's array length). Local transforms unless
 * MCD_SAMPLE_WORLD. Time is clamped to [0, duration] unless MCD_SAMPLE_LOOP; between frames
 * the codec's curve is evaluated unless MCD_SAMPLE_NEAREST. Time is a double (it was a float
 * before 0.3): a float resolves only 0.49 ms two hours in, a double resolves any clip's frames.
 * A time within 1e-4 frames (plus 4e-7 of the frame number, at most 1/128 frame) of a frame
 * shows that frame exactly: frame / frame_rate computed in double lands on the frame's pose at
 * any length, and computed in float up to about 190,000 frames. Between frames, the position in
 * the clip is held as a float frame number (format limit: at most 2^24 frames), so its fraction
 * is resolved to 2^-24 of the frame number (1/16 frame at 864,000 frames, 2 hours at 120 fps).
 * MCD_SAMPLE_NEAREST rounds that float frame number (a half frame up, as before 0.3). Does not
 * allocate; every output float is finite. Fails with MCD_ERROR_INVALID_ARGUMENT on a non-finite
 * time or unknown flags, MCD_ERROR_OUT_OF_RANGE on a bad clip index, MCD_ERROR_BUFFER_TOO_SMALL
 * when pose_capacity < node_count or the scratch is smaller than the clip needs,
 * MCD_ERROR_SCRATCH_MISMATCH when the scratch was initialised for another asset. Sampling the
 * same time twice gives the same pose, whatever was sampled in between.
 */
MCD_API mcd_result mcd_sample(const mcd_asset* asset, uint32_t clip, double time_seconds,
                              uint32_t flags, mcd_transform* out_pose, uint32_t pose_capacity,
                              void* scratch);

/* ---------------------------------------------------------------- retargeting (retarget.c)
 *
 * Poses of an asset skeleton onto a game's rig: its own bone names, hierarchy, rest (bind)
 * transforms and proportions. mcd_retarget_init builds a map once per rig and skeleton into
 * caller memory (mcd_retarget_size bytes); mcd_retarget_pose then turns each sampled local pose
 * into the rig's local transforms without allocating, in a work buffer of the caller's
 * (mcd_retarget_info.work_size bytes, one per thread). The map is read-only after init and
 * holds no pointer into the asset or the rig description.
 *
 * Matching: the caller's pairs first (bone name -> node name, or NULL to leave a bone out),
 * then equal names, then names equal once a namespace up to the last ':' or '|', ASCII case
 * and the characters '_' '-' '.' ' ' are dropped ("mixamorig:Left_Arm" = "LeftArm"), when
 * exactly one node matches so. Joints and end sites match by name; virtual points only by pair.
 *
 * Per matched bone (rig space = the frame the rig's root bones live in; S = space_rotation):
 *   rotation     world(bone) = S world(node) world_rest(node)^-1 S^-1 A world_rest(bone): the
 *                bone turns in rig space as its node turned from its rest in model space, so
 *                an asset made from this very rig poses it exactly, and a rig with other rest
 *                orientations shows the same motion. A is the identity, or with
 *                MCD_RETARGET_MATCH_DIRECTIONS and a bone with exactly one matched child bone
 *                whose node is below the bone's node, the shortest rotation turning the bone's
 *                rest direction (towards that child) onto its node's: the world-space
 *                directions of such bones follow the asset even when the rest poses differ
 *                (A-pose against T-pose). Bones with several matched children (hips, chest)
 *                keep A = identity, so the bones hanging off them stay where the rig has them.
 *   translation  the motion root (a matched bone without a matched ancestor, normally the
 *                hips) is placed where its node is: unit_scale S position(node); without
 *                MCD_RETARGET_ROOT_MOTION only its component along up_axis moves (the two
 *                others stay at its rest position). Every other matched bone keeps its rest
 *                translation plus the node's displacement from the node's rest translation
 *                (none for BVH joints: the rig keeps its own bone lengths). A bone flagged
 *                MCD_RIG_BONE_KEEP_TRANSLATION always keeps its rest translation.
 *   scale        rest scale(bone) x scale(node) / rest scale(node), per axis.
 * An unmatched bone stays at its rest transform (and follows its parent).
 *
 * Retargeting onto a rig:
 *
 *     mcd_rig_bone bones[64];   // name, parent, flags, rest local transform of each rig bone
 *     mcd_retarget_config config;
 *     mcd_retarget_info rinfo;
 *     size_t map_size;
 *     mcd_retarget_config_default(&config);
 *     config.unit_scale = 0.01f * cm_per_unit;   // a rig in metres
 *     mcd_retarget_size(&asset, skeleton, bone_count, &map_size);
 *     void* map = malloc(map_size);
 *     if (mcd_retarget_init(&asset, skeleton, bones, bone_count, NULL, 0, &config, map, map_size,
 *                           NULL) != MCD_OK) ...;
 *     mcd_retarget_get_info(map, &rinfo);
 *     void* work = malloc(rinfo.work_size);      // one per thread
 *     mcd_transform rig_pose[64];
 *     mcd_retarget_pose(map, pose, node_count, rig_pose, 64, work, rinfo.work_size);
 */
typedef struct mcd_rig_bone {
    const char* name;   /* UTF-8, NUL-terminated, 1 ... 255 bytes, unique in the rig */
    int32_t parent;     /* index of the parent bone, -1 for a root; parents come first */
    uint32_t flags;     /* MCD_RIG_BONE_* */
    mcd_transform rest; /* rest (bind) local transform, in the rig's space and units */
} mcd_rig_bone;

#define MCD_RIG_BONE_KEEP_TRANSLATION 0x1u /* always the rest translation, even as motion root */

typedef struct mcd_retarget_pair {
    const char* bone; /* a rig bone's name */
    const char* node; /* the asset node (exact name) that drives it, or NULL: not driven */
} mcd_retarget_pair;

#define MCD_RETARGET_ROOT_MOTION 0x1u      /* the motion root travels; off: it moves along up_axis only */
#define MCD_RETARGET_MATCH_DIRECTIONS 0x2u /* bone directions follow the asset's (see above) */

typedef struct mcd_retarget_config {
    uint32_t flags;          /* MCD_RETARGET_*; the default sets both */
    uint32_t up_axis;        /* 0 x, 1 y, 2 z of rig space; default 1 */
    float unit_scale;        /* rig units per asset unit, > 0; default 1 */
    float space_rotation[4]; /* x y z w: asset model space -> rig space; default identity */
} mcd_retarget_config;

/* Where mcd_retarget_init found the problem its result names. */
#define MCD_RETARGET_ISSUE_NONE 0u
#define MCD_RETARGET_ISSUE_BONE 1u   /* bones[index] */
#define MCD_RETARGET_ISSUE_PAIR 2u   /* pairs[index] */
#define MCD_RETARGET_ISSUE_CONFIG 3u /* the config, the asset or the buffers */
typedef struct mcd_retarget_issue {
    uint32_t where; /* MCD_RETARGET_ISSUE_* */
    uint32_t index;
} mcd_retarget_issue;

typedef struct mcd_retarget_info {
    uint32_t bone_count;   /* rig bones: the transforms mcd_retarget_pose writes */
    uint32_t node_count;   /* asset nodes: the pose it reads */
    uint32_t matched;      /* bones driven by a node */
    uint32_t work_size;    /* bytes of the work buffer mcd_retarget_pose needs */
} mcd_retarget_info;

MCD_API void mcd_retarget_config_default(mcd_retarget_config* out);
/* Bytes of the map for `bone_count` rig bones and skeleton `skeleton` of the asset. */
MCD_API mcd_result mcd_retarget_size(const mcd_asset* asset, uint32_t skeleton, uint32_t bone_count,
                                     size_t* out_size);
/*
 * Build the map in `map` (8-byte aligned, at least mcd_retarget_size bytes). Every input is
 * checked: MCD_ERROR_INVALID_ARGUMENT for a NULL pointer, a bad name, parent, rest transform
 * (finite, |values| <= 1e7, unit rotation within 1e-3, |scale| >= 1e-6), config value or a
 * second pair for one bone; MCD_ERROR_NOT_FOUND for a pair naming a bone or node that does not
 * exist; MCD_ERROR_OUT_OF_RANGE for a bad skeleton index; MCD_ERROR_BUFFER_TOO_SMALL. The
 * optional `out_issue` says which bone, pair or setting. Cost: bones x nodes name compares.
 */
MCD_API mcd_result mcd_retarget_init(const mcd_asset* asset, uint32_t skeleton, const mcd_rig_bone* bones,
                                     uint32_t bone_count, const mcd_retarget_pair* pairs, uint32_t pair_count,
                                     const mcd_retarget_config* config, void* map, size_t map_size,
                                     mcd_retarget_issue* out_issue);
MCD_API mcd_result mcd_retarget_get_info(const void* map, mcd_retarget_info* out);
/* The asset node driving `bone`, or -1 when none does. */
MCD_API mcd_result mcd_retarget_get_node(const void* map, uint32_t bone, int32_t* out_node);
/*
 * The rig's local transforms for a local pose of the map's skeleton (`node_count` = the
 * skeleton's node count; rotations need not be exactly unit, e.g. after blending) into
 * out[0 .. bone_count). Does not allocate. MCD_ERROR_INVALID_ARGUMENT for a map that is not
 * one, a node_count other than the map's, a work buffer not 8-byte aligned, a non-finite
 * value or a zero rotation; MCD_ERROR_BUFFER_TOO_SMALL when out_capacity < bone_count or the
 * work buffer is smaller than mcd_retarget_info.work_size.
 */
MCD_API mcd_result mcd_retarget_pose(const void* map, const mcd_transform* pose, uint32_t node_count,
                                     mcd_transform* out, uint32_t out_capacity, void* work, size_t work_size);

#ifdef __cplusplus
}
#endif

#endif /* MOCODEC_H */
