// The 3D view: the decoded skeleton (joints coloured by their error) and the original (grey
// bones), overlaid or side by side, on a floor grid, with an orbit camera.
import {
  AmbientLight, BufferAttribute, BufferGeometry, Color, DirectionalLight, GridHelper, InstancedMesh,
  LineBasicMaterial, LineSegments, Matrix4, MeshStandardMaterial, PerspectiveCamera, Scene, SphereGeometry,
  Vector3, WebGLRenderer,
} from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const DECODED_BONE = 0x4aa3ff;
const ORIGINAL_BONE = 0xb8b8b8;

/** Green at 0, yellow at half the scale, red at the scale and above. */
export function errorColour(cm, scaleCm, out = new Color()) {
  const x = scaleCm > 0 ? Math.min(Math.max(cm / scaleCm, 0), 1) : 0;
  return out.setRGB(Math.min(1, 2 * x), Math.min(1, 2 * (1 - x)) * 0.85 + 0.1, 0.15);
}

class Skeleton3D {
  constructor(scene, parents, radius, boneColour, withJoints) {
    this.parents = parents;
    const bones = parents.map((p, i) => [p, i]).filter(([p]) => p >= 0);
    this.bones = bones;
    const geometry = new BufferGeometry();
    geometry.setAttribute("position", new BufferAttribute(new Float32Array(bones.length * 6), 3));
    this.lines = new LineSegments(geometry, new LineBasicMaterial({ color: boneColour }));
    this.lines.frustumCulled = false;
    scene.add(this.lines);
    this.joints = null;
    if (withJoints) {
      this.joints = new InstancedMesh(new SphereGeometry(radius, 12, 8), new MeshStandardMaterial({ roughness: 0.6 }),
        parents.length);
      this.joints.frustumCulled = false;
      const white = new Color(1, 1, 1);
      for (let i = 0; i < parents.length; i++) this.joints.setColorAt(i, white);
      scene.add(this.joints);
    }
    this._m = new Matrix4();
  }

  update(positions, offsetX) {
    const attr = this.lines.geometry.getAttribute("position");
    const a = attr.array;
    this.bones.forEach(([p, i], k) => {
      a[k * 6] = positions[p * 3] + offsetX; a[k * 6 + 1] = positions[p * 3 + 1]; a[k * 6 + 2] = positions[p * 3 + 2];
      a[k * 6 + 3] = positions[i * 3] + offsetX; a[k * 6 + 4] = positions[i * 3 + 1]; a[k * 6 + 5] = positions[i * 3 + 2];
    });
    attr.needsUpdate = true;
    if (this.joints) {
      for (let i = 0; i < this.parents.length; i++) {
        this._m.makeTranslation(positions[i * 3] + offsetX, positions[i * 3 + 1], positions[i * 3 + 2]);
        this.joints.setMatrixAt(i, this._m);
      }
      this.joints.instanceMatrix.needsUpdate = true;
    }
  }

  colour(errors, scaleCm) {
    if (!this.joints) return;
    const c = new Color();
    for (let i = 0; i < errors.length; i++) this.joints.setColorAt(i, errorColour(errors[i], scaleCm, c));
    this.joints.instanceColor.needsUpdate = true;
  }

  dispose(scene) {
    scene.remove(this.lines);
    this.lines.geometry.dispose();
    if (this.joints) { scene.remove(this.joints); this.joints.dispose(); }
  }
}

export class View {
  constructor(canvas) {
    this.canvas = canvas;
    this.renderer = new WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.scene = new Scene();
    this.scene.background = new Color(0x1d2026);
    this.scene.add(new AmbientLight(0xffffff, 0.7));
    const sun = new DirectionalLight(0xffffff, 1.6);
    sun.position.set(1, 2, 1.5);
    this.scene.add(sun);
    this.camera = new PerspectiveCamera(40, 1, 0.01, 1e5);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener("change", () => this.render());
    this.grid = null;
    this.decoded = null;
    this.original = null;
    this.sideBySide = false;
    this.follow = true; // the camera keeps the root in view as the clip travels
    this.spacing = 0;
    this._root = new Vector3();
    this._step = new Vector3();
    new ResizeObserver(() => this.resize()).observe(canvas);
  }

  /** A new clip: skeletons for its node hierarchy, the camera fitted to where it moves. */
  setClip(parents, bounds, hasOriginal) {
    this.decoded?.dispose(this.scene);
    this.original?.dispose(this.scene);
    const size = new Vector3().subVectors(bounds.max, bounds.min);
    const height = Math.max(size.y, 1e-6);
    this.decoded = new Skeleton3D(this.scene, parents, height * 0.013, DECODED_BONE, true);
    this.original = hasOriginal ? new Skeleton3D(this.scene, parents, 0, ORIGINAL_BONE, false) : null;
    this.spacing = Math.max(size.x, height * 0.6) * 1.2;
    if (this.grid) { this.scene.remove(this.grid); this.grid.dispose(); }
    const extent = Math.max(size.x, size.z, height) * 2;
    this.grid = new GridHelper(extent, 20, 0x555a66, 0x353943);
    this.grid.position.set((bounds.min.x + bounds.max.x) / 2, bounds.min.y, (bounds.min.z + bounds.max.z) / 2);
    this.scene.add(this.grid);
    const centre = new Vector3().addVectors(bounds.min, bounds.max).multiplyScalar(0.5);
    this.centreY = centre.y;
    this.height = height;
    this._root.set(NaN, NaN, NaN);
    const distance = Math.max(height * 2.6, this.follow ? 0 : Math.hypot(size.x, size.z) * 1.3);
    this.controls.target.copy(centre);
    this.camera.position.set(centre.x + distance * 0.35, centre.y + distance * 0.25, centre.z + distance);
    this.camera.near = distance / 1000;
    this.camera.far = distance * 100;
    this.camera.updateProjectionMatrix();
    this.controls.update();
  }

  /** One moment: decoded and original positions, the decoded joints' errors (cm). */
  show(decoded, original, errors, scaleCm) {
    const shift = this.sideBySide ? this.spacing / 2 : 0;
    if (this.follow) this._follow(decoded[0], decoded[2]);
    this.decoded.update(decoded, shift);
    if (this.original && original) this.original.update(original, -shift);
    if (errors) this.decoded.colour(errors, scaleCm);
    this.render();
  }

  // Move target and camera with the first root over the floor (the view's angle is the user's).
  _follow(x, z) {
    const from = Number.isNaN(this._root.x) ? this.controls.target : this._root;
    const d = this._step.set(x - from.x, 0, z - from.z);
    this.controls.target.add(d);
    this.camera.position.add(d);
    this._root.set(x, 0, z);
    this.controls.update();
  }

  resize() {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    if (!w || !h) return;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  render() { this.renderer.render(this.scene, this.camera); }
}
