// mocodec for the web: the C99 runtime compiled to WebAssembly (runtime_c, `make -C runtime_c wasm`),
// driven from JavaScript. The runtime allocates nothing; this module places the asset bytes, the
// runtime's structs and one scratch buffer per instance in the wasm memory itself, above the
// module's __heap_base, with a bump allocator whose freed scratch slots are reused.
//
//   const runtime = await loadRuntime();                 // or loadRuntime(wasmBytes)
//   const asset = runtime.open(bytes);                   // validates, decodes nothing
//   const player = asset.createInstance();               // one scratch: one playing character
//   const pose = player.sample("walk", 0.5, { world: true });  // Float32Array, 10 floats a node

import {
  ABI, RESULT_NAMES, SAMPLE_FLAGS, NODE_KINDS, RIG_BONE_KEEP_TRANSLATION, RETARGET_FLAGS, RETARGET_ISSUES,
} from "./abi.js";

export { RESULT_NAMES, NODE_KINDS };
export const TRANSFORM_FLOATS = ABI.transform.floats;

/** A runtime call that did not return MCD_OK. */
export class MocodecError extends Error {
  constructor(code, message, context) {
    super(context ? `${context}: ${message}` : message);
    this.name = "MocodecError";
    this.code = code;
    this.codeName = RESULT_NAMES[code] ?? `MCD_ERROR_${code}`;
  }
}

let defaultModule = null;

/**
 * Compile (once) and return the runtime. `source` is the wasm as bytes, a compiled
 * WebAssembly.Module, a Response, or a URL / path; by default mocodec.wasm beside this package.
 */
export async function loadRuntime(source) {
  if (source === undefined) {
    defaultModule ??= compile(new URL("../mocodec.wasm", import.meta.url));
    return new Runtime(await defaultModule);
  }
  return new Runtime(await compile(source));
}

async function compile(source) {
  if (source instanceof WebAssembly.Module) return source;
  if (source instanceof ArrayBuffer || ArrayBuffer.isView(source)) return WebAssembly.compile(source);
  if (typeof Response !== "undefined" && source instanceof Response) {
    return WebAssembly.compile(await source.arrayBuffer());
  }
  const url = source instanceof URL ? source : new URL(String(source), import.meta.url);
  if (url.protocol === "file:") {
    // node (its fetch reads no file: URLs); a computed name keeps browser bundlers from resolving it.
    const fsModule = "node:fs/promises";
    const { readFile } = await import(fsModule);
    return WebAssembly.compile(await readFile(url));
  }
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  return WebAssembly.compile(await response.arrayBuffer());
}

/** The compiled runtime: validates and opens assets (each in a wasm instance of its own). */
export class Runtime {
  constructor(module) {
    const imports = WebAssembly.Module.imports(module);
    if (imports.length) {
      throw new Error(`mocodec.wasm imports ${imports.map((i) => `${i.module}.${i.name}`).join(", ")}: not a runtime build`);
    }
    this.module = module;
    const probe = new Memory(module);
    const v = probe.exports.mcd_version();
    this.version = [v >>> 16, (v >>> 8) & 0xff, v & 0xff];
    this._probe = probe;
  }

  /** The runtime's text for a result code ("checksum mismatch"). */
  resultString(code) {
    return this._probe.cString(this._probe.exports.mcd_result_string(code));
  }

  /**
   * Check bytes without opening them: { ok, code, codeName, message }. Never throws for bad bytes.
   */
  validate(bytes, { skipChecksum = false } = {}) {
    const mem = new Memory(this.module);
    const at = mem.place(toBytes(bytes));
    const code = mem.exports.mcd_validate(at, bytes.byteLength, skipChecksum ? 1 : 0);
    return { ok: code === 0, code, codeName: RESULT_NAMES[code], message: this.resultString(code) };
  }

  /** Open (and validate) an asset; throws MocodecError with the runtime's code and text. */
  open(bytes, { skipChecksum = false } = {}) {
    return new Asset(this, toBytes(bytes), skipChecksum);
  }
}

function toBytes(bytes) {
  if (bytes instanceof Uint8Array) return bytes;
  if (bytes instanceof ArrayBuffer) return new Uint8Array(bytes);
  if (ArrayBuffer.isView(bytes)) return new Uint8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  throw new TypeError("asset bytes must be a Uint8Array, an ArrayBuffer or a typed array");
}

// One wasm instance and its memory, with the bump allocator above __heap_base.
class Memory {
  constructor(module) {
    this.instance = new WebAssembly.Instance(module, {});
    this.exports = this.instance.exports;
    this.memory = this.exports.memory;
    this.top = align(this.exports.__heap_base.value, 16);
  }

  alloc(size, alignment = 16) {
    const at = align(this.top, alignment);
    const end = at + size;
    const have = this.memory.buffer.byteLength;
    if (end > have) this.memory.grow(Math.ceil((end - have) / 65536));
    this.top = end;
    return at;
  }

  placeString(text) {
    const bytes = utf8Encoder.encode(text);
    const at = this.alloc(bytes.byteLength + 1, 1);
    this.u8().set(bytes, at);
    this.u8()[at + bytes.byteLength] = 0;
    return at;
  }

  place(bytes) {
    const at = this.alloc(bytes.byteLength);
    this.u8().set(bytes, at);
    return at;
  }

  // Views are made afresh: growing the memory detaches the old ArrayBuffer.
  u8() { return new Uint8Array(this.memory.buffer); }
  view() { return new DataView(this.memory.buffer); }

  cString(at) {
    const u8 = this.u8();
    let end = at;
    while (u8[end] !== 0) end++;
    return utf8.decode(u8.subarray(at, end));
  }
}

const utf8 = new TextDecoder("utf-8");
const utf8Encoder = new TextEncoder();
const align = (n, a) => Math.ceil(n / a) * a;

/** An opened asset: clips, skeletons and nodes; instances sample it. */
export class Asset {
  constructor(runtime, bytes, skipChecksum) {
    const mem = new Memory(runtime.module);
    this._mem = mem;
    this._runtime = runtime;
    this.size = bytes.byteLength;
    this._struct = mem.alloc(ABI.asset.size);
    this._info = mem.alloc(Math.max(ABI.clipInfo.size, ABI.nodeInfo.size, ABI.skeletonInfo.size));
    const data = mem.place(bytes);
    check(runtime, mem.exports.mcd_open(data, bytes.byteLength, skipChecksum ? 1 : 0, this._struct), "mcd_open");
    this.scratchSize = mem.exports.mcd_scratch_size(this._struct);
    this.skeletons = [];
    for (let s = 0; s < mem.exports.mcd_skeleton_count(this._struct); s++) this.skeletons.push(this._skeleton(s));
    this.clips = [];
    for (let c = 0; c < mem.exports.mcd_clip_count(this._struct); c++) this.clips.push(this._clip(c));
    this._byName = new Map(this.clips.map((c) => [c.name, c]));
    this._freeSlots = [];
    this._maxNodes = Math.max(1, ...this.skeletons.map((s) => s.nodeCount));
  }

  _clip(index) {
    const mem = this._mem, L = ABI.clipInfo;
    check(this._runtime, mem.exports.mcd_get_clip_info(this._struct, index, this._info), "mcd_get_clip_info");
    const v = mem.view(), at = this._info;
    return Object.freeze({
      index,
      name: mem.cString(v.getUint32(at + L.name, true)),
      skeleton: v.getUint32(at + L.skeleton, true),
      codec: v.getUint32(at + L.codec, true),
      frameCount: v.getUint32(at + L.frameCount, true),
      frameRate: v.getFloat32(at + L.frameRate, true),
      duration: v.getFloat32(at + L.duration, true),
      nodeCount: v.getUint32(at + L.nodeCount, true),
      scratchSize: v.getUint32(at + L.scratchSize, true),
      dataOffset: v.getUint32(at + L.dataOffset, true),
      dataSize: v.getUint32(at + L.dataSize, true),
    });
  }

  _skeleton(index) {
    const mem = this._mem, L = ABI.skeletonInfo;
    check(this._runtime, mem.exports.mcd_get_skeleton_info(this._struct, index, this._info), "mcd_get_skeleton_info");
    let v = mem.view();
    const nodeCount = v.getUint32(this._info + L.nodeCount, true);
    const cmPerUnit = v.getFloat32(this._info + L.cmPerUnit, true);
    const nodes = [];
    for (let n = 0; n < nodeCount; n++) {
      check(this._runtime, mem.exports.mcd_get_node_info(this._struct, index, n, this._info), "mcd_get_node_info");
      v = mem.view();
      const at = this._info, N = ABI.nodeInfo;
      const floats = (off, k) => Array.from({ length: k }, (_, i) => v.getFloat32(at + off + 4 * i, true));
      const channelCount = v.getUint32(at + N.channelCount, true);
      nodes.push(Object.freeze({
        name: mem.cString(v.getUint32(at + N.name, true)),
        parent: v.getInt32(at + N.parent, true),
        kind: v.getUint32(at + N.kind, true),
        restTranslation: floats(N.restTranslation, 3),
        restRotation: floats(N.restRotation, 4),
        restScale: floats(N.restScale, 3),
        channels: Array.from({ length: channelCount }, (_, i) => v.getUint8(at + N.channels + i)),
      }));
    }
    return Object.freeze({ index, nodeCount, cmPerUnit, nodes: Object.freeze(nodes) });
  }

  /** A clip by index or name (throws MocodecError for an unknown one). */
  clip(which) {
    const c = typeof which === "string" ? this._byName.get(which) : this.clips[which];
    if (!c) throw new MocodecError(typeof which === "string" ? 13 : 10, typeof which === "string" ? "no clip of that name" : "clip index out of range", `clip ${JSON.stringify(which)}`);
    return c;
  }

  /** A sampling instance with its own scratch (sequential playback is O(1) per frame on it). */
  createInstance() {
    const slot = this._freeSlots.pop() ?? {
      scratch: this._mem.alloc(this.scratchSize, 16),
      pose: this._mem.alloc(this._maxNodes * ABI.transform.size, 16),
    };
    check(this._runtime, this._mem.exports.mcd_scratch_init(this._struct, slot.scratch, this.scratchSize), "mcd_scratch_init");
    return new Instance(this, slot);
  }

  _release(slot) { this._freeSlots.push(slot); }

  /**
   * Poses of skeleton `skeleton` onto a game rig (the runtime's mcd_retarget_*: rules in
   * runtime_c/include/mocodec.h): `bones` = [{ name, parent, rest (10 floats), keepTranslation }],
   * parents first; options: pairs ({ boneName: nodeName or null }), rootMotion, matchDirections
   * (both on by default), upAxis (1), unitScale (1: rig units per asset unit), spaceRotation.
   * Throws MocodecError naming the bone or pair the runtime refused. Its memory stays with the asset.
   */
  createRetarget(skeleton, bones, options = {}) {
    return new Retarget(this, skeleton, bones, options);
  }
}

/** A rig the asset's local poses are turned into (one map; its work buffer is its own). */
export class Retarget {
  constructor(asset, skeleton, bones, options) {
    const mem = asset._mem, x = mem.exports, B = ABI.rigBone, C = ABI.retargetConfig;
    if (!Array.isArray(bones)) throw new TypeError("bones must be an array of { name, parent, rest }");
    const pairs = Object.entries(options.pairs ?? {});
    const rig = mem.alloc(Math.max(1, bones.length) * B.size, 8);
    const names = bones.map((b) => (typeof b.name === "string" ? mem.placeString(b.name) : 0));
    const pairAt = mem.alloc(Math.max(1, pairs.length) * ABI.retargetPair.size, 8);
    const pairNames = pairs.map(([bone, node]) => [mem.placeString(bone), node == null ? 0 : mem.placeString(String(node))]);
    const config = mem.alloc(C.size, 8), issue = mem.alloc(ABI.retargetIssue.size, 8), size = mem.alloc(4, 4);
    let v = mem.view();
    bones.forEach((b, i) => {
      const at = rig + i * B.size, rest = b.rest ?? [0, 0, 0, 1, 0, 0, 0, 1, 1, 1];
      v.setUint32(at + B.name, names[i], true);
      v.setInt32(at + B.parent, b.parent ?? -1, true);
      v.setUint32(at + B.flags, b.keepTranslation ? RIG_BONE_KEEP_TRANSLATION : 0, true);
      for (let k = 0; k < TRANSFORM_FLOATS; k++) v.setFloat32(at + B.rest + 4 * k, Number(rest[k]), true);
    });
    pairNames.forEach(([bone, node], i) => {
      v.setUint32(pairAt + i * 8, bone, true);
      v.setUint32(pairAt + i * 8 + 4, node, true);
    });
    x.mcd_retarget_config_default(config);
    v = mem.view();
    const flags = (options.rootMotion ?? true ? RETARGET_FLAGS.rootMotion : 0)
      | (options.matchDirections ?? true ? RETARGET_FLAGS.matchDirections : 0);
    v.setUint32(config + C.flags, flags, true);
    if (options.upAxis !== undefined) v.setUint32(config + C.upAxis, options.upAxis, true);
    if (options.unitScale !== undefined) v.setFloat32(config + C.unitScale, options.unitScale, true);
    (options.spaceRotation ?? []).forEach((q, k) => v.setFloat32(config + C.spaceRotation + 4 * k, q, true));
    check(asset._runtime, x.mcd_retarget_size(asset._struct, skeleton, bones.length, size), "mcd_retarget_size");
    const mapSize = mem.view().getUint32(size, true);
    this._map = mem.alloc(mapSize, 8);
    const code = x.mcd_retarget_init(asset._struct, skeleton, rig, bones.length, pairAt, pairs.length, config,
      this._map, mapSize, issue);
    if (code !== 0) {
      v = mem.view();
      const where = RETARGET_ISSUES[v.getUint32(issue, true)] ?? "input", index = v.getUint32(issue + 4, true);
      const what = where === "bone" ? `bone ${index} ${JSON.stringify(bones[index]?.name)}`
        : where === "pair" ? `pair ${index} (${JSON.stringify(pairs[index]?.[0])} -> ${JSON.stringify(pairs[index]?.[1])})` : where;
      throw Object.assign(new MocodecError(code, asset._runtime.resultString(code), `mcd_retarget_init: ${what}`), { where, index });
    }
    const info = mem.alloc(ABI.retargetInfo.size, 8), I = ABI.retargetInfo;
    check(asset._runtime, x.mcd_retarget_get_info(this._map, info), "mcd_retarget_get_info");
    v = mem.view();
    this.boneCount = v.getUint32(info + I.boneCount, true);
    this.nodeCount = v.getUint32(info + I.nodeCount, true);
    this.matched = v.getUint32(info + I.matched, true);
    this._workSize = v.getUint32(info + I.workSize, true);
    this._work = mem.alloc(this._workSize, 16);
    this._in = mem.alloc(this.nodeCount * ABI.transform.size, 16);
    this._out = mem.alloc(this.boneCount * ABI.transform.size, 16);
    this._node = mem.alloc(4, 4);
    this.asset = asset;
  }

  /** The asset node driving rig bone `bone`, or -1. */
  nodeOf(bone) {
    const mem = this.asset._mem;
    check(this.asset._runtime, mem.exports.mcd_retarget_get_node(this._map, bone, this._node), "mcd_retarget_get_node");
    return mem.view().getInt32(this._node, true);
  }

  /**
   * The rig's local transforms (boneCount x 10 floats) for a local pose of the skeleton
   * (nodeCount x 10, as Instance.local gives it); into `out` when given (nothing allocated).
   */
  apply(pose, out) {
    const mem = this.asset._mem, n = this.nodeCount * TRANSFORM_FLOATS, m = this.boneCount * TRANSFORM_FLOATS;
    if (!(pose instanceof Float32Array) || pose.length < n) {
      throw new MocodecError(1, "invalid argument", `apply needs a local pose of ${n} floats`);
    }
    if (out === undefined) out = new Float32Array(m);
    else if (!(out instanceof Float32Array) || out.length < m) {
      throw new MocodecError(9, "output buffer too small", `apply needs a Float32Array of ${m} floats`);
    }
    new Float32Array(mem.memory.buffer, this._in, n).set(pose.subarray(0, n));
    check(this.asset._runtime, mem.exports.mcd_retarget_pose(this._map, this._in, this.nodeCount, this._out,
      this.boneCount, this._work, this._workSize), "mcd_retarget_pose");
    out.set(new Float32Array(mem.memory.buffer, this._out, m));
    return out;
  }
}

/** One playing instance: samples poses into Float32Arrays through its own scratch. */
export class Instance {
  constructor(asset, slot) {
    this.asset = asset;
    this._slot = slot;
    this._view = null; // the pose slot as floats; made again after the memory grows
  }

  /**
   * The pose of `clip` (index or name) at `time` seconds (a JS number: the runtime takes a double
   * since 0.3, so late frames of hours-long clips keep their precision): node_count x 10 floats (rotation x y z w,
   * translation x y z, scale x y z), local unless `world`. Written into `out` when given
   * (at least node_count * 10 floats; then nothing is allocated), else into a new Float32Array.
   */
  sample(clip, time, options = {}, out) {
    const flags = (options.world ? SAMPLE_FLAGS.world : 0) | (options.loop ? SAMPLE_FLAGS.loop : 0)
      | (options.nearest ? SAMPLE_FLAGS.nearest : 0) | (options.contacts ? SAMPLE_FLAGS.contacts : 0);
    return this._sample(clip, time, flags, out);
  }

  /** Local transforms (parent-relative). */
  local(clip, time, options = {}, out) { return this._sample(clip, time, this._flags(options) & ~SAMPLE_FLAGS.world, out); }

  /** Model-space transforms. */
  world(clip, time, options = {}, out) { return this._sample(clip, time, this._flags(options) | SAMPLE_FLAGS.world, out); }

  _flags(options) {
    return (options.loop ? SAMPLE_FLAGS.loop : 0) | (options.nearest ? SAMPLE_FLAGS.nearest : 0)
      | (options.contacts ? SAMPLE_FLAGS.contacts : 0);
  }

  _sample(clip, time, flags, out) {
    if (!this._slot) throw new Error("this instance was disposed");
    const info = this.asset.clip(clip);
    const n = info.nodeCount * TRANSFORM_FLOATS;
    if (out === undefined) out = new Float32Array(n);
    else if (!(out instanceof Float32Array) || out.length < n) {
      throw new MocodecError(9, "output buffer too small", `sample needs a Float32Array of ${n} floats`);
    }
    const mem = this.asset._mem;
    const code = mem.exports.mcd_sample(this.asset._struct, info.index, time, flags, this._slot.pose,
      info.nodeCount, this._slot.scratch);
    if (code !== 0) check(this.asset._runtime, code, "mcd_sample");
    if (this._view === null || this._view.buffer !== mem.memory.buffer) {
      this._view = new Float32Array(mem.memory.buffer, this._slot.pose, this.asset._maxNodes * TRANSFORM_FLOATS);
    }
    const view = this._view;
    for (let k = 0; k < n; k++) out[k] = view[k];
    return out;
  }

  /** Give the scratch back to the asset for the next instance. */
  dispose() {
    if (this._slot) this.asset._release(this._slot);
    this._slot = null;
  }
}

function check(runtime, code, context) {
  if (code !== 0) throw new MocodecError(code, runtime.resultString(code), context);
}
