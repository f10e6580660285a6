// Compiled only inside Unity (needs UnityEngine).
using System.Collections.Generic;
using UnityEngine;

namespace Mocodec.Unity
{
    /// <summary>
    /// Plays one clip of a <see cref="MocodecClip"/> on a Transform hierarchy whose objects are
    /// named like the asset's joints. Samples once per frame into a buffer allocated at bind
    /// time, so playback allocates nothing. Runs in LateUpdate so it wins over an Animator on the
    /// same hierarchy. Contact IK is whatever the runtime applies in mcd_sample (the codecs that
    /// store contacts rectify them there); the runtime has no switch for it to expose here.
    /// </summary>
    [AddComponentMenu("Mocodec/Mocodec Player")]
    [DisallowMultipleComponent]
    public sealed class MocodecPlayer : MonoBehaviour
    {
        [Tooltip("The imported .mcd asset.")]
        public MocodecClip clip;

        [Tooltip("Clip name inside the asset; empty plays the first clip.")]
        public string clipName = "";

        [Tooltip("Top of the hierarchy searched for joint names; this object when empty.")]
        public Transform skeletonRoot;

        public bool playOnEnable = true;
        public bool loop = true;
        [Tooltip("Pull feet (and hands) back onto their recorded contacts by IK, for assets encoded with --contacts; no effect on other assets.")]
        public bool contactIK = true;
        [Tooltip("Playback rate; negative plays backwards.")]
        public float speed = 1f;
        [Tooltip("Current time in seconds.")]
        public float time;

        [Tooltip("Write joint translations too (bone lengths of the recording). Off: only the root moves, other joints only rotate, for rigs with their own proportions.")]
        public bool writeJointTranslations = true;

        MocodecContext m_Context;
        MocodecTransform[] m_Pose;
        Transform[] m_Targets;
        int m_Clip = -1;
        float m_Duration;
        float m_MetresPerUnit;
        bool m_Playing;

        public bool IsPlaying { get { return m_Playing; } }
        public float Duration { get { return m_Duration; } }

        public void Play() { m_Playing = true; }
        public void Pause() { m_Playing = false; }

        public void Stop()
        {
            m_Playing = false;
            time = 0f;
            Evaluate();
        }

        /// <summary>Re-resolves the clip and the joint-to-Transform mapping (after changing
        /// <see cref="clip"/>, <see cref="clipName"/> or the hierarchy).</summary>
        public void Bind()
        {
            Unbind();
            if (clip == null)
                return;
            MocodecAsset asset = clip.Asset;
            m_Clip = string.IsNullOrEmpty(clipName) ? 0 : asset.FindClip(clipName);
            ClipInfo info = asset.GetClipInfo(m_Clip);
            m_Duration = info.Duration;
            m_MetresPerUnit = asset.GetSkeletonInfo(info.Skeleton).CmPerUnit * 0.01f;
            m_Pose = new MocodecTransform[info.NodeCount];
            m_Targets = new Transform[info.NodeCount];

            Dictionary<string, Transform> byName = new Dictionary<string, Transform>();
            foreach (Transform t in (skeletonRoot != null ? skeletonRoot : transform).GetComponentsInChildren<Transform>(true))
                if (!byName.ContainsKey(t.name))
                    byName.Add(t.name, t);
            string[] names = asset.GetNodeNames(info.Skeleton);
            int found = 0;
            for (int i = 0; i < names.Length; i++)
                if (byName.TryGetValue(names[i], out m_Targets[i]))
                    found++;
            if (found == 0)
                Debug.LogWarning("MocodecPlayer: no Transform under " + name + " is named like a joint of " + clip.name, this);
            m_Context = asset.CreateContext();
        }

        /// <summary>Samples the clip at <see cref="time"/> and writes the pose.</summary>
        public void Evaluate()
        {
            if (m_Context == null)
                return;
            SampleFlags flags = (loop ? SampleFlags.Loop : SampleFlags.None) | (contactIK ? SampleFlags.Contacts : SampleFlags.None);
            m_Context.Sample(m_Clip, time, m_Pose, flags);
            for (int i = 0; i < m_Targets.Length; i++)
            {
                Transform target = m_Targets[i];
                if (target == null)
                    continue;
                target.localRotation = MocodecUnitySpace.Rotation(m_Pose[i]);
                if (i == 0 || writeJointTranslations)
                    target.localPosition = MocodecUnitySpace.Position(m_Pose[i], m_MetresPerUnit);
            }
        }

        void OnEnable()
        {
            Bind();
            if (playOnEnable)
                m_Playing = true;
        }

        void OnDisable()
        {
            Unbind();
        }

        void LateUpdate()
        {
            if (m_Context == null)
                return;
            if (m_Playing)
            {
                time += Time.deltaTime * speed;
                if (!loop && ((speed > 0f && time >= m_Duration) || (speed < 0f && time <= 0f)))
                {
                    time = Mathf.Clamp(time, 0f, m_Duration);
                    m_Playing = false;
                }
                else if (loop)
                {
                    // Keep the number small so float time stays precise in long sessions.
                    time = Mathf.Repeat(time, m_Duration > 0f ? m_Duration : 1f);
                }
            }
            Evaluate();
        }

        void Unbind()
        {
            if (m_Context != null)
                m_Context.Dispose();
            m_Context = null;
            m_Pose = null;
            m_Targets = null;
            m_Clip = -1;
        }
    }
}
