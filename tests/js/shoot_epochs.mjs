// Open the epochs viewer of `twinreg compare` in the system's headless Chromium (every request that is not local
// refused), and for each epoch save a screenshot (SHOT_K.png) with the probe of its cars; click the first car that
// is not `same` in the last epoch and read its history. Prints one JSON line:
// {"ready", "errors", "blocked", "epochs": [{"cars": [...], "legend"}], "history"}.
//   node shoot_epochs.mjs URL SHOT_PREFIX [width height]
import { localPage } from "./local_browser.mjs";

const [url, prefix, w = "1100", h = "900"] = process.argv.slice(2);
const { browser, page, errors, blocked } = await localPage(w, h);
try {
  await page.goto(url);
  let ready = true;
  try {
    await page.waitForFunction(() => window.epochViewerReady === true, null, { timeout: 120000 });
  } catch (e) { ready = false; errors.push("not ready: " + e.message.split("\n")[0]); }
  const epochs = [];
  let history = null;
  if (ready) {
    const n = await page.evaluate(() => Number(document.getElementById("epoch").max) + 1);
    for (let k = 0; k < n; k++) {
      await page.evaluate((k) => window.setEpoch(k), k);
      await page.waitForTimeout(200);
      await page.screenshot({ path: `${prefix}_${k}.png` });
      epochs.push({ cars: await page.evaluate(() => window.epochViewerProbe()),
        legend: await page.evaluate(() => document.getElementById("legend").innerText) });
    }
    const last = epochs[epochs.length - 1].cars.find((c) => c.status !== "same");
    if (last) {
      await page.mouse.click(last.x, last.y);
      history = { id: last.id, status: last.status,
        text: await page.evaluate(() => document.getElementById("details").innerText) };
    }
  }
  console.log(JSON.stringify({ ready, errors, blocked, epochs, history }));
} finally {
  await browser.close();
}
