using System;
using System.Runtime.InteropServices;
using System.Threading;

namespace Mocodec
{
    /// <summary>
    /// Per-thread sampling state: the runtime's scratch memory (caches that make sequential
    /// playback O(1) per frame). One context per thread; any number of contexts per asset.
    /// Sampling allocates nothing: the caller's pose buffer is pinned for the call only.
    /// </summary>
    public sealed unsafe class MocodecContext : IDisposable
    {
        readonly MocodecAsset _asset;
        IntPtr _block;
        byte* _scratch;

        internal MocodecContext(MocodecAsset asset)
        {
            _asset = asset;
            int size = asset.ScratchSize;
            _block = Marshal.AllocHGlobal(size + 16);
            long a = _block.ToInt64();
            _scratch = (byte*)(a + ((16 - (a & 15)) & 15));
            int r = NativeMethods.ScratchInit(asset.Native, _scratch, (UIntPtr)(uint)size);
            if (r != 0)
            {
                Dispose();
                MocodecRuntime.Check(r, "mcd_scratch_init");
            }
        }

        ~MocodecContext()
        {
            Free();
        }

        public MocodecAsset Asset { get { return _asset; } }

        public void Sample(int clip, double time, MocodecTransform[] poses, SampleFlags flags = SampleFlags.None)
        {
            MocodecRuntime.Check((int)TrySample(clip, time, poses, flags), "mcd_sample");
        }

        public MocodecResult TrySample(int clip, double time, MocodecTransform[] poses, SampleFlags flags = SampleFlags.None)
        {
            if (poses == null)
                throw new ArgumentNullException("poses");
            fixed (MocodecTransform* p = poses)
                return TrySample(clip, time, p, poses.Length, flags);
        }

        public void Sample(int clip, double time, MocodecTransform* poses, int capacity, SampleFlags flags = SampleFlags.None)
        {
            MocodecRuntime.Check((int)TrySample(clip, time, poses, capacity, flags), "mcd_sample");
        }

        public MocodecResult TrySample(int clip, double time, MocodecTransform* poses, int capacity, SampleFlags flags = SampleFlags.None)
        {
            if (_scratch == null)
                throw new ObjectDisposedException("MocodecContext");
            // Negative indices and capacities become values the runtime rejects (out of range,
            // buffer too small), so the runtime stays the one judge of arguments.
            return (MocodecResult)NativeMethods.Sample(_asset.Native, (uint)clip, time, (uint)flags, poses,
                                                       capacity < 0 ? 0u : (uint)capacity, _scratch);
        }

        public void Sample(int clip, double time, Span<MocodecTransform> poses, SampleFlags flags = SampleFlags.None)
        {
            MocodecRuntime.Check((int)TrySample(clip, time, poses, flags), "mcd_sample");
        }

        public MocodecResult TrySample(int clip, double time, Span<MocodecTransform> poses, SampleFlags flags = SampleFlags.None)
        {
            fixed (MocodecTransform* p = &MemoryMarshal.GetReference(poses))
                return TrySample(clip, time, p, poses.Length, flags);
        }

        public void Dispose()
        {
            Free();
            GC.SuppressFinalize(this);
        }

        void Free()
        {
            IntPtr block = Interlocked.Exchange(ref _block, IntPtr.Zero);
            if (block == IntPtr.Zero)
                return;
            _scratch = null;
            Marshal.FreeHGlobal(block);
        }
    }
}
