// Microseconds per sampled pose through the wasm runtime under node: bench/pose_speed.c's loop
// (same modes, same times, same statistics), twice: through the web binding (Instance.sample
// into a Float32Array, what a page pays) and calling the wasm export mcd_sample directly (the
// runtime alone). For bench/wasm_speed.py.
//
//   node bench/pose_speed.mjs ASSET.mcd RUNS WASM   -> one JSON object on stdout
import { readFileSync } from "node:fs";
import { loadRuntime } from "../bindings/web/src/mocodec.js";

const [, , assetPath, runsText = "15", wasmPath] = process.argv;
const runs = Number(runsText);
const runtime = await loadRuntime(readFileSync(wasmPath));
const bytes = new Uint8Array(readFileSync(assetPath));
const asset = runtime.open(bytes);
const player = asset.createInstance();

// xorshift64*, top 53 bits as a double in [0, 1): the C side's sequence.
let seed = 0x9E3779B97F4A7C15n;
const M64 = (1n << 64n) - 1n;
function uniform() {
  seed ^= seed >> 12n; seed = (seed ^ (seed << 25n)) & M64; seed ^= seed >> 27n;
  return Number(((seed * 2685821657736338717n) & M64) >> 11n) / 9007199254740992;
}

const clips = [], seq = [], rnd = [];
for (const c of asset.clips) {
  for (let i = 0; i < c.frameCount; i++) {
    clips.push(c.index);
    seq.push(Math.fround(Math.fround(i) / c.frameRate));
    rnd.push(Math.fround(uniform() * c.duration));
  }
}
const total = clips.length;
const out = new Float32Array(Math.max(...asset.skeletons.map((s) => s.nodeCount)) * 10);

// The runtime alone: the binding's own struct and slot pointers (private, read here on purpose).
const exp = asset._mem.exports, struct = asset._struct, slot = player._slot;
const nodeCounts = asset.clips.map((c) => c.nodeCount);

const through = {
  binding(k, t, world) { player.sample(clips[k], t, world ? WORLD : LOCAL, out); },
  direct(k, t, world) {
    if (exp.mcd_sample(struct, clips[k], t, world ? 1 : 0, slot.pose, nodeCounts[clips[k]], slot.scratch) !== 0) {
      throw new Error("sample failed");
    }
  },
};
const WORLD = { world: true }, LOCAL = {};

const WARMUP_MS = 500; // pose_speed.c's WARMUP_US: V8 moves the hot wasm to TurboFan meanwhile

function time(call, times, world) {
  const per = [];
  const warmUntil = performance.now() + WARMUP_MS;
  for (let r = -1; r < runs; r++) {
    const t0 = performance.now();
    for (let k = 0; k < total; k++) call(k, times[k], world);
    if (r >= 0) per.push(((performance.now() - t0) * 1000) / total);
    else if (performance.now() < warmUntil) r--; // still warming up
  }
  per.sort((a, b) => a - b);
  return { median: per[Math.floor(runs / 2)], min: per[0], max: per[runs - 1] };
}

const result = { asset_bytes: bytes.length, scratch_bytes: asset.scratchSize, clips: asset.clips.length,
  poses_per_pass: total, runs, node: process.version };
for (const [name, call] of Object.entries(through)) {
  result[name] = {
    local_sequential: time(call, seq, false), local_random: time(call, rnd, false),
    world_sequential: time(call, seq, true), world_random: time(call, rnd, true),
  };
}
console.log(JSON.stringify(result));
