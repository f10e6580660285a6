using System;
using System.Collections.Generic;
using NUnit.Framework;

namespace Mocodec.Tests
{
    /// <summary>Every asset with reference poses: load, validate, replay every recorded sample
    /// and sample every frame of every clip.</summary>
    [TestFixture]
    public class PoseTests
    {
        // The Python/C reference prints 9 significant digits; the poses must agree to this.
        const double Tolerance = 1e-5;

        public static IEnumerable<string> Assets
        {
            get { return TestData.AssetNames; }
        }

        [Test]
        public void DataDirectoryHoldsGoldenAndEncodedAssets()
        {
            string[] names = TestData.AssetNames;
            Assert.That(TestData.DataDirectory, Is.Not.Null, "set MOCODEC_TEST_DATA or install the package with its Tests/Data~");
            Assert.That(Array.FindAll(names, n => n.StartsWith("golden_", StringComparison.Ordinal)).Length,
                        Is.GreaterThanOrEqualTo(1), "golden vectors");
            Assert.That(Array.FindAll(names, n => !n.StartsWith("golden_", StringComparison.Ordinal)).Length,
                        Is.GreaterThanOrEqualTo(1), "assets made by the encoder");
        }

        [Test, TestCaseSource("Assets")]
        public void Validates(string name)
        {
            byte[] bytes = TestData.Bytes(name);
            Assert.That(MocodecRuntime.Validate(bytes), Is.EqualTo(MocodecResult.Ok));
            Assert.That(MocodecRuntime.Validate(bytes, ValidateFlags.SkipChecksum), Is.EqualTo(MocodecResult.Ok));
        }

        [Test, TestCaseSource("Assets")]
        public void MatchesReferencePoses(string name)
        {
            List<ReferenceSample> samples = TestData.Poses(name);
            Assert.That(samples.Count, Is.GreaterThan(0));
            using (MocodecAsset asset = MocodecAsset.Load(TestData.Bytes(name)))
            {
                foreach (ReferenceSample s in samples)
                {
                    ClipInfo clip = asset.GetClipInfo(s.Clip);
                    Assert.That(clip.NodeCount, Is.EqualTo(s.Pose.Length), "node count of clip " + s.Clip);
                    MocodecTransform[] pose = new MocodecTransform[clip.NodeCount];
                    asset.Sample(s.Clip, s.Time, pose, s.Flags);
                    double worst;
                    int bad = TestData.FirstMismatch(s.Pose, pose, Tolerance, out worst);
                    Assert.That(bad, Is.EqualTo(-1), string.Format(
                        "{0} clip {1} t={2} flags={3}: node {4} differs by {5:g3}", name, s.Clip, s.Time, s.Flags, bad, worst));
                }
            }
        }

        [Test, TestCaseSource("Assets")]
        public void SamplesEveryFrameOfEveryClipFinite(string name)
        {
            using (MocodecAsset asset = MocodecAsset.Load(TestData.Bytes(name)))
            {
                Assert.That(asset.ClipCount, Is.GreaterThan(0));
                for (int c = 0; c < asset.ClipCount; c++)
                {
                    ClipInfo clip = asset.GetClipInfo(c);
                    MocodecTransform[] pose = new MocodecTransform[clip.NodeCount];
                    foreach (SampleFlags flags in new[] { SampleFlags.None, SampleFlags.World })
                    {
                        for (int f = 0; f < clip.FrameCount; f++)
                        {
                            asset.Sample(c, f / clip.FrameRate, pose, flags);
                            foreach (MocodecTransform t in pose)
                            {
                                float sum = t.Qx + t.Qy + t.Qz + t.Qw + t.Tx + t.Ty + t.Tz + t.Sx + t.Sy + t.Sz;
                                Assert.That(!float.IsNaN(sum) && !float.IsInfinity(sum), "finite pose");
                                double norm = t.Qx * t.Qx + t.Qy * t.Qy + t.Qz * t.Qz + t.Qw * t.Qw;
                                Assert.That(norm, Is.EqualTo(1.0).Within(1e-4), "unit quaternion");
                            }
                        }
                    }
                }
            }
        }
    }
}
