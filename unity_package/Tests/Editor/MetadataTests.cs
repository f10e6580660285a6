using System;
using NUnit.Framework;

namespace Mocodec.Tests
{
    /// <summary>The encoder's report (META) as the importer's inspector shows it.</summary>
    [TestFixture]
    public class MetadataTests
    {
        [Test, TestCaseSource(typeof(PoseTests), "Assets")]
        public void ReportsEveryClipWithinTolerance(string name)
        {
            byte[] bytes = TestData.Bytes(name);
            MocodecMetadata meta = MocodecMetadata.Read(bytes);
            Assert.That(meta, Is.Not.Null, "encoder output carries META");
            StringAssert.StartsWith("mocodec", meta.Encoder);
            using (MocodecAsset asset = MocodecAsset.Load(bytes))
            {
                Assert.That(meta.Clips.Count, Is.EqualTo(asset.ClipCount));
                foreach (ClipMetadata clip in meta.Clips)
                {
                    MocodecCodec codec = asset.GetClipInfo(asset.FindClip(clip.Name)).Codec;
                    Assert.That(meta.Codec, Is.Not.Null.And.Not.Empty, codec.ToString());
                    Assert.That(clip.MaxErrorCm, Is.GreaterThanOrEqualTo(clip.MeanErrorCm));
                    if (meta.HasTolerancePromise)
                        Assert.That(clip.MaxErrorCm, Is.LessThanOrEqualTo(meta.ToleranceCm), clip.Name);
                    else // the paper's settings: the error reached is reported, not promised
                        Assert.That(clip.MaxErrorCm, Is.GreaterThan(0.0).And.LessThan(double.PositiveInfinity), clip.Name);
                }
                Assert.That(meta.RawBvhBytes, Is.GreaterThan(asset.Size), "the asset is smaller than the raw channels");
                Assert.That(meta.HasTolerancePromise, Is.Not.EqualTo(meta.Codec == "rma-pca"), "only rma-pca promises no tolerance");
                Assert.That(double.IsNaN(meta.PcaVariance), Is.EqualTo(meta.HasTolerancePromise), "rma-pca reports its variance fraction");
            }
        }

        [Test]
        public void InvalidBytesHaveNoMetadata()
        {
            Assert.That(MocodecMetadata.Read(new byte[0]), Is.Null);
            byte[] b = TestData.GoldenBytes();
            b[0] = 0;
            Assert.That(MocodecMetadata.Read(b), Is.Null);
        }
    }
}
