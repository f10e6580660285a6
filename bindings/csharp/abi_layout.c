/* Prints the sizes and field offsets of the structs the C# binding mirrors, named as in
 * unity_package/Runtime/Core/NativeMethods.cs, so the NUnit ABI test compares them with
 * Marshal.SizeOf/OffsetOf. */
#include <stddef.h>
#include <stdio.h>

#include "mocodec.h"

#define SIZE(t) printf("sizeof %s %u\n", #t, (unsigned)sizeof(t))
#define FIELD(t, cs, c) printf("offsetof %s %s %u\n", #t, cs, (unsigned)offsetof(t, c))

int main(void) {
    SIZE(mcd_asset);
    FIELD(mcd_asset, "Size", size);
    FIELD(mcd_asset, "ScratchSize", scratch_size);
    FIELD(mcd_asset, "ContactsScratch", contacts_scratch);
    FIELD(mcd_asset, "SkeletonOffsets", skeleton_offsets);
    FIELD(mcd_asset, "SectionCount", section_count);
    SIZE(mcd_clip_info);
    FIELD(mcd_clip_info, "Skeleton", skeleton);
    FIELD(mcd_clip_info, "Codec", codec);
    FIELD(mcd_clip_info, "FrameCount", frame_count);
    FIELD(mcd_clip_info, "FrameRate", frame_rate);
    FIELD(mcd_clip_info, "Duration", duration);
    FIELD(mcd_clip_info, "NodeCount", node_count);
    FIELD(mcd_clip_info, "ScratchSize", scratch_size);
    FIELD(mcd_clip_info, "DataOffset", data_offset);
    FIELD(mcd_clip_info, "DataSize", data_size);
    SIZE(mcd_skeleton_info);
    FIELD(mcd_skeleton_info, "CmPerUnit", cm_per_unit);
    SIZE(mcd_node_info);
    FIELD(mcd_node_info, "Parent", parent);
    FIELD(mcd_node_info, "Kind", kind);
    FIELD(mcd_node_info, "RestTranslation", rest_translation);
    FIELD(mcd_node_info, "RestRotation", rest_rotation);
    FIELD(mcd_node_info, "RestScale", rest_scale);
    FIELD(mcd_node_info, "ChannelCount", channel_count);
    FIELD(mcd_node_info, "Channels", channels);
    SIZE(mcd_transform);
    FIELD(mcd_transform, "Tx", translation);
    FIELD(mcd_transform, "Sx", scale);
    SIZE(mcd_rig_bone);
    FIELD(mcd_rig_bone, "Parent", parent);
    FIELD(mcd_rig_bone, "Flags", flags);
    FIELD(mcd_rig_bone, "Rest", rest);
    SIZE(mcd_retarget_pair);
    FIELD(mcd_retarget_pair, "Node", node);
    SIZE(mcd_retarget_config);
    FIELD(mcd_retarget_config, "UpAxis", up_axis);
    FIELD(mcd_retarget_config, "UnitScale", unit_scale);
    FIELD(mcd_retarget_config, "SpaceRotation", space_rotation);
    SIZE(mcd_retarget_issue);
    FIELD(mcd_retarget_issue, "Index", index);
    SIZE(mcd_retarget_info);
    FIELD(mcd_retarget_info, "WorkSize", work_size);
    return 0;
}
