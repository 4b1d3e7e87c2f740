// The 3D view: every scene object as a BufferGeometry updated from frames, the floor, the
// haptic pointer (grip, proxy on the surface, force arrow with its value) and the contact.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { fromBase64 } from './rpc.js';

const PALETTE = [0xf2994a, 0x56ccf2, 0x6fcf97, 0xbb6bd9, 0xeb5757, 0xf2c94c, 0x2f80ed];
const CONTACT_TINT = new THREE.Color(0xff3d7f);
const ARROW_M_PER_N = 0.02; // arrow length per newton of displayed force [m/N]

const vec = (v) => new THREE.Vector3(v?.x || 0, v?.y || 0, v?.z || 0);

function isSoftwareRenderer(gl) {
  const ext = gl.getExtension('WEBGL_debug_renderer_info');
  const name = ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  return /swiftshader|llvmpipe|software/i.test(String(name));
}

export class View3D {
  /** @param {HTMLCanvasElement} canvas  @param {HTMLElement} overlay element for labels */
  constructor(canvas, overlay) {
    this.canvas = canvas;
    this.overlay = overlay;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    // A software rasteriser (no GPU) gets one pixel per CSS pixel and no shadows, so that the
    // page stays responsive.
    this.software = isSoftwareRenderer(this.renderer.getContext());
    this.renderer.setPixelRatio(this.software ? 1 : Math.min(window.devicePixelRatio || 1, 2));
    this.renderer.shadowMap.enabled = !this.software;
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xeef1f5);
    this.scene.fog = new THREE.Fog(0xeef1f5, 0.6, 2.2); // the floor fades out instead of ending
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.002, 20);
    this.camera.position.set(0.16, 0.14, 0.26);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.target.set(0, 0.02, 0);
    this.controls.enableDamping = true;
    this.controls.addEventListener('change', () => (this.dirty = true));
    this.objects = new Map(); // instanceId -> {mesh, geometry, color}
    this.topology = new Map(); // instanceId -> {vertexCount, triangles}
    this.dirty = true;
    this.framed = false;

    this.addLights();
    this.setFloor(0);
    this.addTool();

    this.resizeObserver = new ResizeObserver(() => this.resize());
    this.resizeObserver.observe(canvas.parentElement);
    this.resize();
    // Without a GPU each picture costs the page's main thread a lot: at most 20 a second then.
    const minGapMs = this.software ? 50 : 0;
    let last = 0;
    const loop = (now) => {
      this.controls.update();
      if (this.dirty && now - last >= minGapMs) {
        last = now;
        this.dirty = false;
        this.renderer.render(this.scene, this.camera);
        this.placeLabel();
      }
      this.raf = requestAnimationFrame(loop);
    };
    this.raf = requestAnimationFrame(loop);
  }

  addLights() {
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8f99, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 2.2);
    sun.position.set(0.3, 0.6, 0.4);
    sun.castShadow = true;
    sun.shadow.mapSize.set(1024, 1024);
    const c = sun.shadow.camera;
    c.left = c.bottom = -0.3;
    c.right = c.top = 0.3;
    c.near = 0.05;
    c.far = 2;
    this.scene.add(sun);
  }

  /** The floor plane at y = `height` [m] (GetScene.floorHeight), with a 1 cm grid. */
  setFloor(height) {
    if (this.floor) this.scene.remove(this.floor);
    const g = new THREE.Group();
    const plane = new THREE.Mesh(
      new THREE.PlaneGeometry(6, 6),
      new THREE.MeshStandardMaterial({ color: 0xdde2ea, roughness: 0.95 }),
    );
    plane.rotation.x = -Math.PI / 2;
    plane.receiveShadow = true;
    g.add(plane);
    const grid = new THREE.GridHelper(0.6, 60, 0xaab2c0, 0xc8ced8);
    grid.position.y = 0.0002;
    g.add(grid);
    g.position.y = height;
    this.floor = g;
    this.floorHeight = height;
    this.scene.add(g);
    this.dirty = true;
  }

  addTool() {
    const t = new THREE.Group();
    t.visible = false;
    const grip = new THREE.Mesh(
      new THREE.OctahedronGeometry(0.006),
      new THREE.MeshStandardMaterial({ color: 0x334155, wireframe: true }),
    );
    const proxy = new THREE.Mesh(
      new THREE.SphereGeometry(1, 24, 16),
      new THREE.MeshStandardMaterial({ color: 0xffd23f, emissive: 0x553300, roughness: 0.4 }),
    );
    const link = new THREE.Line(
      new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]),
      new THREE.LineBasicMaterial({ color: 0x64748b }),
    );
    const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 1, 0), new THREE.Vector3(), 0.01, 0xe11d48, 0.006, 0.004);
    t.add(grip, proxy, link, arrow);
    this.scene.add(t);
    this.tool = { group: t, grip, proxy, link, arrow, forceN: 0, tip: new THREE.Vector3() };
    this.label = document.createElement('div');
    this.label.className = 'force-label';
    this.label.hidden = true;
    this.overlay.appendChild(this.label);
  }

  resize() {
    const el = this.canvas.parentElement;
    const w = Math.max(1, el.clientWidth);
    const h = Math.max(1, el.clientHeight);
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.dirty = true;
  }

  /** Applies one Frame (protobuf JSON) to the view. */
  applyFrame(frame) {
    for (const t of frame.topology || []) {
      this.topology.set(t.instanceId, { vertexCount: t.vertexCount, triangles: t.triangles || [] });
      const o = this.objects.get(t.instanceId);
      if (o) this.removeObject(t.instanceId); // rebuilt below with the new topology
    }
    const seen = new Set();
    let changed = (frame.topology || []).length > 0;
    for (const s of frame.objects || []) {
      seen.add(s.instanceId);
      const o = this.objects.get(s.instanceId) || this.createObject(s.instanceId);
      if (!o) continue;
      // A resting object sends the same positions again: nothing to redraw.
      const key = s.positionsQ || (s.positions && s.positions.length ? s.positions : null);
      if (key && key === o.lastKey) continue;
      if (this.updatePositions(o, s)) {
        o.hasPositions = true;
        o.lastKey = typeof key === 'string' ? key : null;
        changed = true;
      }
      o.mesh.visible = o.hasPositions;
    }
    for (const id of [...this.objects.keys()]) {
      if (!seen.has(id)) {
        this.removeObject(id);
        changed = true;
      }
    }
    for (const id of [...this.topology.keys()]) if (!seen.has(id) && (frame.topology || []).length) this.topology.delete(id);
    const toolKey = JSON.stringify(frame.tool || null);
    if (toolKey !== this.lastToolKey) {
      this.lastToolKey = toolKey;
      this.applyTool(frame.tool);
      changed = true;
    }
    if (!this.framed && this.objects.size && [...this.objects.values()].some((o) => o.hasPositions)) this.frameAll();
    if (changed) this.dirty = true;
  }

  createObject(id) {
    const topo = this.topology.get(id);
    if (!topo) return null;
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(topo.vertexCount * 3), 3));
    const tri = topo.triangles;
    geometry.setIndex(topo.vertexCount > 65535 ? new THREE.Uint32BufferAttribute(tri, 1) : new THREE.Uint16BufferAttribute(tri, 1));
    const color = new THREE.Color(PALETTE[(id - 1 + PALETTE.length) % PALETTE.length]);
    const material = new THREE.MeshStandardMaterial({ color: color.clone(), roughness: 0.45, metalness: 0.0 });
    const mesh = new THREE.Mesh(geometry, material);
    mesh.castShadow = true;
    mesh.receiveShadow = true;
    mesh.userData.instanceId = id;
    mesh.visible = false;
    this.scene.add(mesh);
    const o = { id, mesh, geometry, color, hasPositions: false };
    this.objects.set(id, o);
    return o;
  }

  removeObject(id) {
    const o = this.objects.get(id);
    if (!o) return;
    this.scene.remove(o.mesh);
    o.geometry.dispose();
    o.mesh.material.dispose();
    this.objects.delete(id);
  }

  /** Copies an ObjectState's positions into the geometry; false when it has none. */
  updatePositions(o, s) {
    const attr = o.geometry.getAttribute('position');
    const dst = attr.array;
    if (s.positionsQ) {
      // uint16 little-endian x, y, z per vertex, scaled into [boundsMin, boundsMax].
      const bytes = fromBase64(s.positionsQ);
      const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
      const lo = [s.boundsMin?.x || 0, s.boundsMin?.y || 0, s.boundsMin?.z || 0];
      const hi = [s.boundsMax?.x || 0, s.boundsMax?.y || 0, s.boundsMax?.z || 0];
      const scale = lo.map((l, k) => (hi[k] - l) / 65535);
      const n = Math.min(dst.length, bytes.byteLength >> 1);
      for (let i = 0; i < n; i++) dst[i] = lo[i % 3] + view.getUint16(i * 2, true) * scale[i % 3];
    } else if (s.positions && s.positions.length) {
      const n = Math.min(dst.length, s.positions.length);
      for (let i = 0; i < n; i++) dst[i] = s.positions[i];
    } else {
      return false;
    }
    attr.needsUpdate = true;
    o.geometry.computeVertexNormals();
    o.geometry.computeBoundingSphere();
    o.geometry.computeBoundingBox();
    return true;
  }

  applyTool(tool) {
    const t = this.tool;
    if (!tool || !tool.present) {
      t.group.visible = false;
      this.label.hidden = true;
      for (const o of this.objects.values()) o.mesh.material.color.copy(o.color);
      return;
    }
    t.group.visible = true;
    const grip = vec(tool.devicePose?.position);
    const proxy = vec(tool.proxyPosition);
    t.grip.position.copy(grip);
    t.proxy.position.copy(proxy);
    t.proxy.scale.setScalar(Math.max(tool.tipRadius || 0.003, 0.0005));
    t.link.geometry.setFromPoints([grip, proxy]);
    const f = vec(tool.wrench?.force);
    const n = f.length();
    t.forceN = n;
    t.arrow.visible = n > 1e-3;
    if (t.arrow.visible) {
      const len = Math.min(0.15, Math.max(0.018, n * ARROW_M_PER_N));
      t.arrow.position.copy(proxy);
      t.arrow.setDirection(f.clone().normalize());
      t.arrow.setLength(len, Math.min(0.012, len * 0.35), Math.min(0.008, len * 0.22));
      t.tip.copy(proxy).addScaledVector(f.normalize(), len);
    } else {
      t.tip.copy(proxy);
    }
    this.label.textContent = `${n.toFixed(2)} N`;
    this.label.classList.toggle('contact', !!tool.inContact);
    this.label.hidden = false;
    // The contact: the touched object tinted while the tool is in contact.
    for (const o of this.objects.values()) {
      const touching = tool.inContact && o.id === tool.contactInstanceId;
      o.mesh.material.color.copy(o.color);
      if (touching) o.mesh.material.color.lerp(CONTACT_TINT, 0.45);
    }
    t.proxy.material.emissive.setHex(tool.inContact ? 0xaa2200 : 0x553300);
  }

  placeLabel() {
    if (this.label.hidden) return;
    const p = this.tool.tip.clone().project(this.camera);
    const w = this.canvas.clientWidth;
    const h = this.canvas.clientHeight;
    this.label.style.transform = `translate(${((p.x + 1) / 2) * w + 8}px, ${((1 - p.y) / 2) * h - 24}px)`;
  }

  /** Points the camera at everything in the scene. */
  frameAll() {
    const box = new THREE.Box3();
    for (const o of this.objects.values()) if (o.hasPositions) box.expandByObject(o.mesh);
    if (box.isEmpty()) return;
    this.framed = true;
    const c = box.getCenter(new THREE.Vector3());
    const r = Math.max(0.04, box.getSize(new THREE.Vector3()).length());
    this.controls.target.copy(c);
    const dir = new THREE.Vector3(0.5, 0.45, 0.85).normalize();
    this.camera.position.copy(c).addScaledVector(dir, r * 1.9);
    this.dirty = true;
  }

  /** NDC of a client point. */
  ndc(clientX, clientY) {
    const r = this.canvas.getBoundingClientRect();
    return new THREE.Vector2(((clientX - r.left) / r.width) * 2 - 1, -((clientY - r.top) / r.height) * 2 + 1);
  }

  /** The scene object under a client point: {instanceId, point} or null. */
  pick(clientX, clientY) {
    const ray = new THREE.Raycaster();
    ray.setFromCamera(this.ndc(clientX, clientY), this.camera);
    const meshes = [...this.objects.values()].filter((o) => o.mesh.visible).map((o) => o.mesh);
    const hit = ray.intersectObjects(meshes, false)[0];
    return hit ? { instanceId: hit.object.userData.instanceId, point: hit.point } : null;
  }

  /** Where a client point's ray meets the plane through `through` facing the camera. */
  pointOnViewPlane(clientX, clientY, through) {
    const ray = new THREE.Raycaster();
    ray.setFromCamera(this.ndc(clientX, clientY), this.camera);
    const normal = this.camera.getWorldDirection(new THREE.Vector3()).negate();
    const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(normal, through);
    const out = new THREE.Vector3();
    return ray.ray.intersectPlane(plane, out) ? out : null;
  }

  objectCount() {
    let n = 0;
    for (const o of this.objects.values()) if (o.hasPositions) n++;
    return n;
  }

  /** Drops everything (e.g. a new subscription after reconnecting sends topology again). */
  reset() {
    for (const id of [...this.objects.keys()]) this.removeObject(id);
    this.topology.clear();
    this.lastToolKey = undefined;
    this.dirty = true;
  }
}
