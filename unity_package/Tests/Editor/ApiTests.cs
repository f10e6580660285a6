using System;
using System.Collections.Generic;
using System.IO;
using System.Reflection;
using System.Runtime.InteropServices;
using NUnit.Framework;

namespace Mocodec.Tests
{
    /// <summary>Version check, ABI layout, queries, and the no-allocation promise.</summary>
    [TestFixture]
    public class ApiTests
    {
        [Test]
        public void NativeVersionIsTheExpectedOne()
        {
            Assert.DoesNotThrow(MocodecRuntime.EnsureCompatible);
            uint v = MocodecRuntime.NativeVersion;
            Assert.That(v >> 16, Is.EqualTo(MocodecRuntime.ExpectedMajor));
            Assert.That((v >> 8) & 0xFF, Is.EqualTo(MocodecRuntime.ExpectedMinor));
        }

        [TestCase(0x000300u, true)]
        [TestCase(0x000307u, true)]
        [TestCase(0x000200u, false)] // 0.2 took mcd_sample's time as a float
        [TestCase(0x000400u, false)]
        [TestCase(0x000000u, false)]
        [TestCase(0x010100u, false)]
        public void VersionPolicy(uint version, bool compatible)
        {
            Assert.That(MocodecRuntime.IsCompatible(version), Is.EqualTo(compatible));
        }

        /// <summary>Struct sizes and field offsets against the C compiler's (run_tests.sh writes
        /// them with bindings/csharp/abi_layout.c into MOCODEC_ABI_LAYOUT).</summary>
        [Test]
        public void StructLayoutMatchesTheHeader()
        {
            string path = Environment.GetEnvironmentVariable("MOCODEC_ABI_LAYOUT");
            if (string.IsNullOrEmpty(path))
                Assert.Ignore("MOCODEC_ABI_LAYOUT not set: the layout is checked by bindings/csharp/run_tests.sh");
            Dictionary<string, Type> types = new Dictionary<string, Type>
            {
                { "mcd_asset", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeAsset", true) },
                { "mcd_clip_info", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeClipInfo", true) },
                { "mcd_skeleton_info", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeSkeletonInfo", true) },
                { "mcd_node_info", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeNodeInfo", true) },
                { "mcd_transform", typeof(MocodecTransform) },
                { "mcd_rig_bone", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeRigBone", true) },
                { "mcd_retarget_pair", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeRetargetPair", true) },
                { "mcd_retarget_config", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeRetargetConfig", true) },
                { "mcd_retarget_issue", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeRetargetIssue", true) },
                { "mcd_retarget_info", typeof(MocodecAsset).Assembly.GetType("Mocodec.NativeRetargetInfo", true) }
            };
            int checkedLines = 0;
            foreach (string line in File.ReadAllLines(path))
            {
                // "sizeof mcd_clip_info 40" or "offsetof mcd_clip_info Duration 24"
                string[] f = line.Split(' ');
                Type t = types[f[1]];
                if (f[0] == "sizeof")
                    Assert.That(Marshal.SizeOf(t), Is.EqualTo(int.Parse(f[2])), line);
                else
                    Assert.That(Marshal.OffsetOf(t, f[2]).ToInt32(), Is.EqualTo(int.Parse(f[3])), line);
                checkedLines++;
            }
            Assert.That(checkedLines, Is.GreaterThan(10));
        }

        [Test]
        public void QueriesDescribeTheAsset()
        {
            foreach (string name in TestData.AssetNames)
            {
                byte[] bytes = TestData.Bytes(name);
                using (MocodecAsset asset = MocodecAsset.Load(bytes))
                {
                    Assert.That(asset.Size, Is.EqualTo(bytes.Length));
                    Assert.That(asset.ScratchSize % 16, Is.EqualTo(0));
                    Assert.That(asset.SkeletonCount, Is.GreaterThanOrEqualTo(1));
                    for (int c = 0; c < asset.ClipCount; c++)
                    {
                        ClipInfo clip = asset.GetClipInfo(c);
                        Assert.That(clip.Index, Is.EqualTo(c));
                        Assert.That(asset.FindClip(clip.Name), Is.EqualTo(c), name + " clip " + clip.Name);
                        Assert.That(clip.Duration, Is.EqualTo((clip.FrameCount - 1) / clip.FrameRate).Within(1e-3));
                        Assert.That(Enum.IsDefined(typeof(MocodecCodec), clip.Codec), clip.Codec.ToString());
                        SkeletonInfo skeleton = asset.GetSkeletonInfo(clip.Skeleton);
                        Assert.That(skeleton.NodeCount, Is.EqualTo(clip.NodeCount));
                        Assert.That(skeleton.CmPerUnit, Is.GreaterThan(0f));
                        string[] names = asset.GetNodeNames(clip.Skeleton);
                        Assert.That(new HashSet<string>(names).Count, Is.EqualTo(names.Length), "unique node names");
                        for (int n = 0; n < names.Length; n++)
                        {
                            NodeInfo node = asset.GetNodeInfo(clip.Skeleton, n);
                            Assert.That(node.Parent, Is.LessThan(n), "parents come first");
                            Assert.That(node.Parent == -1, Is.EqualTo(n == 0), "one root, first");
                            int channels = node.Channels.Length;
                            Assert.That(node.Kind != MocodecNodeKind.Joint ? channels == 0 : channels == 0 || channels == 3 || channels == 6,
                                        name + " " + node.Name + " has " + channels + " channels");
                            double norm = node.Rest.Qx * node.Rest.Qx + node.Rest.Qy * node.Rest.Qy + node.Rest.Qz * node.Rest.Qz + node.Rest.Qw * node.Rest.Qw;
                            Assert.That(norm, Is.EqualTo(1.0).Within(1e-4), "unit rest rotation");
                        }
                    }
                }
            }
        }

        [Test]
        public void PointerSpanArrayAndContextAgree()
        {
            byte[] bytes = TestData.GoldenBytes();
            using (MocodecAsset asset = MocodecAsset.Load(bytes))
            using (MocodecContext context = asset.CreateContext())
            {
                ClipInfo clip = asset.GetClipInfo(0);
                float t = clip.Duration * 0.61f;
                MocodecTransform[] a = new MocodecTransform[clip.NodeCount];
                MocodecTransform[] b = new MocodecTransform[clip.NodeCount + 3];
                MocodecTransform[] c = new MocodecTransform[clip.NodeCount];
                MocodecTransform[] d = new MocodecTransform[clip.NodeCount];
                asset.Sample(0, t, a, SampleFlags.World);
                context.Sample(0, t, new Span<MocodecTransform>(b, 3, clip.NodeCount), SampleFlags.World);
                unsafe
                {
                    fixed (MocodecTransform* p = c)
                        context.Sample(0, t, p, c.Length, SampleFlags.World);
                }
                using (MocodecAsset fresh = MocodecAsset.Load(bytes))
                    fresh.Sample(0, t, d, SampleFlags.World);
                double worst;
                Assert.That(TestData.FirstMismatch(a, new Span<MocodecTransform>(b, 3, clip.NodeCount).ToArray(), 0, out worst), Is.EqualTo(-1));
                Assert.That(TestData.FirstMismatch(a, c, 0, out worst), Is.EqualTo(-1));
                Assert.That(TestData.FirstMismatch(a, d, 0, out worst), Is.EqualTo(-1));
            }
        }

        /// <summary>Sampling allocates no managed memory. Needs GC.GetAllocatedBytesForCurrentThread
        /// (mono, .NET Standard 2.1); where the runtime lacks it the test is ignored.</summary>
        [Test]
        public void SamplingDoesNotAllocate()
        {
            MethodInfo m = typeof(GC).GetMethod("GetAllocatedBytesForCurrentThread", BindingFlags.Public | BindingFlags.Static);
            if (m == null)
                Assert.Ignore("GC.GetAllocatedBytesForCurrentThread is not available on this runtime");
            Func<long> allocated = (Func<long>)Delegate.CreateDelegate(typeof(Func<long>), m);
            using (MocodecAsset asset = MocodecAsset.Load(TestData.GoldenBytes()))
            using (MocodecContext context = asset.CreateContext())
            {
                ClipInfo clip = asset.GetClipInfo(0);
                MocodecTransform[] pose = new MocodecTransform[clip.NodeCount];
                // Warm up: the first P/Invoke call generates its marshalling code.
                asset.Sample(0, 0f, pose, SampleFlags.Loop);
                context.Sample(0, 0f, pose, SampleFlags.Loop);
                asset.TrySample(0, 0f, pose);
                long before = allocated();
                for (int i = 0; i < 2000; i++)
                {
                    float t = i / 60f;
                    asset.Sample(0, t, pose, SampleFlags.Loop);
                    context.Sample(0, t, pose, SampleFlags.Loop | SampleFlags.World);
                    asset.TrySample(0, t, pose);
                }
                long after = allocated();
                Assert.That(after - before, Is.EqualTo(0), "bytes allocated by 6000 samples");
            }
        }
    }
}
