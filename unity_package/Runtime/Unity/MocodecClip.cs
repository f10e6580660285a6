// Compiled only inside Unity (needs UnityEngine); the code it calls is the engine-free core.
using System.Runtime.CompilerServices;
using UnityEngine;

[assembly: InternalsVisibleTo("Mocodec.Editor")]

namespace Mocodec.Unity
{
    /// <summary>
    /// A .mcd asset as imported by the editor: its bytes, plus the validation error if the
    /// importer rejected them. Opens the bytes once, on first use, and shares the opened asset
    /// between every player that uses this clip (each player has its own sampling context).
    /// </summary>
    [PreferBinarySerialization]
    public sealed class MocodecClip : ScriptableObject
    {
        [SerializeField, HideInInspector] byte[] m_Bytes = new byte[0];
        [SerializeField] string m_ImportError = "";

        MocodecAsset m_Asset;

        /// <summary>The .mcd bytes.</summary>
        public byte[] Bytes { get { return m_Bytes; } }

        /// <summary>Empty when the runtime accepted the bytes at import.</summary>
        public string ImportError { get { return m_ImportError; } }

        /// <summary>The opened asset; throws MocodecException when the bytes are invalid.</summary>
        public MocodecAsset Asset
        {
            get
            {
                if (m_Asset == null || m_Asset.IsDisposed)
                    // the importer validated these very bytes; a rejected file is validated (and refused) again
                    m_Asset = MocodecAsset.Load(m_Bytes, m_ImportError.Length == 0 ? ValidateFlags.Prevalidated : ValidateFlags.None);
                return m_Asset;
            }
        }

        internal void SetImported(byte[] bytes, string importError)
        {
            m_Bytes = bytes ?? new byte[0];
            m_ImportError = importError ?? "";
            ReleaseAsset();
        }

        void OnDisable()
        {
            ReleaseAsset();
        }

        void ReleaseAsset()
        {
            if (m_Asset != null)
                m_Asset.Dispose();
            m_Asset = null;
        }
    }
}
