using System;
using System.Runtime.InteropServices;
using System.Text;

namespace Mocodec
{
    /// <summary>Library-wide calls: version check, validation, result descriptions.</summary>
    public static unsafe class MocodecRuntime
    {
        /// <summary>The runtime version this wrapper was written against (MCD_VERSION_MAJOR/MINOR).
        /// The patch number may differ; major and minor may not, since before 1.0 a minor
        /// version may change the ABI.</summary>
        public const uint ExpectedMajor = 0;
        public const uint ExpectedMinor = 3;

        static volatile bool s_checked;

        /// <summary>The native library's <c>mcd_version()</c>.</summary>
        public static uint NativeVersion
        {
            get { return NativeMethods.Version(); }
        }

        /// <summary>Whether a native version number (major &lt;&lt; 16 | minor &lt;&lt; 8 | patch)
        /// is one this wrapper can call.</summary>
        public static bool IsCompatible(uint nativeVersion)
        {
            return (nativeVersion >> 16) == ExpectedMajor && ((nativeVersion >> 8) & 0xFF) == ExpectedMinor;
        }

        /// <summary>Throws <see cref="MocodecVersionException"/> when the loaded library does not
        /// match, and <see cref="DllNotFoundException"/> when none is found. Cheap after the
        /// first call; every asset load goes through it.</summary>
        public static void EnsureCompatible()
        {
            if (s_checked)
                return;
            uint v = NativeMethods.Version();
            if (!IsCompatible(v))
                throw new MocodecVersionException(v);
            s_checked = true;
        }

        public static string FormatVersion(uint v)
        {
            return (v >> 16) + "." + ((v >> 8) & 0xFF) + "." + (v & 0xFF);
        }

        /// <summary>The runtime's English description of a result code.</summary>
        public static string Describe(MocodecResult result)
        {
            try
            {
                return Utf8(NativeMethods.ResultString((int)result));
            }
            catch (DllNotFoundException)
            {
                return result.ToString();
            }
        }

        /// <summary>Checks asset bytes without opening them; never throws for bad bytes.</summary>
        public static MocodecResult Validate(byte[] data, ValidateFlags flags = ValidateFlags.None)
        {
            if (data == null)
                throw new ArgumentNullException("data");
            EnsureCompatible();
            byte empty = 0;
            fixed (byte* p = data)
                return (MocodecResult)NativeMethods.Validate(NonNull(p, &empty), (UIntPtr)(uint)data.Length, (uint)flags);
        }

        /// <summary>`fixed` gives NULL for an empty array, which the runtime reads as a missing
        /// argument; an empty asset is a truncated one, as in the other bindings.</summary>
        internal static byte* NonNull(byte* p, byte* empty)
        {
            return p != null ? p : empty;
        }

        internal static void Check(int code, string call)
        {
            if (code != 0)
                throw new MocodecException((MocodecResult)code, call);
        }

        /// <summary>A NUL-terminated UTF-8 string from the runtime (names point into the asset).</summary>
        internal static string Utf8(IntPtr p)
        {
            if (p == IntPtr.Zero)
                return null;
            byte* s = (byte*)p;
            int n = 0;
            while (s[n] != 0)
                n++;
            return Encoding.UTF8.GetString(s, n);
        }

        /// <summary>UTF-8 bytes with a terminating NUL, for names passed to the runtime.</summary>
        internal static byte[] Utf8Z(string s)
        {
            byte[] b = new byte[Encoding.UTF8.GetByteCount(s) + 1];
            Encoding.UTF8.GetBytes(s, 0, s.Length, b, 0);
            return b;
        }
    }
}
