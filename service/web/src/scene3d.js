// The 3D view: three.js scene of the model's instances, its grid sensors as false-colour planes, the model's own
// surfaces in false colour where a surface sensor has a result (per triangle: vertex colours on a non-indexed copy
// of the instance's geometry), its lights as markers; highlights of the last push's changes; picking (which node,
// which triangle, which sensor cell) under the mouse.
// World frame and units are the service's: metres, z up.

import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { gridTexels, turbo } from "./colour.js";
import { geometryBytes } from "./api.js";

/** Colours of the last push's change kinds (also shown as the legend of the "Last push" section). */
export const CHANGE_COLOURS = { added: "#2ec27e", moved: "#ff7800", geometry_changed: "#c061cb" };

const loader = new GLTFLoader();
const geometries = new Map();   // geometry id -> Promise<THREE.BufferGeometry>

/** The mesh of a geometry id: its GLB's one primitive, vertices as uploaded (node transforms in the GLB ignored,
 *  as the service ignores them). */
function geometryOf(gid) {
  if (!geometries.has(gid)) {
    geometries.set(gid, geometryBytes(gid).then((bytes) => loader.parseAsync(bytes, "")).then((gltf) => {
      let found = null;
      gltf.scene.traverse((o) => { if (!found && o.isMesh) found = o.geometry; });
      if (!found) throw new Error(`geometry ${gid} holds no mesh`);
      if (!found.attributes.normal) found.computeVertexNormals();
      found.computeBoundingBox();
      return found;
    }));
  }
  return geometries.get(gid);
}

/** A three.js material that suggests the simulation's material (and the node's CAD colour). */
function materialFor(body, colour) {
  const base = new THREE.Color(...(colour ?? [0.72, 0.72, 0.72]));
  const m = new THREE.MeshStandardMaterial({ color: base, roughness: 0.8, metalness: 0.0, side: THREE.DoubleSide });
  switch (body?.type) {
    case "mirror": m.metalness = 1.0; m.roughness = 0.15; m.color.set(0xdddddd); break;
    case "black": m.color.set(0x111111); break;
    case "dielectric": m.transparent = true; m.opacity = 0.35; m.color.set(0xbfd8ff); m.roughness = 0.05; break;
    case "lambertian": if (!colour) m.color.setScalar(0.25 + 0.65 * (body.reflectance ?? 0.5)); break;
    default: break;
  }
  return m;
}

export class Viewer {
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio);
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xeef1f5);
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.01, 1000);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(6, -6, 4);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener("change", () => this.render());
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8899aa, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 1.2);
    sun.position.set(3, -4, 8);
    this.scene.add(sun);
    this.model = new THREE.Group();     // one mesh per instance (userData: instance record)
    this.sensorGroup = new THREE.Group(); // one plane per grid sensor (userData: sensor record)
    this.lightGroup = new THREE.Group();
    this.scene.add(this.model, this.sensorGroup, this.lightGroup);
    this.meshes = new Map();            // instance id -> THREE.Mesh
    this.fitted = false;
    this.size = 1;                      // the model's bounding-box diagonal, m
    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  resize() {
    const { clientWidth: w, clientHeight: h } = this.container;
    if (!w || !h) return;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }

  /** The view shown, as a camera sensor's body (world metres; `fov_deg` vertical, as three.js's `fov`), `height`
   *  pixels high and as wide as the canvas's aspect asks. */
  cameraBody(height = 120) {
    const p = this.camera.position, t = this.controls.target, u = this.camera.up;
    const width = Math.max(1, Math.min(4096, Math.round(height * this.camera.aspect)));
    return { type: "camera", position: [p.x, p.y, p.z], look_at: [t.x, t.y, t.z], up: [u.x, u.y, u.z],
             fov_deg: this.camera.fov, width, height };
  }

  /**
   * Place the state's instances: new ones loaded (their GLB fetched once per geometry), moved ones moved, gone
   * ones removed, each tinted by the last push's change kind when `highlight` is on. Resolves when all are drawn.
   */
  async setInstances(state, highlight) {
    const nodes = new Map(state.nodes.map((n) => [n.uuid, n]));
    const kinds = changeKinds(state.last_push, nodes);
    const wanted = new Set(state.instances.map((r) => r.instance));
    for (const [id, mesh] of this.meshes) {
      if (!wanted.has(id)) { this.model.remove(mesh); this.meshes.delete(id); }
    }
    await Promise.all(state.instances.map(async (rec) => {
      const geometry = await geometryOf(rec.geometry);
      let mesh = this.meshes.get(rec.instance);
      const node = rec.node ? nodes.get(rec.node) : null;
      if (!mesh) {
        mesh = new THREE.Mesh(geometry, materialFor(rec.material, node?.color));
        mesh.matrixAutoUpdate = false;
        this.meshes.set(rec.instance, mesh);
        this.model.add(mesh);
      } else {
        if (mesh.userData.tally) mesh.geometry.dispose();   // a coloured copy (setSurfaces) goes
        mesh.geometry = geometry;
        mesh.material.dispose();
        mesh.material = materialFor(rec.material, node?.color);
      }
      mesh.matrix.set(...rec.matrix);   // row-major world_from_mesh, as the service sends it
      mesh.matrixWorldNeedsUpdate = true;
      const kind = rec.node ? kinds.get(rec.node) : null;
      mesh.userData = { kind: "instance", rec, change: kind ?? null };
      mesh.material.emissive = new THREE.Color(highlight && kind ? CHANGE_COLOURS[kind] : 0x000000);
      mesh.material.emissiveIntensity = highlight && kind ? 0.45 : 0;
    }));
    this.model.updateMatrixWorld(true);
    if (!this.fitted && this.meshes.size) this.fit();
    this.render();
  }

  /** Frame the whole model (once, on the first load: later updates keep the user's camera). */
  fit() {
    // the CAD model and the sensors; a simulation-owned floor (often far larger) only when there is nothing else
    const box = new THREE.Box3();
    for (const mesh of this.meshes.values()) if (mesh.userData.rec.node) box.expandByObject(mesh);
    for (const plane of this.sensorGroup.children) box.expandByObject(plane);
    if (box.isEmpty()) box.setFromObject(this.model);
    if (box.isEmpty()) return;
    const centre = box.getCenter(new THREE.Vector3());
    this.size = Math.max(box.getSize(new THREE.Vector3()).length(), 1e-3);
    this.camera.near = this.size / 1000;
    this.camera.far = this.size * 100;
    this.camera.position.copy(centre).add(new THREE.Vector3(0.9, -1.1, 0.8).multiplyScalar(this.size * 0.9));
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(centre);
    this.controls.update();
    this.fitted = true;
  }

  /** Grid sensors as planes coloured by their latest result on `scale` (grey while not simulated); disks as rings. */
  setSensors(sensors, scale) {
    for (const child of [...this.sensorGroup.children]) {
      this.sensorGroup.remove(child);
      child.geometry.dispose();
      child.material.map?.dispose();
      child.material.dispose();
    }
    for (const s of sensors) {
      const draw = SENSOR_SHAPES[s.type];   // kinds without a shape of their own are not drawn
      if (draw) this.sensorGroup.add(draw(s, scale));
    }
    this.render();
  }

  /**
   * Colour the meshes of every surface sensor's result per triangle on `scale` (the grids' scale and legend): a
   * non-indexed copy of the instance's geometry whose three vertices of triangle k carry the colour of lux[k]
   * (triangle k of the geometry as uploaded: the service's order), unlit like the grid planes. Meshes no result
   * covers any more get their own geometry and material back.
   */
  setSurfaces(sensors, scale) {
    const wanted = new Map();   // instance id -> { sensor, lux, stderr }
    for (const s of sensors) {
      if (s.type !== "surface" || !s.result?.instances) continue;
      for (const part of s.result.instances) wanted.set(part.instance, { sensor: s, lux: part.lux, stderr: part.stderr });
    }
    for (const [id, mesh] of this.meshes) {
      const tally = wanted.get(id);
      if (mesh.userData.tally) {   // back to the plain mesh first
        mesh.geometry.dispose();
        mesh.material.dispose();
        mesh.geometry = mesh.userData.plain.geometry;
        mesh.material = mesh.userData.plain.material;
        delete mesh.userData.tally;
        delete mesh.userData.plain;
      }
      if (!tally) continue;
      const flat = mesh.geometry.index ? mesh.geometry.toNonIndexed() : mesh.geometry.clone();
      const n = flat.attributes.position.count / 3;
      if (n !== tally.lux.length) { flat.dispose(); continue; }   // another revision's mesh: leave it plain
      const colours = new Float32Array(9 * n);
      const c = new THREE.Color();
      for (let k = 0; k < n; k++) {
        const [r, g, b] = turbo(scale.norm(tally.lux[k]));
        c.setRGB(r, g, b, THREE.SRGBColorSpace);   // the legend's sRGB colour, drawn as such
        for (let j = 0; j < 3; j++) colours.set([c.r, c.g, c.b], 9 * k + 3 * j);
      }
      flat.setAttribute("color", new THREE.BufferAttribute(colours, 3));
      mesh.userData.plain = { geometry: mesh.geometry, material: mesh.material };
      mesh.userData.tally = tally;
      mesh.geometry = flat;
      mesh.material = new THREE.MeshBasicMaterial({ vertexColors: true, side: THREE.DoubleSide });
    }
    this.render();
  }

  /** Lights as small yellow spheres, with an arrow along a spot's or collimated light's direction. */
  setLights(lights) {
    this.lightGroup.clear();
    const r = Math.max(this.size * 0.012, 0.005);
    for (const light of lights) {
      const at = light.position ?? light.origin;
      if (!at) continue;   // an area light is its node's surfaces
      const marker = new THREE.Mesh(new THREE.SphereGeometry(r, 16, 8), new THREE.MeshBasicMaterial({ color: 0xf6c945 }));
      marker.position.set(...at);
      marker.userData = { kind: "light", light };
      this.lightGroup.add(marker);
      if (light.direction) {
        const d = new THREE.Vector3(...light.direction).normalize();
        this.lightGroup.add(new THREE.ArrowHelper(d, marker.position, r * 8, 0xe5a50a, r * 2.5, r * 1.5));
      }
    }
    this.render();
  }

  /**
   * What is under the client point (x, y): the nearest surface, and a sensor cell if a sensor plane is (about)
   * as near — a sensor lying on a floor wins over the floor, and the floor is still named.
   */
  pick(clientX, clientY) {
    const rect = this.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.camera);
    const surface = ray.intersectObjects([...this.meshes.values()], false)[0] ?? null;
    const sensorHit = ray.intersectObjects(this.sensorGroup.children, false)[0] ?? null;
    const tolerance = this.size * 1e-3;
    const sensor = sensorHit && (!surface || sensorHit.distance <= surface.distance + tolerance) ? sensorHit : null;
    if (!surface && !sensor) return null;
    const out = { point: (sensor ?? surface).point.toArray() };
    if (surface) {
      const normal = surface.face.normal.clone().transformDirection(surface.object.matrixWorld);
      if (normal.dot(ray.ray.direction) > 0) normal.negate();   // the side facing the viewer
      out.surface = { rec: surface.object.userData.rec, point: surface.point.toArray(), normal: normal.toArray(),
        triangle: surface.faceIndex, tally: surface.object.userData.tally ?? null };
    }
    if (sensor && sensor.object.userData.cells) {
      const s = sensor.object.userData.sensor;
      const i = Math.min(s.nu - 1, Math.floor(sensor.uv.x * s.nu));
      const j = Math.min(s.nv - 1, Math.floor(sensor.uv.y * s.nv));
      out.sensor = { sensor: s, i, j };
    }
    return out;
  }

  /** Client coordinates of a world point (tests click through it). */
  screenOf(p) {
    const v = new THREE.Vector3(...p).project(this.camera);
    const rect = this.renderer.domElement.getBoundingClientRect();
    return { x: rect.left + ((v.x + 1) / 2) * rect.width, y: rect.top + ((1 - v.y) / 2) * rect.height };
  }

  /** The RGBA bytes drawn at client point (x, y) (tests compare them with the false colour they expect). */
  pixelAt(x, y) {
    this.render();
    const gl = this.renderer.getContext();
    const rect = this.renderer.domElement.getBoundingClientRect();
    const ratio = this.renderer.getPixelRatio();
    const out = new Uint8Array(4);
    gl.readPixels(Math.round((x - rect.left) * ratio), Math.round((rect.bottom - y) * ratio), 1, 1, gl.RGBA,
      gl.UNSIGNED_BYTE, out);
    return [...out];
  }

  /** The world matrix (16 numbers, row-major) an instance is drawn with, or null. */
  matrixOf(instance) {
    const mesh = this.meshes.get(instance);
    return mesh ? mesh.matrixWorld.clone().transpose().toArray() : null;
  }

  /** How many meshes of each kind the three.js scene holds now. */
  counts() {
    let instances = 0;
    let sensors = 0;
    this.scene.traverse((o) => {
      if (!o.isMesh) return;
      if (o.userData.kind === "instance") instances++;
      if (o.userData.kind === "sensor") sensors++;
    });
    return { instances, sensors };
  }
}

/** node uuid -> change kind of the last push; an added or moved assembly marks every node below it. */
function changeKinds(push, nodes) {
  const kinds = new Map();
  if (!push) return kinds;
  const direct = new Map();
  for (const kind of ["added", "moved", "geometry_changed"]) for (const u of push[kind] ?? []) direct.set(u, kind);
  for (const [uuid] of nodes) {
    let kind = direct.get(uuid);
    for (let p = nodes.get(uuid)?.parent; !kind && p; p = nodes.get(p)?.parent) {
      const up = direct.get(p);
      if (up === "added" || up === "moved") kind = up;
    }
    if (kind) kinds.set(uuid, kind);
  }
  return kinds;
}

/** The plane of a grid sensor: corners origin, +u, +u+v, +v (uv = cell coordinates); drawn over the surface it lies on. */
function gridPlane(s, scale) {
  const o = new THREE.Vector3(...s.origin);
  const u = new THREE.Vector3(...s.u);
  const v = new THREE.Vector3(...s.v);
  const corners = [o, o.clone().add(u), o.clone().add(u).add(v), o.clone().add(v)];
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.Float32BufferAttribute(corners.flatMap((c) => c.toArray()), 3));
  g.setAttribute("uv", new THREE.Float32BufferAttribute([0, 0, 1, 0, 1, 1, 0, 1], 2));
  g.setIndex([0, 1, 2, 0, 2, 3]);
  const m = new THREE.MeshBasicMaterial({
    side: THREE.DoubleSide, polygonOffset: true, polygonOffsetFactor: -2, polygonOffsetUnits: -8,
  });
  if (s.result) {
    const tex = new THREE.DataTexture(gridTexels(s.result.lux, scale), s.nu, s.nv, THREE.RGBAFormat);
    tex.magFilter = THREE.NearestFilter;
    tex.minFilter = THREE.NearestFilter;
    tex.colorSpace = THREE.SRGBColorSpace;
    tex.needsUpdate = true;
    m.map = tex;
  } else {
    m.color.set(0x99c1f1);   // not simulated at this revision: a translucent blue sheet
    m.transparent = true;
    m.opacity = 0.45;
  }
  const mesh = new THREE.Mesh(g, m);
  mesh.userData = { kind: "sensor", sensor: s, coloured: Boolean(s.result), cells: true };   // hover names a cell
  return mesh;
}

/** The sensor kinds the view draws, by type: the only place in the page that tells sensor kinds apart. */
const SENSOR_SHAPES = { grid: gridPlane, disk: diskMarker };

/** A disk sensor: a thin ring where it measures. */
function diskMarker(s) {
  const ring = new THREE.Mesh(new THREE.RingGeometry(s.radius * 0.8, s.radius, 24),
    new THREE.MeshBasicMaterial({ color: 0x3584e4, side: THREE.DoubleSide }));
  ring.position.set(...s.center);
  ring.lookAt(ring.position.clone().add(new THREE.Vector3(...s.normal)));
  ring.userData = { kind: "sensor", sensor: s, coloured: false };
  return ring;
}
