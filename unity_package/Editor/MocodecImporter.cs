// Compiled only inside the Unity editor (needs UnityEditor).
using System.IO;
using Mocodec.Unity;
using UnityEditor.AssetImporters;
using UnityEngine;

namespace Mocodec.Editor
{
    /// <summary>Imports .mcd files as <see cref="MocodecClip"/> assets. The runtime validates the
    /// bytes at import (every byte, checksum included) so a corrupt file is reported in the
    /// console, not at play time, and the clip opens them later without validating again
    /// (<see cref="ValidateFlags.Prevalidated"/>: O(clips) at load).</summary>
    [ScriptedImporter(2, "mcd")] // 2: format 2 (in-place) assets
    public sealed class MocodecImporter : ScriptedImporter
    {
        public override void OnImportAsset(AssetImportContext ctx)
        {
            byte[] bytes = File.ReadAllBytes(ctx.assetPath);
            string error = "";
            MocodecResult result = MocodecRuntime.Validate(bytes);
            if (result != MocodecResult.Ok)
            {
                error = MocodecRuntime.Describe(result) + " (" + result + ")";
                ctx.LogImportError(ctx.assetPath + ": not a valid mocodec asset: " + error);
            }
            MocodecClip clip = ScriptableObject.CreateInstance<MocodecClip>();
            clip.SetImported(bytes, error);
            ctx.AddObjectToAsset("clip", clip);
            ctx.SetMainObject(clip);
        }
    }
}
