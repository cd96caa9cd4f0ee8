// What both viewer pages share: the renderer in #view, a Z-up world (east, north, up) under three.js's Y-up scene,
// orbit controls, drawing on demand (a city of thousands of cars is heavy for a laptop's GPU, and for a software
// one), framing the camera on what is loaded, and picking from a click.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

export function makeStage(lights) {
  const view = document.getElementById("view");
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(view.clientWidth, view.clientHeight);
  view.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x20242b);
  for (const light of lights) scene.add(light);
  const camera = new THREE.PerspectiveCamera(45, view.clientWidth / view.clientHeight, 0.5, 50000);
  const controls = new OrbitControls(camera, renderer.domElement);
  const world = new THREE.Group();
  world.rotation.x = -Math.PI / 2;
  scene.add(world);
  let pending = false;
  const redraw = () => {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => { pending = false; renderer.render(scene, camera); });
  };
  controls.addEventListener("change", redraw);
  window.addEventListener("resize", () => {
    camera.aspect = view.clientWidth / view.clientHeight; camera.updateProjectionMatrix();
    renderer.setSize(view.clientWidth, view.clientHeight);
    redraw();
  });
  // the box of the world in view, seen from ``direction`` (three.js axes: y up)
  const frame = (box, direction) => {
    const centre = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3());
    const span = Math.max(size.x, size.z, 20);
    const dist = 0.62 * span / Math.tan(THREE.MathUtils.degToRad(camera.fov / 2));
    controls.target.copy(centre);
    camera.position.copy(centre).add(direction.clone().normalize().multiplyScalar(dist));
    camera.far = dist * 20; camera.updateProjectionMatrix();
    controls.update();
  };
  // the first of ``objects`` under a click, through ``onHit(hit)``
  const ray = new THREE.Raycaster();
  const onClick = (objects, onHit) => renderer.domElement.addEventListener("click", (ev) => {
    const r = renderer.domElement.getBoundingClientRect();
    ray.setFromCamera(new THREE.Vector2(((ev.clientX - r.left) / r.width) * 2 - 1,
      -((ev.clientY - r.top) / r.height) * 2 + 1), camera);
    const hit = ray.intersectObjects(objects(), false)[0];
    if (hit && hit.instanceId !== undefined) onHit(hit);
  });
  // a screen position (css pixels) of a world-space point
  const toScreen = (v) => {
    const r = renderer.domElement.getBoundingClientRect(), p = v.clone().project(camera);
    return { x: (p.x + 1) / 2 * r.width, y: (1 - p.y) / 2 * r.height };
  };
  const fail = (e) => { console.error("viewer failed: " + e); document.getElementById("summary").textContent = "error: " + e; };
  return { renderer, scene, camera, controls, world, redraw, frame, onClick, toScreen, fail,
    render: () => renderer.render(scene, camera) };
}

// a two-column table of [key, value] rows, every cell set as text (a twin's strings are never markup)
export function textTable(rows) {
  const table = document.createElement("table");
  for (const [k, v] of rows) {
    const tr = table.insertRow();
    tr.insertCell().textContent = k;
    tr.insertCell().textContent = String(v);
  }
  return table;
}
