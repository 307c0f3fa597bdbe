// The 3D view of a job's mesh: orbit and zoom, a sun whose direction the user sets and whose
// shadows fall on the model, shaded / wireframe / wire over shaded, vertex colours on or off,
// water at the job's level, a ground grid, an axis gizmo, full screen, and overlays with the
// triangle count and the height legend (viewer_overlay.ts).

import {
  AmbientLight,
  Box3,
  BufferGeometry,
  Color,
  DirectionalLight,
  DoubleSide,
  FrontSide,
  GridHelper,
  HemisphereLight,
  Material,
  Mesh,
  MeshBasicMaterial,
  MeshLambertMaterial,
  MeshStandardMaterial,
  Object3D,
  PCFShadowMap,
  PerspectiveCamera,
  PlaneGeometry,
  Scene,
  Sphere,
  Raycaster,
  Vector2,
  Vector3,
  WebGLRenderer,
} from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { ViewHelper } from 'three/examples/jsm/helpers/ViewHelper.js';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/examples/jsm/libs/meshopt_decoder.module.js';
import { Overlay, niceStep } from './viewer_overlay';

export type Shading = 'shaded' | 'wireframe' | 'wire-over-shaded';

export interface ViewOptions {
  shading: Shading;
  vertexColors: boolean;
  sunAzimuth: number; // degrees
  sunElevation: number; // degrees
  sea: boolean;
  grid: boolean;
  shadows: boolean;
}

/** What a job's result says about how to show it (job.ts reads it from the job). */
export interface Setting {
  /** A terrain seen from outside: the orbit stays above it, a ground grid is drawn under it. */
  ground: boolean;
  /** The water level (m) to show, if the result has one. */
  water: number | null;
  /** The sea level the vertex colours were tinted with, when they are the height tint. */
  tintSea: number | null;
}

/** The shadow map's side (px): enough for a 1 m cell over a few hundred metres, and cheap. */
const SHADOW_MAP = 2048;

/** The sea: matte (no specular), so a high sun does not turn it into a white mirror. */
const waterMaterial = (): MeshLambertMaterial =>
  new MeshLambertMaterial({ color: 0x2f6f9f, transparent: true, opacity: 0.55, side: DoubleSide, depthWrite: false });

export class Viewer {
  readonly canvas: HTMLCanvasElement;
  readonly overlay: Overlay;
  private host: HTMLElement;
  private renderer: WebGLRenderer | null = null;
  private scene = new Scene();
  private camera = new PerspectiveCamera(45, 1, 0.01, 1e6);
  private controls: OrbitControls | null = null;
  private gizmo: ViewHelper | null = null;
  private sun = new DirectionalLight(0xffffff, 2.2);
  private model: Object3D | null = null;
  /** The model's own water (carve-coast's `sea` node), shown and hidden with the sea plane. */
  private ownWater: Mesh[] = [];
  private seaPlane: Mesh | null = null;
  private grid: GridHelper | null = null;
  private setting: Setting = { ground: false, water: null, tintSea: null };
  private loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
  private framed = false;
  private resize = new ResizeObserver(() => this.fit());
  private onFullscreen = (): void => this.fullscreenChanged();
  private frame = 0;
  opts: ViewOptions = { shading: 'shaded', vertexColors: true, sunAzimuth: 315, sunElevation: 45, sea: true, grid: true, shadows: true };
  /** Why WebGL is not there, if it is not. */
  readonly failure: string | null = null;
  /** Called with the point of the model under a click (not a drag, not the gizmo), in metres. */
  onPick: ((point: Vector3) => void) | null = null;

  constructor(host: HTMLElement) {
    this.host = host;
    this.canvas = document.createElement('canvas');
    this.canvas.className = 'viewer-canvas';
    this.canvas.tabIndex = 0;
    this.canvas.setAttribute('role', 'img');
    this.canvas.setAttribute('aria-label', '3D view of the mesh: drag to orbit, wheel to zoom, arrow keys to pan, F or Home to frame it all; click an axis of the gizmo to look along it');
    host.append(this.canvas);
    this.overlay = new Overlay(host);
    this.overlay.fullscreen.addEventListener('click', () => void this.toggleFullscreen());
    document.addEventListener('fullscreenchange', this.onFullscreen);
    try {
      // preserveDrawingBuffer: the canvas can be read back (screenshots, the tests' pixel checks).
      this.renderer = new WebGLRenderer({ canvas: this.canvas, antialias: true, preserveDrawingBuffer: true });
    } catch (e) {
      this.failure = `WebGL is not available here (${(e as Error).message}); the pictures below show the result.`;
      this.overlay.fullscreen.hidden = true;
      return;
    }
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    // Cleared by hand: the gizmo is drawn into a corner after the scene.
    this.renderer.autoClear = false;
    this.renderer.shadowMap.type = PCFShadowMap;
    this.sun.shadow.mapSize.set(SHADOW_MAP, SHADOW_MAP);
    this.scene.background = new Color(0x1d2733);
    this.scene.add(new HemisphereLight(0xdfe9f3, 0x3a3328, 0.9), new AmbientLight(0xffffff, 0.15), this.sun, this.sun.target);
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.listenToKeyEvents(this.canvas);
    this.controls.addEventListener('change', () => this.draw());
    this.gizmo = new ViewHelper(this.camera, this.canvas);
    this.gizmo.setLabels('X', 'Y', 'Z');
    // A click on an axis end turns the view to look along it (a drag is an orbit, not a click).
    let down: [number, number] | null = null;
    this.canvas.addEventListener('pointerdown', (e) => (down = [e.clientX, e.clientY]));
    this.canvas.addEventListener('click', (e) => {
      if (!down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 3 || !this.gizmo || !this.controls) return;
      this.gizmo.center.copy(this.controls.target);
      if (this.gizmo.handleClick(e)) {
        this.turn();
        return;
      }
      const hit = this.onPick ? this.pick(e.clientX, e.clientY) : null;
      if (hit) this.onPick?.(hit);
    });
    // Back from wherever the orbit went: F (as in Blender and Unity) or Home frames it all.
    this.canvas.addEventListener('keydown', (e) => {
      if ((e.key === 'f' || e.key === 'F' || e.key === 'Home') && !e.ctrlKey && !e.metaKey && !e.altKey) {
        e.preventDefault();
        this.frameAll();
      }
    });
    this.resize.observe(host);
    this.fit();
  }

  /**
   * How to show the results to come: a terrain seen from outside keeps the orbit above the
   * ground (under it the terrain vanishes, back faces culled) and has a ground grid; a cave or a
   * column is free to be looked at from below.
   */
  configure(setting: Setting): void {
    this.setting = setting;
    if (!this.controls) return;
    // Just short of horizontal: the camera never passes under the target's level.
    this.controls.maxPolarAngle = setting.ground ? Math.PI / 2 - 0.02 : Math.PI;
    this.controls.update();
  }

  /** Frame the whole model again, as when it was first shown. */
  frameAll(): void {
    if (!this.renderer || !this.model) return;
    this.frameCamera();
    this.draw();
  }

  /** Whether the model has water of its own (then no sea plane is added). */
  get hasOwnWater(): boolean {
    return this.ownWater.length > 0;
  }

  /** Whether water is shown: the model's own, or a sea plane at a level within its reach. */
  get showsWater(): boolean {
    return this.hasOwnWater || this.seaPlane !== null;
  }

  /**
   * Show a glb (replacing what was shown) as last configured; the camera is framed on the first
   * one, and again when a mesh is elsewhere or of another size.
   */
  async show(bytes: ArrayBuffer): Promise<void> {
    if (!this.renderer) return;
    const gltf = await this.loader.parseAsync(bytes, '');
    const before = this.model ? this.bounds() : null;
    if (this.model) {
      this.scene.remove(this.model);
      dispose(this.model);
    }
    this.model = gltf.scene;
    this.ownWater = [];
    this.model.traverse((o) => {
      const m = o as Mesh;
      if (!m.isMesh) return;
      if (isWater(m)) {
        // Matte like the sea plane, and no shadow caster (it would shade the sea floor).
        (m.material as Material).dispose();
        m.material = waterMaterial();
        m.receiveShadow = true;
        m.renderOrder = 1;
        this.ownWater.push(m);
        return;
      }
      m.castShadow = true;
      m.receiveShadow = true;
      // A closed chamber's walls face inwards (a cave seen from outside shows its inside through
      // the near walls, culled): the sun then shines through them too, as the eye sees through.
      if (!this.setting.ground && signedVolume(m.geometry) < 0) for (const mat of materials(m)) mat.shadowSide = FrontSide;
    });
    this.scene.add(this.model);
    // Framed on the first mesh, and again when one is of another size or place (a draft of a
    // terrain four times as large): the orbit the user chose is kept otherwise.
    if (!this.framed || (before && elsewhere(before, this.bounds()))) this.frameCamera();
    this.framed = true;
    this.placeSea();
    this.placeGrid();
    this.apply();
  }

  /** Where the model (not its water) is under a point of the window, in the model's metres. */
  pick(clientX: number, clientY: number): Vector3 | null {
    if (!this.model) return null;
    const r = this.canvas.getBoundingClientRect();
    const ndc = new Vector2(((clientX - r.left) / r.width) * 2 - 1, -((clientY - r.top) / r.height) * 2 + 1);
    const ray = new Raycaster();
    ray.setFromCamera(ndc, this.camera);
    const hit = ray.intersectObject(this.model, true).find((h) => !this.ownWater.includes(h.object as Mesh));
    return hit ? hit.point.clone() : null;
  }

  set(opts: Partial<ViewOptions>): void {
    this.opts = { ...this.opts, ...opts };
    this.apply();
  }

  dispose(): void {
    this.resize.disconnect();
    document.removeEventListener('fullscreenchange', this.onFullscreen);
    cancelAnimationFrame(this.frame);
    if (this.model) dispose(this.model);
    this.gizmo?.dispose();
    this.controls?.dispose();
    this.renderer?.dispose();
  }

  private apply(): void {
    this.model?.traverse((o) => {
      const m = o as Mesh;
      if (!m.isMesh || m.userData.wire || this.ownWater.includes(m)) return;
      for (const mat of materials(m) as MeshStandardMaterial[]) {
        mat.wireframe = this.opts.shading === 'wireframe';
        const hasColors = Boolean(m.geometry.getAttribute('color'));
        mat.vertexColors = hasColors && this.opts.vertexColors;
        // Front faces only: a closed chamber (normals inward) seen from outside shows its inside
        // through the near walls, a cut-away view; a terrain is seen from above as before.
        mat.side = FrontSide;
        // Wire over shaded: the faces pushed back a little so that their edges win the depth test.
        mat.polygonOffset = this.opts.shading === 'wire-over-shaded';
        mat.polygonOffsetFactor = 1;
        mat.polygonOffsetUnits = 1;
        mat.needsUpdate = true;
      }
      wireOver(m, this.opts.shading === 'wire-over-shaded');
    });
    this.canvas.dataset.shading = this.opts.shading;
    for (const w of this.ownWater) w.visible = this.opts.sea;
    if (this.seaPlane) this.seaPlane.visible = this.opts.sea;
    if (this.grid) this.grid.visible = this.opts.grid;
    this.overlay.showGrid(this.opts.grid && this.grid !== null);
    this.placeSun();
    this.count();
    this.draw();
  }

  /** The sun around the model, its shadow camera fitted to the model's bounding sphere. */
  private placeSun(): void {
    const sphere = this.bounds().getBoundingSphere(new Sphere());
    const r = sphere.radius || 1;
    const az = (this.opts.sunAzimuth * Math.PI) / 180;
    const el = (this.opts.sunElevation * Math.PI) / 180;
    const c = sphere.center;
    this.sun.position.set(c.x + 2 * r * Math.cos(el) * Math.sin(az), c.y + 2 * r * Math.sin(el), c.z + 2 * r * Math.cos(el) * Math.cos(az));
    this.sun.target.position.copy(c);
    const on = this.opts.shadows && this.model !== null;
    this.sun.castShadow = on;
    if (this.renderer) {
      if (this.renderer.shadowMap.enabled !== on) this.scene.traverse((o) => materials(o as Mesh).forEach((m) => (m.needsUpdate = true)));
      this.renderer.shadowMap.enabled = on;
      this.renderer.shadowMap.needsUpdate = true;
    }
    const cam = this.sun.shadow.camera;
    [cam.left, cam.right, cam.top, cam.bottom, cam.near, cam.far] = [-r, r, r, -r, r * 0.5, r * 3.5];
    cam.updateProjectionMatrix();
    // Offsets in world units against shadow acne, scaled by the model (a texel is 2r / 2048).
    this.sun.shadow.bias = -0.0005;
    this.sun.shadow.normalBias = (2 * r) / SHADOW_MAP;
    this.canvas.dataset.shadows = on ? String(this.sun.shadow.mapSize.x) : 'off';
  }

  /** Triangles and vertices of the meshes shown, counted from their geometry. */
  private count(): void {
    let triangles = 0;
    let vertices = 0;
    this.model?.traverseVisible((o) => {
      const m = o as Mesh;
      if (!m.isMesh || m.userData.wire) return;
      const g = m.geometry;
      const position = g.getAttribute('position');
      triangles += Math.floor((g.index ? g.index.count : position.count) / 3);
      vertices += position.count;
    });
    if (!this.model) return;
    this.canvas.dataset.triangles = String(triangles);
    this.canvas.dataset.vertices = String(vertices);
    this.overlay.showCounts(triangles, vertices);
  }

  /** The model's bounds, its own water left out (it spans the sea, not the land). */
  private bounds(): Box3 {
    if (!this.model) return new Box3(new Vector3(-1, -1, -1), new Vector3(1, 1, 1));
    const box = new Box3();
    this.model.updateMatrixWorld(true);
    this.model.traverse((o) => {
      const m = o as Mesh;
      if (m.isMesh && !m.userData.wire && !this.ownWater.includes(m)) box.expandByObject(m);
    });
    return box.isEmpty() ? new Box3().setFromObject(this.model) : box;
  }

  private frameCamera(): void {
    const box = this.bounds();
    const centre = box.getCenter(new Vector3());
    const size = box.getSize(new Vector3());
    const r = Math.max(size.x, size.y, size.z) || 1;
    this.camera.near = r / 1000;
    this.camera.far = r * 100;
    this.camera.position.set(centre.x + r * 0.9, centre.y + r * 0.8, centre.z + r * 1.1);
    this.camera.updateProjectionMatrix();
    this.controls!.target.copy(centre);
    this.controls!.update();
  }

  private placeSea(): void {
    if (this.seaPlane) {
      this.scene.remove(this.seaPlane);
      this.seaPlane.geometry.dispose();
      (this.seaPlane.material as Material).dispose();
      this.seaPlane = null;
    }
    const box = this.bounds();
    const water = this.setting.water;
    this.overlay.showHeights(box.min.y, box.max.y, this.setting.tintSea, water ?? (this.hasOwnWater ? 0 : null), this.setting.ground ? this.gridStep() : null);
    // A level below the whole model (erode's uplift-range keeps its sea at −1000 m) wets nothing:
    // a plane there would only float in the void under the terrain.
    if (water === null || this.hasOwnWater || water < box.min.y) return;
    const size = box.getSize(new Vector3());
    const centre = box.getCenter(new Vector3());
    const plane = new Mesh(new PlaneGeometry(size.x * 1.6, size.z * 1.6), waterMaterial());
    plane.rotation.x = -Math.PI / 2;
    plane.position.set(centre.x, water, centre.z);
    plane.renderOrder = 1;
    plane.receiveShadow = true;
    this.seaPlane = plane;
    this.scene.add(plane);
  }

  private gridStep(): number {
    const size = this.bounds().getSize(new Vector3());
    return niceStep(Math.max(size.x, size.z));
  }

  /** A ground grid under a terrain, twice its footprint, at its lowest point. */
  private placeGrid(): void {
    if (this.grid) {
      this.scene.remove(this.grid);
      this.grid.dispose();
      this.grid = null;
    }
    if (!this.setting.ground || !this.model) return;
    const box = this.bounds();
    const size = box.getSize(new Vector3());
    const step = this.gridStep();
    const cells = 2 * Math.ceil(Math.max(size.x, size.z) / step);
    const grid = new GridHelper(cells * step, cells, 0x8fa3b8, 0x4a5a6a);
    const centre = box.getCenter(new Vector3());
    // Snapped to the grid's own spacing so its lines fall on round coordinates.
    grid.position.set(Math.round(centre.x / step) * step, box.min.y - size.y * 0.002, Math.round(centre.z / step) * step);
    this.grid = grid;
    this.scene.add(grid);
  }

  private fullscreenChanged(): void {
    const on = document.fullscreenElement === this.host;
    this.overlay.fullscreen.textContent = on ? 'Exit full screen' : 'Full screen';
    this.overlay.fullscreen.setAttribute('aria-pressed', String(on));
    this.fit();
  }

  private async toggleFullscreen(): Promise<void> {
    try {
      if (document.fullscreenElement === this.host) await document.exitFullscreen();
      else await this.host.requestFullscreen();
    } catch (e) {
      this.overlay.fullscreen.title = `Full screen is not available here: ${(e as Error).message}`;
    }
  }

  private fit(): void {
    if (!this.renderer) return;
    const full = document.fullscreenElement === this.host;
    const w = this.host.clientWidth || 640;
    const h = full ? this.host.clientHeight || window.innerHeight : Math.round(Math.min(w * 0.62, 560));
    this.renderer.setSize(w, h, true);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.draw();
  }

  /** The gizmo's turn to look along an axis, animated. */
  private turn(): void {
    let before = performance.now();
    const step = (now: number): void => {
      if (!this.gizmo || !this.renderer) return;
      this.gizmo.update(Math.max(0, now - before) / 1000);
      before = now;
      this.render();
      if (this.gizmo.animating) requestAnimationFrame(step);
      else this.controls?.update();
    };
    requestAnimationFrame(step);
  }

  private render(): void {
    const r = this.renderer!;
    r.clear();
    r.render(this.scene, this.camera);
    this.gizmo?.render(r);
    this.canvas.dataset.frames = String(Number(this.canvas.dataset.frames ?? 0) + 1);
    // The camera's angle from straight up (radians), for tests and tools reading the page.
    this.canvas.dataset.polar = this.controls ? this.controls.getPolarAngle().toFixed(3) : '';
  }

  /** Draw on the next frame (once however many changes ask). */
  private draw(): void {
    if (!this.renderer) return;
    cancelAnimationFrame(this.frame);
    this.frame = requestAnimationFrame(() => this.render());
  }
}

function materials(m: Mesh): Material[] {
  if (!m.material) return [];
  return Array.isArray(m.material) ? m.material : [m.material];
}

/** The model's water: glb.rs names its material `water` (carve-coast's `sea` node). */
function isWater(m: Mesh): boolean {
  return materials(m).some((mat) => mat.name === 'water');
}

/** Wire over shaded: the mesh's edges drawn by a child sharing its geometry. */
function wireOver(m: Mesh, on: boolean): void {
  let wire = m.children.find((c) => c.userData.wire) as Mesh | undefined;
  if (on && !wire) {
    wire = new Mesh(m.geometry, new MeshBasicMaterial({ color: 0x0b1118, wireframe: true, transparent: true, opacity: 0.45 }));
    wire.userData.wire = true;
    m.add(wire);
  }
  if (wire) wire.visible = on;
}

/**
 * Six times the volume a closed mesh encloses, negative when its faces point inwards (a cave's
 * chamber). Sampled: every triangle of a small mesh, a spread of a large one's; taken about the
 * mesh's centre, where each face of a chamber adds with the same sign.
 */
function signedVolume(g: BufferGeometry): number {
  const p = g.getAttribute('position');
  if (!g.boundingBox) g.computeBoundingBox();
  const o = g.boundingBox!.getCenter(new Vector3());
  const index = g.index;
  const n = Math.floor((index ? index.count : p.count) / 3);
  const stride = Math.max(1, Math.floor(n / 200000));
  const [a, b, c] = [new Vector3(), new Vector3(), new Vector3()];
  let v = 0;
  for (let t = 0; t < n; t += stride) {
    const i = (k: number): number => (index ? index.getX(3 * t + k) : 3 * t + k);
    a.fromBufferAttribute(p, i(0)).sub(o);
    b.fromBufferAttribute(p, i(1)).sub(o);
    c.fromBufferAttribute(p, i(2)).sub(o);
    v += a.dot(b.cross(c));
  }
  return v;
}

/** Whether `b` is not where `a` was: its longest side 1.5 times or more off, or its centre moved by half of it. */
function elsewhere(a: Box3, b: Box3): boolean {
  const side = (x: Box3): number => Math.max(...x.getSize(new Vector3()).toArray());
  const [sa, sb] = [side(a), side(b)];
  if (!(sa > 0 && sb > 0)) return false;
  const moved = a.getCenter(new Vector3()).distanceTo(b.getCenter(new Vector3()));
  return sb / sa >= 1.5 || sa / sb >= 1.5 || moved > 0.5 * Math.max(sa, sb);
}

function dispose(root: Object3D): void {
  root.traverse((o) => {
    const m = o as Mesh;
    if (!m.isMesh) return;
    if (!m.userData.wire) m.geometry.dispose();
    for (const mat of materials(m)) mat.dispose();
  });
}
