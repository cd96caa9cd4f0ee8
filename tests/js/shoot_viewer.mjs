// Open the twinreg viewer in the system's headless Chromium (playwright-core, no downloaded browser), refuse every
// request that does not go to 127.0.0.1, wait for the viewer's ready flag, save a screenshot and print one JSON
// line: {"ready", "ms", "stats", "errors", "blocked", "cars": [{id, x, y, colour}]}.
//   node shoot_viewer.mjs URL SCREENSHOT.png [width height]
import { chromium } from "playwright-core";

const [url, shot, w = "1280", h = "800"] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  args: ["--no-sandbox", "--headless=new", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
    "--disable-quic", "--no-first-run", "--disable-background-networking", "--disable-component-update",
    "--disable-sync"],
});
const errors = [], blocked = [];
try {
  const page = await browser.newPage({ viewport: { width: Number(w), height: Number(h) } });
  await page.route("**/*", (route) => {
    const u = new URL(route.request().url());
    if (u.hostname === "127.0.0.1" || u.protocol === "data:" || u.protocol === "blob:") return route.continue();
    blocked.push(u.href);
    return route.abort();
  });
  page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
  page.on("pageerror", (e) => errors.push(String(e)));
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
  console.log(JSON.stringify({ ready, ms, stats, errors, blocked, cars, clicked, found }));
} finally {
  await browser.close();
}
