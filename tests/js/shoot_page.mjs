// Open a local page (file:// or 127.0.0.1) in the system's headless Chromium (local_browser.mjs: every other
// request is refused), save a screenshot and print one JSON line:
// {"errors", "blocked", "images": [{src, loaded}], "text"}.
//   node shoot_page.mjs URL SCREENSHOT.png [width height]
import { localPage } from "./local_browser.mjs";

const [url, shot, w = "1280", h = "900"] = process.argv.slice(2);
const { browser, page, errors, blocked } = await localPage(w, h);
try {
  await page.goto(url, { waitUntil: "load" });
  const images = await page.evaluate(() => [...document.images].map((i) => ({ src: i.getAttribute("src"),
    loaded: i.complete && i.naturalWidth > 0 })));
  const text = await page.evaluate(() => document.body.innerText.slice(0, 4000));
  await page.screenshot({ path: shot, fullPage: false });
  console.log(JSON.stringify({ errors, blocked, images, text }));
} finally {
  await browser.close();
}
