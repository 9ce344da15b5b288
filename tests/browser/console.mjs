// Drives the web console (`sadesim console`) in Debian's Chromium through playwright-core,
// as a person would: clicks on the map, types into the forms, imports and exports files,
// launches a run and follows it. tests/interop/test_console.py checks what it reports.
//
//   node tests/browser/console.mjs CONFIG.json
//
// CONFIG.json: {"url": "http://127.0.0.1:PORT/", "outDir": "...", "scenario": NAME,
// "allowHttpErrors": [401, ...] (HTTP errors the scenario expects: not reported), ...}
// with NAME one of
//   "zone"      draw a zone, give it a ceiling, add a group, break and fix fields, export
//   "roundtrip" import each of `files` through the file input and export it
//   "launch"    import `file`, launch it, follow it to its end, report, replay, archive, verify
//   "fps"       import `file`, measure the frame rate while panning the map for `seconds`
//   "stop"      import `file`, switch its clock to realtime and its live view on, launch,
//               watch the live view in the run's page, stop the run while it flies
//   "auth"      the cluster backend's API mocked in the page (token, 401, a refused launch);
//               `file` is pasted into the plan
//   "cluster"   a real cluster's console (`allowHosts`: its host): log in with `token`, launch
//               `file` into `namespace`, then into `forbidden` and show the refusal
// Prints one JSON object: {"result": {...}, "external": [URLs the page asked for off this
// machine: each was refused], "errors": [console errors and page errors]}.
import { chromium } from '../../.tools/npm/node_modules/playwright-core/index.mjs';
import { readFileSync } from 'node:fs';
import { join } from 'node:path';

const config = JSON.parse(readFileSync(process.argv[2], 'utf8'));
// This machine, and the hosts a scenario names (the cluster's console pod).
const LOCAL = new Set(['127.0.0.1', 'localhost', '[::1]', '::1', ...(config.allowHosts || [])]);
const external = [];
const errors = [];
const shots = [];
let result = {};

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const context = await browser.newContext({ viewport: { width: 1360, height: 840 }, acceptDownloads: true });
await context.route('**/*', (route) => {
  const u = new URL(route.request().url());
  if (u.protocol === 'blob:' || u.protocol === 'data:' || LOCAL.has(u.hostname)) return route.continue();
  external.push(u.href);
  return route.abort();
});
function watchPage(p) {
  p.on('console', (m) => {
    if (m.type() !== 'error') return;
    // Chromium logs every 4xx answer; a scenario that expects some says which.
    const status = /Failed to load resource: the server responded with a status of (\d+)/.exec(m.text());
    if (status && (config.allowHttpErrors || []).includes(Number(status[1]))) return;
    errors.push(`console error: ${m.text()} (${p.url()})`);
  });
  p.on('pageerror', (e) => errors.push(`pageerror: ${e.message} (${p.url()})`));
}
context.on('page', watchPage);
const page = await context.newPage();

const base = config.url.replace(/\/$/, '');
const sleep = (ms) => page.waitForTimeout(ms);

async function shot(name, target = page) {
  const path = join(config.outDir, `${name}.png`);
  await target.screenshot({ path });
  shots.push(path);
  return path;
}

/** Waits until the console has loaded and the plan map has drawn its city. */
async function openPlan() {
  await page.goto(`${base}/#/plan`);
  await page.waitForFunction(() => window.sadesimConsole && window.sadesimConsole.ready && window.sadesimConsole.mapReady && window.sadesimConsole.worldLoads > 0, null, { timeout: 60000 });
  await waitIdle();
}

/** No validation and no city load pending. */
async function waitIdle() {
  await sleep(700);
  await page.waitForFunction(() => !document.body.dataset.validating && document.querySelector('.map-spinner').hidden, null, { timeout: 90000 });
}

/** The client pixel of a relative point of the map (0..1 across, 0..1 down). */
async function mapPoint(fx, fy) {
  const box = await page.locator('#plan-map').boundingBox();
  return { x: box.x + box.width * fx, y: box.y + box.height * fy };
}

async function latLonAt(p) {
  return page.evaluate(({ x, y }) => {
    const r = document.getElementById('plan-map').getBoundingClientRect();
    const ll = window.sadesimConsole.map().unproject([x - r.left, y - r.top]);
    return { lat: ll.lat, lon: ll.lng };
  }, p);
}

/** The text of the `.field-error` right after the control `data-field=path`, or null. */
function errorAfter(path) {
  return page.evaluate((p) => {
    const el = document.querySelector(`[data-field="${CSS.escape(p)}"]`);
    if (!el) return { missing: true };
    const next = el.nextElementSibling;
    return next && next.classList.contains('field-error') ? next.textContent : null;
  }, path);
}

async function waitErrorAfter(path, present, timeout = 15000) {
  await page.waitForFunction(({ p, want }) => {
    const el = document.querySelector(`[data-field="${CSS.escape(p)}"]`);
    if (!el) return false;
    const next = el.nextElementSibling;
    const has = !!(next && next.classList.contains('field-error'));
    return has === want && !document.body.dataset.validating;
  }, { p: path, want: present }, { timeout, polling: 100 });
  return errorAfter(path);
}

async function field(path) {
  const loc = page.locator(`[data-field="${path}"]`);
  await loc.scrollIntoViewIfNeeded();
  return loc;
}

async function importFile(file) {
  const before = await page.evaluate(() => window.sadesimConsole.validations);
  await page.setInputFiles('#import-file', file);
  const base = file.split('/').pop();
  await page.waitForFunction((b) => document.querySelector('.flash').textContent.includes(b), base, { timeout: 30000 });
  const flash = await page.locator('.flash').textContent();
  if (!flash.startsWith('loaded')) throw new Error(`import of ${file} failed: ${flash}`);
  await page.waitForFunction((b) => window.sadesimConsole.validations > b, before, { timeout: 30000 });
  await waitIdle();
  return flash;
}

async function exportTo(name) {
  const [download] = await Promise.all([page.waitForEvent('download', { timeout: 30000 }), page.click('#export')]);
  const path = join(config.outDir, name);
  await download.saveAs(path);
  return { path, suggested: download.suggestedFilename() };
}

// ---------------------------------------------------------------- scenarios

async function zone() {
  await openPlan();
  const startZones = await page.evaluate(() => (window.sadesimConsole.doc().spec.zones || []).length);
  // Draw a zone: four corners clicked on the map, then Finish.
  await page.click('#draw-zone');
  const corners = [[0.62, 0.22], [0.8, 0.22], [0.8, 0.42], [0.62, 0.42]];
  const clicked = [];
  for (const [fx, fy] of corners) {
    const p = await mapPoint(fx, fy);
    await page.mouse.click(p.x, p.y);
    clicked.push(await latLonAt(p));
    await sleep(150);
  }
  const drafted = await page.evaluate(() => window.sadesimConsole.mapData('draft'));
  const metresPerPixel = await page.evaluate(() => {
    const m = window.sadesimConsole.map();
    const c = m.getCenter();
    return (40075016.686 * Math.cos((c.lat * Math.PI) / 180)) / (512 * 2 ** m.getZoom());
  });
  await page.click('#finish-zone');
  const zi = startZones;
  const zp = `spec.zones[${zi}]`;
  await page.waitForSelector(`[data-field="${zp}.ceiling.heightM"]`, { state: 'visible' });
  // Its ceiling, typed in its form.
  await (await field(`${zp}.ceiling.heightM`)).fill('90');
  // A group: Add group, then its home clicked on the map.
  await page.click('#add-group');
  const home = await mapPoint(0.2, 0.3);
  await page.mouse.click(home.x, home.y);
  const homeLatLon = await latLonAt(home);
  const gi = await page.evaluate(() => window.sadesimConsole.doc().spec.fleet.length - 1);
  const gp = `spec.fleet[${gi}]`;
  await page.waitForSelector(`[data-field="${gp}.count"]`, { state: 'visible' });
  await waitIdle();
  const errorsBefore = await page.evaluate(() => window.sadesimConsole.errors());
  // A bad count: its message appears right after the count, then goes when fixed.
  await (await field(`${gp}.count`)).fill('0');
  const countError = await waitErrorAfter(`${gp}.count`, true);
  await shot('plan-count-error');
  // Launching it is refused, with the same problem at the same place.
  await page.click('#launch');
  await page.waitForFunction(() => /not launched/.test(document.querySelector('.flash').textContent), null, { timeout: 30000 });
  const launchRefused = { flash: await page.locator('.flash').textContent(), hash: new URL(page.url()).hash, countError: await errorAfter(`${gp}.count`) };
  await (await field(`${gp}.count`)).fill('3');
  const countFixed = await waitErrorAfter(`${gp}.count`, false);
  // Its route: Add waypoints on the map, two clicks, Esc.
  await page.locator(`#group-${gi} button`, { hasText: 'Add waypoints on the map' }).click();
  const waypointsClicked = [];
  for (const [fx, fy] of [[0.3, 0.2], [0.4, 0.55]]) {
    const p = await mapPoint(fx, fy);
    await page.mouse.click(p.x, p.y);
    waypointsClicked.push(await latLonAt(p));
    await sleep(150);
  }
  await page.keyboard.press('Escape');
  const mission = await page.evaluate((i) => window.sadesimConsole.doc().spec.fleet[i].mission, gi);
  const routeDrawn = await page.evaluate((i) => (window.sadesimConsole.mapData('missions').features.find((f) => f.properties.index === i) || { geometry: { coordinates: [] } }).geometry.coordinates.length, gi);
  // A floor above the ceiling: the message is on the zone's ceiling, then goes.
  await page.click('.tabs button[data-tab="zones"]');
  await (await field(`${zp}.floor.reference`)).selectOption('agl');
  await (await field(`${zp}.floor.heightM`)).fill('120');
  const ceilingError = await waitErrorAfter(`${zp}.ceiling`, true);
  const zoneHighlighted = await page.evaluate((i) => window.sadesimConsole.mapData('zones').features.some((f) => f.properties.index === i && f.properties.error), zi);
  await shot('plan-zone-error');
  await (await field(`${zp}.floor.heightM`)).fill('10');
  const ceilingFixed = await waitErrorAfter(`${zp}.ceiling`, false);
  // A triangle: two clicks and a double-click on its third corner close it.
  await page.click('#draw-zone');
  for (const [fx, fy] of [[0.42, 0.12], [0.54, 0.12]]) {
    const p = await mapPoint(fx, fy);
    await page.mouse.click(p.x, p.y);
    await sleep(150);
  }
  const third = await mapPoint(0.48, 0.3);
  await page.mouse.dblclick(third.x, third.y);
  await page.waitForFunction((n) => (window.sadesimConsole.doc().spec.zones || []).length === n, zi + 2, { timeout: 10000 });
  const triangle = await page.evaluate((i) => window.sadesimConsole.doc().spec.zones[i], zi + 1);
  const modeAfterTriangle = await page.evaluate(() => window.sadesimConsole.mode);
  await waitIdle();
  // The origin, picked on the map: the city is built again around it.
  const loadsBefore = await page.evaluate(() => window.sadesimConsole.worldLoads);
  await page.click('#pick-origin');
  const o = await mapPoint(0.5, 0.62);
  await page.mouse.click(o.x, o.y);
  const originClicked = await latLonAt(o);
  await page.waitForFunction((n) => window.sadesimConsole.worldLoads > n, loadsBefore, { timeout: 60000 });
  await waitIdle();
  const errorsAfter = await page.evaluate(() => window.sadesimConsole.errors());
  const status = await page.locator('.status-line').textContent();
  await shot('plan-zone');
  // Export: the download and the YAML tab.
  const exported = await exportTo('drawn.yaml');
  await page.click('.tabs button[data-tab="yaml"]');
  await page.waitForFunction(() => !/exporting/.test(document.getElementById('yaml-text').textContent));
  const yamlTab = await page.locator('#yaml-text').textContent();
  const doc = await page.evaluate(() => window.sadesimConsole.doc());
  result = {
    clicked, metresPerPixel, launchRefused, drafted: drafted.features.length, homeLatLon, zoneIndex: zi, groupIndex: gi, errorsBefore,
    countError, countFixed, ceilingError, ceilingFixed, zoneHighlighted, errorsAfter, status,
    exported, yamlTab, triangle, waypointsClicked, mission, routeDrawn, originClicked, origin: doc.spec.origin, modeAfterTriangle, zone: doc.spec.zones[zi], group: doc.spec.fleet[gi],
  };
}

async function roundtrip() {
  await openPlan();
  const out = [];
  for (const file of config.files) {
    const flash = await importFile(file);
    const name = await page.evaluate(() => window.sadesimConsole.doc().metadata.name);
    const problems = await page.locator('.status-line').getAttribute('data-problems');
    const exported = await exportTo(`roundtrip-${out.length}.yaml`);
    out.push({ file, flash, name, problems: Number(problems), ...exported });
  }
  await shot('plan-imported');
  result = { files: out };
}

async function launch() {
  await openPlan();
  await importFile(config.file);
  const doc = await page.evaluate(() => window.sadesimConsole.doc());
  await page.click('#launch');
  await page.waitForURL(/#\/runs\/.+/, { timeout: 60000 });
  const runHash = new URL(page.url()).hash;
  // The runs list follows the run to its end.
  await page.click('a.nav-link[data-route="runs"]');
  const row = page.locator(`.runs-table tbody tr[data-name="${doc.metadata.name}"]`).first();
  await row.waitFor({ timeout: 60000 });
  const phases = new Set();
  const deadline = Date.now() + config.timeoutMs;
  for (;;) {
    const ph = await row.getAttribute('data-phase');
    phases.add(ph);
    if (ph === 'Succeeded' || ph === 'Failed') break;
    if (Date.now() > deadline) throw new Error(`the run did not end: phases ${[...phases]}`);
    await sleep(250);
  }
  await page.waitForFunction((n) => {
    const r = document.querySelector(`.runs-table tbody tr[data-name="${n}"] td.verdict`);
    return r && r.textContent.trim() !== '–';
  }, doc.metadata.name, { timeout: 30000 });
  const verdict = (await row.locator('td.verdict').textContent()).trim();
  const listPhase = await row.getAttribute('data-phase');
  await shot('runs');
  // Its page: criteria, events, links to the report, the replay and the archive entry.
  await row.locator('a').click();
  await page.waitForSelector('#open-report', { timeout: 60000 });
  await page.waitForFunction(() => document.querySelectorAll('.events tr').length > 0, null, { timeout: 30000 });
  const criteria = await page.locator('ul.criteria li').evaluateAll((ls) => ls.map((l) => ({ state: l.dataset.state, text: l.textContent })));
  const events = await page.locator('.events tr').count();
  await shot('run');
  const [report] = await Promise.all([context.waitForEvent('page'), page.click('#open-report')]);
  await report.waitForLoadState('load');
  const reportHtml = await report.content();
  const reportTitle = await report.title();
  await report.close();
  const [replay] = await Promise.all([context.waitForEvent('page'), page.click('#open-replay')]);
  await replay.waitForLoadState('load');
  await replay.waitForSelector('canvas', { timeout: 60000 });
  await replay.waitForFunction(() => window.sadesimView && window.sadesimView.ready, null, { timeout: 60000 }).catch(() => {});
  const replayState = await replay.evaluate(() => ({
    canvases: document.querySelectorAll('canvas').length,
    ready: !!(window.sadesimView && window.sadesimView.ready),
    frames: window.sadesimView ? window.sadesimView.frames : null,
  }));
  await replay.close();
  // The archive lists it; its entry verifies.
  await page.click('a.nav-link[data-route="archive"]');
  const arow = page.locator(`.archive-table tbody tr[data-scenario="${doc.metadata.name}"]`).first();
  await arow.waitFor({ timeout: 30000 });
  const archiveRow = await arow.locator('td').allTextContents();
  await arow.locator('a').click();
  await page.waitForSelector('#verify');
  const files = await page.locator('table.files tr').evaluateAll((rs) => rs.map((r) => ({ path: r.querySelector('a').textContent, highlighted: r.classList.contains('highlight') })));
  await page.waitForFunction(() => document.querySelectorAll('.archive-events tr').length > 1, null, { timeout: 30000 });
  const archiveEvents = await page.locator('.archive-events tbody tr').count();
  await page.click('#verify');
  await page.waitForFunction(() => document.querySelector('.verify-result').dataset.ok !== undefined, null, { timeout: 60000 });
  const verify = { ok: await page.locator('.verify-result').getAttribute('data-ok'), text: await page.locator('.verify-result').textContent() };
  await shot('archive-entry');
  result = {
    name: doc.metadata.name, runHash, phases: [...phases], listPhase, verdict, criteria, events, reportTitle,
    reportHasName: reportHtml.includes(doc.metadata.name), reportLength: reportHtml.length, replayState,
    archiveRow, files, archiveEvents, verify,
  };
}

async function fps() {
  await openPlan();
  await importFile(config.file);
  await page.waitForFunction((n) => window.sadesimConsole.worldLoads >= n, 2, { timeout: 90000 });
  await waitIdle();
  const buildings = await page.evaluate(() => (window.sadesimConsole.mapData('buildings') || { features: [] }).features.length);
  await shot('plan-chicago');
  for (const layer of config.hideLayers || []) await page.evaluate((l) => window.sadesimConsole.map().setLayoutProperty(l, 'visibility', 'none'), layer);
  const c = await mapPoint(0.5, 0.5);
  await page.evaluate(() => {
    window.__frames = 0;
    window.__renders = 0;
    window.__counting = true;
    const tick = () => { if (!window.__counting) return; window.__frames++; requestAnimationFrame(tick); };
    requestAnimationFrame(tick);
    window.sadesimConsole.map().on('render', () => { if (window.__counting) window.__renders++; });
  });
  const t0 = Date.now();
  await page.mouse.move(c.x, c.y);
  await page.mouse.down();
  let k = 0;
  while (Date.now() - t0 < config.seconds * 1000) {
    const a = (k++ / 20) * Math.PI;
    await page.mouse.move(c.x + 220 * Math.sin(a), c.y + 120 * Math.sin(2 * a), { steps: 2 });
  }
  await page.mouse.up();
  const measured = await page.evaluate(() => { window.__counting = false; return { frames: window.__frames, renders: window.__renders }; });
  const seconds = (Date.now() - t0) / 1000;
  result = {
    seconds, frames: measured.frames, renders: measured.renders, fps: measured.frames / seconds,
    mapRendersPerS: measured.renders / seconds, moves: k, buildings,
    drones: await page.evaluate(() => window.sadesimConsole.doc().spec.fleet.reduce((s, g) => s + g.count, 0)),
  };
}

/** The cluster backend's side of the page, its API answered here: a console that needs the
 * user's token, refuses without it, and a Kubernetes API server that refuses the launch. */
async function auth() {
  const seen = { watch: [], launch: null, validate: [] };
  const json = (route, status, body) => route.fulfill({ status, contentType: 'application/json', body: JSON.stringify(body) });
  await page.route('**/api/info', (route) => json(route, 200, { backend: 'cluster', version: '0.1.0', namespaces: ['team-a', 'team-b'], needsToken: true, archive: 's3://bucket/runs' }));
  await page.route('**/api/runs/watch*', (route) => {
    const a = route.request().headers().authorization || null;
    seen.watch.push(a);
    if (a !== 'Bearer tok-123') return json(route, 401, { error: 'Unauthorized' });
    const run = { id: 'team-a/mocked-run', name: 'mocked-run', namespace: 'team-a', phase: 'Running', progress: 0.25, simTimeS: 45, durationS: 180, realTimeFactor: 1.0, queuePosition: null, verdict: null, message: null, startedAt: new Date().toISOString(), drones: 4, archiveId: null };
    return route.fulfill({ status: 200, contentType: 'text/event-stream', body: `: hello\n\nevent: runs\ndata: ${JSON.stringify({ runs: [run] })}\n\n` });
  });
  await page.route('**/api/runs', (route) => {
    if (route.request().method() !== 'POST') return route.fallback();
    seen.launch = { authorization: route.request().headers().authorization || null, body: route.request().postDataJSON() };
    return json(route, 403, { error: 'simulationruns.sadesim.io is forbidden: User "alice" cannot create resource "simulationruns" in API group "sadesim.io" in the namespace "team-b"' });
  });
  await page.route('**/api/scenario/validate', (route) => { seen.validate.push(route.request().headers().authorization || null); return route.fallback(); });

  await page.goto(`${base}/#/runs`);
  await page.waitForSelector('.login-banner:not([hidden])', { timeout: 20000 });
  const banner = await page.locator('.login-banner').textContent();
  const tokenBoxShown = await page.locator('.token-box').isVisible();
  await page.fill('#token', 'tok-123');
  await page.click('.token-box button[type=submit]');
  await page.waitForSelector('.runs-table tbody tr[data-name="mocked-run"]', { timeout: 20000 });
  const listed = await page.locator('.runs-table tbody tr').first().locator('td').allTextContents();
  const stored = await page.evaluate(() => sessionStorage.getItem('sadesim-console-token'));
  const cookie = (await context.cookies()).find((c) => c.name === 'sadesim_token');
  const bannerAfter = await page.locator('.login-banner').isVisible();
  // Plan: a scenario pasted, a namespace and a queue chosen, launched: refused.
  await page.click('a.nav-link[data-route="plan"]');
  await page.waitForFunction(() => window.sadesimConsole && window.sadesimConsole.mapReady, null, { timeout: 60000 });
  await page.click('#paste-open');
  await page.fill('#paste-text', readFileSync(config.file, 'utf8'));
  await page.click('#paste-load');
  await page.waitForFunction(() => document.querySelector('.flash').textContent.includes('pasted'), null, { timeout: 20000 });
  const namespaces = await page.locator('#namespaces option').evaluateAll((os) => os.map((o) => o.value));
  await page.fill('#namespace', 'team-b');
  await page.dispatchEvent('#namespace', 'change');
  await page.fill('#launch-queue', 'q1');
  await waitIdle();
  await page.click('#launch');
  await page.waitForSelector('.api-refusal:not([hidden])', { timeout: 20000 });
  const refusal = await page.locator('.api-refusal').textContent();
  await shot('plan-refused');
  result = {
    banner, tokenBoxShown, listed, stored, cookie: cookie ? { value: cookie.value, sameSite: cookie.sameSite, path: cookie.path } : null, bannerAfter, namespaces, refusal, hash: new URL(page.url()).hash,
    watch: seen.watch, launch: seen.launch && { authorization: seen.launch.authorization, namespace: seen.launch.body.namespace, queue: seen.launch.body.queue, name: seen.launch.body.document.metadata.name },
    validateAuth: [...new Set(seen.validate)],
  };
}

/** A real cluster's console (tests/cluster/test_console.py): log in with `token`, launch
 * `file` into `namespace` (allowed), then into `forbidden` (the API server refuses). */
async function cluster() {
  await page.goto(`${base}/#/plan`);
  await page.waitForSelector('.token-box:not([hidden])', { timeout: 20000 });
  await page.fill('#token', config.token);
  await page.click('.token-box button[type=submit]');
  await page.fill('#namespace', config.namespace);
  await page.dispatchEvent('#namespace', 'change');
  await page.waitForFunction(() => window.sadesimConsole && window.sadesimConsole.mapReady, null, { timeout: 90000 });
  await page.click('#paste-open');
  await page.fill('#paste-text', readFileSync(config.file, 'utf8'));
  await page.click('#paste-load');
  await page.waitForFunction(() => document.querySelector('.flash').textContent.includes('pasted'), null, { timeout: 20000 });
  await waitIdle();
  await page.click('#launch');
  await page.waitForURL(/#\/runs\/.+/, { timeout: 60000 });
  const launched = decodeURIComponent(new URL(page.url()).hash);
  await page.waitForSelector('.run-head', { timeout: 60000 });
  await shot('cluster-run');
  await page.fill('#namespace', config.forbidden);
  await page.dispatchEvent('#namespace', 'change');
  await page.click('a.nav-link[data-route="plan"]');
  await waitIdle();
  await page.click('#launch');
  await page.waitForSelector('.api-refusal:not([hidden])', { timeout: 20000 });
  const refusal = await page.locator('.api-refusal').textContent();
  await shot('cluster-refused');
  result = { launched, refusal };
}

async function stop() {
  await openPlan();
  await importFile(config.file);
  // In real time, so that it is still flying when stopped.
  await (await field('spec.clock.mode')).selectOption('realtime');
  // With the live 3D view.
  await (await field('spec.rendering.enabled')).check();
  await waitIdle();
  await page.click('#launch');
  await page.waitForURL(/#\/runs\/.+/, { timeout: 60000 });
  const head = page.locator('.run-head');
  await page.waitForFunction(() => /Running/.test(document.querySelector('.run-head .badge')?.textContent || ''), null, { timeout: 120000 });
  const before = await head.locator('.badge').first().textContent();
  // The live view, embedded: its page draws (its own canvas, its own stream).
  await page.waitForSelector('iframe.live-view', { timeout: 60000 });
  const viewUrl = await page.locator('iframe.live-view').getAttribute('src');
  const frame = page.frameLocator('iframe.live-view');
  await frame.locator('canvas').first().waitFor({ timeout: 60000 });
  const view = page.frames().find((f) => f.url().startsWith(viewUrl.replace(/\/$/, '')));
  await view.waitForFunction(() => window.sadesimView && window.sadesimView.ready && window.sadesimView.frames > 5 && window.sadesimView.time > 0, null, { timeout: 60000 });
  const liveView = await view.evaluate(() => ({ ready: window.sadesimView.ready, frames: window.sadesimView.frames, time: window.sadesimView.time }));
  await shot('run-live');
  await page.click('#stop-run');
  await page.waitForFunction(() => /Aborted|Succeeded|Failed/.test(document.querySelector('.run-head .badge')?.textContent || ''), null, { timeout: 120000 });
  const after = await head.locator('.badge').first().textContent();
  await page.waitForSelector('#open-archive', { timeout: 60000 });
  const message = await page.locator('.run-message').textContent().catch(() => null);
  const stopShown = await page.locator('#stop-run').count();
  result = { before, after, message, stopShown, viewUrl, liveView, viewGone: await page.locator('iframe.live-view').count(), rendering: (await page.evaluate(() => window.sadesimConsole.doc().spec.rendering)), clock: (await page.evaluate(() => window.sadesimConsole.doc().spec.clock)) };
}

let failure = null;
try {
  await ({ zone, roundtrip, launch, fps, auth, stop, cluster })[config.scenario]();
} catch (e) {
  failure = String(e && e.stack ? e.stack : e);
  try { await shot('failure'); } catch { /* the page is gone */ }
} finally {
  await browser.close();
}
console.log(JSON.stringify({ result, external, errors, shots, failure }));
