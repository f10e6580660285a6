// Errors of one clip: the decoded world positions (from the wasm runtime) against the original's,
// per joint and frame, in centimetres; the figures follow encoder/mocodec/metrics.py (max, p99
// over every joint-frame sample with linear interpolation as numpy's percentile, mean of the
// per-joint means over frames).

const FLOATS = 10; // mcd_transform: rotation 4, translation 3, scale 3

/** World positions (frames x nodes x 3, file units) of every frame, sampled by `instance`. */
export function decodedPositions(instance, clip) {
  const n = clip.nodeCount;
  const out = new Float32Array(clip.frameCount * n * 3);
  const pose = new Float32Array(n * FLOATS);
  for (let f = 0; f < clip.frameCount; f++) {
    instance.world(clip.index, f / clip.frameRate, {}, pose);
    for (let i = 0; i < n; i++) out.set(pose.subarray(i * FLOATS + 4, i * FLOATS + 7), (f * n + i) * 3);
  }
  return out;
}

/** Positions (nodes x 3) of one sampled world pose. */
export function posePositions(pose, n, out = new Float32Array(n * 3)) {
  for (let i = 0; i < n; i++) out.set(pose.subarray(i * FLOATS + 4, i * FLOATS + 7), i * 3);
  return out;
}

/** The original's positions at a time between frames: linear between the two frames around it. */
export function originalAt(original, frameRate, time, out) {
  const { frames, nodes, positions } = original;
  const x = Math.min(Math.max(time * frameRate, 0), frames - 1);
  const f0 = Math.floor(x), f1 = Math.min(f0 + 1, frames - 1), w = x - f0;
  const a = f0 * nodes * 3, b = f1 * nodes * 3;
  for (let k = 0; k < nodes * 3; k++) out[k] = positions[a + k] * (1 - w) + positions[b + k] * w;
  return out;
}

/** Distance per node between two position arrays, in cm. */
export function nodeErrors(a, b, n, cmPerUnit, out = new Float32Array(n)) {
  for (let i = 0; i < n; i++) {
    const dx = a[i * 3] - b[i * 3], dy = a[i * 3 + 1] - b[i * 3 + 1], dz = a[i * 3 + 2] - b[i * 3 + 2];
    out[i] = Math.hypot(dx, dy, dz) * cmPerUnit;
  }
  return out;
}

/**
 * Errors of a clip at every frame: { perFrame (max over nodes), perFrameMean, perNodeMax,
 * max, p99, mean, worstFrame, worstNode, worstFrames }.
 */
export function clipErrors(decoded, original, clip, cmPerUnit) {
  const n = clip.nodeCount, frames = clip.frameCount;
  const all = new Float64Array(frames * n);
  const perFrame = new Float64Array(frames), perFrameMean = new Float64Array(frames);
  const perNodeMax = new Float64Array(n), perNodeSum = new Float64Array(n);
  let max = -1, worstFrame = 0, worstNode = 0;
  for (let f = 0; f < frames; f++) {
    let fmax = 0, fsum = 0;
    for (let i = 0; i < n; i++) {
      const k = (f * n + i) * 3;
      const e = Math.hypot(decoded[k] - original.positions[k], decoded[k + 1] - original.positions[k + 1],
        decoded[k + 2] - original.positions[k + 2]) * cmPerUnit;
      all[f * n + i] = e;
      fsum += e;
      if (e > fmax) fmax = e;
      if (e > perNodeMax[i]) perNodeMax[i] = e;
      perNodeSum[i] += e;
      if (e > max) { max = e; worstFrame = f; worstNode = i; }
    }
    perFrame[f] = fmax;
    perFrameMean[f] = fsum / n;
  }
  let mean = 0;
  for (let i = 0; i < n; i++) mean += perNodeSum[i] / frames;
  mean /= n;
  return { perFrame, perFrameMean, perNodeMax, max, p99: percentile(all, 99), mean, worstFrame, worstNode,
    worstFrames: worstFrames(perFrame) };
}

/** numpy.percentile's default (linear) on a copy of `values`. */
export function percentile(values, q) {
  const s = Float64Array.from(values).sort();
  if (!s.length) return NaN;
  const x = (q / 100) * (s.length - 1), lo = Math.floor(x), hi = Math.min(lo + 1, s.length - 1);
  return s[lo] + (s[hi] - s[lo]) * (x - lo);
}

/** The frames of largest error, at least `gap` frames apart (peaks, not one peak's shoulders). */
export function worstFrames(perFrame, count = 8, gap = 5) {
  const order = Array.from(perFrame.keys()).sort((a, b) => perFrame[b] - perFrame[a]);
  const picked = [];
  for (const f of order) {
    if (picked.length === count) break;
    if (picked.every((p) => Math.abs(p - f) >= gap)) picked.push(f);
  }
  return picked;
}

/** Bytes of the clip as raw data in the two conventions of the project's figures. */
export function rawBytes(clip, skeleton) {
  const channels = skeleton.nodes.reduce((s, node) => s + node.channels.length, 0);
  return { bvh: channels * clip.frameCount * 4, acl: skeleton.nodeCount * clip.frameCount * 40 };
}
