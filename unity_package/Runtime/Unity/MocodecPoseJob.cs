// Compiled only inside Unity (needs UnityEngine.Animations); not compiled or run on the test machine.
using Unity.Collections;
using UnityEngine;
using UnityEngine.Animations;

namespace Mocodec.Unity
{
    /// <summary>
    /// The animation job of <see cref="MocodecAnimatorDriver"/>: writes a retargeted pose (sampled
    /// on the main thread, 10 floats per bone: rotation xyzw, position, scale, Unity space) over
    /// the stream its input produced (the Animator controller), blended by <see cref="weight"/>.
    /// Holds only native containers, as animation jobs must; it never calls the runtime.
    /// </summary>
    public struct MocodecPoseJob : IAnimationJob
    {
        public NativeArray<TransformStreamHandle> handles;
        [ReadOnly] public NativeArray<float> pose;
        public float weight;

        public void ProcessRootMotion(AnimationStream stream)
        {
        }

        public void ProcessAnimation(AnimationStream stream)
        {
            float w = Mathf.Clamp01(weight);
            if (w <= 0f)
                return; // the input's pose, untouched
            for (int i = 0; i < handles.Length; i++)
            {
                TransformStreamHandle h = handles[i];
                int o = i * 10;
                Quaternion q = new Quaternion(pose[o], pose[o + 1], pose[o + 2], pose[o + 3]);
                Vector3 p = new Vector3(pose[o + 4], pose[o + 5], pose[o + 6]);
                Vector3 s = new Vector3(pose[o + 7], pose[o + 8], pose[o + 9]);
                if (w < 1f)
                {
                    q = Quaternion.Slerp(h.GetLocalRotation(stream), q, w);
                    p = Vector3.Lerp(h.GetLocalPosition(stream), p, w);
                    s = Vector3.Lerp(h.GetLocalScale(stream), s, w);
                }
                h.SetLocalRotation(stream, q);
                h.SetLocalPosition(stream, p);
                h.SetLocalScale(stream, s);
            }
        }
    }
}
