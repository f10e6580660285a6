using System;
using System.Collections.Generic;
using System.Runtime.InteropServices;
using System.Threading;

namespace Mocodec
{
    /// <summary>A bone of a game rig, as the retargeting sees it.</summary>
    public struct RigBone
    {
        public string Name;
        /// <summary>Index of the parent bone, -1 for a root; parents come before children.</summary>
        public int Parent;
        /// <summary>The rest (bind) local transform, in the rig's right-handed space and units
        /// (<see cref="MocodecSpace.MirrorX(MocodecTransform)"/> turns a Unity rest into one).</summary>
        public MocodecTransform Rest;
        /// <summary>Always the rest translation, even for the motion root.</summary>
        public bool KeepTranslation;

        public RigBone(string name, int parent, MocodecTransform rest, bool keepTranslation = false)
        {
            Name = name;
            Parent = parent;
            Rest = rest;
            KeepTranslation = keepTranslation;
        }
    }

    /// <summary>How a <see cref="MocodecRetarget"/> maps the asset onto the rig
    /// (<c>mcd_retarget_config</c>); the defaults are the runtime's.</summary>
    public struct RetargetSettings
    {
        /// <summary>The motion root travels; off: it moves along <see cref="UpAxis"/> only.</summary>
        public bool RootMotion;
        /// <summary>Bones with one matched child point where their node points (A-pose rigs).</summary>
        public bool MatchDirections;
        /// <summary>0 x, 1 y, 2 z of rig space.</summary>
        public int UpAxis;
        /// <summary>Rig units per asset unit (metres: <see cref="SkeletonInfo.CmPerUnit"/> / 100).</summary>
        public float UnitScale;
        /// <summary>Asset model space to rig space (x y z w).</summary>
        public float SpaceQx, SpaceQy, SpaceQz, SpaceQw;

        public static RetargetSettings Default
        {
            get
            {
                return new RetargetSettings { RootMotion = true, MatchDirections = true, UpAxis = 1, UnitScale = 1f, SpaceQw = 1f };
            }
        }
    }

    /// <summary>Where the runtime found a bad retargeting input (<c>mcd_retarget_issue</c>).</summary>
    public enum RetargetIssue
    {
        None = 0,
        Bone = 1,
        Pair = 2,
        Settings = 3
    }

    /// <summary>A retargeting input the runtime refused, with the bone or pair it names.</summary>
    public sealed class MocodecRetargetException : MocodecException
    {
        public readonly RetargetIssue Issue;
        public readonly int Index;

        public MocodecRetargetException(MocodecResult result, RetargetIssue issue, int index, string what)
            : base(result, "mcd_retarget_init: " + what)
        {
            Issue = issue;
            Index = index;
        }
    }

    /// <summary>
    /// Poses of one skeleton of an asset onto a game rig with its own names, rest transforms and
    /// proportions: the runtime's <c>mcd_retarget_*</c> (runtime_c/include/mocodec.h has the
    /// rules), so the math lives once, in C. Built once per rig; <see cref="Apply"/> allocates
    /// nothing. One thread at a time per instance (it owns one work buffer); the native map is
    /// read-only, so several instances for several threads are fine.
    /// </summary>
    public sealed unsafe class MocodecRetarget : IDisposable
    {
        IntPtr _map, _work;
        byte* _mapAligned, _workAligned;
        readonly int _boneCount, _nodeCount, _matched, _workSize;
        readonly MocodecAsset _asset;

        /// <param name="pairs">Bone name to asset node name (null: the bone is not driven);
        /// names match first, then exact and loose names (namespace, case, separators).</param>
        public MocodecRetarget(MocodecAsset asset, int skeleton, RigBone[] bones, IDictionary<string, string> pairs,
                               RetargetSettings settings)
        {
            if (asset == null)
                throw new ArgumentNullException("asset");
            if (bones == null)
                throw new ArgumentNullException("bones");
            _asset = asset;
            List<IntPtr> strings = new List<IntPtr>();
            try
            {
                NativeRigBone[] native = new NativeRigBone[Math.Max(bones.Length, 1)];
                for (int i = 0; i < bones.Length; i++)
                {
                    native[i].Name = Utf8(bones[i].Name, strings);
                    native[i].Parent = bones[i].Parent;
                    native[i].Flags = bones[i].KeepTranslation ? 1u : 0u;
                    native[i].Rest = bones[i].Rest;
                }
                List<string> pairNames = new List<string>();
                NativeRetargetPair[] nativePairs = new NativeRetargetPair[Math.Max(pairs == null ? 0 : pairs.Count, 1)];
                int pairCount = 0;
                if (pairs != null)
                {
                    foreach (KeyValuePair<string, string> p in pairs)
                    {
                        nativePairs[pairCount].Bone = Utf8(p.Key, strings);
                        nativePairs[pairCount].Node = p.Value == null ? IntPtr.Zero : Utf8(p.Value, strings);
                        pairNames.Add(p.Key + " -> " + (p.Value ?? "(none)"));
                        pairCount++;
                    }
                }
                NativeRetargetConfig config;
                NativeMethods.RetargetConfigDefault(&config);
                config.Flags = (settings.RootMotion ? 1u : 0u) | (settings.MatchDirections ? 2u : 0u);
                config.UpAxis = (uint)settings.UpAxis;
                config.UnitScale = settings.UnitScale;
                config.SpaceRotation[0] = settings.SpaceQx;
                config.SpaceRotation[1] = settings.SpaceQy;
                config.SpaceRotation[2] = settings.SpaceQz;
                config.SpaceRotation[3] = settings.SpaceQw;

                UIntPtr size;
                MocodecRuntime.Check(NativeMethods.RetargetSize(asset.Native, (uint)skeleton, (uint)bones.Length, &size),
                                     "mcd_retarget_size");
                _map = Marshal.AllocHGlobal((IntPtr)((long)size.ToUInt64() + 16));
                _mapAligned = Align16(_map);
                NativeRetargetIssue issue;
                int r;
                fixed (NativeRigBone* b = native)
                fixed (NativeRetargetPair* p = nativePairs)
                    r = NativeMethods.RetargetInit(asset.Native, (uint)skeleton, b, (uint)bones.Length, p, (uint)pairCount,
                                                   &config, _mapAligned, size, &issue);
                if (r != 0)
                {
                    RetargetIssue where = (RetargetIssue)issue.Where;
                    int index = (int)issue.Index;
                    string what = where == RetargetIssue.Bone && index < bones.Length ? "bone " + index + " '" + bones[index].Name + "'"
                                : where == RetargetIssue.Pair && index < pairNames.Count ? "pair " + index + " (" + pairNames[index] + ")"
                                : where == RetargetIssue.Settings ? "settings, asset or skeleton" : "input";
                    Free();
                    throw new MocodecRetargetException((MocodecResult)r, where, index, what);
                }
                NativeRetargetInfo info;
                MocodecRuntime.Check(NativeMethods.RetargetGetInfo(_mapAligned, &info), "mcd_retarget_get_info");
                _boneCount = (int)info.BoneCount;
                _nodeCount = (int)info.NodeCount;
                _matched = (int)info.Matched;
                _workSize = (int)info.WorkSize;
                _work = Marshal.AllocHGlobal(_workSize + 16);
                _workAligned = Align16(_work);
            }
            finally
            {
                foreach (IntPtr s in strings)
                    Marshal.FreeHGlobal(s);
            }
        }

        public MocodecRetarget(MocodecAsset asset, int skeleton, RigBone[] bones)
            : this(asset, skeleton, bones, null, RetargetSettings.Default)
        {
        }

        ~MocodecRetarget()
        {
            Free();
        }

        /// <summary>Rig bones: the length <see cref="Apply"/> writes.</summary>
        public int BoneCount { get { return _boneCount; } }

        /// <summary>Asset nodes: the length of the pose <see cref="Apply"/> reads.</summary>
        public int NodeCount { get { return _nodeCount; } }

        /// <summary>Bones driven by a node.</summary>
        public int MatchedCount { get { return _matched; } }

        public MocodecAsset Asset { get { return _asset; } }

        /// <summary>The asset node that drives bone <paramref name="bone"/>, or -1.</summary>
        public int NodeOf(int bone)
        {
            ThrowIfDisposed();
            int node;
            MocodecRuntime.Check(NativeMethods.RetargetGetNode(_mapAligned, (uint)bone, &node), "mcd_retarget_get_node");
            return node;
        }

        /// <summary>The rig's local transforms for a local pose of the asset's skeleton (as
        /// <see cref="MocodecContext.Sample(int, float, MocodecTransform[], SampleFlags)"/> writes
        /// it). No allocation.</summary>
        public void Apply(MocodecTransform[] pose, MocodecTransform[] rigPose)
        {
            MocodecRuntime.Check((int)TryApply(pose, rigPose), "mcd_retarget_pose");
        }

        public MocodecResult TryApply(MocodecTransform[] pose, MocodecTransform[] rigPose)
        {
            if (pose == null)
                throw new ArgumentNullException("pose");
            if (rigPose == null)
                throw new ArgumentNullException("rigPose");
            fixed (MocodecTransform* p = pose)
            fixed (MocodecTransform* o = rigPose)
                return TryApply(p, pose.Length, o, rigPose.Length);
        }

        /// <summary>Pointer form (pinned or unmanaged buffers).</summary>
        public MocodecResult TryApply(MocodecTransform* pose, int nodeCount, MocodecTransform* rigPose, int capacity)
        {
            ThrowIfDisposed();
            return (MocodecResult)NativeMethods.RetargetPose(_mapAligned, pose, nodeCount < 0 ? 0u : (uint)nodeCount, rigPose,
                                                             capacity < 0 ? 0u : (uint)capacity, _workAligned, (UIntPtr)(uint)_workSize);
        }

        public void Dispose()
        {
            Free();
            GC.SuppressFinalize(this);
        }

        void ThrowIfDisposed()
        {
            if (_mapAligned == null || _workAligned == null)
                throw new ObjectDisposedException("MocodecRetarget");
        }

        static IntPtr Utf8(string s, List<IntPtr> owned)
        {
            if (s == null)
                return IntPtr.Zero; // the runtime refuses it and names the bone or pair
            byte[] b = MocodecRuntime.Utf8Z(s);
            IntPtr p = Marshal.AllocHGlobal(b.Length);
            Marshal.Copy(b, 0, p, b.Length);
            owned.Add(p);
            return p;
        }

        static byte* Align16(IntPtr p)
        {
            long a = p.ToInt64();
            return (byte*)(a + ((16 - (a & 15)) & 15));
        }

        void Free()
        {
            _mapAligned = null;
            _workAligned = null;
            Marshal.FreeHGlobal(Interlocked.Exchange(ref _map, IntPtr.Zero));
            Marshal.FreeHGlobal(Interlocked.Exchange(ref _work, IntPtr.Zero));
        }
    }
}
