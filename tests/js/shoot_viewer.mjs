// Open the twinreg viewer in the system's headless Chromium (local_browser.mjs: every request that is not local is
// refused), wait for the viewer's ready flag, save a screenshot and print one JSON
// line: {"ready", "ms", "stats", "errors", "blocked", "cars": [{id, x, y, colour}], "clicked", "found", "zoom",
// "kinds": the kind filter's options and the ids drawn with each};
// with "zoom" as the fifth argument, the camera then goes close and back ("zoom": the stats at each step).
//   node shoot_viewer.mjs URL SCREENSHOT.png [width height [zoom]]
import { localPage } from "./local_browser.mjs";

const [url, shot, w = "1280", h = "800", zoomed = ""] = process.argv.slice(2);
const { browser, page, errors, blocked } = await localPage(w, h);
try {
  const t0 = Date.now();
  await page.goto(url);
  let ready = true;
  try {
    await page.waitForFunction(() => window.twinViewerReady === true, null, { timeout: 120000 });
  } catch (e) { ready = false; errors.push("not ready: " + e.message.split("\n")[0]); }
  const ms = Date.now() - t0;
  await page.waitForTimeout(300);
  const stats = await page.evaluate(() => window.twinViewerStats || null);
  const cars = ready ? await page.evaluate(() => window.twinViewerProbe()) : [];
  await page.screenshot({ path: shot });
  // a click on the first car shows its record and its sections; the search finds cars by model name
  let clicked = null, found = null;
  if (cars.length) {
    await page.mouse.click(cars[0].x, cars[0].y);
    clicked = await page.evaluate(() => ({ text: document.getElementById("details").innerText,
      sections: document.querySelectorAll("#details canvas.sections").length }));
    const model = (clicked.text.match(/model\s+(\S+)/) || [])[1] || "";
    await page.fill("#search", model);
    found = { model, hits: await page.evaluate(() => document.querySelectorAll("#hits div[data-id]").length) };
  }
  // the scan streamed by level of detail: closer to a car, denser tiles are requested; back out, they are hidden
  let zoom = null;
  if (ready && zoomed) {
    const near = await page.evaluate(() => window.twinViewerZoom(0.08));
    const far = await page.evaluate(() => window.twinViewerZoom(1 / 0.08));
    zoom = { start: stats, near, far };
  }
  // the kind filter: its options, and the objects drawn with each of them chosen (and with a kind the twin lacks)
  let kinds = null;
  if (ready) {
    const options = await page.evaluate(() => [...document.querySelectorAll("#kind option")].map((o) => o.value));
    const shown = {};
    for (const k of [...options.filter((o) => o), "no_such_kind", ""]) {
      await page.evaluate((kind) => window.twinViewerFilter(kind), k);
      shown[k] = (await page.evaluate(() => window.twinViewerProbe())).map((c) => c.id);
    }
    kinds = { options, shown };
  }
  console.log(JSON.stringify({ ready, ms, stats, errors, blocked, cars, clicked, found, zoom, kinds }));
} finally {
  await browser.close();
}
