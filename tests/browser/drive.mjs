// Drives a page of the SADE-SIM view (live or replay) in Debian's Chromium through
// playwright-core, as a user's browser would, and reports what it saw: the tests read the
// screenshots' pixels (tests/interop/test_view.py).
//
//   node tests/browser/drive.mjs STEPS.json
//
// STEPS.json: {"url": "...", "outDir": "...", "steps": [...]}, each step one of
//   {"waitFor": "<js expression>", "timeoutMs": 60000}   poll until truthy
//   {"eval": "<js expression>"}                            its value is reported
//   {"sleepMs": 1500}
//   {"shot": "name", "project": [[e, n, u], ...]}          freeze the drones, screenshot
//        outDir/name.png, report the page's time, its drones' ENU positions and their
//        pixels, and the pixels of the given ENU points, then unfreeze
// Prints one JSON object: {"results": [...], "console": [...]} (each step's result).
import { chromium } from '../../.tools/npm/node_modules/playwright-core/index.mjs';
import { readFileSync } from 'node:fs';
import { join } from 'node:path';

const config = JSON.parse(readFileSync(process.argv[2], 'utf8'));
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const consoleLines = [];
const results = [];
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
  page.on('console', (m) => consoleLines.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => consoleLines.push(`pageerror: ${e.message}`));
  await page.goto(config.url);
  for (const step of config.steps) {
    if (step.waitFor) {
      await page.waitForFunction(step.waitFor, null, { timeout: step.timeoutMs || 60000, polling: 100 });
      results.push({ waitFor: step.waitFor });
    } else if (step.eval) {
      results.push({ eval: step.eval, value: await page.evaluate(step.eval) });
    } else if (step.sleepMs) {
      await page.waitForTimeout(step.sleepMs);
      results.push({ sleptMs: step.sleepMs });
    } else if (step.shot) {
      await page.evaluate(() => window.sadesimView.freeze(true));
      // Two animation frames: the frozen state is drawn before the screenshot.
      await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
      const path = join(config.outDir, `${step.shot}.png`);
      await page.screenshot({ path });
      const seen = await page.evaluate((points) => {
        const v = window.sadesimView;
        const drones = v.positions();
        return {
          time: v.time,
          drones: drones.map((p) => ({ enu: p, pixel: v.project(...p) })),
          points: points.map((p) => ({ enu: p, pixel: v.project(...p) })),
        };
      }, step.project || []);
      await page.evaluate(() => window.sadesimView.freeze(false));
      results.push({ shot: step.shot, path, ...seen });
    }
  }
} finally {
  await browser.close();
}
console.log(JSON.stringify({ results, console: consoleLines }));
