// The system's headless Chromium (playwright-core, no downloaded browser) with one page on which every request
// that is not local (127.0.0.1, file:, data:, blob:) is refused; console errors and refused URLs are collected.
import { chromium } from "playwright-core";

export async function localPage(width, height) {
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
    args: ["--no-sandbox", "--headless=new", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
      "--disable-quic", "--no-first-run", "--disable-background-networking", "--disable-component-update",
      "--disable-sync", "--allow-file-access-from-files"],
  });
  const errors = [], blocked = [];
  const page = await browser.newPage({ viewport: { width: Number(width), height: Number(height) } });
  await page.route("**/*", (route) => {
    const u = new URL(route.request().url());
    if (u.hostname === "127.0.0.1" || ["file:", "data:", "blob:"].includes(u.protocol)) return route.continue();
    blocked.push(u.href);
    return route.abort();
  });
  page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
  page.on("pageerror", (e) => errors.push(String(e)));
  return { browser, page, errors, blocked };
}
