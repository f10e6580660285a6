// Sample of the mocodec package (compiled only inside Unity). Put it on an empty GameObject,
// assign the sample's cmu_09_11_run clip, press Play: it builds a figure of spheres from the
// clip's own skeleton and plays the clip on it with a MocodecPlayer.
using Mocodec;
using Mocodec.Unity;
using UnityEngine;

public sealed class MocodecSampleFigure : MonoBehaviour
{
    public MocodecClip clip;
    [Tooltip("Diameter of a joint's sphere, metres.")]
    public float jointSize = 0.04f;

    void Start()
    {
        if (clip == null)
        {
            Debug.LogWarning("MocodecSampleFigure: assign the sample's cmu_09_11_run clip", this);
            return;
        }
        MocodecAsset asset = clip.Asset;
        int skeleton = asset.GetClipInfo(0).Skeleton;
        float metres = MocodecSpace.MetresPerUnit(asset.GetSkeletonInfo(skeleton));
        // The asset's skeleton as Transforms, at its rest pose in Unity's left-handed metres.
        RigBone[] nodes = asset.GetSkeletonAsRig(skeleton);
        Transform[] made = new Transform[nodes.Length];
        for (int i = 0; i < nodes.Length; i++)
        {
            Transform t = new GameObject(nodes[i].Name).transform;
            t.SetParent(nodes[i].Parent >= 0 ? made[nodes[i].Parent] : transform, false);
            MocodecTransform rest = MocodecSpace.MirrorX(nodes[i].Rest);
            t.localRotation = new Quaternion(rest.Qx, rest.Qy, rest.Qz, rest.Qw);
            t.localPosition = new Vector3(rest.Tx, rest.Ty, rest.Tz) * metres;
            t.localScale = new Vector3(rest.Sx, rest.Sy, rest.Sz);
            GameObject dot = GameObject.CreatePrimitive(PrimitiveType.Sphere);
            Destroy(dot.GetComponent<Collider>());
            dot.name = nodes[i].Name + " (sphere)"; // matches no joint: it just follows its parent
            dot.transform.SetParent(t, false);
            dot.transform.localScale = Vector3.one * jointSize;
            made[i] = t;
        }
        MocodecPlayer player = gameObject.AddComponent<MocodecPlayer>();
        player.clip = clip;
        player.Bind(); // the figure's pose now is the rest it retargets against
        player.Play();
    }
}
