// The web binding against the native runtime. Run by bindings/web/run_tests.sh (which makes the
// fixtures with the encoder and the native C runtime); `npm test` alone runs the tests that need
// no fixture and skips the others loudly.
import { test } from "node:test";
import assert from "node:assert/strict";
import { readFileSync, readdirSync, existsSync } from "node:fs";
import { join } from "node:path";

import { loadRuntime, MocodecError, RESULT_NAMES, TRANSFORM_FLOATS } from "../src/mocodec.js";

const FIXTURES = process.env.MOCODEC_WEB_FIXTURES;
const POSE_TOLERANCE = 1e-5;
const pkg = JSON.parse(readFileSync(new URL("../package.json", import.meta.url)));

const runtime = await loadRuntime();

function fixtures() {
  if (!FIXTURES || !existsSync(FIXTURES)) return [];
  return readdirSync(FIXTURES).filter((f) => f.endsWith(".mcd")).sort().map((f) => {
    const codec = f.slice(0, -4);
    return { codec, bytes: new Uint8Array(readFileSync(join(FIXTURES, f))),
      native: JSON.parse(readFileSync(join(FIXTURES, `${codec}.json`), "utf8")) };
  });
}
const cases = fixtures();
if (!cases.length) {
  console.log(`!! SKIPPING the comparisons with the native runtime: MOCODEC_WEB_FIXTURES=${FIXTURES ?? "(unset)"} ` +
    "holds no fixtures (bindings/web/run_tests.sh makes them)");
} else {
  const skipped = JSON.parse(readFileSync(join(FIXTURES, "skipped.json"), "utf8"));
  for (const [codec, why] of Object.entries(skipped)) console.log(`!! codec ${codec} not compared: ${why}`);
}

test("the wasm imports nothing and is the runtime version of this package", () => {
  assert.deepEqual(WebAssembly.Module.imports(runtime.module), []);
  assert.deepEqual(runtime.version.slice(0, 2), pkg.version.split(".").map(Number).slice(0, 2));
});

test("bytes that are no asset: a clear error, never a crash", () => {
  const junk = new Uint8Array(256).map((_, i) => (i * 37) & 0xff);
  const v = runtime.validate(junk);
  assert.equal(v.ok, false);
  assert.equal(v.codeName, "MCD_ERROR_BAD_MAGIC");
  assert.match(v.message, /magic/);
  assert.throws(() => runtime.open(junk), (e) => e instanceof MocodecError && e.code === 3 && /mcd_open: .*magic/.test(e.message));
  assert.throws(() => runtime.open(new Uint8Array(0)), (e) => e instanceof MocodecError && e.code !== 0);
  assert.throws(() => runtime.open("not bytes"), TypeError);
  assert.equal(RESULT_NAMES[6], "MCD_ERROR_CHECKSUM");
});

for (const { codec, bytes, native } of cases) {
  test(`${codec}: clips, skeletons and nodes as the native runtime reads them`, () => {
    const asset = runtime.open(bytes);
    assert.equal(asset.size, native.size);
    assert.equal(asset.scratchSize, native.scratchSize);
    assert.equal(asset.clips.length, native.clips.length);
    native.clips.forEach((c, i) => {
      const mine = asset.clips[i];
      for (const key of Object.keys(c)) {
        if (typeof c[key] === "number" && !Number.isInteger(c[key])) assert.equal(Math.fround(mine[key]), Math.fround(c[key]), key);
        else assert.equal(mine[key], c[key], `clip ${i} ${key}`);
      }
      assert.equal(asset.clip(c.name), mine);
    });
    native.skeletons.forEach((s, i) => {
      const mine = asset.skeletons[i];
      assert.equal(mine.nodeCount, s.nodeCount);
      assert.equal(Math.fround(mine.cmPerUnit), Math.fround(s.cmPerUnit));
      assert.deepEqual(mine.nodes.map((n) => ({ ...n })), s.nodes);
    });
  });

  test(`${codec}: poses equal the native runtime's within ${POSE_TOLERANCE}`, () => {
    const asset = runtime.open(bytes);
    const player = asset.createInstance();
    let worst = 0;
    for (const p of native.poses) {
      const options = { world: !!(p.flags & 1), loop: !!(p.flags & 2), nearest: !!(p.flags & 4) };
      const pose = player.sample(p.clip, p.time, options);
      assert.equal(pose.length, p.pose.length);
      for (let k = 0; k < pose.length; k++) worst = Math.max(worst, Math.abs(pose[k] - p.pose[k]));
    }
    console.log(`  ${codec}: ${native.poses.length} poses, largest difference from native ${worst.toExponential(2)}`);
    assert.ok(worst <= POSE_TOLERANCE, `largest difference ${worst}`);
  });

  test(`${codec}: instances are independent; the same time gives the same pose in any order`, () => {
    const asset = runtime.open(bytes);
    const a = asset.createInstance(), b = asset.createInstance();
    const clip = asset.clips.at(-1);
    const times = Array.from({ length: clip.frameCount }, (_, i) => i / clip.frameRate);
    const forward = times.map((t) => a.world(clip.index, t));
    const backward = [...times].reverse().map((t) => b.world(clip.name, t)).reverse();
    forward.forEach((p, i) => assert.deepEqual(p, backward[i], `frame ${i}`));
    const out = new Float32Array(clip.nodeCount * TRANSFORM_FLOATS + 5);
    assert.equal(a.local(clip.index, times[3], {}, out), out);
    assert.deepEqual(out.subarray(0, clip.nodeCount * TRANSFORM_FLOATS), b.local(clip.index, times[3]));
    a.dispose();
    const c = asset.createInstance(); // reuses a's scratch, initialised afresh
    assert.deepEqual(c.world(clip.index, times[5]), forward[5]);
    assert.throws(() => a.world(0, 0), /disposed/);
  });

  test(`${codec}: bad calls and damaged bytes are errors with the runtime's words`, () => {
    const asset = runtime.open(bytes);
    const player = asset.createInstance();
    assert.throws(() => player.sample("no such clip", 0), (e) => e.codeName === "MCD_ERROR_NOT_FOUND");
    assert.throws(() => player.sample(99, 0), (e) => e.codeName === "MCD_ERROR_OUT_OF_RANGE");
    assert.throws(() => player.sample(0, NaN), (e) => e.codeName === "MCD_ERROR_INVALID_ARGUMENT");
    assert.throws(() => player.sample(0, 0, {}, new Float32Array(3)), (e) => e.codeName === "MCD_ERROR_BUFFER_TOO_SMALL");
    const damaged = bytes.slice();
    damaged[Math.floor(damaged.length / 2)] ^= 0x5a;
    const v = runtime.validate(damaged);
    assert.equal(v.codeName, "MCD_ERROR_CHECKSUM");
    assert.throws(() => runtime.open(damaged), /mcd_open: checksum/);
    assert.equal(runtime.validate(bytes.subarray(0, bytes.length - 7)).ok, false);
    // Structural checks alone: either refused, or every sample is finite (the runtime's promise).
    let opened = null;
    try { opened = runtime.open(damaged, { skipChecksum: true }); } catch (e) { assert.ok(e instanceof MocodecError); }
    if (opened) {
      const p = opened.createInstance();
      for (const c of opened.clips) {
        for (let f = 0; f < c.frameCount; f += 7) assert.ok(p.world(c.index, f / c.frameRate).every(Number.isFinite));
      }
    }
  });

  test(`${codec}: retargeting onto a rig equals the native runtime's, and onto its own skeleton is the pose`, () => {
    const asset = runtime.open(bytes);
    const player = asset.createInstance();
    const { bones, options, matched, nodeOf, cases: rc } = native.retarget;
    const rig = asset.createRetarget(0, bones, options);
    assert.equal(rig.boneCount, bones.length);
    assert.equal(rig.matched, matched);
    assert.deepEqual(bones.map((_, i) => rig.nodeOf(i)), nodeOf);
    let worst = 0;
    for (const c of rc) {
      const out = rig.apply(player.local(c.clip, c.time));
      for (let k = 0; k < out.length; k++) worst = Math.max(worst, Math.abs(out[k] - c.pose[k]));
    }
    console.log(`  ${codec}: retargeted ${rc.length} poses onto a turned, renamed, half-size rig: largest difference from native ${worst.toExponential(2)}`);
    assert.ok(worst <= POSE_TOLERANCE, `largest difference from native ${worst}`);
    // The asset's own skeleton as the rig: every bone gets the sampled local transform back.
    const own = asset.skeletons[0].nodes.map((n) => ({ name: n.name, parent: n.parent,
      rest: [...n.restRotation, ...n.restTranslation, ...n.restScale] }));
    const self = asset.createRetarget(0, own);
    const clip = asset.clips.find((c) => c.skeleton === 0);
    const local = player.local(clip.index, clip.duration * 0.4);
    const out = self.apply(local, new Float32Array(own.length * TRANSFORM_FLOATS));
    let err = 0;
    for (let i = 0; i < own.length; i++) {
      if (asset.skeletons[0].nodes[i].kind === 2) continue; // virtual points match only by pair
      const o = i * TRANSFORM_FLOATS;
      const dot = [0, 1, 2, 3].reduce((a, k) => a + out[o + k] * local[o + k], 0);
      err = Math.max(err, 1 - Math.abs(dot));
      for (let k = 4; k < TRANSFORM_FLOATS; k++) err = Math.max(err, Math.abs(out[o + k] - local[o + k]) / 100);
    }
    console.log(`  ${codec}: onto its own skeleton: largest difference ${err.toExponential(2)}`);
    assert.ok(err < 1e-5, `own skeleton: ${err}`);
  });

  test(`${codec}: a refused rig names the bone or pair`, () => {
    const asset = runtime.open(bytes);
    const nodes = asset.skeletons[0].nodes;
    const ok = (n) => ({ name: n.name, parent: n.parent, rest: [...n.restRotation, ...n.restTranslation, ...n.restScale] });
    const bones = nodes.map(ok);
    bones[2] = { ...bones[2], parent: 5 };
    assert.throws(() => asset.createRetarget(0, bones), (e) => e.codeName === "MCD_ERROR_INVALID_ARGUMENT"
      && e.where === "bone" && e.index === 2 && e.message.includes(JSON.stringify(nodes[2].name)));
    assert.throws(() => asset.createRetarget(0, nodes.map(ok), { pairs: { [nodes[0].name]: "no such node" } }),
      (e) => e.codeName === "MCD_ERROR_NOT_FOUND" && e.where === "pair" && /no such node/.test(e.message));
    assert.throws(() => asset.createRetarget(0, nodes.map(ok), { unitScale: 0 }), (e) => e.where === "config");
    const rig = asset.createRetarget(0, nodes.map(ok));
    assert.throws(() => rig.apply(new Float32Array(3)), (e) => e.codeName === "MCD_ERROR_INVALID_ARGUMENT");
  });
}
