// The page `mocodec view` writes: the asset decoded in the page by the wasm runtime, beside the
// original motion; errors per joint now and per frame; the clip list and the figures.
// Everything it shows comes from the page's data block (the wasm, the asset, the originals'
// world positions) and the runtime: nothing is fetched.
import { Box3, Vector3 } from "three";
import { loadRuntime } from "mocodec-web";

import { clipErrors, decodedPositions, nodeErrors, originalAt, posePositions, rawBytes } from "./analysis.js";
import { ErrorPlot } from "./plot.js";
import { View } from "./scene.js";

const $ = (id) => document.getElementById(id);
const data = JSON.parse($("mocodec-data").textContent);
const fmtCm = (v) => (Number.isFinite(v) ? `${v.toFixed(v < 0.1 ? 4 : 3)} cm` : "–");
const fmtInt = (n) => Math.round(n).toLocaleString("en-US");

function fromBase64(text) {
  const s = atob(text);
  const out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}

// The hooks the browser test (and a curious user in the console) drive the page with.
const api = (window.mocodecViewer = { state: "loading", error: null });

const view = new View($("view"));
const plot = new ErrorPlot($("plot"), (frame) => { pause(); seek(frame / current.clip.frameRate); });
let runtime = null, asset = null, player = null, probe = null;
let current = null; // { clip, skeleton, original, decoded, errors, scaleCm, bounds }
let time = 0, playing = false, last = 0;
const perClip = new Map();

function showError(text) {
  api.state = "error";
  api.error = text;
  const box = $("error");
  box.textContent = text;
  box.hidden = false;
}

function codecName(id) { return data.codecs?.[id] ?? `codec ${id}`; }

function openAsset(bytes, name, originals) {
  const check = runtime.validate(bytes);
  if (!check.ok) {
    showError(`Cannot open ${name}: ${check.message} (${check.codeName}).\n` +
      "The file is damaged, truncated or not a mocodec asset; re-encode it or check the copy.");
    return false;
  }
  asset = runtime.open(bytes);
  player = asset.createInstance();
  probe = asset.createInstance();
  perClip.clear();
  api.assetName = name;
  api.originals = originals;
  $("error").hidden = true;
  $("title").textContent = `${name} · ${fmtInt(asset.size)} bytes · ${asset.clips.length} clip${asset.clips.length === 1 ? "" : "s"}`;
  document.title = `mocodec view: ${name}`;
  const body = $("clips").tBodies[0];
  body.replaceChildren(...asset.clips.map((clip) => {
    const row = document.createElement("tr");
    const e = analyse(clip, originals).errors;
    const metaMax = data.meta?.clips?.[clip.name]?.max_error_cm;
    for (const text of [clip.name, codecName(clip.codec), fmtInt(clip.frameCount),
      e ? e.max.toFixed(3) : metaMax != null ? `(${metaMax.toFixed(3)})` : "–"]) {
      const td = document.createElement("td");
      td.textContent = text;
      row.append(td);
    }
    row.title = clip.name;
    row.addEventListener("click", () => selectClip(clip.index));
    return row;
  }));
  selectClip(0);
  api.state = "ready";
  return true;
}

// Decoded positions of every frame and, with an original, the errors: once per clip.
function analyse(clip, originals) {
  if (perClip.has(clip.index)) return perClip.get(clip.index);
  const skeleton = asset.skeletons[clip.skeleton];
  const decoded = decodedPositions(probe, clip);
  let original = null, note = null;
  const entry = originals?.[clip.name];
  if (entry) {
    if (entry.frames !== clip.frameCount || entry.nodes !== clip.nodeCount) {
      note = `original ${entry.source}: ${entry.frames} frames x ${entry.nodes} nodes, the clip has ` +
        `${clip.frameCount} x ${clip.nodeCount}: not compared`;
    } else {
      original = { ...entry, positions: entry.positions ?? new Float32Array(fromBase64(entry.positions_b64).buffer) };
    }
  }
  const errors = original ? clipErrors(decoded, original, clip, skeleton.cmPerUnit) : null;
  const box = new Box3();
  const v = new Vector3();
  for (const source of original ? [decoded, original.positions] : [decoded]) {
    for (let k = 0; k < source.length; k += 3) box.expandByPoint(v.set(source[k], source[k + 1], source[k + 2]));
  }
  const tolerance = data.meta?.settings?.tolerance_cm ?? null;
  const result = { clip, skeleton, decoded, original, errors, note, bounds: box, tolerance,
    scaleCm: tolerance || errors?.max || 1 };
  perClip.set(clip.index, result);
  return result;
}

function selectClip(index) {
  pause();
  current = analyse(asset.clip(index), api.originals);
  const { clip, skeleton, errors } = current;
  [...$("clips").tBodies[0].rows].forEach((r, i) => r.classList.toggle("selected", i === index));
  view.setClip(skeleton.nodes.map((n) => n.parent), current.bounds, !!current.original);
  $("scrub").max = String(clip.duration);
  $("who").textContent = current.original ? "grey: original · blue with coloured joints: decoded by the wasm runtime"
    : "decoded by the wasm runtime (no original given)";
  $("legend-max").textContent = `${+current.scaleCm.toPrecision(3)} cm${current.tolerance ? " (tolerance)" : " (clip max)"}`;
  plot.set(errors, current.tolerance);
  figures();
  const worst = $("worst");
  worst.replaceChildren(...(errors ? errors.worstFrames : []).map((f) => {
    const li = document.createElement("li");
    li.textContent = `frame ${f}: ${errors.perFrame[f].toFixed(3)} cm`;
    li.addEventListener("click", () => { pause(); seek(f / clip.frameRate); });
    return li;
  }));
  if (!errors) worst.replaceChildren(Object.assign(document.createElement("li"), { textContent: current.note ?? "no original given" }));
  seek(0);
}

function figures() {
  const { clip, skeleton, errors } = current;
  const raw = rawBytes(clip, skeleton);
  const allRaw = asset.clips.reduce((s, c) => s + rawBytes(c, asset.skeletons[c.skeleton]).bvh, 0);
  const rows = [
    ["asset", `${fmtInt(asset.size)} B`],
    ["ratio (asset)", `${(allRaw / asset.size).toFixed(1)} : 1 vs BVH float32`],
    ["scratch / instance", `${fmtInt(asset.scratchSize)} B`],
    ["clip", clip.name],
    ["codec", codecName(clip.codec)],
    ["frames", `${fmtInt(clip.frameCount)} at ${+clip.frameRate.toFixed(3)} fps (${clip.duration.toFixed(2)} s)`],
    ["nodes", String(clip.nodeCount)],
    ["clip data", `${fmtInt(clip.dataSize)} B`],
    ["ratio (clip)", `${(raw.bvh / clip.dataSize).toFixed(1)} : 1 BVH, ${(raw.acl / clip.dataSize).toFixed(1)} : 1 ACL 40 B`],
  ];
  if (errors) {
    rows.push(["max error", `${fmtCm(errors.max)} (frame ${errors.worstFrame}, ${skeleton.nodes[errors.worstNode].name})`],
      ["p99 error", fmtCm(errors.p99)], ["mean error", fmtCm(errors.mean)]);
  } else {
    const m = data.meta?.clips?.[clip.name];
    rows.push(["errors", current.note ?? "no original given"]);
    if (m) rows.push(["encoder's max / p99 / mean", `${fmtCm(m.max_error_cm)} / ${fmtCm(m.p99_error_cm)} / ${fmtCm(m.mean_error_cm)}`]);
  }
  if (current.tolerance) rows.push(["tolerance", fmtCm(current.tolerance)]);
  $("figures").replaceChildren(...rows.flatMap(([k, v]) => {
    const dt = document.createElement("dt"), dd = document.createElement("dd");
    dt.textContent = k;
    dd.textContent = v;
    return [dt, dd];
  }));
  api.figures = errors ? { max: errors.max, p99: errors.p99, mean: errors.mean, worstFrame: errors.worstFrame } : null;
}

const pose = { buffer: null, positions: null, original: null, errors: null };

// Everything at time t: decoded pose by the runtime, original between its frames, joint errors.
function seek(t) {
  const { clip, skeleton, original } = current;
  time = Math.min(Math.max(t, 0), clip.duration);
  const n = clip.nodeCount;
  if (!pose.buffer || pose.buffer.length < n * 10) {
    pose.buffer = new Float32Array(n * 10);
    pose.positions = new Float32Array(n * 3);
    pose.original = new Float32Array(n * 3);
    pose.errors = new Float32Array(n);
  }
  player.world(clip.index, time, {}, pose.buffer);
  const positions = posePositions(pose.buffer, n, pose.positions.subarray(0, n * 3));
  let errors = null;
  if (original) {
    const o = originalAt(original, clip.frameRate, time, pose.original.subarray(0, n * 3));
    errors = nodeErrors(positions, o, n, skeleton.cmPerUnit, pose.errors.subarray(0, n));
  }
  view.show(positions, original ? pose.original : null, errors, current.scaleCm);
  const frame = time * clip.frameRate;
  $("clock").textContent = `${time.toFixed(3)} s · frame ${frame.toFixed(2)} / ${clip.frameCount - 1}`;
  $("scrub").value = String(time);
  plot.cursor(frame);
  if (errors) {
    let worst = 0;
    for (let i = 1; i < n; i++) if (errors[i] > errors[worst]) worst = i;
    $("now").textContent = `now: max ${fmtCm(errors[worst])} at ${skeleton.nodes[worst].name}`;
  } else {
    $("now").textContent = "";
  }
  api.time = time;
}

function tick(now) {
  if (!playing) return;
  const dt = (now - last) / 1000;
  last = now;
  let t = time + dt * Number($("speed").value);
  if (t > current.clip.duration) {
    if ($("loop").checked) t = current.clip.duration > 0 ? t % current.clip.duration : 0;
    else { t = current.clip.duration; pause(); }
  }
  seek(t);
  if (playing) requestAnimationFrame(tick);
}

function play() {
  if (playing || !current) return;
  if (time >= current.clip.duration && !$("loop").checked) time = 0;
  playing = true;
  $("play").innerHTML = "&#10074;&#10074;";
  last = performance.now();
  requestAnimationFrame(tick);
}

function pause() {
  playing = false;
  $("play").innerHTML = "&#9654;";
}

function step(frames) {
  if (!current) return;
  pause();
  const f = Math.round(time * current.clip.frameRate) + frames;
  seek(f / current.clip.frameRate);
}

$("play").addEventListener("click", () => (playing ? pause() : play()));
$("prev").addEventListener("click", () => step(-1));
$("next").addEventListener("click", () => step(1));
$("scrub").addEventListener("input", (e) => { pause(); seek(Number(e.target.value)); });
$("side-by-side").addEventListener("change", (e) => { view.sideBySide = e.target.checked; seek(time); });
$("follow").addEventListener("change", (e) => {
  view.follow = e.target.checked;
  if (!current) return;
  const t = time; // the camera is fitted again; the moment stays
  selectClip(current.clip.index);
  seek(t);
});
window.addEventListener("keydown", (e) => {
  if (!current || e.target instanceof HTMLInputElement && e.target.type !== "range") return;
  if (e.key === " ") { e.preventDefault(); playing ? pause() : play(); }
  if (e.key === "ArrowLeft") step(-1);
  if (e.key === "ArrowRight") step(1);
});
$("open").addEventListener("change", async (e) => {
  const file = e.target.files?.[0];
  if (!file) return;
  pause();
  try {
    // Originals stay matched by clip name; their frame and node counts are checked per clip.
    openAsset(new Uint8Array(await file.arrayBuffer()), file.name, api.originals);
  } catch (err) {
    showError(`Cannot open ${file.name}: ${err.message}`);
  }
});

Object.assign(api, {
  selectClip: (i) => selectClip(i),
  setTime: (t) => { pause(); seek(t); },
  play, pause,
  clips: () => asset.clips,
  /** A pose by the page's wasm runtime (its own instance): an Array of node_count x 10 floats;
   * options as the binding's sample ({ world, loop, nearest, contacts }). */
  pose: (clip, t, options) => Array.from(probe.sample(clip, t, options)),
  frameErrors: () => (current.errors ? Array.from(current.errors.perFrame) : null),
});

api.ready = (async () => {
  try {
    runtime = await loadRuntime(fromBase64(data.wasm));
    api.runtimeVersion = runtime.version.join(".");
    openAsset(fromBase64(data.asset.bytes), data.asset.name, data.originals);
  } catch (err) {
    showError(`The viewer could not start: ${err.message}`);
  }
})();
