using System;
using NUnit.Framework;

namespace Mocodec.Tests
{
    /// <summary>Bad bytes and bad arguments give the runtime's result code, as an exception from
    /// the throwing form and as a return value from the TryX form.</summary>
    [TestFixture]
    public class ErrorTests
    {
        static byte[] Golden()
        {
            return TestData.GoldenBytes();
        }

        static void ExpectLoadFailure(byte[] bytes, MocodecResult expected)
        {
            MocodecException e = Assert.Throws<MocodecException>(() => MocodecAsset.Load(bytes));
            Assert.That(e.Result, Is.EqualTo(expected));
            StringAssert.Contains(expected.ToString(), e.Message);
            MocodecAsset asset;
            Assert.That(MocodecAsset.TryLoad(bytes, out asset), Is.EqualTo(expected));
            Assert.That(asset, Is.Null);
            Assert.That(MocodecRuntime.Validate(bytes), Is.EqualTo(expected));
        }

        [Test]
        public void EmptyIsTruncated()
        {
            ExpectLoadFailure(new byte[0], MocodecResult.Truncated);
        }

        [Test]
        public void NullIsAnArgumentError()
        {
            Assert.Throws<ArgumentNullException>(() => MocodecAsset.Load(null));
            Assert.Throws<ArgumentNullException>(() => MocodecRuntime.Validate(null));
        }

        [Test]
        public void WrongMagic()
        {
            byte[] b = Golden();
            b[1] ^= 0x20;
            ExpectLoadFailure(b, MocodecResult.BadMagic);
        }

        [Test]
        public void FormatTooNewAndTooOld()
        {
            byte[] b = Golden();
            b[8] = 3; // version_major (the runtime reads 2), outside the checksummed range
            ExpectLoadFailure(b, MocodecResult.VersionTooNew);
            b[8] = 1; // format 1 (mocodec 0.1) is refused as too old
            ExpectLoadFailure(b, MocodecResult.VersionTooOld);
            ExpectLoadFailure(b, MocodecResult.VersionTooOld);
        }

        [Test]
        public void FlippedBitFailsTheChecksum()
        {
            byte[] b = Golden();
            b[b.Length / 2] ^= 0x10;
            ExpectLoadFailure(b, MocodecResult.Checksum);
        }

        [Test]
        public void TrailingBytes()
        {
            byte[] g = Golden();
            byte[] b = new byte[g.Length + 16];
            Buffer.BlockCopy(g, 0, b, 0, g.Length);
            ExpectLoadFailure(b, MocodecResult.TrailingData);
        }

        [Test]
        public void EveryTruncationIsRejected()
        {
            byte[] g = Golden();
            for (int n = 0; n < g.Length; n++)
            {
                byte[] prefix = new byte[n];
                Buffer.BlockCopy(g, 0, prefix, 0, n);
                MocodecAsset asset;
                MocodecResult r = MocodecAsset.TryLoad(prefix, out asset);
                if (r != MocodecResult.Truncated)
                    Assert.Fail("prefix of " + n + " bytes gave " + r);
            }
        }

        [Test]
        public void SampleArgumentErrors()
        {
            using (MocodecAsset asset = MocodecAsset.Load(Golden()))
            {
                int nodes = asset.GetClipInfo(0).NodeCount;
                MocodecTransform[] pose = new MocodecTransform[nodes];
                Assert.That(asset.TrySample(asset.ClipCount, 0f, pose), Is.EqualTo(MocodecResult.OutOfRange));
                Assert.That(asset.TrySample(-1, 0f, pose), Is.EqualTo(MocodecResult.OutOfRange));
                Assert.That(asset.TrySample(0, float.NaN, pose), Is.EqualTo(MocodecResult.InvalidArgument));
                Assert.That(asset.TrySample(0, 0f, pose, (SampleFlags)0x100), Is.EqualTo(MocodecResult.InvalidArgument));
                Assert.That(asset.TrySample(0, 0f, new MocodecTransform[nodes - 1]), Is.EqualTo(MocodecResult.BufferTooSmall));

                MocodecException e = Assert.Throws<MocodecException>(() => asset.Sample(0, 0f, new MocodecTransform[1]));
                Assert.That(e.Result, Is.EqualTo(MocodecResult.BufferTooSmall));
                e = Assert.Throws<MocodecException>(() => asset.Sample(asset.ClipCount, 0f, pose));
                Assert.That(e.Result, Is.EqualTo(MocodecResult.OutOfRange));
                Assert.Throws<ArgumentNullException>(() => asset.Sample(0, 0f, null));
                Assert.That(asset.TrySample(0, 0f, pose), Is.EqualTo(MocodecResult.Ok));
            }
        }

        [Test]
        public void QueryErrors()
        {
            using (MocodecAsset asset = MocodecAsset.Load(Golden()))
            {
                int clip;
                Assert.That(asset.TryFindClip("no such clip", out clip), Is.EqualTo(MocodecResult.NotFound));
                Assert.That(clip, Is.EqualTo(-1));
                Assert.That(Assert.Throws<MocodecException>(() => asset.FindClip("no such clip")).Result,
                            Is.EqualTo(MocodecResult.NotFound));
                Assert.That(Assert.Throws<MocodecException>(() => asset.GetClipInfo(asset.ClipCount)).Result,
                            Is.EqualTo(MocodecResult.OutOfRange));
                Assert.That(Assert.Throws<MocodecException>(() => asset.GetSkeletonInfo(asset.SkeletonCount)).Result,
                            Is.EqualTo(MocodecResult.OutOfRange));
                int nodes = asset.GetSkeletonInfo(0).NodeCount;
                NodeInfo info;
                Assert.That(asset.TryGetNodeInfo(0, nodes, out info), Is.EqualTo(MocodecResult.OutOfRange));
            }
        }

        [Test]
        public void DisposedAssetThrows()
        {
            MocodecAsset asset = MocodecAsset.Load(Golden());
            MocodecContext context = asset.CreateContext();
            MocodecTransform[] pose = new MocodecTransform[asset.GetClipInfo(0).NodeCount];
            asset.Dispose();
            asset.Dispose(); // twice is allowed
            Assert.That(asset.IsDisposed, Is.True);
            Assert.Throws<ObjectDisposedException>(() => asset.Sample(0, 0f, pose));
            Assert.Throws<ObjectDisposedException>(() => context.Sample(0, 0f, pose));
            Assert.Throws<ObjectDisposedException>(() => asset.GetClipInfo(0));
        }
    }
}
