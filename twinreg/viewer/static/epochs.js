// The twin over time: reads view/epochs.json and changes.json written by `twinreg compare`, shows one epoch at a
// time (the slider or the buttons) with its scan and its cars as boxes coloured by status (what brought each car
// there; for the first epoch, what became of it), the cars that left or went unobserved as ghosts, and a click on
// a car shows its history. A twin may come from someone else: its text is shown with textContent only.
import * as THREE from "three";
import { makeStage, textTable } from "./stage.js";

const COLOURS = { same: 0x9aa5ad, moved: 0xf39c12, replaced: 0xa55eea, left: 0xe74c3c, arrived: 0x2ecc71,
  unobserved: 0x6c7a89 };
const stage = makeStage([new THREE.HemisphereLight(0xffffff, 0x666666, 2.4)]);
const { world, redraw } = stage;

let data = null, changes = null, current = 0;
const layers = [];   // per epoch: {group, cars (InstancedMesh), items, ghosts}
const box = new THREE.BoxGeometry(1, 1, 1);

function instanced(items, transparent) {
  const mat = new THREE.MeshLambertMaterial({ color: 0xffffff, transparent, opacity: transparent ? 0.35 : 1.0,
    wireframe: transparent });
  const mesh = new THREE.InstancedMesh(box, mat, Math.max(items.length, 1));
  mesh.count = items.length;
  const m = new THREE.Matrix4(), q = new THREE.Quaternion(), z = new THREE.Vector3(0, 0, 1);
  items.forEach((o, k) => {
    q.setFromAxisAngle(z, o.h);
    m.compose(new THREE.Vector3(o.c[0], o.c[1], o.c[2]), q, new THREE.Vector3(o.l, o.w, o.ht));
    mesh.setMatrixAt(k, m);
    mesh.setColorAt(k, new THREE.Color(COLOURS[o.status] ?? 0xffffff));
  });
  if (mesh.instanceColor) mesh.instanceColor.needsUpdate = true;
  mesh.userData.items = items;
  return mesh;
}

async function loadEpoch(e) {
  const group = new THREE.Group();
  const buf = await (await fetch("/twin/view/" + encodeURIComponent(e.scan))).arrayBuffer();
  const n = e.n_points;
  if (n > 0 && buf.byteLength === n * 15) {
    const geom = new THREE.BufferGeometry();
    geom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(buf, 0, n * 3), 3));
    geom.setAttribute("color", new THREE.BufferAttribute(new Uint8Array(buf, n * 12, n * 3), 3, true));
    group.add(new THREE.Points(geom, new THREE.PointsMaterial({ size: 3, sizeAttenuation: false, vertexColors: true })));
  }
  const cars = instanced(e.objects, false), ghosts = instanced(e.ghosts, true);
  group.add(cars, ghosts);
  group.visible = false;
  world.add(group);
  return { group, cars, ghosts, epoch: e };
}

function counts(items) {
  const c = {};
  for (const o of items) c[o.status] = (c[o.status] || 0) + 1;
  return c;
}

function setEpoch(k) {
  current = Math.max(0, Math.min(layers.length - 1, Number(k)));
  layers.forEach((l, i) => { l.group.visible = i === current; });
  const e = layers[current].epoch;
  document.getElementById("epoch").value = String(current);
  document.getElementById("date").textContent = `epoch ${current}: ${e.date || "no date"}`;
  const legend = document.getElementById("legend");
  legend.replaceChildren();
  const c = counts(e.objects.concat(e.ghosts));
  for (const [status, colour] of Object.entries(COLOURS)) {
    if (!c[status]) continue;
    const row = document.createElement("div");
    const sw = document.createElement("span");
    sw.className = "swatch";
    sw.dataset.status = status;
    row.appendChild(sw);
    row.appendChild(document.createTextNode(`${status}: ${c[status]}`));
    legend.appendChild(row);
  }
  document.getElementById("details").replaceChildren();
  redraw();
}

function history(item) {
  const d = document.getElementById("details");
  d.replaceChildren();
  const epoch = current;
  const track = (changes.tracks || []).find((t) => t.epochs.some((k, i) => k === epoch && t.ids[i] === item.id));
  const rows = [["object", item.id], ["model", item.model || "none"], ["status", item.status]];
  if (track) {
    rows.push(["vehicle", track.id], ["seen in epochs", track.epochs.join(", ")],
      ["first seen", track.first_seen.date || `epoch ${track.first_seen.epoch}`],
      ["last seen", track.last_seen.date || `epoch ${track.last_seen.epoch}`],
      ["days", track.days == null ? "-" : String(track.days)], ["ended", track.end || "-"]);
  }
  for (const c of changes.changes) {
    const mine = (c.from === epoch && c.before && c.before.id === item.id) || (c.to === epoch && c.after && c.after.id === item.id);
    if (!mine) continue;
    const what = `${c.status} (${c.confidence.toFixed(2)})` + (c.displacement_m != null ? `, ${c.displacement_m.toFixed(2)} m` : "");
    rows.push([`epoch ${c.from} -> ${c.to}`, what], ["why", c.reason || ""]);
  }
  d.appendChild(textTable(rows));
}

stage.onClick(() => [layers[current].cars, layers[current].ghosts],
  (hit) => history(hit.object.userData.items[hit.instanceId]));

// screen positions and colours of the current epoch's cars (for tests and scripts)
window.epochViewerProbe = () => {
  const out = [], l = layers[current];
  l.cars.updateMatrixWorld(true);
  l.cars.userData.items.forEach((o) => {
    const top = new THREE.Vector3(o.c[0], o.c[1], o.c[2] + o.ht / 2).applyMatrix4(l.cars.matrixWorld);
    out.push({ id: o.id, status: o.status, ...stage.toScreen(top), colour: new THREE.Color(COLOURS[o.status]).getHexString() });
  });
  return out;
};
window.setEpoch = (k) => { setEpoch(k); stage.render(); };

async function main() {
  data = await (await fetch("/twin/view/epochs.json")).json();
  changes = await (await fetch("/twin/changes.json")).json();
  for (const e of data.epochs) layers.push(await loadEpoch(e));
  const bounds = new THREE.Box3();
  world.updateMatrixWorld(true);
  layers.forEach((l) => { l.group.visible = true; bounds.expandByObject(l.group); });
  stage.frame(bounds, new THREE.Vector3(0.05, 0.92, 0.38));
  const slider = document.getElementById("epoch");
  slider.max = String(layers.length - 1);
  slider.oninput = (e) => setEpoch(e.target.value);
  const buttons = document.getElementById("buttons");
  layers.forEach((l, k) => {
    const b = document.createElement("button");
    b.textContent = l.epoch.date || `epoch ${k}`;
    b.onclick = () => setEpoch(k);
    buttons.appendChild(b);
  });
  document.getElementById("summary").textContent =
    `${layers.length} surveys; ${changes.changes.length} changes; ${(changes.tracks || []).length} vehicles`;
  setEpoch(layers.length - 1);
  stage.render();
  window.epochViewerReady = true;
}

main().then(redraw).catch(stage.fail);
