using System;
using System.Threading;
using NUnit.Framework;

namespace Mocodec.Tests
{
    /// <summary>One asset shared by four threads, each with its own context, gives bit for bit
    /// the poses of a serial run.</summary>
    [TestFixture]
    public class ThreadingTests
    {
        const int Threads = 4;

        [Test, TestCaseSource(typeof(PoseTests), "Assets")]
        public void FourThreadsMatchSerial(string name)
        {
            using (MocodecAsset asset = MocodecAsset.Load(TestData.Bytes(name)))
            {
                float[] serial;
                using (MocodecContext context = asset.CreateContext())
                    serial = SampleAll(asset, context, 0);
                float[][] results = new float[Threads][];
                Exception[] errors = new Exception[Threads];
                Thread[] threads = new Thread[Threads];
                for (int i = 0; i < Threads; i++)
                {
                    int k = i;
                    threads[k] = new Thread(() =>
                    {
                        try
                        {
                            using (MocodecContext context = asset.CreateContext())
                                results[k] = SampleAll(asset, context, k);
                        }
                        catch (Exception e)
                        {
                            errors[k] = e;
                        }
                    });
                }
                foreach (Thread t in threads)
                    t.Start();
                foreach (Thread t in threads)
                    t.Join();
                for (int i = 0; i < Threads; i++)
                {
                    Assert.That(errors[i], Is.Null, "thread " + i);
                    Assert.That(results[i].Length, Is.EqualTo(serial.Length));
                    for (int j = 0; j < serial.Length; j++)
                        if (!BitsEqual(results[i][j], serial[j]))
                            Assert.Fail("thread " + i + " value " + j + ": " + results[i][j] + " != " + serial[j]);
                }
            }
        }

        /// <summary>Every frame of every clip, local then world, in an order that depends on
        /// <paramref name="rotation"/> so the threads' caches see different histories; the
        /// output is stored in one canonical order.</summary>
        static float[] SampleAll(MocodecAsset asset, MocodecContext context, int rotation)
        {
            int total = 0;
            for (int c = 0; c < asset.ClipCount; c++)
                total += asset.GetClipInfo(c).FrameCount * asset.GetClipInfo(c).NodeCount * 10 * 2;
            float[] out_ = new float[total];
            int clipBase = 0;
            for (int c = 0; c < asset.ClipCount; c++)
            {
                ClipInfo clip = asset.GetClipInfo(c);
                MocodecTransform[] pose = new MocodecTransform[clip.NodeCount];
                int stride = clip.NodeCount * 10;
                for (int pass = 0; pass < 2; pass++)
                {
                    SampleFlags flags = pass == 0 ? SampleFlags.None : SampleFlags.World;
                    for (int n = 0; n < clip.FrameCount; n++)
                    {
                        // Frame order: forward from an offset for odd rotations, backward for even.
                        int f = (rotation % 2 == 1) ? (n + rotation * 17) % clip.FrameCount : clip.FrameCount - 1 - n;
                        context.Sample(c, f / clip.FrameRate, pose, flags);
                        int o = clipBase + (pass * clip.FrameCount + f) * stride;
                        for (int j = 0; j < pose.Length; j++)
                        {
                            out_[o++] = pose[j].Qx; out_[o++] = pose[j].Qy; out_[o++] = pose[j].Qz; out_[o++] = pose[j].Qw;
                            out_[o++] = pose[j].Tx; out_[o++] = pose[j].Ty; out_[o++] = pose[j].Tz;
                            out_[o++] = pose[j].Sx; out_[o++] = pose[j].Sy; out_[o++] = pose[j].Sz;
                        }
                    }
                }
                clipBase += 2 * clip.FrameCount * stride;
            }
            return out_;
        }

        static bool BitsEqual(float a, float b)
        {
            return BitConverter.ToInt32(BitConverter.GetBytes(a), 0) == BitConverter.ToInt32(BitConverter.GetBytes(b), 0);
        }
    }
}
