// Open the viewer and count the tileset requests it makes until it is ready (a tileset that points back at itself
// must be read once, not followed for ever):
//   node count_tilesets.mjs URL  ->  {"ready", "tilesets": {path: n}, "errors", "blocked"}
import { localPage } from "./local_browser.mjs";

const [url] = process.argv.slice(2);
const { browser, page, errors, blocked } = await localPage(800, 600);
const tilesets = {};
page.on("request", (r) => {
  const u = new URL(r.url());
  if (u.pathname.endsWith(".json") && u.pathname.includes("/tiles/")) tilesets[u.pathname] = (tilesets[u.pathname] || 0) + 1;
});
try {
  await page.goto(url);
  let ready = true;
  try {
    await page.waitForFunction(() => window.twinViewerReady === true, null, { timeout: 60000 });
  } catch (e) { ready = false; }
  await page.waitForTimeout(1500);
  console.log(JSON.stringify({ ready, tilesets, errors: errors.filter((e) => !e.includes("not followed")), blocked }));
} finally {
  await browser.close();
}
