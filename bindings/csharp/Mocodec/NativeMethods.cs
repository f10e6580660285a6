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
        public fixed uint SkeletonOffsets[16];
        public uint SectionTable;
        public uint SectionCount;
        public IntPtr Resident;
        public UIntPtr ResidentSize;
        public fixed uint ResidentOffsets[8];
        public fixed uint CodecSections[8];
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
        public uint IsEndSite;
        public fixed float RestOffset[3];
        public uint ChannelCount;
        public fixed byte Channels[6];
        public fixed byte Reserved[2];
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

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_resident_size")]
        internal static extern int ResidentSize(byte* data, UIntPtr size, uint flags, UIntPtr* outSize);

        [DllImport(Library, CallingConvention = CallingConvention.Cdecl, EntryPoint = "mcd_open")]
        internal static extern int Open(byte* data, UIntPtr size, uint flags, byte* resident,
                                        UIntPtr residentSize, NativeAsset* outAsset);

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
        internal static extern int Sample(NativeAsset* asset, uint clip, float timeSeconds, uint flags,
                                          MocodecTransform* outPose, uint poseCapacity, byte* scratch);
    }
}
