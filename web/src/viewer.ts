// The 3D view of a job's mesh: orbit and zoom, a sun whose direction the user sets, wireframe,
// vertex colours on or off, the sea plane where the job has one, and its levels of detail.

import {
  AmbientLight,
  Box3,
  Color,
  DirectionalLight,
  DoubleSide,
  FrontSide,
  HemisphereLight,
  Material,
  Mesh,
  MeshStandardMaterial,
  Object3D,
  PerspectiveCamera,
  PlaneGeometry,
  Scene,
  Vector3,
  WebGLRenderer,
} from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/examples/jsm/libs/meshopt_decoder.module.js';

export interface ViewOptions {
  wireframe: boolean;
  vertexColors: boolean;
  sunAzimuth: number; // degrees
  sunElevation: number; // degrees
  sea: boolean;
}

export class Viewer {
  readonly canvas: HTMLCanvasElement;
  private renderer: WebGLRenderer | null = null;
  private scene = new Scene();
  private camera = new PerspectiveCamera(45, 1, 0.01, 1e6);
  private controls: OrbitControls | null = null;
  private sun = new DirectionalLight(0xffffff, 2.2);
  private model: Object3D | null = null;
  private seaPlane: Mesh | null = null;
  private seaLevel: number | null = null;
  private loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
  private framed = false;
  private resize = new ResizeObserver(() => this.fit());
  private frame = 0;
  opts: ViewOptions = { wireframe: false, vertexColors: true, sunAzimuth: 315, sunElevation: 45, sea: true };
  /** Why WebGL is not there, if it is not. */
  readonly failure: string | null = null;

  constructor(host: HTMLElement) {
    this.canvas = document.createElement('canvas');
    this.canvas.className = 'viewer-canvas';
    this.canvas.tabIndex = 0;
    this.canvas.setAttribute('role', 'img');
    this.canvas.setAttribute('aria-label', '3D view of the mesh: drag to orbit, wheel to zoom, arrow keys to pan, F or Home to frame it all');
    host.append(this.canvas);
    try {
      // preserveDrawingBuffer: the canvas can be read back (screenshots, the tests' pixel checks).
      this.renderer = new WebGLRenderer({ canvas: this.canvas, antialias: true, preserveDrawingBuffer: true });
    } catch (e) {
      this.failure = `WebGL is not available here (${(e as Error).message}); the pictures below show the result.`;
      return;
    }
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.scene.background = new Color(0x1d2733);
    this.scene.add(new HemisphereLight(0xdfe9f3, 0x3a3328, 0.9), new AmbientLight(0xffffff, 0.15), this.sun, this.sun.target);
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.listenToKeyEvents(this.canvas);
    this.controls.addEventListener('change', () => this.draw());
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
   * Keep the orbit above the ground (for a terrain seen from outside: under it the terrain
   * vanishes, back faces culled); a cave or a column is free to be looked at from below.
   */
  aboveGround(on: boolean): void {
    if (!this.controls) return;
    // Just short of horizontal: the camera never passes under the target's level.
    this.controls.maxPolarAngle = on ? Math.PI / 2 - 0.02 : Math.PI;
    this.controls.update();
  }

  /** Frame the whole model again, as when it was first shown. */
  frameAll(): void {
    if (!this.renderer || !this.model) return;
    this.frameCamera();
    this.draw();
  }

  /** Show a glb (replacing what was shown); the camera is framed on the first one only. */
  async show(bytes: ArrayBuffer, seaLevel: number | null): Promise<void> {
    if (!this.renderer) return;
    const gltf = await this.loader.parseAsync(bytes, '');
    if (this.model) {
      this.scene.remove(this.model);
      dispose(this.model);
    }
    this.model = gltf.scene;
    this.scene.add(this.model);
    this.seaLevel = seaLevel;
    if (!this.framed) this.frameCamera();
    this.framed = true;
    this.placeSea();
    this.apply();
  }

  set(opts: Partial<ViewOptions>): void {
    this.opts = { ...this.opts, ...opts };
    this.apply();
  }

  dispose(): void {
    this.resize.disconnect();
    cancelAnimationFrame(this.frame);
    if (this.model) dispose(this.model);
    this.controls?.dispose();
    this.renderer?.dispose();
  }

  private apply(): void {
    this.model?.traverse((o) => {
      const m = o as Mesh;
      if (!m.isMesh) return;
      const mats = (Array.isArray(m.material) ? m.material : [m.material]) as MeshStandardMaterial[];
      for (const mat of mats) {
        mat.wireframe = this.opts.wireframe;
        const hasColors = Boolean(m.geometry.getAttribute('color'));
        mat.vertexColors = hasColors && this.opts.vertexColors;
        // Front faces only: a closed chamber (normals inward) seen from outside shows its inside
        // through the near walls, a cut-away view; a terrain is seen from above as before.
        mat.side = FrontSide;
        mat.needsUpdate = true;
      }
    });
    if (this.seaPlane) this.seaPlane.visible = this.opts.sea;
    const box = this.bounds();
    const size = box.getSize(new Vector3()).length() || 1;
    const centre = box.getCenter(new Vector3());
    const az = (this.opts.sunAzimuth * Math.PI) / 180;
    const el = (this.opts.sunElevation * Math.PI) / 180;
    this.sun.position.set(
      centre.x + size * Math.cos(el) * Math.sin(az),
      centre.y + size * Math.sin(el),
      centre.z + size * Math.cos(el) * Math.cos(az),
    );
    this.sun.target.position.copy(centre);
    this.draw();
  }

  private bounds(): Box3 {
    return this.model ? new Box3().setFromObject(this.model) : new Box3(new Vector3(-1, -1, -1), new Vector3(1, 1, 1));
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
    if (this.seaLevel === null) return;
    const box = this.bounds();
    const size = box.getSize(new Vector3());
    const centre = box.getCenter(new Vector3());
    const plane = new Mesh(
      new PlaneGeometry(size.x * 1.6, size.z * 1.6),
      new MeshStandardMaterial({ color: 0x2f6f9f, transparent: true, opacity: 0.55, roughness: 0.25, metalness: 0.1, side: DoubleSide, depthWrite: false }),
    );
    plane.rotation.x = -Math.PI / 2;
    plane.position.set(centre.x, this.seaLevel, centre.z);
    plane.renderOrder = 1;
    this.seaPlane = plane;
    this.scene.add(plane);
  }

  private fit(): void {
    if (!this.renderer) return;
    const w = this.canvas.parentElement?.clientWidth || 640;
    const h = Math.round(Math.min(w * 0.62, 560));
    this.renderer.setSize(w, h, true);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.draw();
  }

  /** Draw on the next frame (once however many changes ask). */
  private draw(): void {
    if (!this.renderer) return;
    cancelAnimationFrame(this.frame);
    this.frame = requestAnimationFrame(() => {
      this.renderer!.render(this.scene, this.camera);
      this.canvas.dataset.frames = String(Number(this.canvas.dataset.frames ?? 0) + 1);
      // The camera's angle from straight up (radians), for tests and tools reading the page.
      this.canvas.dataset.polar = this.controls ? this.controls.getPolarAngle().toFixed(3) : '';
    });
  }
}

function dispose(root: Object3D): void {
  root.traverse((o) => {
    const m = o as Mesh;
    if (!m.isMesh) return;
    m.geometry.dispose();
    for (const mat of Array.isArray(m.material) ? m.material : [m.material]) mat.dispose();
  });
}
