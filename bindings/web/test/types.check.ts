// Compiled by `npm run typecheck` (tsc --noEmit): the declarations in src/mocodec.d.ts describe
// the API the README shows. Never run.
import { loadRuntime, MocodecError, TRANSFORM_FLOATS, type ClipInfo } from "../src/mocodec.js";

export async function example(bytes: Uint8Array): Promise<number> {
  const runtime = await loadRuntime();
  const check = runtime.validate(bytes, { skipChecksum: false });
  if (!check.ok) throw new Error(`${check.codeName}: ${check.message}`);
  const asset = runtime.open(bytes);
  const clip: ClipInfo = asset.clip(0);
  const player = asset.createInstance();
  const out = new Float32Array(clip.nodeCount * TRANSFORM_FLOATS);
  player.sample(clip.name, clip.duration / 2, { world: true, loop: true }, out);
  const local: Float32Array = player.local(clip.index, 0);
  const [major] = runtime.version;
  const rig = asset.createRetarget(clip.skeleton, [{ name: "Hips", parent: -1, rest: [0, 0, 0, 1, 0, 0, 0, 1, 1, 1] }],
    { pairs: { Hips: null }, unitScale: 0.01, rootMotion: false });
  const rigPose: Float32Array = rig.apply(local, new Float32Array(rig.boneCount * TRANSFORM_FLOATS));
  player.dispose();
  try {
    asset.clip("missing");
  } catch (e) {
    if (e instanceof MocodecError) return e.code + major + local.length + rigPose.length + rig.nodeOf(0);
  }
  return asset.skeletons[clip.skeleton].nodes[0].restRotation[3] + asset.scratchSize;
}
