// Types of the mocodec web binding (src/mocodec.js).

/** mcd_result names by value: RESULT_NAMES[6] === "MCD_ERROR_CHECKSUM". */
export const RESULT_NAMES: readonly string[];
export const NODE_KINDS: Readonly<{ joint: 0; endSite: 1; virtual: 2 }>;
/** Floats per node in a pose: rotation x y z w, translation x y z, scale x y z. */
export const TRANSFORM_FLOATS: 10;

export class MocodecError extends Error {
  /** The mcd_result value. */
  readonly code: number;
  /** Its name, e.g. "MCD_ERROR_CHECKSUM". */
  readonly codeName: string;
}

/** Asset bytes: a Uint8Array (a node Buffer too), any other typed array or DataView, or an ArrayBuffer. */
export type AssetBytes = ArrayBuffer | ArrayBufferView;

export type WasmSource = AssetBytes | WebAssembly.Module | Response | URL | string;

/** Compile the runtime (by default mocodec.wasm beside this package). */
export function loadRuntime(source?: WasmSource): Promise<Runtime>;

export interface ValidateResult {
  ok: boolean;
  code: number;
  codeName: string;
  message: string;
}

export interface OpenOptions {
  /** Structural checks only (MCD_VALIDATE_SKIP_CHECKSUM). */
  skipChecksum?: boolean;
}

export class Runtime {
  readonly module: WebAssembly.Module;
  /** [major, minor, patch] of the C runtime. */
  readonly version: [number, number, number];
  resultString(code: number): string;
  validate(bytes: AssetBytes, options?: OpenOptions): ValidateResult;
  open(bytes: AssetBytes, options?: OpenOptions): Asset;
}

export interface ClipInfo {
  readonly index: number;
  readonly name: string;
  readonly skeleton: number;
  /** mcd_codec: 1 spline, 2 rma, 3 ik-predict, 4 fk-wavelet, 5 neural, 6 rma-pca. */
  readonly codec: number;
  readonly frameCount: number;
  readonly frameRate: number;
  readonly duration: number;
  readonly nodeCount: number;
  readonly scratchSize: number;
  readonly dataOffset: number;
  readonly dataSize: number;
}

export interface NodeInfo {
  readonly name: string;
  /** -1 for a root. */
  readonly parent: number;
  /** NODE_KINDS: joint, end site or virtual point. */
  readonly kind: number;
  readonly restTranslation: number[];
  readonly restRotation: number[];
  readonly restScale: number[];
  /** BVH channel codes in file order (0-2 position, 3-5 rotation X Y Z). */
  readonly channels: number[];
}

export interface SkeletonInfo {
  readonly index: number;
  readonly nodeCount: number;
  readonly cmPerUnit: number;
  readonly nodes: readonly NodeInfo[];
}

export class Asset {
  /** Bytes of the asset. */
  readonly size: number;
  /** Scratch bytes of one instance. */
  readonly scratchSize: number;
  readonly clips: readonly ClipInfo[];
  readonly skeletons: readonly SkeletonInfo[];
  clip(which: number | string): ClipInfo;
  createInstance(): Instance;
  /** Poses of skeleton `skeleton` onto a game rig (mcd_retarget_*). */
  createRetarget(skeleton: number, bones: readonly RigBone[], options?: RetargetOptions): Retarget;
}

export interface RigBone {
  name: string;
  /** Index of the parent bone, -1 for a root; parents come first. */
  parent: number;
  /** Rest (bind) local transform, 10 floats (rotation x y z w, translation, scale), rig space and units. */
  rest: ArrayLike<number>;
  /** Always the rest translation, even for the motion root. */
  keepTranslation?: boolean;
}

export interface RetargetOptions {
  /** Bone name -> asset node name (null: not driven); matched before names. */
  pairs?: Record<string, string | null>;
  /** The motion root travels (default true); off: it moves along upAxis only. */
  rootMotion?: boolean;
  /** Single-child bones point where their node points (default true). */
  matchDirections?: boolean;
  /** 0 x, 1 y, 2 z of rig space (default 1). */
  upAxis?: number;
  /** Rig units per asset unit (default 1). */
  unitScale?: number;
  /** Asset model space to rig space, x y z w (default identity). */
  spaceRotation?: [number, number, number, number];
}

export class Retarget {
  readonly asset: Asset;
  readonly boneCount: number;
  readonly nodeCount: number;
  /** Bones driven by a node. */
  readonly matched: number;
  /** The asset node driving a bone, or -1. */
  nodeOf(bone: number): number;
  /** The rig's local transforms for a local pose of the skeleton. */
  apply(pose: Float32Array, out?: Float32Array): Float32Array;
}

export interface SampleOptions {
  /** Model-space transforms instead of local ones. */
  world?: boolean;
  /** Wrap time into the clip instead of clamping. */
  loop?: boolean;
  /** Nearest frame instead of the codec's curve between frames. */
  nearest?: boolean;
  /** Apply the clip's contact trajectories (MCD_SAMPLE_CONTACTS). */
  contacts?: boolean;
}

export class Instance {
  readonly asset: Asset;
  sample(clip: number | string, time: number, options?: SampleOptions, out?: Float32Array): Float32Array;
  local(clip: number | string, time: number, options?: SampleOptions, out?: Float32Array): Float32Array;
  world(clip: number | string, time: number, options?: SampleOptions, out?: Float32Array): Float32Array;
  dispose(): void;
}
