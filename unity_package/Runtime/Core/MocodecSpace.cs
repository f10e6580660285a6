namespace Mocodec
{
    /// <summary>
    /// Handedness and units, without any engine type: the asset is right-handed (BVH, glTF: Y
    /// up, X right, Z towards the viewer); Unity is left-handed with the same Y up and Z forward,
    /// which is the asset mirrored across its X axis. Mirroring negates X in positions and the Y
    /// and Z parts of a quaternion (a rotation's axis is mirrored and its sense reversed).
    /// Applied twice it is the identity, and it commutes with composing transforms, so a rig
    /// described in Unity space is mirrored once into the runtime's space and its pose mirrored
    /// back.
    /// </summary>
    public static class MocodecSpace
    {
        /// <summary>A transform seen in the space mirrored across X.</summary>
        public static MocodecTransform MirrorX(MocodecTransform t)
        {
            return new MocodecTransform(t.Qx, -t.Qy, -t.Qz, t.Qw, -t.Tx, t.Ty, t.Tz, t.Sx, t.Sy, t.Sz);
        }

        /// <summary>Mirrors the first <paramref name="count"/> transforms in place.</summary>
        public static void MirrorX(MocodecTransform[] poses, int count)
        {
            for (int i = 0; i < count; i++)
            {
                MocodecTransform t = poses[i];
                poses[i].Qy = -t.Qy;
                poses[i].Qz = -t.Qz;
                poses[i].Tx = -t.Tx;
            }
        }

        /// <summary>A copy of the rig with every rest mirrored across X.</summary>
        public static RigBone[] MirrorX(RigBone[] rig)
        {
            RigBone[] mirrored = new RigBone[rig.Length];
            for (int i = 0; i < rig.Length; i++)
            {
                mirrored[i] = rig[i];
                mirrored[i].Rest = MirrorX(rig[i].Rest);
            }
            return mirrored;
        }

        /// <summary>Metres per asset unit (a rig in metres: Unity, Godot).</summary>
        public static float MetresPerUnit(SkeletonInfo skeleton)
        {
            return skeleton.CmPerUnit * 0.01f;
        }
    }
}
