// The SADE-SIM live view and replay (issue 18). One page for both: `/scene.json` says which.
//
// Frames: world ENU metres (x east, y north, z up from the origin's ground), mapped onto
// three.js's Y-up frame exactly as the bundle's world.glb is: x = e, y = u, z = -n.
// Attitudes are body FLU -> ENU quaternions [w, x, y, z].
//
// `window.sadesimView` is the page's small API for scripts and browser tests: `ready`,
// `time`, `frames`, `project(e, n, u)` (CSS pixels), `lookAt(eye, target)` (ENU),
// `seek(t)`, `play()`, `pause()`, `follow(name)`.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const MAX_LABELLED = 50;      // drone name labels beyond this fleet size would hide the city
const MAX_TRAILED = 200;      // trail lines per drone up to this fleet size
const TRAIL_POINTS = 400;     // per drone
const TRAIL_STEP_M = 0.5;     // a new trail point after this much movement
const MAX_EVENTS_SHOWN = 14;

const $ = (id) => document.getElementById(id);
const toThree = (e, n, u) => new THREE.Vector3(e, u, -n);

const api = { ready: false, time: 0, frames: 0, mode: null };
window.sadesimView = api;

const scene = await (await fetch('scene.json')).json();
api.mode = scene.mode;
$('run').textContent = `${scene.namespace}/${scene.run} — ${scene.mode === 'live' ? 'live' : 'replay'}`;

// --- renderer, camera, light ---------------------------------------------------------
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(window.innerWidth, window.innerHeight);
$('view').appendChild(renderer.domElement);
const world = new THREE.Scene();
world.background = new THREE.Color('#cfd8e3');
const camera = new THREE.PerspectiveCamera(55, window.innerWidth / window.innerHeight, 0.5, 4 * scene.worldExtentM + 2000);
const controls = new OrbitControls(camera, renderer.domElement);
controls.maxPolarAngle = Math.PI * 0.495;
world.add(new THREE.HemisphereLight('#ffffff', '#667755', 1.6));
const sun = new THREE.DirectionalLight('#ffffff', 1.8);
sun.position.set(0.5, 1.0, 0.3);
world.add(sun);
window.addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
});

// --- the city from the asset bundle --------------------------------------------------
if (scene.worldModel) {
  new GLTFLoader().load('world.glb', (gltf) => {
    gltf.scene.traverse((o) => {
      if (!o.isMesh) return;
      const ground = o.name.includes('ground') || (o.parent && o.parent.name.includes('ground'));
      o.material = new THREE.MeshLambertMaterial({ color: ground ? '#9aa58c' : '#b9bcc2' });
    });
    world.add(gltf.scene);
  }, undefined, (e) => showError(`world.glb: ${e.message || e}`));
} else {
  const ground = new THREE.Mesh(new THREE.PlaneGeometry(2 * scene.worldExtentM, 2 * scene.worldExtentM),
    new THREE.MeshLambertMaterial({ color: '#9aa58c' }));
  ground.rotation.x = -Math.PI / 2;
  world.add(ground);
}

// --- zones: translucent pink volumes with their names ---------------------------------
const labels = [];
function label(text, cls) {
  const el = document.createElement('div');
  el.className = `label ${cls || ''}`;
  el.textContent = text;
  $('labels').appendChild(el);
  return el;
}
for (const zone of scene.zones) {
  const c = zone.corners; // [e, n, floor, ceiling]
  const positions = [];
  const push = (e, n, u) => positions.push(e, u, -n);
  for (let i = 0; i < c.length; i++) {
    const a = c[i], b = c[(i + 1) % c.length];
    push(a[0], a[1], a[2]); push(b[0], b[1], b[2]); push(b[0], b[1], b[3]);
    push(a[0], a[1], a[2]); push(b[0], b[1], b[3]); push(a[0], a[1], a[3]);
  }
  const contour = c.map((p) => new THREE.Vector2(p[0], p[1]));
  for (const [i, j, k] of THREE.ShapeUtils.triangulateShape(contour, [])) {
    for (const level of [2, 3]) {
      push(c[i][0], c[i][1], c[i][level]); push(c[j][0], c[j][1], c[j][level]); push(c[k][0], c[k][1], c[k][level]);
    }
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.Float32BufferAttribute(positions, 3));
  const volume = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({
    color: scene.zoneColour, transparent: true, opacity: 0.35, side: THREE.DoubleSide, depthWrite: false,
  }));
  volume.renderOrder = 1;
  world.add(volume);
  const edges = [];
  for (let i = 0; i < c.length; i++) {
    const a = c[i], b = c[(i + 1) % c.length];
    for (const level of [2, 3]) edges.push(toThree(a[0], a[1], a[level]), toThree(b[0], b[1], b[level]));
    edges.push(toThree(a[0], a[1], a[2]), toThree(a[0], a[1], a[3]));
  }
  world.add(new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(edges),
    new THREE.LineBasicMaterial({ color: scene.zoneColour })));
  const centre = c.reduce((s, p) => [s[0] + p[0] / c.length, s[1] + p[1] / c.length, Math.max(s[2], p[3])], [0, 0, -Infinity]);
  labels.push({ el: label(zone.name, 'zone'), at: () => toThree(centre[0], centre[1], centre[2]) });
}

// --- drones: screen-sized points in their group colours, labels and trails ------------
const count = scene.drones.length;
const dronePositions = new Float32Array(count * 3);
const droneColours = new Float32Array(count * 3);
const groupColour = scene.drones.map((d) => new THREE.Color(d.colour));
const crashedColour = new THREE.Color('#111111');
scene.drones.forEach((d, i) => {
  const p = toThree(...d.homeEnuM);
  dronePositions.set([p.x, p.y, p.z], i * 3);
  droneColours.set([groupColour[i].r, groupColour[i].g, groupColour[i].b], i * 3);
});
const droneGeometry = new THREE.BufferGeometry();
droneGeometry.setAttribute('position', new THREE.BufferAttribute(dronePositions, 3));
droneGeometry.setAttribute('color', new THREE.BufferAttribute(droneColours, 3));
const dronePoints = new THREE.Points(droneGeometry, new THREE.PointsMaterial({
  size: 11, sizeAttenuation: false, vertexColors: true, depthTest: false,
}));
dronePoints.renderOrder = 3; // over the zones: a drone inside a zone stays visible
dronePoints.frustumCulled = false;
world.add(dronePoints);

const trails = count <= MAX_TRAILED ? scene.drones.map((d, i) => {
  const buffer = new Float32Array(TRAIL_POINTS * 3);
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(buffer, 3));
  geometry.setDrawRange(0, 0);
  const line = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: groupColour[i], transparent: true, opacity: 0.8 }));
  line.frustumCulled = false;
  world.add(line);
  return { buffer, geometry, n: 0, last: null };
}) : null;
if (count > MAX_LABELLED) $('status').textContent = `${count} drones: names shown for the followed drone only`;
const droneLabels = scene.drones.map((d, i) => {
  const entry = { el: label(d.name), at: () => new THREE.Vector3(dronePositions[i * 3], dronePositions[i * 3 + 1], dronePositions[i * 3 + 2]), drone: i };
  if (count <= MAX_LABELLED) labels.push(entry);
  return entry;
});
for (const d of scene.drones) $('follow').add(new Option(d.name, d.name));

function resetTrails() {
  if (!trails) return;
  for (const t of trails) { t.n = 0; t.last = null; t.geometry.setDrawRange(0, 0); }
}

function addTrailPoint(i, v) {
  const t = trails[i];
  if (t.last && t.last.distanceTo(v) < TRAIL_STEP_M) return;
  if (t.n === TRAIL_POINTS) { t.buffer.copyWithin(0, 3); t.n--; }
  t.buffer.set([v.x, v.y, v.z], t.n * 3);
  t.n++;
  t.last = v.clone();
  t.geometry.setDrawRange(0, t.n);
  t.geometry.attributes.position.needsUpdate = true;
}

// --- frames (the live stream's format, see sim-worker/src/view/feed.rs) ---------------
let following = null;
let lastFollowed = null;
let frozen = false;   // sadesimView.freeze(true): frames wait, so a screenshot and the
let pending = null;   // positions it is compared with are of the same instant
api.freeze = (on) => {
  frozen = on;
  if (!on && pending) { const f = pending; pending = null; applyFrame(f); }
};
api.positions = () => scene.drones.map((d, i) => [dronePositions[i * 3], -dronePositions[i * 3 + 2], dronePositions[i * 3 + 1]]);
function applyFrame(f) {
  if (frozen) { pending = f; return; }
  for (let i = 0; i < count; i++) {
    const e = f.p[i * 3], n = f.p[i * 3 + 1], u = f.p[i * 3 + 2];
    dronePositions[i * 3] = e; dronePositions[i * 3 + 1] = u; dronePositions[i * 3 + 2] = -n;
    const c = f.s[i] === 'C' ? crashedColour : groupColour[i];
    droneColours[i * 3] = c.r; droneColours[i * 3 + 1] = c.g; droneColours[i * 3 + 2] = c.b;
    if (trails && f.s[i] !== 'G') addTrailPoint(i, new THREE.Vector3(e, u, -n));
  }
  droneGeometry.attributes.position.needsUpdate = true;
  droneGeometry.attributes.color.needsUpdate = true;
  if (following !== null) {
    const now = droneLabels[following].at();
    if (lastFollowed) {
      const delta = now.clone().sub(lastFollowed);
      camera.position.add(delta);
    }
    controls.target.copy(now);
    lastFollowed = now;
  }
  api.time = f.t;
  api.frames++;
  $('time').textContent = f.t.toFixed(1);
  $('rtf').textContent = f.rtf == null ? '' : `· ${f.rtf.toFixed(1)}× real time`;
  $('air').textContent = f.air;
  $('ground').textContent = f.ground;
  $('crashed').textContent = f.crashed;
}

// --- events ------------------------------------------------------------------------
const AIRSPACE = /^zone|lease|violation|conflict/i;
function describe(ev) {
  const who = ev.drone == null ? '' : `${scene.drones[ev.drone] ? scene.drones[ev.drone].name : `drone ${ev.drone}`} `;
  const { timeS, drone, event, ...rest } = ev;
  const details = Object.entries(rest).map(([k, v]) => `${k} ${typeof v === 'object' ? JSON.stringify(v) : v}`).join(', ');
  return `${timeS.toFixed(2)} s  ${who}${event}${details ? ': ' + details : ''}`;
}
function eventClass(ev) {
  const name = ev.event || '';
  if (/violat/i.test(name)) return 'violation';
  if (/denied|refused/i.test(name)) return 'denied';
  if (name === 'crashed') return 'crashed';
  return AIRSPACE.test(name) ? 'airspace' : '';
}
function showEvents(list) {
  const box = $('events');
  while (box.children.length > 1) box.removeChild(box.lastChild);
  for (const ev of list.slice(-MAX_EVENTS_SHOWN).reverse()) {
    const row = document.createElement('div');
    row.className = eventClass(ev);
    row.textContent = describe(ev);
    box.appendChild(row);
  }
}

function showError(text) {
  $('error').style.display = 'block';
  $('error').textContent = text;
}

// --- camera: free (orbit) or following a drone ------------------------------------------
function frameFleet() {
  const homes = scene.drones.map((d) => d.homeEnuM);
  const zonePoints = scene.zones.flatMap((z) => z.corners.map((c) => [c[0], c[1], c[3]]));
  const pts = homes.concat(zonePoints);
  if (pts.length === 0) pts.push([0, 0, 0]);
  const lo = [0, 1, 2].map((k) => Math.min(...pts.map((p) => p[k])));
  const hi = [0, 1, 2].map((k) => Math.max(...pts.map((p) => p[k])));
  const centre = lo.map((v, k) => (v + hi[k]) / 2);
  const span = Math.max(80, hi[0] - lo[0], hi[1] - lo[1]);
  api.lookAt([centre[0] + 0.2 * span, centre[1] - 0.9 * span, centre[2] + 0.7 * span], centre);
}
api.lookAt = (eye, target) => {
  following = null; lastFollowed = null; $('follow').value = '';
  camera.position.copy(toThree(...eye));
  controls.target.copy(toThree(...target));
  controls.update();
  render();
};
api.follow = (name) => {
  const i = scene.drones.findIndex((d) => d.name === name);
  following = i >= 0 ? i : null;
  lastFollowed = null;
  $('follow').value = i >= 0 ? name : '';
  if (following !== null) {
    const at = droneLabels[following].at();
    camera.position.copy(at.clone().add(new THREE.Vector3(-25, 18, 25)));
    controls.target.copy(at);
  }
};
$('follow').addEventListener('change', (e) => api.follow(e.target.value));
api.project = (e, n, u) => {
  const v = toThree(e, n, u).project(camera);
  const rect = renderer.domElement.getBoundingClientRect();
  return [rect.left + (v.x + 1) / 2 * rect.width, rect.top + (1 - v.y) / 2 * rect.height, v.z];
};

function render() {
  controls.update();
  renderer.render(world, camera);
  const rect = renderer.domElement.getBoundingClientRect();
  for (const l of labels.concat(following !== null && count > MAX_LABELLED ? [droneLabels[following]] : [])) {
    const v = l.at().project(camera);
    const visible = v.z < 1 && Math.abs(v.x) <= 1.05 && Math.abs(v.y) <= 1.05;
    l.el.style.display = visible ? 'block' : 'none';
    if (visible) {
      l.el.style.left = `${rect.left + (v.x + 1) / 2 * rect.width}px`;
      l.el.style.top = `${rect.top + (1 - v.y) / 2 * rect.height}px`;
    }
  }
}

// --- live: Server-Sent Events from the renderer ---------------------------------------
async function live() {
  const events = [];
  const source = new EventSource('live');
  source.addEventListener('frame', (m) => applyFrame(JSON.parse(m.data)));
  source.addEventListener('event', (m) => {
    const ev = JSON.parse(m.data);
    events.push(ev);
    if (events.length > 500) events.splice(0, events.length - 500);
    showEvents(events);
    if (ev.event === 'runEnded') {
      // The server ends the stream here; closed, the page does not try to reconnect.
      source.close();
      $('status').textContent = `run ended: ${ev.reason}`;
    }
  });
  source.addEventListener('lagged', (m) => { $('status').textContent = `this browser missed ${m.data} events`; });
  source.onerror = () => { if (!$('status').textContent.startsWith('run ended')) $('status').textContent = 'stream closed'; };
}

// --- replay: the whole recording, a timeline to play, pause and scrub -----------------------
async function replay() {
  const rec = await (await fetch('replay.json')).json();
  $('timeline').style.display = 'flex';
  const scrub = $('scrub');
  scrub.max = rec.endS;
  scrub.step = 1 / rec.rateHz;
  let playing = false;
  let t = 0;
  let last = performance.now();
  const show = (time) => {
    t = Math.min(Math.max(time, 0), rec.endS);
    const k = Math.min(rec.frames.length - 1, Math.round(t * rec.rateHz));
    if (k < api.shownFrame) resetTrails();
    api.shownFrame = k;
    applyFrame(rec.frames[k]);
    scrub.value = t;
    $('scrubTime').textContent = `${t.toFixed(1)} / ${rec.endS.toFixed(1)} s`;
    showEvents(rec.events.filter((e) => e.timeS <= t + 1e-9));
  };
  api.shownFrame = 0;
  api.seek = (time) => { resetTrails(); api.shownFrame = 0; show(time); render(); };
  api.play = () => { playing = true; last = performance.now(); $('play').textContent = 'pause'; };
  api.pause = () => { playing = false; $('play').textContent = 'play'; };
  $('play').addEventListener('click', () => (playing ? api.pause() : api.play()));
  scrub.addEventListener('input', () => api.seek(Number(scrub.value)));
  const tick = (now) => {
    if (playing) {
      show(t + (now - last) / 1000 * Number($('speed').value));
      if (t >= rec.endS) api.pause();
    }
    last = now;
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
  show(0);
}

frameFleet();
renderer.setAnimationLoop(render);
try {
  if (scene.mode === 'live') await live(); else await replay();
  api.ready = true;
} catch (e) {
  showError(`${e.message || e}`);
}
