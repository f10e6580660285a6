// The wasm32 (ILP32) layout of the structs in runtime_c/include/mocodec.h, and its constants. The
// tests read every field back against the native runtime (through the Python binding), so a
// change of the header that is not mirrored here fails them.

export const ABI = Object.freeze({
  transform: { size: 40, floats: 10 }, // rotation[4], translation[3], scale[3]
  asset: { size: 120 },                // opaque to JavaScript: only its size matters
  clipInfo: {
    size: 40, name: 0, skeleton: 4, codec: 8, frameCount: 12, frameRate: 16, duration: 20,
    nodeCount: 24, scratchSize: 28, dataOffset: 32, dataSize: 36,
  },
  skeletonInfo: { size: 8, nodeCount: 0, cmPerUnit: 4 },
  nodeInfo: {
    size: 64, name: 0, parent: 4, kind: 8, restTranslation: 12, restRotation: 24, restScale: 40,
    channelCount: 52, channels: 56,
  },
  // retargeting (mcd_retarget_*): mcd_rig_bone, mcd_retarget_pair, _config, _issue, _info
  rigBone: { size: 52, name: 0, parent: 4, flags: 8, rest: 12 },
  retargetPair: { size: 8, bone: 0, node: 4 },
  retargetConfig: { size: 28, flags: 0, upAxis: 4, unitScale: 8, spaceRotation: 12 },
  retargetIssue: { size: 8, where: 0, index: 4 },
  retargetInfo: { size: 16, boneCount: 0, nodeCount: 4, matched: 8, workSize: 12 },
});

export const RIG_BONE_KEEP_TRANSLATION = 0x1;
export const RETARGET_FLAGS = Object.freeze({ rootMotion: 0x1, matchDirections: 0x2 });
export const RETARGET_ISSUES = Object.freeze(["none", "bone", "pair", "config"]);

export const SAMPLE_FLAGS = Object.freeze({ world: 0x1, loop: 0x2, nearest: 0x4, contacts: 0x8 });

export const NODE_KINDS = Object.freeze({ joint: 0, endSite: 1, virtual: 2 });

// mcd_result, by value (the values never change: mocodec.h).
export const RESULT_NAMES = Object.freeze([
  "MCD_OK", "MCD_ERROR_INVALID_ARGUMENT", "MCD_ERROR_TRUNCATED", "MCD_ERROR_BAD_MAGIC",
  "MCD_ERROR_VERSION_TOO_NEW", "MCD_ERROR_VERSION_TOO_OLD", "MCD_ERROR_CHECKSUM", "MCD_ERROR_MALFORMED",
  "MCD_ERROR_UNSUPPORTED", "MCD_ERROR_BUFFER_TOO_SMALL", "MCD_ERROR_OUT_OF_RANGE",
  "MCD_ERROR_SCRATCH_MISMATCH", "MCD_ERROR_TRAILING_DATA", "MCD_ERROR_NOT_FOUND",
]);
