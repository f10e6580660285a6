// P/Invoke declarations of runtime_c/include/mocodec.h. Only blittable types cross the boundary:
// fixed-width integers, floats, pointers; results come back as int and are mapped to
// MocodecResult by the callers.
using System;
using System.Runtime.InteropServices;

namespace Mocodec
{
    /// <summary>Mirror of <c>mcd_asset</c>. Never read from C#; only its size must match
    /// (checked against the C compiler's sizeof by the ABI test).</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal unsafe struct NativeAsset
    {
        public IntPtr Data;
        public UIntPtr Size;
        public uint SkeletonCount;
        public uint ClipCount;
        public uint ClipRecords;
        public uint ClipStrings;
        public uint ClipStringsSize;
        public uint MaxNodes;
        public uint ScratchSize;
        public uint Contacts;
        public uint ContactsSize;
        public uint ContactsScratch;
        public fixed uint SkeletonOffsets[16];
        public uint SectionTable;
        public uint SectionCount;
    }

    /// <summary>Mirror of <c>mcd_clip_info</c>.</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal struct NativeClipInfo
    {
        public IntPtr Name;
        public uint Skeleton;
        public uint Codec;
        public uint FrameCount;
        public float FrameRate;
        public float Duration;
        public uint NodeCount;
        public uint ScratchSize;
        public uint DataOffset;
        public uint DataSize;
    }

    /// <summary>Mirror of <c>mcd_skeleton_info</c>.</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal struct NativeSkeletonInfo
    {
        public uint NodeCount;
        public float CmPerUnit;
    }

    /// <summary>Mirror of <c>mcd_node_info</c>.</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal unsafe struct NativeNodeInfo
    {
        public IntPtr Name;
        public int Parent;
        public uint Kind;
        public fixed float RestTranslation[3];
        public fixed float RestRotation[4];
        public fixed float RestScale[3];
        public uint ChannelCount;
        public fixed byte Channels[6];
        public fixed byte Reserved[2];
    }

    /// <summary>Mirror of <c>mcd_rig_bone</c>.</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal struct NativeRigBone
    {
        public IntPtr Name;
        public int Parent;
        public uint Flags;
        public MocodecTransform Rest;
    }

    /// <summary>Mirror of <c>mcd_retarget_pair</c>.</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal struct NativeRetargetPair
    {
        public IntPtr Bone;
        public IntPtr Node;
    }

    /// <summary>Mirror of <c>mcd_retarget_config</c>.</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal unsafe struct NativeRetargetConfig
    {
        public uint Flags;
        public uint UpAxis;
        public float UnitScale;
        public fixed float SpaceRotation[4];
    }

    /// <summary>Mirror of <c>mcd_retarget_issue</c>.</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal struct NativeRetargetIssue
    {
        public uint Where;
        public uint Index;
    }

    /// <summary>Mirror of <c>mcd_retarget_info</c>.</summary>
    [StructLayout(LayoutKind.Sequential)]
    internal struct NativeRetargetInfo
    {
        public uint BoneCount;
        public uint NodeCount;
        public uint Matched;
        public uint WorkSize;
    }

    internal static unsafe class NativeMethods
    {
#if UNITY_IOS && !UNITY_EDITOR
        // iOS links the runtime statically into the player.
        internal const string Library = "__Internal";
#else
        // Resolved by the platform's loader: libmocodec.so, mocodec.dll, libmocodec.dylib.
        internal const string Library = "mocodec";
#endif

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_version")]
        internal static extern uint Version();

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_result_string")]
        internal static extern IntPtr ResultString(int result);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_validate")]
        internal static extern int Validate(byte* data, UIntPtr size, uint flags);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_open")]
        internal static extern int Open(byte* data, UIntPtr size, uint flags, NativeAsset* outAsset);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_clip_count")]
        internal static extern uint ClipCount(NativeAsset* asset);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_skeleton_count")]
        internal static extern uint SkeletonCount(NativeAsset* asset);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_get_clip_info")]
        internal static extern int GetClipInfo(NativeAsset* asset, uint clip, NativeClipInfo* info);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_find_clip")]
        internal static extern int FindClip(NativeAsset* asset, byte* nameUtf8, uint* outClip);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_get_skeleton_info")]
        internal static extern int GetSkeletonInfo(NativeAsset* asset, uint skeleton, NativeSkeletonInfo* info);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_get_node_info")]
        internal static extern int GetNodeInfo(NativeAsset* asset, uint skeleton, uint node, NativeNodeInfo* info);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_scratch_size")]
        internal static extern UIntPtr ScratchSize(NativeAsset* asset);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_scratch_init")]
        internal static extern int ScratchInit(NativeAsset* asset, byte* scratch, UIntPtr scratchSize);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_sample")]
        internal static extern int Sample(NativeAsset* asset, uint clip, double timeSeconds, uint flags,
                                          MocodecTransform* outPose, uint poseCapacity, byte* scratch);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_retarget_config_default")]
        internal static extern void RetargetConfigDefault(NativeRetargetConfig* config);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_retarget_size")]
        internal static extern int RetargetSize(NativeAsset* asset, uint skeleton, uint boneCount, UIntPtr* outSize);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_retarget_init")]
        internal static extern int RetargetInit(NativeAsset* asset, uint skeleton, NativeRigBone* bones, uint boneCount,
                                                NativeRetargetPair* pairs, uint pairCount, NativeRetargetConfig* config,
                                                byte* map, UIntPtr mapSize, NativeRetargetIssue* outIssue);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_retarget_get_info")]
        internal static extern int RetargetGetInfo(byte* map, NativeRetargetInfo* info);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_retarget_get_node")]
        internal static extern int RetargetGetNode(byte* map, uint bone, int* outNode);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_retarget_pose")]
        internal static extern int RetargetPose(byte* map, MocodecTransform* pose, uint nodeCount, MocodecTransform* output,
                                                uint outputCapacity, byte* work, UIntPtr workSize);
    }
}
