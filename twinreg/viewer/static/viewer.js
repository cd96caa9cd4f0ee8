// The twin viewer: reads tiles/tileset.json (children, transforms, external tilesets, GLB content with
// EXT_mesh_gpu_instancing) with three.js, shows the scan and the placed models, a click on a car shows its
// twin.json record and sections, the search box finds cars by model name. Everything comes from 127.0.0.1.
// A twin may come from someone else: what it says is shown as text (textContent), never parsed as HTML.
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { LodTile, matrixOf } from "./lod.js";
import { makeStage, textTable } from "./stage.js";

const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(0.4, 1.0, 0.3);
const stage = makeStage([new THREE.HemisphereLight(0xffffff, 0x555555, 2.2), sun]);
const { camera, controls, world, redraw } = stage;
const loader = new GLTFLoader();
const cars = [];        // instanced meshes of the models, each with userData.ids
const stats = { tiles: 0, instances: 0, points: 0, scanRequests: 0, scanTiles: 0, scanPoints: 0 };
const scanRoots = [];   // the scan's tilesets, streamed by screen-space error (lod.js)

async function loadPoints(href) {
  const gltf = await loader.loadAsync(href);
  gltf.scene.rotation.x = Math.PI / 2;   // glTF Y-up -> the tile's Z-up
  gltf.scene.traverse((o) => { if (o.isPoints) { o.material.size = 1.5; o.material.sizeAttenuation = false; } });
  return gltf.scene;
}

// refine the scan for the current view; the stats say what is shown
let lodRunning = null, lodAgain = false;
async function updateScan() {
  if (lodRunning) { lodAgain = true; return lodRunning; }
  lodRunning = (async () => {
    do {
      lodAgain = false;
      world.updateMatrixWorld(true);
      const shown = { points: 0, tiles: 0 };
      const height = stage.renderer.domElement.clientHeight;
      await Promise.all(scanRoots.map((r) => r.update(camera, height, shown)));
      stats.scanPoints = shown.points; stats.scanTiles = shown.tiles;
      redraw();
    } while (lodAgain);
  })();
  await lodRunning;
  lodRunning = null;
}

// a stranger's tileset may nest without end or point back at itself: each external tileset is read once, and no
// deeper than MAX_DEPTH tiles
const MAX_DEPTH = 64;
const seenTilesets = new Set();

async function loadTile(tile, base, parent, depth = 0) {
  if (depth > MAX_DEPTH) { console.warn(`tileset deeper than ${MAX_DEPTH} levels: not followed`); return; }
  const group = new THREE.Group();
  group.matrixAutoUpdate = false;
  group.matrix.copy(matrixOf(tile));
  parent.add(group);
  if (tile.content) {
    const uri = new URL(tile.content.uri, base);
    if (uri.pathname.endsWith(".json") && uri.pathname.includes("/scan/")) {
      scanRoots.push(new LodTile({ boundingVolume: tile.boundingVolume, content: tile.content,
        geometricError: tile.geometricError }, base, group, loadPoints, stats));
    } else if (uri.pathname.endsWith(".json")) {
      if (seenTilesets.has(uri.href)) { console.warn(`${uri.pathname} is read already: not followed again`); return; }
      seenTilesets.add(uri.href);
      const ext = await (await fetch(uri)).json();
      await loadTile(ext.root, uri, group, depth + 1);
    } else {
      const gltf = await loader.loadAsync(uri.href);
      gltf.scene.rotation.x = Math.PI / 2;   // glTF Y-up -> the tile's Z-up
      group.add(gltf.scene);
      stats.tiles += 1;
      gltf.scene.traverse((o) => {
        if (o.isInstancedMesh) {
          let p = o; while (p && !p.userData.ids) p = p.parent;
          o.userData.ids = p ? p.userData.ids : [];
          cars.push(o);
          stats.instances += o.count;
        } else if (o.isPoints) {
          o.material.size = 1.5; o.material.sizeAttenuation = false;
          stats.points += o.geometry.attributes.position.count;
        }
      });
    }
  }
  await Promise.all((tile.children || []).map((c) => loadTile(c, base, group, depth + 1)));
}

let twin = null, sections = {};
const byId = new Map();

function showObject(id) {
  const o = byId.get(id);
  const d = document.getElementById("details");
  d.replaceChildren();
  if (!o) return;
  const m = o.match;
  const rows = [["id", o.id], ["model", m ? `${m.name} (${m.make || ""} ${m.model || ""})` : "none: " + (o.reason || "")],
    ["confidence", m && m.confidence != null ? m.confidence.toFixed(2) : "-"],
    ["RMSE", m ? (m.rmse_m * 100).toFixed(1) + " cm" : "-"],
    ["size", `${o.size.length} x ${o.size.width} x ${o.size.height} m`],
    ["measured", o.measured_size ? `${o.measured_size.length.toFixed(2)} x ${o.measured_size.width.toFixed(2)} x ${o.measured_size.height.toFixed(2)} m` : "-"],
    ["lat, lon", `${o.lat.toFixed(7)}, ${o.lon.toFixed(7)}`], ["bearing", `${o.bearing_deg.toFixed(1)} deg`],
    ["points", o.n_points], ["cluster", o.cluster]];
  d.appendChild(textTable(rows));
  const s = sections[id];
  if (s) {
    const c = document.createElement("canvas");
    c.className = "sections"; c.width = 540; c.height = 200;
    d.appendChild(c);
    drawSections(c, s);
  }
}

function drawSections(c, s) {
  const g = c.getContext("2d");
  const panels = [["longitudinal", s.lon, s.model_lon], ["transverse", s.tra, s.model_tra]];
  panels.forEach(([name, pts, model], k) => {
    const x0 = k * 270, all = (pts || []).concat(model || []);
    if (!all.length) return;
    const us = all.map((p) => p[0]), zs = all.map((p) => p[1]);
    const umin = Math.min(...us), umax = Math.max(...us), zmin = Math.min(...zs), zmax = Math.max(...zs);
    const sc = Math.min(250 / (umax - umin || 1), 170 / (zmax - zmin || 1));
    const at = (p) => [x0 + 10 + (p[0] - umin) * sc, 190 - (p[1] - zmin) * sc];
    g.fillStyle = "#333"; g.fillText(name, x0 + 10, 12);
    g.fillStyle = "#1f77b4"; (pts || []).forEach((p) => { const [x, y] = at(p); g.fillRect(x - 1, y - 1, 2, 2); });
    g.fillStyle = "#d62728"; (model || []).forEach((p) => { const [x, y] = at(p); g.fillRect(x, y, 1, 1); });
  });
}

function search(text) {
  const hits = document.getElementById("hits");
  hits.replaceChildren();
  const q = text.trim().toLowerCase();
  if (!q) return;
  const found = twin.objects.filter((o) => o.match && String(o.match.name).toLowerCase().includes(q)).slice(0, 200);
  const count = document.createElement("div");
  count.textContent = `${found.length} found`;
  hits.appendChild(count);
  for (const o of found) {
    const el = document.createElement("div");
    el.dataset.id = o.id;
    el.textContent = `${o.id}: ${o.match.name}`;
    el.addEventListener("click", () => focusOn(o.id));
    hits.appendChild(el);
  }
}

function carPosition(id) {
  for (const mesh of cars) {
    const k = mesh.userData.ids.indexOf(id);
    if (k >= 0) {
      const m = new THREE.Matrix4();
      mesh.getMatrixAt(k, m);
      return new THREE.Vector3().setFromMatrixPosition(m.premultiply(mesh.matrixWorld));
    }
  }
  return null;
}

function focusOn(id) {
  const p = carPosition(id);
  showObject(id);
  if (!p) return;
  const offset = camera.position.clone().sub(controls.target).setLength(25);
  controls.target.copy(p);
  camera.position.copy(p).add(offset);
  controls.update();
  redraw();
}

stage.onClick(() => cars, (hit) => showObject(hit.object.userData.ids[hit.instanceId]));

// screen positions of the cars (for tests and scripts): [{id, x, y, model}]
// move the camera towards (factor < 1) or away from its target, then stream the scan for the new view
window.twinViewerZoom = async (factor, target) => {
  if (target) controls.target.set(target[0], target[1], target[2]);
  const offset = camera.position.clone().sub(controls.target).multiplyScalar(factor);
  camera.position.copy(controls.target).add(offset);
  controls.update();
  await updateScan();
  stage.render();
  return Object.assign({}, stats);
};

// show only the objects of one kind ("" for every kind): the others' instances are scaled to nothing
const shownMatrices = new Map();
function filterKind(kind) {
  for (const mesh of cars) {
    if (!shownMatrices.has(mesh)) shownMatrices.set(mesh, mesh.instanceMatrix.array.slice());
    const src = shownMatrices.get(mesh), dst = mesh.instanceMatrix.array;
    mesh.userData.ids.forEach((id, k) => {
      const show = !kind || (byId.get(id) || {}).kind === kind;
      for (let j = 0; j < 16; j++) dst[k * 16 + j] = show ? src[k * 16 + j] : 0;
    });
    mesh.instanceMatrix.needsUpdate = true;
  }
  stage.render();
}
window.twinViewerFilter = (kind) => { document.getElementById("kind").value = kind; filterKind(kind); };

function kindOptions() {
  const counts = new Map();
  for (const o of twin.objects) counts.set(o.kind || "unknown", (counts.get(o.kind || "unknown") || 0) + 1);
  const select = document.getElementById("kind");
  select.options[0].textContent = `every kind (${twin.objects.length})`;
  for (const [kind, n] of [...counts.entries()].sort((a, b) => b[1] - a[1])) {
    const opt = document.createElement("option");
    opt.value = kind;
    opt.textContent = `${kind} (${n})`;
    select.appendChild(opt);
  }
  select.onchange = (e) => filterKind(e.target.value);
}

window.twinViewerProbe = () => {
  const out = [];
  for (const mesh of cars) {
    const m = new THREE.Matrix4(), colour = mesh.material.color ? mesh.material.color.getHexString() : "";
    for (let k = 0; k < mesh.count; k++) {
      mesh.getMatrixAt(k, m);
      if (m.determinant() === 0) continue;  // hidden by the kind filter
      const box = mesh.geometry.boundingBox || (mesh.geometry.computeBoundingBox(), mesh.geometry.boundingBox);
      const centre = box.getCenter(new THREE.Vector3()).applyMatrix4(m).applyMatrix4(mesh.matrixWorld);
      out.push({ id: mesh.userData.ids[k], ...stage.toScreen(centre), colour });
    }
  }
  return out;
};

async function main() {
  const t0 = performance.now();
  twin = await (await fetch("/twin/twin.json")).json();
  twin.objects.forEach((o) => byId.set(o.id, o));
  try { sections = await (await fetch("/twin/sections.json")).json(); } catch (e) { sections = {}; }
  const tilesetUrl = new URL("/twin/tiles/tileset.json", window.location.href);
  const tileset = await (await fetch(tilesetUrl)).json();
  seenTilesets.add(tilesetUrl.href);
  const root = Object.assign({}, tileset.root, { transform: undefined });  // the local frame: no ECEF
  await loadTile(root, tilesetUrl, world);
  world.updateMatrixWorld(true);
  // the whole twin in view, seen from the south and above
  stage.frame(new THREE.Box3().setFromObject(world), new THREE.Vector3(0.1, 0.85, 0.52));
  const matched = twin.objects.filter((o) => o.match).length;
  // the shapes drawn for objects without a model: their type's fused shape or the kind's template (each type in a
  // colour of its own, as each model is), or a box (red)
  const fused = twin.objects.filter((o) => !o.match && o.shape && ["fused", "generic"].includes(o.shape.source)).length;
  document.getElementById("title").textContent = `twinreg: ${twin.scene}`;
  document.getElementById("search").oninput = (e) => search(e.target.value);
  kindOptions();
  await updateScan();
  controls.addEventListener("change", () => { updateScan(); });
  document.getElementById("summary").textContent =
    `${twin.objects.length} objects, ${matched} with a model, ${fused} with their type's fused shape (a colour a type), ` +
    `${twin.objects.length - matched - fused} as boxes (red); ${stats.instances} instances in ${stats.tiles} tiles; ` +
    `the scan streamed by level of detail (${stats.scanPoints.toLocaleString()} points in view)`;
  stage.render();
  stats.ms = performance.now() - t0;
  window.twinViewerStats = stats;
  window.twinViewerReady = true;
}

main().then(redraw).catch(stage.fail);
