/* Prints the sizes and field offsets of the structs the C# binding mirrors, named as in
 * Mocodec/NativeMethods.cs, so the NUnit ABI test compares them with Marshal.SizeOf/OffsetOf. */
#include <stddef.h>
#include <stdio.h>

#include "mocodec.h"

#define SIZE(t) printf("sizeof %s %u\n", #t, (unsigned)sizeof(t))
#define FIELD(t, cs, c) printf("offsetof %s %s %u\n", #t, cs, (unsigned)offsetof(t, c))

int main(void) {
    SIZE(mcd_asset);
    FIELD(mcd_asset, "Size", size);
    FIELD(mcd_asset, "SkeletonOffsets", skeleton_offsets);
    FIELD(mcd_asset, "Resident", resident);
    FIELD(mcd_asset, "ResidentOffsets", resident_offsets);
    FIELD(mcd_asset, "CodecSections", codec_sections);
    SIZE(mcd_clip_info);
    FIELD(mcd_clip_info, "Skeleton", skeleton);
    FIELD(mcd_clip_info, "Codec", codec);
    FIELD(mcd_clip_info, "FrameCount", frame_count);
    FIELD(mcd_clip_info, "FrameRate", frame_rate);
    FIELD(mcd_clip_info, "Duration", duration);
    FIELD(mcd_clip_info, "NodeCount", node_count);
    SIZE(mcd_skeleton_info);
    FIELD(mcd_skeleton_info, "CmPerUnit", cm_per_unit);
    SIZE(mcd_node_info);
    FIELD(mcd_node_info, "Parent", parent);
    FIELD(mcd_node_info, "IsEndSite", is_end_site);
    FIELD(mcd_node_info, "RestOffset", rest_offset);
    FIELD(mcd_node_info, "ChannelCount", channel_count);
    FIELD(mcd_node_info, "Channels", channels);
    SIZE(mcd_transform);
    FIELD(mcd_transform, "Tx", translation);
    return 0;
}
