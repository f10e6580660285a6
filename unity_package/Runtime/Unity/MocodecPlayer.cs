// Compiled only inside Unity (needs UnityEngine); playback, retargeting and the space
// conversion are the engine-free core (MocodecPlayback), tested under mono.
using System.Collections.Generic;
using UnityEngine;

namespace Mocodec.Unity
{
    /// <summary>
    /// Plays one clip of a <see cref="MocodecClip"/> on a character's Transform hierarchy, through
    /// the runtime's retargeting: bones matched to the asset's joints by name (exact, then
    /// ignoring a namespace such as "mixamorig:", case and separators), posed against their own
    /// rest (their local transforms when the player binds) so rigs from FBX or glTF with other
    /// rest orientations and proportions are posed right. Samples once per frame into buffers
    /// allocated at bind time, so playback allocates nothing. Runs in LateUpdate, so it wins over
    /// an Animator on the same hierarchy; to blend with the Animator instead, use
    /// <see cref="MocodecAnimatorDriver"/>.
    /// </summary>
    [AddComponentMenu("Mocodec/Mocodec Player")]
    [DisallowMultipleComponent]
    public sealed class MocodecPlayer : MonoBehaviour
    {
        [Tooltip("The imported .mcd asset.")]
        public MocodecClip clip;

        [Tooltip("Clip name inside the asset; empty plays the first clip.")]
        public string clipName = "";

        [Tooltip("Top of the rig: every Transform below it is a bone (this object when empty). Its local pose at bind time is the rest pose.")]
        public Transform skeletonRoot;

        public bool playOnEnable = true;
        public bool loop = true;
        [Tooltip("Pull feet (and hands) back onto their recorded contacts by IK, for assets encoded with --contacts; no effect on other assets.")]
        public bool contactIK = true;
        [Tooltip("The hips travel across the floor; off: they stay over their rest spot (height still moves).")]
        public bool rootMotion = true;
        [Tooltip("Bones with one child point where the asset's bones point, for rigs whose rest is not the asset's (A-pose against T-pose).")]
        public bool matchBoneDirections = true;
        [Tooltip("Playback rate; negative plays backwards.")]
        public float speed = 1f;
        [Tooltip("Current time in seconds.")]
        public float time;

        MocodecPlayback m_Playback;
        readonly List<Transform> m_Bones = new List<Transform>();
        bool[] m_Driven;

        public bool IsPlaying { get { return m_Playback != null && m_Playback.Playing; } }
        public float Duration { get { return m_Playback != null ? m_Playback.Duration : 0f; } }

        public void Play() { if (m_Playback != null) m_Playback.Playing = true; }
        public void Pause() { if (m_Playback != null) m_Playback.Playing = false; }

        public void Stop()
        {
            Pause();
            time = 0f;
            Evaluate();
        }

        /// <summary>Re-resolves the clip and the rig (after changing <see cref="clip"/>,
        /// <see cref="clipName"/>, the settings or the hierarchy). The bones' current local
        /// transforms become the rest pose.</summary>
        public void Bind()
        {
            Unbind();
            if (clip == null)
                return;
            MocodecAsset asset = clip.Asset;
            int index = string.IsNullOrEmpty(clipName) ? 0 : asset.FindClip(clipName);
            RigBone[] rig = MocodecRig.FromHierarchy(skeletonRoot != null ? skeletonRoot : transform, m_Bones);
            if (rig.Length == 0)
            {
                Debug.LogWarning("MocodecPlayer: " + name + " has no child Transforms to pose", this);
                return;
            }
            RetargetSettings settings = RetargetSettings.Default;
            settings.RootMotion = rootMotion;
            settings.MatchDirections = matchBoneDirections;
            settings.UnitScale = MocodecSpace.MetresPerUnit(asset.GetSkeletonInfo(asset.GetClipInfo(index).Skeleton));
            m_Playback = new MocodecPlayback(asset, index, rig, true, settings);
            m_Driven = new bool[rig.Length];
            int found = 0;
            for (int i = 0; i < rig.Length; i++)
                if (m_Driven[i] = m_Playback.Retarget.NodeOf(i) >= 0)
                    found++;
            if (found == 0)
                Debug.LogWarning("MocodecPlayer: no Transform under " + name + " is named like a joint of " + clip.name, this);
        }

        /// <summary>Samples the clip at <see cref="time"/> and writes the driven bones.</summary>
        public void Evaluate()
        {
            if (m_Playback == null)
                return;
            m_Playback.Tick(time, speed, loop, contactIK, 0f);
            WritePose();
        }

        void WritePose()
        {
            MocodecTransform[] pose = m_Playback.RigPose;
            for (int i = 0; i < m_Bones.Count; i++)
            {
                if (!m_Driven[i])
                    continue;
                m_Bones[i].localRotation = MocodecRig.Rotation(pose[i]);
                m_Bones[i].localPosition = MocodecRig.Position(pose[i]);
                m_Bones[i].localScale = MocodecRig.Scale(pose[i]);
            }
        }

        void OnEnable()
        {
            Bind();
            if (playOnEnable)
                Play();
        }

        void OnDisable()
        {
            Unbind();
        }

        void LateUpdate()
        {
            if (m_Playback == null)
                return;
            time = m_Playback.Tick(time, speed, loop, contactIK, Time.deltaTime);
            WritePose();
        }

        void Unbind()
        {
            if (m_Playback != null)
                m_Playback.Dispose();
            m_Playback = null;
            m_Driven = null;
            m_Bones.Clear();
        }
    }
}
