// Open a local page (file:// or 127.0.0.1) in the system's headless Chromium (playwright-core, no downloaded
// browser), refuse every other request, save a full-page screenshot and print one JSON line:
// {"errors", "blocked", "images": [{src, loaded}], "text"}.
//   node shoot_page.mjs URL SCREENSHOT.png [width height]
import { chromium } from "playwright-core";

const [url, shot, w = "1280", h = "900"] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  args: ["--no-sandbox", "--headless=new", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--allow-file-access-from-files"],
});
const errors = [], blocked = [];
try {
  const page = await browser.newPage({ viewport: { width: Number(w), height: Number(h) } });
  await page.route("**/*", (route) => {
    const u = new URL(route.request().url());
    if (u.protocol === "file:" || u.hostname === "127.0.0.1" || u.protocol === "data:") return route.continue();
    blocked.push(u.href);
    return route.abort();
  });
  page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
  page.on("pageerror", (e) => errors.push(String(e)));
  await page.goto(url, { waitUntil: "load" });
  const images = await page.evaluate(() => [...document.images].map((i) => ({ src: i.getAttribute("src"),
    loaded: i.complete && i.naturalWidth > 0 })));
  const text = await page.evaluate(() => document.body.innerText.slice(0, 4000));
  await page.screenshot({ path: shot, fullPage: false });
  console.log(JSON.stringify({ errors, blocked, images, text }));
} finally {
  await browser.close();
}
