// Per-pose cost of sampling through the C# binding (MocodecContext.Sample into a reused array),
// the same loop as bench_c.c: 60 Hz forward playback, looping, best of five rounds.
using System;
using System.Diagnostics;
using System.IO;
using Mocodec;

static class Bench
{
    static int Main(string[] args)
    {
        byte[] bytes = File.ReadAllBytes(args[0]);
        long n = long.Parse(args[1]);
        using (MocodecAsset asset = MocodecAsset.Load(bytes))
        using (MocodecContext context = asset.CreateContext())
        {
            ClipInfo clip = asset.GetClipInfo(0);
            MocodecTransform[] pose = new MocodecTransform[clip.NodeCount];
            double best = double.MaxValue, sink = 0;
            for (int round = 0; round < 5; round++)
            {
                Stopwatch watch = Stopwatch.StartNew();
                for (long i = 0; i < n; i++)
                {
                    context.Sample(0, i / 60f, pose, SampleFlags.Loop);
                    sink += pose[3].Qx;
                }
                double us = watch.Elapsed.TotalMilliseconds * 1000.0 / n;
                best = Math.Min(best, us);
            }
            Console.WriteLine("csharp " + clip.NodeCount + " " + best.ToString("0.0000", System.Globalization.CultureInfo.InvariantCulture) + " " + sink);
        }
        return 0;
    }
}
