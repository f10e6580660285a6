using System;
using System.Runtime.InteropServices;
using System.Threading;

namespace Mocodec
{
    /// <summary>
    /// An opened asset (.mcd bytes). Load validates the bytes (checksum included unless asked
    /// not to), copies them into unmanaged memory and opens them, so the caller's array may be
    /// reused at once and nothing the runtime reads is moved by the garbage collector. The
    /// runtime samples those bytes in place: what the asset holds is its size, plus one scratch
    /// buffer (<see cref="ScratchSize"/>) per <see cref="MocodecContext"/>.
    /// <para>Queries and <see cref="CreateContext"/> may be called from any thread. The
    /// <c>Sample</c> methods of the asset itself share one built-in context and so must be
    /// called from one thread at a time; give each other thread its own
    /// <see cref="MocodecContext"/>. Dispose only once no thread samples any more.</para>
    /// </summary>
    public sealed unsafe class MocodecAsset : IDisposable
    {
        // Head-room past sizeof(mcd_asset): should the header grow before this mirror does, the
        // runtime writes into slack instead of past the block (the ABI test catches the drift).
        const int AssetSlack = 256;

        IntPtr _bytes;
        IntPtr _assetBlock;
        NativeAsset* _asset;
        readonly int _size;
        readonly int _scratchSize;
        readonly ClipInfo[] _clips;
        MocodecContext _context;

        MocodecAsset(byte[] data, ValidateFlags flags, out MocodecResult result, out string call)
        {
            _size = data.Length;
            _clips = new ClipInfo[0];
            _bytes = Marshal.AllocHGlobal(Math.Max(_size, 1));
            Marshal.Copy(data, 0, _bytes, _size);
            _assetBlock = Marshal.AllocHGlobal(Marshal.SizeOf(typeof(NativeAsset)) + AssetSlack);
            _asset = (NativeAsset*)_assetBlock;
            GC.AddMemoryPressure(Math.Max(_size, 1));

            result = (MocodecResult)NativeMethods.Open((byte*)_bytes, (UIntPtr)(uint)_size, (uint)flags, _asset);
            call = "mcd_open";
            if (result != MocodecResult.Ok)
            {
                Dispose();
                return;
            }
            _scratchSize = (int)NativeMethods.ScratchSize(_asset).ToUInt32();
            int count = (int)NativeMethods.ClipCount(_asset);
            _clips = new ClipInfo[count];
            for (int i = 0; i < count; i++)
            {
                result = ReadClipInfo(i, out _clips[i]);
                call = "mcd_get_clip_info";
                if (result != MocodecResult.Ok)
                {
                    Dispose();
                    return;
                }
            }
            _context = new MocodecContext(this);
        }

        ~MocodecAsset()
        {
            Free();
        }

        /// <summary>Validates and opens asset bytes; throws <see cref="MocodecException"/> with
        /// the runtime's code when they are not a valid asset.</summary>
        public static MocodecAsset Load(byte[] data, ValidateFlags flags = ValidateFlags.None)
        {
            MocodecAsset asset;
            string call;
            MocodecResult r = TryLoad(data, flags, out asset, out call);
            if (r != MocodecResult.Ok)
                throw new MocodecException(r, call);
            return asset;
        }

        /// <summary>Like <see cref="Load"/> but returns the result code instead of throwing for
        /// bad bytes; <paramref name="asset"/> is null unless the result is Ok.</summary>
        public static MocodecResult TryLoad(byte[] data, out MocodecAsset asset, ValidateFlags flags = ValidateFlags.None)
        {
            string call;
            return TryLoad(data, flags, out asset, out call);
        }

        static MocodecResult TryLoad(byte[] data, ValidateFlags flags, out MocodecAsset asset, out string call)
        {
            if (data == null)
                throw new ArgumentNullException("data");
            MocodecRuntime.EnsureCompatible();
            MocodecResult r;
            asset = new MocodecAsset(data, flags, out r, out call);
            if (r != MocodecResult.Ok)
            {
                GC.SuppressFinalize(asset);
                asset = null;
            }
            return r;
        }

        /// <summary>Size of the asset bytes.</summary>
        public int Size { get { return _size; } }

        /// <summary>Bytes of scratch memory each <see cref="MocodecContext"/> holds.</summary>
        public int ScratchSize { get { return _scratchSize; } }

        public int ClipCount { get { return _clips.Length; } }

        public int SkeletonCount
        {
            get { return (int)NativeMethods.SkeletonCount(Native); }
        }

        /// <summary>Directory entry of a clip (cached at load: no native call, no allocation).</summary>
        public ClipInfo GetClipInfo(int clip)
        {
            ClipInfo info;
            MocodecResult r = TryGetClipInfo(clip, out info);
            if (r != MocodecResult.Ok)
                throw new MocodecException(r, "mcd_get_clip_info");
            return info;
        }

        public MocodecResult TryGetClipInfo(int clip, out ClipInfo info)
        {
            ThrowIfDisposed();
            if (clip < 0 || clip >= _clips.Length)
            {
                info = default(ClipInfo);
                return MocodecResult.OutOfRange;
            }
            info = _clips[clip];
            return MocodecResult.Ok;
        }

        /// <summary>Index of the clip with this exact name.</summary>
        public int FindClip(string name)
        {
            int clip;
            MocodecResult r = TryFindClip(name, out clip);
            if (r != MocodecResult.Ok)
                throw new MocodecException(r, "mcd_find_clip");
            return clip;
        }

        public MocodecResult TryFindClip(string name, out int clip)
        {
            if (name == null)
                throw new ArgumentNullException("name");
            byte[] utf8 = MocodecRuntime.Utf8Z(name);
            uint index = 0;
            MocodecResult r;
            fixed (byte* p = utf8)
                r = (MocodecResult)NativeMethods.FindClip(Native, p, &index);
            clip = r == MocodecResult.Ok ? (int)index : -1;
            return r;
        }

        public SkeletonInfo GetSkeletonInfo(int skeleton)
        {
            SkeletonInfo info;
            MocodecResult r = TryGetSkeletonInfo(skeleton, out info);
            if (r != MocodecResult.Ok)
                throw new MocodecException(r, "mcd_get_skeleton_info");
            return info;
        }

        public MocodecResult TryGetSkeletonInfo(int skeleton, out SkeletonInfo info)
        {
            NativeSkeletonInfo n;
            MocodecResult r = (MocodecResult)NativeMethods.GetSkeletonInfo(Native, (uint)skeleton, &n);
            info = default(SkeletonInfo);
            if (r == MocodecResult.Ok)
            {
                info.NodeCount = (int)n.NodeCount;
                info.CmPerUnit = n.CmPerUnit;
            }
            return r;
        }

        public NodeInfo GetNodeInfo(int skeleton, int node)
        {
            NodeInfo info;
            MocodecResult r = TryGetNodeInfo(skeleton, node, out info);
            if (r != MocodecResult.Ok)
                throw new MocodecException(r, "mcd_get_node_info");
            return info;
        }

        public MocodecResult TryGetNodeInfo(int skeleton, int node, out NodeInfo info)
        {
            NativeNodeInfo n;
            MocodecResult r = (MocodecResult)NativeMethods.GetNodeInfo(Native, (uint)skeleton, (uint)node, &n);
            info = default(NodeInfo);
            if (r != MocodecResult.Ok)
                return r;
            info.Name = MocodecRuntime.Utf8(n.Name);
            info.Parent = n.Parent;
            info.Kind = (MocodecNodeKind)n.Kind;
            info.Rest = new MocodecTransform(n.RestRotation[0], n.RestRotation[1], n.RestRotation[2], n.RestRotation[3],
                                             n.RestTranslation[0], n.RestTranslation[1], n.RestTranslation[2],
                                             n.RestScale[0], n.RestScale[1], n.RestScale[2]);
            info.Channels = new MocodecChannel[Math.Min(n.ChannelCount, 6u)];
            for (int i = 0; i < info.Channels.Length; i++)
                info.Channels[i] = (MocodecChannel)n.Channels[i];
            return r;
        }

        /// <summary>Names of a skeleton's nodes in index order (pose order).</summary>
        public string[] GetNodeNames(int skeleton)
        {
            int count = GetSkeletonInfo(skeleton).NodeCount;
            string[] names = new string[count];
            for (int i = 0; i < count; i++)
                names[i] = GetNodeInfo(skeleton, i).Name;
            return names;
        }

        /// <summary>A new sampling context (scratch memory) for one thread.</summary>
        public MocodecContext CreateContext()
        {
            ThrowIfDisposed();
            return new MocodecContext(this);
        }

        /// <summary>Samples a clip into <paramref name="poses"/> (at least the clip's NodeCount
        /// long) with the asset's built-in context: one thread at a time. No allocation.
        /// <paramref name="time"/> is in seconds, a double as <c>mcd_sample</c> takes it: a float
        /// resolves only 0.49 ms two hours into a clip.</summary>
        public void Sample(int clip, double time, MocodecTransform[] poses, SampleFlags flags = SampleFlags.None)
        {
            Context.Sample(clip, time, poses, flags);
        }

        public MocodecResult TrySample(int clip, double time, MocodecTransform[] poses, SampleFlags flags = SampleFlags.None)
        {
            return Context.TrySample(clip, time, poses, flags);
        }

        /// <summary>Pointer form, for unmanaged or already pinned buffers (a Unity NativeArray).</summary>
        public void Sample(int clip, double time, MocodecTransform* poses, int capacity, SampleFlags flags = SampleFlags.None)
        {
            Context.Sample(clip, time, poses, capacity, flags);
        }

        public MocodecResult TrySample(int clip, double time, MocodecTransform* poses, int capacity, SampleFlags flags = SampleFlags.None)
        {
            return Context.TrySample(clip, time, poses, capacity, flags);
        }

        public void Sample(int clip, double time, Span<MocodecTransform> poses, SampleFlags flags = SampleFlags.None)
        {
            Context.Sample(clip, time, poses, flags);
        }

        public MocodecResult TrySample(int clip, double time, Span<MocodecTransform> poses, SampleFlags flags = SampleFlags.None)
        {
            return Context.TrySample(clip, time, poses, flags);
        }

        public void Dispose()
        {
            Free();
            GC.SuppressFinalize(this);
        }

        public bool IsDisposed { get { return _asset == null; } }

        MocodecContext Context
        {
            get
            {
                ThrowIfDisposed();
                return _context;
            }
        }

        /// <summary>Reads a skeleton's nodes (names, parents, rests) as a rig description: the rig
        /// that an asset made from this very skeleton drives exactly.</summary>
        public RigBone[] GetSkeletonAsRig(int skeleton)
        {
            int count = GetSkeletonInfo(skeleton).NodeCount;
            RigBone[] bones = new RigBone[count];
            for (int i = 0; i < count; i++)
            {
                NodeInfo node = GetNodeInfo(skeleton, i);
                bones[i] = new RigBone(node.Name, node.Parent, node.Rest);
            }
            return bones;
        }

        internal NativeAsset* Native
        {
            get
            {
                ThrowIfDisposed();
                return _asset;
            }
        }

        void ThrowIfDisposed()
        {
            if (_asset == null)
                throw new ObjectDisposedException("MocodecAsset");
        }

        MocodecResult ReadClipInfo(int clip, out ClipInfo info)
        {
            NativeClipInfo n;
            MocodecResult r = (MocodecResult)NativeMethods.GetClipInfo(_asset, (uint)clip, &n);
            info = default(ClipInfo);
            if (r != MocodecResult.Ok)
                return r;
            info.Index = clip;
            info.Name = MocodecRuntime.Utf8(n.Name);
            info.Skeleton = (int)n.Skeleton;
            info.Codec = (MocodecCodec)n.Codec;
            info.FrameCount = (int)n.FrameCount;
            info.FrameRate = n.FrameRate;
            info.Duration = n.Duration;
            info.NodeCount = (int)n.NodeCount;
            info.ScratchSize = (int)n.ScratchSize;
            info.DataOffset = n.DataOffset;
            info.DataSize = n.DataSize;
            return r;
        }

        void Free()
        {
            // Exchange so that Dispose racing the finalizer frees each block once.
            IntPtr block = Interlocked.Exchange(ref _assetBlock, IntPtr.Zero);
            if (block == IntPtr.Zero)
                return;
            _asset = null;
            if (_context != null)
                _context.Dispose();
            Marshal.FreeHGlobal(block);
            Marshal.FreeHGlobal(Interlocked.Exchange(ref _bytes, IntPtr.Zero));
            GC.RemoveMemoryPressure(Math.Max(_size, 1));
        }
    }
}
