// The heart in three.js: the surface mesh (vertex colours, normals recomputed per frame),
// an orbit camera, and picking of the point under the pointer for a push.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

export class HeartView {
  constructor(canvas) {
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x1d2026);
    this.camera = new THREE.PerspectiveCamera(30, 1, 1e-4, 100);
    this.camera.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.camera, canvas);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.6));
    const key = new THREE.DirectionalLight(0xffffff, 1.4);
    key.position.set(1, -1, 2);
    this.camera.add(key);
    this.scene.add(this.camera);
    this.material = new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide });
    this.mesh = null;
    this.raycaster = new THREE.Raycaster();
    this.needsRender = true;
    this.controls.addEventListener("change", () => { this.needsRender = true; });
  }

  // A new run's surface: triangles (flat vertex indices) and rest positions (flat, m).
  setSurface(triangles, rest) {
    if (this.mesh) {
      this.scene.remove(this.mesh);
      this.mesh.geometry.dispose();
    }
    const g = new THREE.BufferGeometry();
    g.setIndex(new THREE.BufferAttribute(new Uint32Array(triangles), 1));
    g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(rest), 3));
    g.setAttribute("color", new THREE.BufferAttribute(new Float32Array(rest.length).fill(0.7), 3));
    g.computeVertexNormals();
    g.computeBoundingSphere();
    this.mesh = new THREE.Mesh(g, this.material);
    this.scene.add(this.mesh);
    this.frameCamera(g.boundingSphere);
    this.needsRender = true;
  }

  frameCamera(sphere) {
    const d = sphere.radius / Math.sin(THREE.MathUtils.degToRad(this.camera.fov / 2)) * 1.15;
    const dir = new THREE.Vector3(1, -1.4, 0.8).normalize();
    this.camera.position.copy(sphere.center).addScaledVector(dir, d);
    this.camera.near = d / 100;
    this.camera.far = d * 10;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(sphere.center);
    this.controls.update();
  }

  // Positions and colours of one frame (Float32Arrays of 3 per vertex).
  setFrame(positions, rgb) {
    const g = this.mesh.geometry;
    g.attributes.position.array.set(positions);
    g.attributes.position.needsUpdate = true;
    g.attributes.color.array.set(rgb);
    g.attributes.color.needsUpdate = true;
    g.computeVertexNormals();
    this.needsRender = true;
  }

  colours() { return this.mesh ? this.mesh.geometry.attributes.color.array : null; }

  // The surface point under a pointer event and the view ray's direction there, or null.
  pick(event) {
    if (!this.mesh) return null;
    const r = this.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((event.clientX - r.left) / r.width) * 2 - 1, -((event.clientY - r.top) / r.height) * 2 + 1);
    this.raycaster.setFromCamera(ndc, this.camera);
    const hit = this.raycaster.intersectObject(this.mesh)[0];
    return hit ? { point: hit.point.toArray(), direction: this.raycaster.ray.direction.toArray() } : null;
  }

  resize() {
    const c = this.renderer.domElement;
    const w = c.clientWidth, h = c.clientHeight;
    if (c.width !== Math.floor(w * window.devicePixelRatio) || c.height !== Math.floor(h * window.devicePixelRatio)) {
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / Math.max(h, 1);
      this.camera.updateProjectionMatrix();
      this.needsRender = true;
    }
  }

  render() {
    this.resize();
    this.renderer.render(this.scene, this.camera);
    this.needsRender = false;
  }
}
