// Public value types and enums of the binding. Numeric values copy runtime_c/include/mocodec.h,
// which promises never to change them.
using System;
using System.Runtime.InteropServices;

namespace Mocodec
{
    /// <summary>The runtime's result codes (<c>mcd_result</c>).</summary>
    public enum MocodecResult
    {
        Ok = 0,
        InvalidArgument = 1,
        Truncated = 2,
        BadMagic = 3,
        VersionTooNew = 4,
        VersionTooOld = 5,
        Checksum = 6,
        Malformed = 7,
        Unsupported = 8,
        BufferTooSmall = 9,
        OutOfRange = 10,
        ScratchMismatch = 11,
        TrailingData = 12,
        NotFound = 13
    }

    /// <summary>Flags of <c>mcd_validate</c> and <c>mcd_open</c>.</summary>
    [Flags]
    public enum ValidateFlags : uint
    {
        None = 0,
        /// <summary>Structural checks only; still safe to sample.</summary>
        SkipChecksum = 0x1,
        /// <summary>Open only: the bytes passed <see cref="MocodecRuntime.Validate"/> before (at
        /// import or cook time), so opening reads the container alone, O(clips + sections).</summary>
        Prevalidated = 0x2
    }

    /// <summary>Flags of <c>mcd_sample</c>. None: local transforms, clamped time, interpolated.</summary>
    [Flags]
    public enum SampleFlags : uint
    {
        None = 0,
        /// <summary>Model-space transforms instead of parent-relative ones.</summary>
        World = 0x1,
        /// <summary>Wrap time into the clip instead of clamping it.</summary>
        Loop = 0x2,
        /// <summary>Nearest frame instead of the codec's curve between frames.</summary>
        Nearest = 0x4,
        /// <summary>Pull planted feet onto the clip's contact trajectories by IK (no-op without them).</summary>
        Contacts = 0x8
    }

    /// <summary>Codec identifiers of the clip directory (<c>mcd_codec</c>).</summary>
    public enum MocodecCodec
    {
        Spline = 1,
        Rma = 2,
        IkPredict = 3,
        FkWavelet = 4,
        Neural = 5,
        RmaPca = 6
    }

    /// <summary>BVH channel codes (<c>mcd_channel</c>).</summary>
    public enum MocodecChannel
    {
        XPosition = 0,
        YPosition = 1,
        ZPosition = 2,
        XRotation = 3,
        YRotation = 4,
        ZRotation = 5
    }

    /// <summary>One node's transform, laid out as <c>mcd_transform</c>: unit quaternion
    /// (x y z w), translation in the asset's units (see <see cref="SkeletonInfo.CmPerUnit"/>),
    /// scale; applied as scale, then rotation, then translation. Right-handed, as in the BVH
    /// file (<see cref="MocodecSpace"/> converts).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct MocodecTransform
    {
        public float Qx, Qy, Qz, Qw;
        public float Tx, Ty, Tz;
        public float Sx, Sy, Sz;

        /// <summary>No rotation, no translation, unit scale.</summary>
        public static MocodecTransform Identity
        {
            get { return new MocodecTransform { Qw = 1f, Sx = 1f, Sy = 1f, Sz = 1f }; }
        }

        public MocodecTransform(float qx, float qy, float qz, float qw, float tx, float ty, float tz,
                                float sx = 1f, float sy = 1f, float sz = 1f)
        {
            Qx = qx; Qy = qy; Qz = qz; Qw = qw;
            Tx = tx; Ty = ty; Tz = tz;
            Sx = sx; Sy = sy; Sz = sz;
        }
    }

    /// <summary>What a skeleton node is (<c>mcd_node_info.kind</c>).</summary>
    public enum MocodecNodeKind
    {
        Joint = 0,
        /// <summary>A BVH End Site: no channels, no children.</summary>
        EndSite = 1,
        /// <summary>A point the encoder added at a leaf joint; not in the source file.</summary>
        Virtual = 2
    }

    /// <summary>A clip of the directory.</summary>
    public struct ClipInfo
    {
        public int Index;
        public string Name;
        public int Skeleton;
        public MocodecCodec Codec;
        public int FrameCount;
        /// <summary>Frames per second.</summary>
        public float FrameRate;
        /// <summary>Seconds, (FrameCount - 1) / FrameRate.</summary>
        public float Duration;
        /// <summary>Transforms one sample writes: the length a pose buffer needs.</summary>
        public int NodeCount;
        /// <summary>Scratch bytes sampling this clip needs (<see cref="MocodecAsset.ScratchSize"/> covers every clip).</summary>
        public int ScratchSize;
        /// <summary>The byte range of the asset this clip's samples read (for paging clips).</summary>
        public long DataOffset, DataSize;
    }

    /// <summary>A skeleton of the asset.</summary>
    public struct SkeletonInfo
    {
        public int NodeCount;
        /// <summary>Centimetres per asset unit.</summary>
        public float CmPerUnit;
    }

    /// <summary>A node (joint, BVH end site or virtual point) of a skeleton.</summary>
    public struct NodeInfo
    {
        public string Name;
        /// <summary>Index of the parent node, -1 for a root.</summary>
        public int Parent;
        public MocodecNodeKind Kind;
        /// <summary>The rest (bind) local transform: BVH OFFSET with identity rotation and unit
        /// scale, or the glTF rest TRS.</summary>
        public MocodecTransform Rest;
        /// <summary>BVH channels in file order.</summary>
        public MocodecChannel[] Channels;

        public bool IsEndSite { get { return Kind == MocodecNodeKind.EndSite; } }
    }
}
