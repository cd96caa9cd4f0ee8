// The scan streamed by screen-space error, as 3D Tiles viewers draw a point tileset: a tile's content is fetched
// when it comes into view at a level of detail the screen needs, its children (refine: ADD) only while its
// geometric error spans more than MAX_SSE pixels; tiles that are no longer needed are hidden (kept loaded).
import * as THREE from "three";

export const MAX_SSE = 16;

// a tile's transform as a three.js matrix
export function matrixOf(spec) {
  const m = new THREE.Matrix4();
  if (spec.transform) m.fromArray(spec.transform);   // column-major, as 3D Tiles stores it
  return m;
}

// a stranger's tileset may nest without end or point back at itself: each external tileset is read once (per
// scan root), and no deeper than MAX_DEPTH tiles
const MAX_DEPTH = 64;

export class LodTile {
  constructor(spec, base, parent, loadGlb, stats, depth = 0, seen = new Set()) {
    this.spec = spec; this.base = base; this.loadGlb = loadGlb; this.stats = stats;
    this.depth = depth; this.seen = seen;
    this.group = new THREE.Group();
    this.group.matrixAutoUpdate = false;
    this.group.matrix.copy(matrixOf(spec));
    parent.add(this.group);
    this.children = null; this.state = "new"; this.points = 0;
  }

  // the tile's bounding sphere in world coordinates
  sphere() {
    const b = this.spec.boundingVolume.box;
    const centre = new THREE.Vector3(b[0], b[1], b[2]).applyMatrix4(this.group.matrixWorld);
    const r = Math.hypot(Math.hypot(b[3], b[4], b[5]), Math.hypot(b[6], b[7], b[8]), Math.hypot(b[9], b[10], b[11]));
    return { centre, radius: r };
  }

  sse(camera, height) {
    if (!this.spec.geometricError) return 0;
    const { centre, radius } = this.sphere();
    const d = Math.max(camera.position.distanceTo(centre) - radius, 1e-3);
    return this.spec.geometricError * height / (2 * d * Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2));
  }

  async load() {
    if (this.state !== "new") return;
    this.state = "loading";
    const c = this.spec.content;
    if (c) {
      const uri = new URL(c.uri, this.base);
      this.stats.scanRequests += 1;
      if (uri.pathname.endsWith(".json")) {   // an external tileset: its root is this tile's only child
        if (this.seen.has(uri.href) || this.depth >= MAX_DEPTH) {
          this.children = [];
          console.warn(`${uri.pathname}: read already or nested too deep, not followed`);
        } else {
          this.seen.add(uri.href);
          const ext = await (await fetch(uri)).json();
          this.children = [new LodTile(ext.root, uri, this.group, this.loadGlb, this.stats, this.depth + 1, this.seen)];
        }
      } else {
        const scene = await this.loadGlb(uri.href);
        this.group.add(scene);
        scene.traverse((o) => { if (o.isPoints) this.points += o.geometry.attributes.position.count; });
      }
    }
    if (!this.children) {
      this.children = this.depth >= MAX_DEPTH ? [] : (this.spec.children || []).map(
        (s) => new LodTile(s, this.base, this.group, this.loadGlb, this.stats, this.depth + 1, this.seen));
    }
    this.state = "ready";
  }

  // show this tile and refine where the screen needs it; resolves when what is shown is loaded
  async update(camera, height, shown) {
    this.group.visible = true;
    await this.load();
    shown.points += this.points;
    if (this.points) shown.tiles += 1;
    const refine = !this.spec.content || this.spec.content.uri.endsWith(".json") || this.sse(camera, height) > MAX_SSE;
    const jobs = [];
    for (const child of this.children) {
      child.group.updateMatrixWorld(true);
      if (refine) jobs.push(child.update(camera, height, shown));
      else child.group.visible = false;
    }
    await Promise.all(jobs);
  }
}
