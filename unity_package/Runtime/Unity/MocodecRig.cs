// Compiled only inside Unity (needs UnityEngine); the math it feeds is the engine-free core.
using System.Collections.Generic;
using UnityEngine;

namespace Mocodec.Unity
{
    /// <summary>
    /// A Transform hierarchy as the rig the runtime retargets onto: every Transform below
    /// <c>root</c> (not the root itself, whose space is the rig space), parents first, with the
    /// local transforms it has now as the rest (bind) pose, in Unity's left-handed metres.
    /// </summary>
    public static class MocodecRig
    {
        public static RigBone[] FromHierarchy(Transform root, List<Transform> bones)
        {
            bones.Clear();
            Dictionary<Transform, int> index = new Dictionary<Transform, int>();
            Queue<Transform> open = new Queue<Transform>();
            for (int i = 0; i < root.childCount; i++)
                open.Enqueue(root.GetChild(i));
            List<RigBone> rig = new List<RigBone>();
            while (open.Count > 0) // breadth first: parents come before children
            {
                Transform t = open.Dequeue();
                int parent;
                if (!index.TryGetValue(t.parent, out parent))
                    parent = -1;
                index[t] = bones.Count;
                bones.Add(t);
                Quaternion q = t.localRotation;
                Vector3 p = t.localPosition, s = t.localScale;
                rig.Add(new RigBone(t.name, parent, new MocodecTransform(q.x, q.y, q.z, q.w, p.x, p.y, p.z, s.x, s.y, s.z)));
                for (int i = 0; i < t.childCount; i++)
                    open.Enqueue(t.GetChild(i));
            }
            return rig.ToArray();
        }

        public static Quaternion Rotation(MocodecTransform t)
        {
            return new Quaternion(t.Qx, t.Qy, t.Qz, t.Qw);
        }

        public static Vector3 Position(MocodecTransform t)
        {
            return new Vector3(t.Tx, t.Ty, t.Tz);
        }

        public static Vector3 Scale(MocodecTransform t)
        {
            return new Vector3(t.Sx, t.Sy, t.Sz);
        }
    }
}
