// Compiled only inside the Unity editor (needs UnityEditor).
using System;
using Mocodec.Unity;
using UnityEditor;
using UnityEngine;

namespace Mocodec.Editor
{
    /// <summary>Inspector of an imported .mcd: its clips, durations, size, compression ratio and
    /// the errors the encoder measured (from the asset's META section).</summary>
    [CustomEditor(typeof(MocodecClip))]
    public sealed class MocodecClipEditor : UnityEditor.Editor
    {
        ClipInfo[] m_Clips = new ClipInfo[0];
        MocodecMetadata m_Meta;
        string m_Problem;

        void OnEnable()
        {
            MocodecClip clip = (MocodecClip)target;
            m_Problem = clip.ImportError;
            if (!string.IsNullOrEmpty(m_Problem))
                return;
            try
            {
                // A private asset, not the clip's shared one, so the inspector never disposes
                // what a playing component uses.
                using (MocodecAsset asset = MocodecAsset.Load(clip.Bytes))
                {
                    m_Clips = new ClipInfo[asset.ClipCount];
                    for (int i = 0; i < m_Clips.Length; i++)
                        m_Clips[i] = asset.GetClipInfo(i);
                }
                m_Meta = MocodecMetadata.Read(clip.Bytes);
            }
            catch (Exception e)
            {
                m_Problem = e.Message;
            }
        }

        public override void OnInspectorGUI()
        {
            MocodecClip clip = (MocodecClip)target;
            if (!string.IsNullOrEmpty(m_Problem))
            {
                EditorGUILayout.HelpBox(m_Problem, MessageType.Error);
                return;
            }
            EditorGUILayout.LabelField("Size", EditorUtility.FormatBytes(clip.Bytes.Length));
            if (m_Meta != null)
            {
                if (m_Meta.RawBvhBytes > 0)
                    EditorGUILayout.LabelField("Ratio", (m_Meta.RawBvhBytes / (double)clip.Bytes.Length).ToString("0.0") + " : 1 (raw BVH channels as float32)");
                EditorGUILayout.LabelField("Codec", m_Meta.Codec ?? "?");
                EditorGUILayout.LabelField("Tolerance", m_Meta.HasTolerancePromise
                    ? Cm(m_Meta.ToleranceCm)
                    : "none promised (PCA variance " + m_Meta.PcaVariance.ToString("0.###") + ")");
                EditorGUILayout.LabelField("Encoder", m_Meta.Encoder ?? "?");
            }
            else
            {
                EditorGUILayout.HelpBox("No encoder report (META section) in this asset.", MessageType.Info);
            }
            EditorGUILayout.Space();
            EditorGUILayout.LabelField("Clips", m_Clips.Length.ToString(), EditorStyles.boldLabel);
            foreach (ClipInfo c in m_Clips)
            {
                ClipMetadata report = m_Meta != null ? m_Meta.Clips.Find(x => x.Name == c.Name) : null;
                string errors = report != null
                    ? "max error " + Cm(report.MaxErrorCm) + ", mean " + Cm(report.MeanErrorCm)
                    : "no encoder report";
                EditorGUILayout.LabelField(c.Name, string.Format("{0:0.00} s, {1} frames at {2:0.#} fps, {3} joints, {4}; {5}",
                    c.Duration, c.FrameCount, c.FrameRate, c.NodeCount, c.Codec, errors));
            }
        }

        static string Cm(double v)
        {
            return double.IsNaN(v) ? "?" : v.ToString("0.###") + " cm";
        }
    }
}
