// The 3D view both pages share: a three.js renderer on a canvas, orbit controls, lights, and
// framing of what is loaded.  Rendering happens on demand (after a change, while orbiting).
import { THREE, OrbitControls, GLTFLoader } from './vendor/three.bundle.js';

export class View3D {
  constructor(canvas) {
    this.canvas = canvas;
    // preserveDrawingBuffer: the page API (drawnFraction) and screenshots read the pixels back
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.renderer.outputColorSpace = THREE.SRGBColorSpace;
    this.scene = new THREE.Scene();
    this.background = new THREE.Color(0xdfe6ec);
    this.scene.background = this.background;
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.05, 5000);
    this.camera.position.set(0, 10, 40);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener('change', () => this.render());
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8070, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 1.8);
    sun.position.set(-30, 50, 60);
    this.scene.add(sun);
    this.content = new THREE.Group();
    this.scene.add(this.content);
    this.framed = false;
    new ResizeObserver(() => this.resize()).observe(canvas);
    this.resize();
  }

  resize() {
    const w = Math.max(1, this.canvas.clientWidth), h = Math.max(1, this.canvas.clientHeight);
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  render() { this.renderer.render(this.scene, this.camera); }

  /** Replace the content by `objects`; frame the camera on it the first time (or when asked). */
  setContent(objects, reframe = false) {
    for (const old of [...this.content.children]) {
      this.content.remove(old);
      old.traverse((o) => {
        if (o.geometry) o.geometry.dispose();
        const mats = o.material ? (Array.isArray(o.material) ? o.material : [o.material]) : [];
        for (const m of mats) { if (m.map) m.map.dispose(); m.dispose(); }
      });
    }
    for (const o of objects) this.content.add(o);
    if (!this.framed || reframe) this.frame();
    this.render();
  }

  frame() {
    const box = new THREE.Box3().setFromObject(this.content);
    if (box.isEmpty()) return;
    const c = box.getCenter(new THREE.Vector3());
    const size = box.getSize(new THREE.Vector3());
    const r = Math.max(size.length() / 2, 0.5);          // the bounding sphere fits the view
    const vfov = (this.camera.fov * Math.PI) / 180;
    const hfov = 2 * Math.atan(Math.tan(vfov / 2) * this.camera.aspect);
    const dist = r / Math.sin(Math.min(vfov, hfov) / 2);
    const dir = new THREE.Vector3(0.25, 0.15, 1).normalize();
    this.camera.position.copy(c).addScaledVector(dir, dist);
    this.camera.near = Math.max(0.01, dist / 1000);
    this.camera.far = dist * 20 + r * 4;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(c);
    this.controls.update();
    this.framed = true;
  }

  async parseGLB(buffer) {
    const gltf = await new GLTFLoader().parseAsync(buffer, '');
    return gltf.scene;
  }

  /** Share of the canvas's pixels that differ from the background (0..1): 0 means nothing
   * was drawn.  Read back from the drawing buffer after a fresh render. */
  drawnFraction() {
    this.render();
    const gl = this.renderer.getContext();
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const bg = this.background.clone().convertLinearToSRGB();
    const br = Math.round(bg.r * 255), bgG = Math.round(bg.g * 255), bb = Math.round(bg.b * 255);
    let drawn = 0;
    for (let i = 0; i < px.length; i += 4) {
      if (Math.abs(px[i] - br) + Math.abs(px[i + 1] - bgG) + Math.abs(px[i + 2] - bb) > 12) drawn++;
    }
    return drawn / (w * h);
  }
}

export { THREE };
