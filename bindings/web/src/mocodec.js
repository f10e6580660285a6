// mocodec for the web: the C99 runtime compiled to WebAssembly (runtime_c, `make -C runtime_c wasm`),
// driven from JavaScript. The runtime allocates nothing; this module places the asset bytes, the
// runtime's structs and one scratch buffer per instance in the wasm memory itself, above the
// module's __heap_base, with a bump allocator whose freed scratch slots are reused.
//
//   const runtime = await loadRuntime();                 // or loadRuntime(wasmBytes)
//   const asset = runtime.open(bytes);                   // validates, decodes nothing
//   const player = asset.createInstance();               // one scratch: one playing character
//   const pose = player.sample("walk", 0.5, { world: true });  // Float32Array, 10 floats a node

import { ABI, RESULT_NAMES, SAMPLE_FLAGS, NODE_KINDS } from "./abi.js";

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
}

/** One playing instance: samples poses into Float32Arrays through its own scratch. */
export class Instance {
  constructor(asset, slot) {
    this.asset = asset;
    this._slot = slot;
    this._view = null; // the pose slot as floats; made again after the memory grows
  }

  /**
   * The pose of `clip` (index or name) at `time` seconds: node_count x 10 floats (rotation x y z w,
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
