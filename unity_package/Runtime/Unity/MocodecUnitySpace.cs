// Compiled only inside Unity (needs UnityEngine).
using UnityEngine;

namespace Mocodec.Unity
{
    /// <summary>
    /// From the asset's space (BVH: right-handed, Y up, file units) to Unity's (left-handed, Y up,
    /// metres): mirror the X axis, which negates a quaternion's Y and Z, and scale lengths.
    /// </summary>
    public static class MocodecUnitySpace
    {
        public static Quaternion Rotation(MocodecTransform t)
        {
            return new Quaternion(t.Qx, -t.Qy, -t.Qz, t.Qw);
        }

        public static Vector3 Position(MocodecTransform t, float metresPerUnit)
        {
            return new Vector3(-t.Tx * metresPerUnit, t.Ty * metresPerUnit, t.Tz * metresPerUnit);
        }
    }
}
