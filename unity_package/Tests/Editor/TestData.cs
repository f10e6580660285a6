// Finds the assets and reference poses the tests replay. Written against the NUnit surface that
// 2.6 (mono, here) and 3 (Unity Test Runner) share.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.IO;
using NUnit.Framework;

namespace Mocodec.Tests
{
    /// <summary>One recorded sample: clip, time, flags and the pose the reference runtime gave.</summary>
    public sealed class ReferenceSample
    {
        public int Clip;
        public float Time;
        public SampleFlags Flags;
        public MocodecTransform[] Pose;
    }

    public static class TestData
    {
        // Unity ignores folders ending in '~', so the packaged .mcd files are not imported as
        // assets there; the run here points MOCODEC_TEST_DATA at freshly encoded files.
        const string PackagedDir = "Packages/com.mocodec.runtime/Tests/Data~";

        public static string DataDirectory
        {
            get
            {
                string env = Environment.GetEnvironmentVariable("MOCODEC_TEST_DATA");
                if (!string.IsNullOrEmpty(env))
                    return env;
                string packaged = Path.GetFullPath(PackagedDir);
                return Directory.Exists(packaged) ? packaged : null;
            }
        }

        /// <summary>Names (without extension) of the assets that have reference poses.</summary>
        public static string[] AssetNames
        {
            get
            {
                string dir = DataDirectory;
                List<string> names = new List<string>();
                if (dir != null && Directory.Exists(dir))
                {
                    foreach (string path in Directory.GetFiles(dir, "*.mcd"))
                    {
                        string name = Path.GetFileNameWithoutExtension(path);
                        if (File.Exists(Path.Combine(dir, name + ".poses.txt")))
                            names.Add(name);
                    }
                }
                names.Sort(StringComparer.Ordinal);
                return names.ToArray();
            }
        }

        public static byte[] Bytes(string name)
        {
            return File.ReadAllBytes(Path.Combine(DataDirectory, name + ".mcd"));
        }

        /// <summary>The first golden asset: the bytes the error tests corrupt.</summary>
        public static byte[] GoldenBytes()
        {
            foreach (string name in AssetNames)
                if (name.StartsWith("golden_", StringComparison.Ordinal))
                    return Bytes(name);
            Assert.Fail("no golden_*.mcd in " + DataDirectory);
            return null;
        }

        /// <summary>Parses NAME.poses.txt (format: tests/golden/make_golden.py).</summary>
        public static List<ReferenceSample> Poses(string name)
        {
            List<ReferenceSample> samples = new List<ReferenceSample>();
            List<MocodecTransform> rows = new List<MocodecTransform>();
            ReferenceSample current = null;
            foreach (string line in File.ReadAllLines(Path.Combine(DataDirectory, name + ".poses.txt")))
            {
                string[] f = line.Split(new[] { ' ' }, StringSplitOptions.RemoveEmptyEntries);
                if (f.Length == 0)
                    continue;
                if (f[0] == "sample")
                {
                    Close(current, rows, samples);
                    current = new ReferenceSample
                    {
                        Clip = int.Parse(f[1], CultureInfo.InvariantCulture),
                        Time = float.Parse(f[2], CultureInfo.InvariantCulture),
                        Flags = (SampleFlags)uint.Parse(f[3], CultureInfo.InvariantCulture)
                    };
                    continue;
                }
                Assert.That(f.Length, Is.EqualTo(10), "pose row (qx qy qz qw tx ty tz sx sy sz): " + line);
                MocodecTransform t;
                t.Qx = Parse(f[0]); t.Qy = Parse(f[1]); t.Qz = Parse(f[2]); t.Qw = Parse(f[3]);
                t.Tx = Parse(f[4]); t.Ty = Parse(f[5]); t.Tz = Parse(f[6]);
                t.Sx = Parse(f[7]); t.Sy = Parse(f[8]); t.Sz = Parse(f[9]);
                rows.Add(t);
            }
            Close(current, rows, samples);
            return samples;
        }

        /// <summary>Index of the first component farther than tol from the reference, or -1.</summary>
        public static int FirstMismatch(MocodecTransform[] expected, MocodecTransform[] actual, double tol, out double worst)
        {
            worst = 0;
            int bad = -1;
            for (int i = 0; i < expected.Length; i++)
            {
                double d = MaxDiff(expected[i], actual[i]);
                if (d > worst)
                    worst = d;
                if (d > tol && bad < 0)
                    bad = i;
            }
            return bad;
        }

        static double MaxDiff(MocodecTransform a, MocodecTransform b)
        {
            double d = Math.Abs(a.Qx - b.Qx);
            d = Math.Max(d, Math.Abs(a.Qy - b.Qy));
            d = Math.Max(d, Math.Abs(a.Qz - b.Qz));
            d = Math.Max(d, Math.Abs(a.Qw - b.Qw));
            d = Math.Max(d, Math.Abs(a.Tx - b.Tx));
            d = Math.Max(d, Math.Abs(a.Ty - b.Ty));
            d = Math.Max(d, Math.Abs(a.Tz - b.Tz));
            d = Math.Max(d, Math.Abs(a.Sx - b.Sx));
            d = Math.Max(d, Math.Abs(a.Sy - b.Sy));
            d = Math.Max(d, Math.Abs(a.Sz - b.Sz));
            // NaN compares false everywhere above; make it the worst difference instead.
            return double.IsNaN(d) || HasNaN(a) || HasNaN(b) ? double.PositiveInfinity : d;
        }

        static bool HasNaN(MocodecTransform t)
        {
            return float.IsNaN(t.Qx + t.Qy + t.Qz + t.Qw + t.Tx + t.Ty + t.Tz + t.Sx + t.Sy + t.Sz);
        }

        static float Parse(string s)
        {
            return float.Parse(s, NumberStyles.Float, CultureInfo.InvariantCulture);
        }

        static void Close(ReferenceSample current, List<MocodecTransform> rows, List<ReferenceSample> samples)
        {
            if (current == null)
                return;
            current.Pose = rows.ToArray();
            rows.Clear();
            samples.Add(current);
        }
    }
}
