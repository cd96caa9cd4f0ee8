// Open the viewer on a twin whose names are HTML, click a car, search for it, and report whether any script ran:
//   node probe_xss.mjs URL  ->  {"ready", "ran", "details", "hits", "errors", "blocked"}
import { localPage } from "./local_browser.mjs";

const [url] = process.argv.slice(2);
const { browser, page, errors, blocked } = await localPage(1000, 700);
try {
  await page.goto(url);
  let ready = true;
  try {
    await page.waitForFunction(() => window.twinViewerReady === true, null, { timeout: 120000 });
  } catch (e) { ready = false; errors.push("not ready: " + e.message.split("\n")[0]); }
  const cars = ready ? await page.evaluate(() => window.twinViewerProbe()) : [];
  const target = await page.evaluate(() => window.__xssTarget || null);
  for (const car of cars) {
    await page.mouse.click(car.x, car.y);
    const text = await page.evaluate(() => document.getElementById("details").innerText);
    if (text.includes("<img")) break;
  }
  const details = await page.evaluate(() => document.getElementById("details").innerText);
  await page.fill("#search", "img");
  await page.waitForTimeout(300);
  const hits = await page.evaluate(() => [...document.querySelectorAll("#hits div[data-id]")].map((d) => d.innerText));
  const ran = await page.evaluate(() => window.__xss === 1 || document.title === "pwned");
  console.log(JSON.stringify({ ready, ran, details, hits, errors, blocked, target }));
} finally {
  await browser.close();
}
