// Compiled only inside Unity (needs UnityEngine.Playables); not compiled or run on the test
// machine. Sampling and retargeting are the engine-free core (MocodecPlayback), tested under mono.
using System.Collections.Generic;
using Unity.Collections;
using UnityEngine;
using UnityEngine.Animations;
using UnityEngine.Playables;

namespace Mocodec.Unity
{
    /// <summary>
    /// Plays a <see cref="MocodecClip"/> through the Animator: a PlayableGraph whose
    /// AnimationScriptPlayable (<see cref="MocodecPoseJob"/>) takes the Animator's own controller
    /// as its input and lays the clip over it by <see cref="weight"/>, so a mocodec clip blends
    /// with the state machine (weight 0: the controller alone, 1: the clip on every bone it
    /// drives; bones it does not drive keep the controller's pose). The clip is sampled and
    /// retargeted on the main thread in Update (before the Animator evaluates); the job only
    /// writes the stream. Bones are matched and posed as <see cref="MocodecPlayer"/> does:
    /// their local transforms at enable time are the rest pose. Generic rigs; on a Humanoid
    /// Animator the stream's transforms are written after the muscle pass.
    /// </summary>
    [AddComponentMenu("Mocodec/Mocodec Animator Driver")]
    [RequireComponent(typeof(Animator))]
    [DisallowMultipleComponent]
    public sealed class MocodecAnimatorDriver : MonoBehaviour
    {
        public MocodecClip clip;
        [Tooltip("Clip name inside the asset; empty plays the first clip.")]
        public string clipName = "";
        [Range(0f, 1f), Tooltip("0: the Animator controller's pose; 1: the mocodec clip on the bones it drives.")]
        public float weight = 1f;
        public bool loop = true;
        public bool contactIK = true;
        public bool rootMotion = true;
        public bool matchBoneDirections = true;
        public float speed = 1f;
        public float time;

        PlayableGraph m_Graph;
        AnimationScriptPlayable m_Script;
        MocodecPlayback m_Playback;
        NativeArray<TransformStreamHandle> m_Handles;
        NativeArray<float> m_Pose;
        int[] m_RigIndex; // handle -> rig bone

        public bool IsPlaying { get { return m_Playback != null && m_Playback.Playing; } }
        public float Duration { get { return m_Playback != null ? m_Playback.Duration : 0f; } }
        /// <summary>The graph, for a caller who wants to add to it (valid while enabled).</summary>
        public PlayableGraph Graph { get { return m_Graph; } }

        public void Play() { if (m_Playback != null) m_Playback.Playing = true; }
        public void Pause() { if (m_Playback != null) m_Playback.Playing = false; }

        void OnEnable()
        {
            if (clip == null)
                return;
            Animator animator = GetComponent<Animator>();
            MocodecAsset asset = clip.Asset;
            int index = string.IsNullOrEmpty(clipName) ? 0 : asset.FindClip(clipName);
            List<Transform> bones = new List<Transform>();
            RigBone[] rig = MocodecRig.FromHierarchy(transform, bones);
            RetargetSettings settings = RetargetSettings.Default;
            settings.RootMotion = rootMotion;
            settings.MatchDirections = matchBoneDirections;
            settings.UnitScale = MocodecSpace.MetresPerUnit(asset.GetSkeletonInfo(asset.GetClipInfo(index).Skeleton));
            m_Playback = new MocodecPlayback(asset, index, rig, true, settings);

            List<int> driven = new List<int>();
            for (int i = 0; i < rig.Length; i++)
                if (m_Playback.Retarget.NodeOf(i) >= 0)
                    driven.Add(i);
            if (driven.Count == 0)
                Debug.LogWarning("MocodecAnimatorDriver: no Transform under " + name + " is named like a joint of " + clip.name, this);
            m_RigIndex = driven.ToArray();
            m_Handles = new NativeArray<TransformStreamHandle>(m_RigIndex.Length, Allocator.Persistent);
            m_Pose = new NativeArray<float>(m_RigIndex.Length * 10, Allocator.Persistent);
            for (int i = 0; i < m_RigIndex.Length; i++)
                m_Handles[i] = animator.BindStreamTransform(bones[m_RigIndex[i]]);

            m_Graph = PlayableGraph.Create(name + " (mocodec)");
            m_Graph.SetTimeUpdateMode(DirectorUpdateMode.GameTime);
            MocodecPoseJob job = new MocodecPoseJob { handles = m_Handles, pose = m_Pose, weight = 0f };
            RuntimeAnimatorController controller = animator.runtimeAnimatorController;
            m_Script = AnimationScriptPlayable.Create(m_Graph, job, controller != null ? 1 : 0);
            if (controller != null)
            {
                AnimatorControllerPlayable input = AnimatorControllerPlayable.Create(m_Graph, controller);
                m_Graph.Connect(input, 0, m_Script, 0);
                m_Script.SetInputWeight(0, 1f);
            }
            AnimationPlayableOutput output = AnimationPlayableOutput.Create(m_Graph, "mocodec", animator);
            output.SetSourcePlayable(m_Script);
            m_Playback.Tick(time, speed, loop, contactIK, 0f);
            WriteJob();
            m_Graph.Play();
        }

        void Update()
        {
            if (m_Playback == null)
                return;
            time = m_Playback.Tick(time, speed, loop, contactIK, Time.deltaTime);
            WriteJob();
        }

        // The pose sampled on the main thread, into the job's arrays, and the weight.
        void WriteJob()
        {
            MocodecTransform[] pose = m_Playback.RigPose;
            for (int i = 0; i < m_RigIndex.Length; i++)
            {
                MocodecTransform t = pose[m_RigIndex[i]];
                int o = i * 10;
                m_Pose[o] = t.Qx; m_Pose[o + 1] = t.Qy; m_Pose[o + 2] = t.Qz; m_Pose[o + 3] = t.Qw;
                m_Pose[o + 4] = t.Tx; m_Pose[o + 5] = t.Ty; m_Pose[o + 6] = t.Tz;
                m_Pose[o + 7] = t.Sx; m_Pose[o + 8] = t.Sy; m_Pose[o + 9] = t.Sz;
            }
            MocodecPoseJob job = m_Script.GetJobData<MocodecPoseJob>();
            job.weight = weight;
            m_Script.SetJobData(job);
        }

        void OnDisable()
        {
            if (m_Graph.IsValid())
                m_Graph.Destroy();
            if (m_Handles.IsCreated)
                m_Handles.Dispose();
            if (m_Pose.IsCreated)
                m_Pose.Dispose();
            if (m_Playback != null)
                m_Playback.Dispose();
            m_Playback = null;
            m_RigIndex = null;
        }
    }
}
