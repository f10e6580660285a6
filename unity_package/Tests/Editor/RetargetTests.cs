// Retargeting, handedness and units through the C# core (the math is the runtime's
// mcd_retarget_*; these check the binding's marshalling and the engine-side conversions).
// Written against the NUnit surface that 2.6 (mono, here) and 3 (Unity Test Runner) share.
using System;
using System.Collections.Generic;
using System.Reflection;
using NUnit.Framework;

namespace Mocodec.Tests
{
    [TestFixture]
    public class RetargetTests
    {
        static IEnumerable<string> Assets()
        {
            return TestData.AssetNames;
        }

        // ---- a little double-precision math, independent of the runtime's

        struct Q
        {
            public double X, Y, Z, W;
            public Q(double x, double y, double z, double w) { X = x; Y = y; Z = z; W = w; }
            public static Q Of(MocodecTransform t) { return new Q(t.Qx, t.Qy, t.Qz, t.Qw); }
            public static Q Axis(double x, double y, double z, double angle)
            {
                double n = Math.Sqrt(x * x + y * y + z * z), s = Math.Sin(angle / 2);
                return new Q(x / n * s, y / n * s, z / n * s, Math.Cos(angle / 2));
            }
            public static Q operator *(Q a, Q b)
            {
                return new Q(a.W * b.X + a.X * b.W + a.Y * b.Z - a.Z * b.Y, a.W * b.Y - a.X * b.Z + a.Y * b.W + a.Z * b.X,
                             a.W * b.Z + a.X * b.Y - a.Y * b.X + a.Z * b.W, a.W * b.W - a.X * b.X - a.Y * b.Y - a.Z * b.Z);
            }
            public Q Conj { get { return new Q(-X, -Y, -Z, W); } }
            public double[] Rotate(double[] v)
            {
                Q r = this * new Q(v[0], v[1], v[2], 0) * Conj;
                return new[] { r.X, r.Y, r.Z };
            }
        }

        /// <summary>World positions and rotations from local transforms (unit scales).</summary>
        static void World(MocodecTransform[] local, int[] parents, out Q[] rot, out double[][] pos)
        {
            rot = new Q[local.Length];
            pos = new double[local.Length][];
            for (int i = 0; i < local.Length; i++)
            {
                double[] t = { local[i].Tx, local[i].Ty, local[i].Tz };
                if (parents[i] < 0)
                {
                    rot[i] = Q.Of(local[i]);
                    pos[i] = t;
                    continue;
                }
                int p = parents[i];
                double[] v = rot[p].Rotate(t);
                rot[i] = rot[p] * Q.Of(local[i]);
                pos[i] = new[] { pos[p][0] + v[0], pos[p][1] + v[1], pos[p][2] + v[2] };
            }
        }

        /// <summary>The angle between two rotations, in double (a float dot near 1 would lose it).</summary>
        static double Angle(MocodecTransform a, MocodecTransform b)
        {
            Q p = Q.Of(a), q = Q.Of(b);
            double na = Math.Sqrt(p.X * p.X + p.Y * p.Y + p.Z * p.Z + p.W * p.W);
            double nb = Math.Sqrt(q.X * q.X + q.Y * q.Y + q.Z * q.Z + q.W * q.W);
            double d = Math.Abs(p.X * q.X + p.Y * q.Y + p.Z * q.Z + p.W * q.W) / (na * nb);
            return 2 * Math.Acos(Math.Min(1.0, d));
        }

        static int[] Parents(RigBone[] rig)
        {
            int[] p = new int[rig.Length];
            for (int i = 0; i < rig.Length; i++)
                p[i] = rig[i].Parent;
            return p;
        }

        [Test, TestCaseSource("Assets")]
        public void TheAssetsOwnSkeletonIsPosedExactly(string name)
        {
            using (MocodecAsset asset = MocodecAsset.Load(TestData.Bytes(name)))
            using (MocodecContext context = asset.CreateContext())
            {
                ClipInfo clip = asset.GetClipInfo(0);
                RigBone[] rig = asset.GetSkeletonAsRig(clip.Skeleton);
                using (MocodecRetarget retarget = new MocodecRetarget(asset, clip.Skeleton, rig))
                {
                    Assert.That(retarget.BoneCount, Is.EqualTo(clip.NodeCount));
                    MocodecTransform[] pose = new MocodecTransform[clip.NodeCount];
                    MocodecTransform[] output = new MocodecTransform[clip.NodeCount];
                    for (int k = 0; k <= 6; k++)
                    {
                        context.Sample(0, clip.Duration * k / 6f, pose);
                        retarget.Apply(pose, output);
                        for (int i = 0; i < pose.Length; i++)
                        {
                            Assert.That(Angle(pose[i], output[i]), Is.LessThan(2e-6), name + " node " + i + " rotation");
                            Assert.That(output[i].Tx, Is.EqualTo(pose[i].Tx).Within(2e-6 * (1 + Math.Abs(pose[i].Tx))), name + " node " + i);
                            Assert.That(output[i].Ty, Is.EqualTo(pose[i].Ty).Within(2e-6 * (1 + Math.Abs(pose[i].Ty))), name + " node " + i);
                            Assert.That(output[i].Tz, Is.EqualTo(pose[i].Tz).Within(2e-6 * (1 + Math.Abs(pose[i].Tz))), name + " node " + i);
                            Assert.That(output[i].Sy, Is.EqualTo(pose[i].Sy).Within(2e-6), name + " node " + i + " scale");
                        }
                    }
                }
            }
        }

        /// <summary>A Unity-like rig: left-handed, in metres, every bone with a rest rotation of its
        /// own (the same rest shape as the asset). Played through MocodecPlayback, its joints land
        /// where the asset's world-space sample has them, mirrored and in metres.</summary>
        [Test, TestCaseSource("Assets")]
        public void ALeftHandedRigInMetresWithOtherRestsFollowsTheWorldPose(string name)
        {
            using (MocodecAsset asset = MocodecAsset.Load(TestData.Bytes(name)))
            using (MocodecContext context = asset.CreateContext())
            {
                ClipInfo clip = asset.GetClipInfo(0);
                float metres = MocodecSpace.MetresPerUnit(asset.GetSkeletonInfo(clip.Skeleton));
                RigBone[] own = asset.GetSkeletonAsRig(clip.Skeleton);
                int[] parents = Parents(own);
                MocodecTransform[] rests = new MocodecTransform[own.Length];
                for (int i = 0; i < own.Length; i++)
                    rests[i] = own[i].Rest;
                Q[] restRot;
                double[][] restPos;
                World(rests, parents, out restRot, out restPos);
                // right-handed rig rests in metres with a turn per bone, then mirrored into Unity space
                Random random = new Random(11);
                Q[] rigRot = new Q[own.Length];
                RigBone[] rig = new RigBone[own.Length];
                for (int i = 0; i < own.Length; i++)
                {
                    rigRot[i] = restRot[i] * Q.Axis(random.NextDouble() - 0.5, 1, random.NextDouble(), 0.3 + 2.5 * random.NextDouble());
                    Q local;
                    double[] t;
                    if (parents[i] < 0)
                    {
                        local = rigRot[i];
                        t = restPos[i];
                    }
                    else
                    {
                        int p = parents[i];
                        local = rigRot[p].Conj * rigRot[i];
                        t = rigRot[p].Conj.Rotate(new[] { restPos[i][0] - restPos[p][0], restPos[i][1] - restPos[p][1], restPos[i][2] - restPos[p][2] });
                    }
                    MocodecTransform rest = new MocodecTransform((float)local.X, (float)local.Y, (float)local.Z, (float)local.W,
                                                                 (float)(t[0] * metres), (float)(t[1] * metres), (float)(t[2] * metres));
                    rig[i] = new RigBone("Armature:" + own[i].Name, parents[i], MocodecSpace.MirrorX(rest));
                }
                RetargetSettings settings = RetargetSettings.Default;
                settings.UnitScale = metres;
                using (MocodecPlayback playback = new MocodecPlayback(asset, 0, rig, true, settings))
                {
                    playback.Contacts = false;
                    MocodecTransform[] world = new MocodecTransform[clip.NodeCount];
                    for (int k = 0; k <= 4; k++)
                    {
                        playback.Time = clip.Duration * k / 4f * 0.999f;
                        playback.Evaluate();
                        context.Sample(0, playback.Time, world, SampleFlags.World | SampleFlags.Loop);
                        // compose in Unity space, mirror back, compare in the asset's space
                        MocodecTransform[] unity = (MocodecTransform[])playback.RigPose.Clone();
                        Q[] r;
                        double[][] got;
                        World(unity, parents, out r, out got);
                        double size = 1e-3;
                        foreach (double[] w in restPos)
                            size = Math.Max(size, Math.Abs(w[1]) * metres);
                        for (int i = 0; i < clip.NodeCount; i++)
                        {
                            double[] want = { -world[i].Tx * metres, world[i].Ty * metres, world[i].Tz * metres };
                            double d = Math.Sqrt(Math.Pow(got[i][0] - want[0], 2) + Math.Pow(got[i][1] - want[1], 2) + Math.Pow(got[i][2] - want[2], 2));
                            Assert.That(d, Is.LessThan(1e-5 * Math.Max(size, 1.0)),
                                        name + " t=" + playback.Time + " bone " + rig[i].Name + ": " + d + " m off the world sample");
                        }
                    }
                }
            }
        }

        [Test]
        public void MirroringTwiceIsTheIdentityAndCommutesWithComposition()
        {
            MocodecTransform a = new MocodecTransform(0.1f, 0.7f, -0.2f, 0.6782f, 1, 2, 3);
            MocodecTransform m = MocodecSpace.MirrorX(MocodecSpace.MirrorX(a));
            Assert.That(m.Qx == a.Qx && m.Qy == a.Qy && m.Qz == a.Qz && m.Qw == a.Qw && m.Tx == a.Tx && m.Ty == a.Ty && m.Tz == a.Tz);
            // rotate a point with a, then mirror == mirror the point, rotate with mirrored a
            double[] p = { 0.3, -1.1, 2.0 };
            double[] ra = Q.Of(a).Rotate(p);
            double[] rm = Q.Of(MocodecSpace.MirrorX(a)).Rotate(new[] { -p[0], p[1], p[2] });
            double n = Math.Sqrt(a.Qx * a.Qx + a.Qy * a.Qy + a.Qz * a.Qz + a.Qw * a.Qw);
            Assert.That(rm[0], Is.EqualTo(-ra[0]).Within(1e-5 * n * n));
            Assert.That(rm[1], Is.EqualTo(ra[1]).Within(1e-5 * n * n));
            Assert.That(rm[2], Is.EqualTo(ra[2]).Within(1e-5 * n * n));
        }

        [Test]
        public void PairsAndBadInputAreReportedWithTheBoneOrPair()
        {
            using (MocodecAsset asset = MocodecAsset.Load(TestData.GoldenBytes()))
            {
                RigBone[] rig = asset.GetSkeletonAsRig(0);
                Dictionary<string, string> pairs = new Dictionary<string, string> { { rig[1].Name, rig[2].Name }, { rig[3].Name, null } };
                using (MocodecRetarget r = new MocodecRetarget(asset, 0, rig, pairs, RetargetSettings.Default))
                {
                    Assert.That(r.NodeOf(1), Is.EqualTo(2));
                    Assert.That(r.NodeOf(3), Is.EqualTo(-1));
                    Assert.That(r.NodeOf(4), Is.EqualTo(4));
                }
                RigBone[] broken = (RigBone[])rig.Clone();
                broken[4].Parent = 6;
                MocodecRetargetException e = Assert.Throws<MocodecRetargetException>(() => new MocodecRetarget(asset, 0, broken));
                Assert.That(e.Result, Is.EqualTo(MocodecResult.InvalidArgument));
                Assert.That(e.Issue, Is.EqualTo(RetargetIssue.Bone));
                Assert.That(e.Index, Is.EqualTo(4));
                StringAssert.Contains(rig[4].Name, e.Message);
                e = Assert.Throws<MocodecRetargetException>(() => new MocodecRetarget(asset, 0, rig,
                    new Dictionary<string, string> { { rig[2].Name, "no such node" } }, RetargetSettings.Default));
                Assert.That(e.Result, Is.EqualTo(MocodecResult.NotFound));
                Assert.That(e.Issue, Is.EqualTo(RetargetIssue.Pair));
                RetargetSettings bad = RetargetSettings.Default;
                bad.UnitScale = 0f;
                e = Assert.Throws<MocodecRetargetException>(() => new MocodecRetarget(asset, 0, rig, null, bad));
                Assert.That(e.Issue, Is.EqualTo(RetargetIssue.Settings));
                using (MocodecRetarget r = new MocodecRetarget(asset, 0, rig))
                {
                    Assert.That(r.TryApply(new MocodecTransform[rig.Length - 1], new MocodecTransform[rig.Length]),
                                Is.EqualTo(MocodecResult.InvalidArgument), "a pose of another node count");
                    Assert.That(r.TryApply(new MocodecTransform[rig.Length], new MocodecTransform[rig.Length]),
                                Is.EqualTo(MocodecResult.InvalidArgument), "an all-zero pose has zero rotations");
                }
            }
        }

        [Test]
        public void PlaybackTimeLoopsOrStopsAndEvaluateDoesNotAllocate()
        {
            using (MocodecAsset asset = MocodecAsset.Load(TestData.GoldenBytes()))
            using (MocodecPlayback playback = new MocodecPlayback(asset, 0, asset.GetSkeletonAsRig(asset.GetClipInfo(0).Skeleton), false,
                                                                   RetargetSettings.Default))
            {
                float d = playback.Duration;
                playback.Advance(d * 2.5f);
                Assert.That(playback.Time, Is.EqualTo(d * 0.5f).Within(1e-3f * d));
                playback.Loop = false;
                playback.Advance(d);
                Assert.That(playback.Time, Is.EqualTo(d));
                Assert.That(playback.Playing, Is.False);
                playback.Playing = true;
                playback.Speed = -1f;
                playback.Advance(d * 3f);
                Assert.That(playback.Time, Is.EqualTo(0f));
                Assert.That(playback.Playing, Is.False);

                // Tick: the component's fields in, the new time out, the pose sampled there
                playback.Playing = true;
                float t = playback.Tick(d * 0.25f, 2f, true, true, d * 0.5f);
                Assert.That(t, Is.EqualTo(d * 0.25f).Within(1e-3f * d), "0.25 d + 2 x 0.5 d wraps to 0.25 d");
                MocodecTransform[] atT = (MocodecTransform[])playback.RigPose.Clone();
                playback.Tick(t, 1f, true, true, 0f);
                Assert.That(playback.Time, Is.EqualTo(t));
                Assert.That(playback.RigPose, Is.EqualTo(atT), "a zero step samples the same time again");
                playback.Tick(d * 0.75f, 1f, true, true, 0f);
                Assert.That(playback.RigPose, Is.Not.EqualTo(atT), "another time, another pose");

                MethodInfo m = typeof(GC).GetMethod("GetAllocatedBytesForCurrentThread", BindingFlags.Public | BindingFlags.Static);
                if (m == null)
                    Assert.Ignore("GC.GetAllocatedBytesForCurrentThread is not available on this runtime");
                Func<long> allocated = (Func<long>)Delegate.CreateDelegate(typeof(Func<long>), m);
                playback.Playing = true;
                playback.Loop = true;
                playback.Speed = 1f;
                playback.Evaluate();
                long before = allocated();
                for (int i = 0; i < 1000; i++)
                {
                    playback.Advance(1f / 60f);
                    playback.Evaluate();
                }
                Assert.That(allocated() - before, Is.EqualTo(0), "bytes allocated by 1000 frames");
            }
        }
    }
}
