using System;

namespace Mocodec
{
    /// <summary>A runtime call returned a result other than <see cref="MocodecResult.Ok"/>.</summary>
    public class MocodecException : Exception
    {
        public MocodecResult Result { get; private set; }

        public MocodecException(MocodecResult result, string call)
            : base(call + ": " + MocodecRuntime.Describe(result) + " (" + result + ")")
        {
            Result = result;
        }
    }

    /// <summary>The native library's version is not the one this wrapper was written for.</summary>
    public class MocodecVersionException : Exception
    {
        public uint NativeVersion { get; private set; }

        public MocodecVersionException(uint nativeVersion)
            : base("native mocodec library is version " + MocodecRuntime.FormatVersion(nativeVersion) +
                   ", this wrapper needs " + MocodecRuntime.ExpectedMajor + "." + MocodecRuntime.ExpectedMinor + ".x")
        {
            NativeVersion = nativeVersion;
        }
    }
}
