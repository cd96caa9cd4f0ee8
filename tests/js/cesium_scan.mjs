// CesiumJS (the npm package's built bundle, served from 127.0.0.1; no ion, no imagery, no terrain) opens a twin's
// tiles/tileset.json at its default detail (maximumScreenSpaceError 16) in headless Chromium: the camera frames the
// whole twin, then comes down to street level over one point. For each view: the scan tiles requested (their
// quadtree levels), the points CesiumJS selected to draw, and the car tiles; from the whole twin's view, the count
// of the model tiles' features by their "kind" property. Prints one JSON line.
// usage: node cesium_scan.mjs TWIN_DIR SHOT.png [LON LAT H]   (the street-level camera, H its ellipsoidal height;
// default: 25 m above the tileset's centre)
import http from "node:http";
import fs from "node:fs";
import path from "node:path";
import { fileURLToPath } from "node:url";
import { localPage } from "./local_browser.mjs";

const here = path.dirname(fileURLToPath(import.meta.url));
const cesium = path.resolve(here, "..", "..", "node_modules", "cesium", "Build", "Cesium");
const [twin, shot, lon, lat, h] = process.argv.slice(2);
const TYPES = { ".js": "text/javascript", ".json": "application/json", ".glb": "model/gltf-binary",
  ".css": "text/css", ".wasm": "application/wasm", ".png": "image/png", ".html": "text/html" };

const PAGE = `<!doctype html><html><head><meta charset="utf-8">
<link rel="stylesheet" href="/cesium/Widgets/widgets.css">
<style>html,body,#c{margin:0;width:100%;height:100%;overflow:hidden}</style>
<script>window.CESIUM_BASE_URL = "/cesium/";</script><script src="/cesium/Cesium.js"></script></head>
<body><div id="c"></div><script>
(async () => {
  Cesium.Ion.defaultAccessToken = "";
  const viewer = new Cesium.Viewer("c", { baseLayer: false, baseLayerPicker: false, geocoder: false,
    timeline: false, animation: false, homeButton: false, sceneModePicker: false, navigationHelpButton: false,
    fullscreenButton: false, infoBox: false, selectionIndicator: false,
    terrainProvider: new Cesium.EllipsoidTerrainProvider() });
  viewer.scene.globe.baseColor = Cesium.Color.DIMGRAY;
  const tileset = await Cesium.Cesium3DTileset.fromUrl("/twin/tiles/tileset.json");
  viewer.scene.primitives.add(tileset);
  window.frames = 0;
  viewer.scene.postRender.addEventListener(() => { window.frames += 1; });
  window.viewer = viewer; window.tileset = tileset; window.ready = true;
})().catch((e) => { window.failed = String(e && e.stack || e); });
</script></body></html>`;

function send(res, file) {
  fs.readFile(file, (err, data) => {
    if (err) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { "Content-Type": TYPES[path.extname(file)] || "application/octet-stream" });
    res.end(data);
  });
}

const server = http.createServer((req, res) => {
  const url = decodeURIComponent(new URL(req.url, "http://127.0.0.1").pathname);
  if (url === "/") { res.writeHead(200, { "Content-Type": "text/html" }); res.end(PAGE); return; }
  for (const [prefix, root] of [["/cesium/", cesium], ["/twin/", twin]]) {
    if (url.startsWith(prefix)) {
      const file = path.resolve(root, "." + url.slice(prefix.length - 1));
      if (!file.startsWith(path.resolve(root) + path.sep)) break;
      return send(res, file);
    }
  }
  res.writeHead(404); res.end();
});
await new Promise((ok) => server.listen(0, "127.0.0.1", ok));
const base = `http://127.0.0.1:${server.address().port}/`;

const { browser, page, errors, blocked } = await localPage(Number(process.env.WIDTH || 640), Number(process.env.HEIGHT || 400));
let requests = [];
page.on("request", (r) => {
  const p = new URL(r.url()).pathname;
  if (p.startsWith("/twin/tiles/")) requests.push(p.slice("/twin/tiles/".length));
});
const out = { errors, blocked, views: {} };
try {
  await page.goto(base);
  await page.waitForFunction(() => window.ready || window.failed, null, { timeout: 120000 });
  out.failed = await page.evaluate(() => window.failed || null);
  if (!out.failed) {
    const settle = async () => {
      // loaded and drawn: 6 frames drawn since the move, then no tile pending for 8 polls in a row
      const start = await page.evaluate(() => window.frames);
      await page.waitForFunction((f0) => {
        const t = window.tileset;
        window.__calm = t.tilesLoaded && window.frames > f0 + 6 ? (window.__calm || 0) + 1 : 0;
        return window.__calm > 8;
      }, start, { timeout: 120000, polling: 100 });
      return page.evaluate(() => ({ points: window.tileset.statistics.numberOfPointsSelected,
        selected: window.tileset.statistics.selected, height: window.viewer.camera.positionCartographic.height }));
    };
    const view = async (name, fly) => {
      requests = [];
      await page.evaluate(fly, [Number(lon), Number(lat), Number(h)]);
      const stats = await settle();
      const scan = requests.filter((u) => u.startsWith("scan/") && u.endsWith(".glb"));
      out.views[name] = { ...stats, scan: scan.length, levels: [...new Set(scan.map((u) =>
        Number(path.basename(u).split("-")[0])))].sort(), cars: requests.filter((u) => u.startsWith("cells/")).length };
    };
    await view("city", () => {
      const s = window.tileset.boundingSphere;
      window.viewer.camera.viewBoundingSphere(s, new Cesium.HeadingPitchRange(0, -Math.PI / 3, s.radius * 2.5));
    });
    // the model tiles' features as CesiumJS reads them: each feature's kind (the 3D Tiles metadata)
    out.kinds = await page.evaluate(() => {
      const kinds = {};
      const walk = (tile) => {
        const c = tile.content;
        if (c && !tile.hasEmptyContent && c.featuresLength) {
          for (let i = 0; i < c.featuresLength; i += 1) {
            const f = c.getFeature(i);
            const k = f.hasProperty && f.hasProperty("kind") ? String(f.getProperty("kind")) : "(none)";
            kinds[k] = (kinds[k] || 0) + 1;
          }
        }
        (tile.children || []).forEach(walk);
      };
      walk(window.tileset.root);
      return kinds;
    });
    await view("street", ([x, y, z]) => {
      let at;
      if (Number.isFinite(x)) at = Cesium.Cartesian3.fromDegrees(x, y, z);
      else {
        const c = Cesium.Cartographic.fromCartesian(window.tileset.boundingSphere.center);
        at = Cesium.Cartesian3.fromRadians(c.longitude, c.latitude, c.height + 25);
      }
      window.viewer.camera.setView({ destination: at, orientation: { heading: 0, pitch: -Math.PI / 2, roll: 0 } });
    });
    await view("city_again", () => {
      const s = window.tileset.boundingSphere;
      window.viewer.camera.viewBoundingSphere(s, new Cesium.HeadingPitchRange(0, -Math.PI / 3, s.radius * 2.5));
    });
    if (shot) await page.screenshot({ path: shot });
  }
} finally {
  await browser.close();
  server.close();
}
console.log(JSON.stringify(out));
