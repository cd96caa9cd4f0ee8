// Open a report page (file://) in the system's headless Chromium at WIDTH x HEIGHT (every non-local request
// refused) and print one JSON line: {"errors", "blocked", "images": [{src, loaded}], "lead": {top, bottom} of the
// page's first image, "cells": number of table cells, "tall": the cells taller than two lines [{text, lines}]}.
//   node report_layout.mjs URL [width height]
import { localPage } from "./local_browser.mjs";

const [url, w = "1280", h = "900"] = process.argv.slice(2);
const { browser, page, errors, blocked } = await localPage(w, h);
try {
  await page.goto(url, { waitUntil: "load" });
  const got = await page.evaluate(() => {
    const images = [...document.images].map((i) => ({ src: i.getAttribute("src"), loaded: i.complete && i.naturalWidth > 0 }));
    const first = document.images[0].getBoundingClientRect();
    const tall = [], cells = [...document.querySelectorAll("td, th")];
    for (const c of cells) {
      const style = getComputedStyle(c);
      const line = parseFloat(style.lineHeight) || 1.2 * parseFloat(style.fontSize);
      const inner = c.getBoundingClientRect().height - parseFloat(style.paddingTop) - parseFloat(style.paddingBottom);
      if (inner > 2.05 * line) tall.push({ text: c.innerText.slice(0, 80), lines: inner / line });
    }
    return { images, lead: { top: first.top, bottom: first.bottom }, cells: cells.length, tall };
  });
  console.log(JSON.stringify({ errors, blocked, ...got }));
} finally {
  await browser.close();
}
