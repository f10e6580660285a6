using System;
using System.Collections.Generic;
using System.Globalization;
using System.Text;

namespace Mocodec
{
    /// <summary>What the encoder measured, per clip (the META section's <c>clips[name]</c>).</summary>
    public sealed class ClipMetadata
    {
        public string Name;
        public double MaxErrorCm = double.NaN;
        public double P99ErrorCm = double.NaN;
        public double MeanErrorCm = double.NaN;
        public double HeightCm = double.NaN;
        /// <summary>Every BVH channel of every frame as float32: the raw size of the ratio.</summary>
        public long RawBvhBytes;
    }

    /// <summary>
    /// The encoder's report stored in the asset's optional META section (UTF-8 JSON, see
    /// docs/FORMAT.md): codec, tolerance and per-clip errors, for editors and tools. The runtime
    /// has no call for it (it only bounds-checks the section), so this reads the documented
    /// section table of bytes that <c>mcd_validate</c> has accepted first. Not for the frame loop.
    /// </summary>
    public sealed class MocodecMetadata
    {
        public string Json;
        public string Encoder;
        public string Codec;
        /// <summary>The promised max error; NaN when the encoder promised none (rma-pca).</summary>
        public double ToleranceCm = double.NaN;
        /// <summary>The variance fraction of seed 003's settings (rma-pca); NaN otherwise.</summary>
        public double PcaVariance = double.NaN;

        /// <summary>True when every clip's max error is bounded by <see cref="ToleranceCm"/>.</summary>
        public bool HasTolerancePromise
        {
            get { return !double.IsNaN(ToleranceCm); }
        }
        public readonly List<ClipMetadata> Clips = new List<ClipMetadata>();

        /// <summary>Sum of the clips' raw BVH sizes.</summary>
        public long RawBvhBytes
        {
            get
            {
                long sum = 0;
                foreach (ClipMetadata c in Clips)
                    sum += c.RawBvhBytes;
                return sum;
            }
        }

        /// <summary>The metadata of valid asset bytes, or null when the bytes do not validate or
        /// carry no META section. Throws FormatException when the JSON itself is malformed.</summary>
        public static MocodecMetadata Read(byte[] asset)
        {
            if (MocodecRuntime.Validate(asset, ValidateFlags.SkipChecksum) != MocodecResult.Ok)
                return null;
            string json = FindJson(asset);
            if (json == null)
                return null;
            MocodecMetadata meta = new MocodecMetadata { Json = json };
            Dictionary<string, object> root = new JsonReader(json).ReadValue() as Dictionary<string, object>;
            if (root == null)
                return meta;
            meta.Encoder = root.ContainsKey("encoder") ? root["encoder"] as string : null;
            meta.Codec = root.ContainsKey("codec") ? root["codec"] as string : null;
            Dictionary<string, object> settings = Get(root, "settings");
            if (settings != null)
            {
                meta.ToleranceCm = Number(settings, "tolerance_cm");
                meta.PcaVariance = Number(settings, "pca_variance");
            }
            Dictionary<string, object> clips = Get(root, "clips");
            if (clips != null)
            {
                foreach (KeyValuePair<string, object> kv in clips)
                {
                    Dictionary<string, object> c = kv.Value as Dictionary<string, object>;
                    if (c == null)
                        continue;
                    double raw = Number(c, "raw_bvh_bytes");
                    meta.Clips.Add(new ClipMetadata
                    {
                        Name = kv.Key,
                        MaxErrorCm = Number(c, "max_error_cm"),
                        P99ErrorCm = Number(c, "p99_error_cm"),
                        MeanErrorCm = Number(c, "mean_error_cm"),
                        HeightCm = Number(c, "height_cm"),
                        RawBvhBytes = double.IsNaN(raw) ? 0 : (long)raw
                    });
                }
            }
            return meta;
        }

        static string FindJson(byte[] b)
        {
            // Header: section_count at 24; table of 16-byte entries from 32: kind, version, offset, size.
            uint count = U32(b, 24);
            for (uint i = 0; i < count; i++)
            {
                long e = 32 + 16L * i;
                if (e + 16 > b.Length)
                    return null;
                if (b[e] == 'M' && b[e + 1] == 'E' && b[e + 2] == 'T' && b[e + 3] == 'A')
                {
                    long offset = U32(b, (int)e + 8), size = U32(b, (int)e + 12);
                    if (offset + size > b.Length)
                        return null;
                    return Encoding.UTF8.GetString(b, (int)offset, (int)size);
                }
            }
            return null;
        }

        static uint U32(byte[] b, int at)
        {
            return (uint)(b[at] | b[at + 1] << 8 | b[at + 2] << 16 | b[at + 3] << 24);
        }

        static Dictionary<string, object> Get(Dictionary<string, object> d, string key)
        {
            object v;
            return d.TryGetValue(key, out v) ? v as Dictionary<string, object> : null;
        }

        static double Number(Dictionary<string, object> d, string key)
        {
            object v;
            return d.TryGetValue(key, out v) && v is double ? (double)v : double.NaN;
        }

        /// <summary>A small strict JSON reader: objects, arrays, strings, numbers, literals.</summary>
        sealed class JsonReader
        {
            readonly string _s;
            int _i;

            public JsonReader(string s)
            {
                _s = s;
            }

            public object ReadValue()
            {
                SkipSpace();
                if (_i >= _s.Length)
                    throw Error("end of text");
                char c = _s[_i];
                if (c == '{')
                    return ReadObject();
                if (c == '[')
                    return ReadArray();
                if (c == '"')
                    return ReadString();
                if (Literal("true"))
                    return true;
                if (Literal("false"))
                    return false;
                if (Literal("null"))
                    return null;
                return ReadNumber();
            }

            Dictionary<string, object> ReadObject()
            {
                Dictionary<string, object> d = new Dictionary<string, object>();
                _i++;
                SkipSpace();
                if (Peek('}'))
                    return d;
                while (true)
                {
                    SkipSpace();
                    string key = ReadString();
                    SkipSpace();
                    Expect(':');
                    d[key] = ReadValue();
                    SkipSpace();
                    if (Peek('}'))
                        return d;
                    Expect(',');
                }
            }

            List<object> ReadArray()
            {
                List<object> a = new List<object>();
                _i++;
                SkipSpace();
                if (Peek(']'))
                    return a;
                while (true)
                {
                    a.Add(ReadValue());
                    SkipSpace();
                    if (Peek(']'))
                        return a;
                    Expect(',');
                }
            }

            string ReadString()
            {
                Expect('"');
                StringBuilder sb = new StringBuilder();
                while (_i < _s.Length)
                {
                    char c = _s[_i++];
                    if (c == '"')
                        return sb.ToString();
                    if (c != '\\')
                    {
                        sb.Append(c);
                        continue;
                    }
                    if (_i >= _s.Length)
                        break;
                    char e = _s[_i++];
                    switch (e)
                    {
                        case 'n': sb.Append('\n'); break;
                        case 't': sb.Append('\t'); break;
                        case 'r': sb.Append('\r'); break;
                        case 'b': sb.Append('\b'); break;
                        case 'f': sb.Append('\f'); break;
                        case 'u':
                            if (_i + 4 > _s.Length)
                                throw Error("short \\u escape");
                            sb.Append((char)int.Parse(_s.Substring(_i, 4), NumberStyles.HexNumber, CultureInfo.InvariantCulture));
                            _i += 4;
                            break;
                        default: sb.Append(e); break;
                    }
                }
                throw Error("unterminated string");
            }

            double ReadNumber()
            {
                int start = _i;
                while (_i < _s.Length && "+-0123456789.eE".IndexOf(_s[_i]) >= 0)
                    _i++;
                double v;
                if (!double.TryParse(_s.Substring(start, _i - start), NumberStyles.Float, CultureInfo.InvariantCulture, out v))
                    throw Error("bad number");
                return v;
            }

            bool Literal(string word)
            {
                if (string.CompareOrdinal(_s, _i, word, 0, word.Length) != 0)
                    return false;
                _i += word.Length;
                return true;
            }

            bool Peek(char c)
            {
                if (_i < _s.Length && _s[_i] == c)
                {
                    _i++;
                    return true;
                }
                return false;
            }

            void Expect(char c)
            {
                if (!Peek(c))
                    throw Error("expected '" + c + "'");
            }

            void SkipSpace()
            {
                while (_i < _s.Length && char.IsWhiteSpace(_s[_i]))
                    _i++;
            }

            FormatException Error(string what)
            {
                return new FormatException("META JSON: " + what + " at " + _i);
            }
        }
    }
}
