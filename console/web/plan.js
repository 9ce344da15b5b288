// The plan page (#/plan): a scenario editor on a map. The document is a SimulationRun as
// JSON; every edit is validated by the backend (debounced) and each problem is shown next
// to the control whose `data-field` is its path.

import { h, fill, getPath, setPath, clone, debounce, parsePath, joinPath, GROUP_COLOURS } from './util.js';
import { call, post, ApiError, namespace } from './api.js';
import * as F from './forms.js';
import {
  defaultDocument, MISSION_KINDS, CRITERION_KINDS, AIRFRAMES, ROLES, kindOf, newMissionItem, newCriterion,
  pos, isPos, discRing, worldSquare, centroid, groupHomes, groupAnchor,
} from './scenario.js';

const STORE_KEY = 'sadesim-console-plan';
const TABS = [['general', 'General'], ['zones', 'Zones'], ['fleet', 'Fleet'], ['environment', 'Environment'], ['pilot', 'Pilot & criteria'], ['yaml', 'YAML']];

const S = {
  doc: null,
  original: null,       // the imported text, sent back on export (unchanged -> byte-identical)
  errors: [],
  plan: null,
  validated: false,
  mode: null,           // {kind: 'origin'|'zone'|'group'|'home'|'area'|'openArea'|'waypoint', ...}
  draft: [],            // vertices of the zone being drawn
  selectedZone: -1,
  selectedGroup: -1,
  tab: 'general',
  yaml: null,
  world: null,
  worldKey: null,
  fitPending: true,
  info: null,
};

let el = {};            // the page's elements
let map = null;
let mapReady = false;
let labelMarkers = [];
let originMarker = null;
const hooks = { worldLoads: 0, validations: 0, fps: null };

// ---------------------------------------------------------------- document and storage

function loadStored() {
  try {
    const s = JSON.parse(sessionStorage.getItem(STORE_KEY) || 'null');
    if (s && s.doc && s.doc.spec) { S.doc = s.doc; S.original = s.original ?? null; return; }
  } catch { /* fall through */ }
  S.doc = defaultDocument();
  S.original = null;
}

function store() {
  try { sessionStorage.setItem(STORE_KEY, JSON.stringify({ doc: S.doc, original: S.original })); } catch { /* full */ }
}

function spec() { return S.doc.spec || (S.doc.spec = {}); }

/** Called after every edit of the document. */
function changed(path, { structure = false } = {}) {
  S.yaml = null;
  store();
  if (path && /^spec\.zones\[\d+\]\.name$/.test(path)) {
    const i = parsePath(path)[2];
    const t = document.getElementById(`zone-title-${i}`);
    if (t) t.textContent = S.doc.spec.zones[i].name || `zone ${i + 1}`;
  }
  if (path && /^spec\.fleet\[\d+\]\.name$/.test(path)) {
    const i = parsePath(path)[2];
    const t = document.getElementById(`group-title-${i}`);
    if (t) t.textContent = S.doc.spec.fleet[i].name || `group ${i + 1}`;
  }
  if (structure) renderForms();
  scheduleValidate();
  updateMap();
  scheduleWorld();
  if (S.tab === 'yaml') refreshYaml();
}

// ---------------------------------------------------------------- building the page

export function mountPlan(container, info) {
  S.info = info;
  loadStored();
  F.bind({ doc: () => S.doc, changed: (p) => changed(p) });

  const fileInput = h('input#import-file', { type: 'file', accept: '.yaml,.yml,.json,text/yaml,application/json', hidden: true });
  fileInput.addEventListener('change', async () => {
    const f = fileInput.files && fileInput.files[0];
    if (f) await importText(await f.text(), f.name);
    fileInput.value = '';
  });
  el.pasteBox = h('div.paste-box', { hidden: true },
    el.pasteText = h('textarea#paste-text', { rows: 8, placeholder: 'Paste a SimulationRun (YAML or JSON) here', spellcheck: 'false' }),
    h('div.actions',
      h('button#paste-load', { type: 'button', onclick: async () => { if (await importText(el.pasteText.value, 'pasted')) el.pasteBox.hidden = true; } }, 'Load'),
      h('button', { type: 'button', class: 'secondary', onclick: () => { el.pasteBox.hidden = true; } }, 'Cancel')));

  el.exportLink = h('a#export-link', { hidden: true, download: 'scenario.yaml' }, 'download');
  el.queue = h('input#launch-queue', { type: 'text', placeholder: 'queue (optional)', size: 14, spellcheck: 'false' });
  el.launchBox = h('div.launch',
    el.queueRow = h('label.inline', { hidden: true }, ' ', el.queue),
    el.launch = h('button#launch.primary', { type: 'button', onclick: launch }, 'Launch'));
  setInfo(info);

  el.panel = h('aside.plan-panel',
    h('div.panel-head',
      h('div.file-actions',
        h('label.button#import-label', { for: 'import-file', title: 'Open a SimulationRun file' }, 'Import…', fileInput),
        h('button#paste-open.secondary', { type: 'button', onclick: () => { el.pasteBox.hidden = !el.pasteBox.hidden; el.pasteText.focus(); } }, 'Paste…'),
        h('button#new-scenario.secondary', { type: 'button', onclick: newScenario }, 'New'),
        h('button#export', { type: 'button', onclick: () => exportYaml(true) }, 'Export YAML'),
        el.exportLink),
      el.pasteBox,
      el.launchBox,
      el.refusal = h('div.api-refusal', { hidden: true, role: 'alert' }),
      el.flash = h('div.flash', { hidden: true }),
      el.status = h('div.status-line', { 'aria-live': 'polite' }, 'validating…'),
      el.topErrors = h('ul.top-errors')),
    el.tabs = h('nav.tabs', TABS.map(([id, label]) => h('button', { type: 'button', dataset: { tab: id }, onclick: () => selectTab(id) }, label, h('span.tab-badge')))),
    el.bodies = h('div.tab-bodies', TABS.map(([id]) => h('section.tab-body', { dataset: { tab: id } }))));

  el.hint = h('div.map-hint', { hidden: true });
  el.spinner = h('div.map-spinner', { hidden: true }, h('span.spin'), ' building the city…');
  el.worldNote = h('div.map-note', { hidden: true });
  el.mapTools = h('div.map-tools',
    h('button#pick-origin', { type: 'button', onclick: () => setMode({ kind: 'origin' }) }, 'Pick origin'),
    h('button#draw-zone', { type: 'button', onclick: () => startZone(-1) }, 'Draw zone'),
    el.finishZone = h('button#finish-zone.primary', { type: 'button', hidden: true, onclick: finishZone }, 'Finish zone'),
    h('button#add-group', { type: 'button', onclick: () => setMode({ kind: 'group' }) }, 'Add group'),
    el.cancelMode = h('button#cancel-mode.secondary', { type: 'button', hidden: true, onclick: () => setMode(null) }, 'Cancel'));
  el.mapEl = h('div#plan-map');
  el.mapWrap = h('div.plan-map', el.mapEl, el.mapTools, el.hint, el.spinner, el.worldNote);
  el.root = h('div.plan', el.mapWrap, el.panel);
  container.append(el.root);

  document.addEventListener('keydown', (e) => {
    if (el.root.offsetParent === null) return;
    if (e.target && /INPUT|TEXTAREA|SELECT/.test(e.target.tagName)) return;
    if (e.key === 'Escape') setMode(null);
    if (e.key === 'Enter' && S.mode && S.mode.kind === 'zone') finishZone();
  });

  renderForms();
  selectTab(S.tab);
  const hooksApi = {
    doc: () => clone(S.doc),
    errors: () => clone(S.errors),
    original: () => S.original,
    get validated() { return S.validated; },
    get worldLoads() { return hooks.worldLoads; },
    get validations() { return hooks.validations; },
    get mapReady() { return mapReady; },
    get mode() { return S.mode ? S.mode.kind : null; },
    /** The client pixel (for page.mouse) of a WGS84 point on the plan map. */
    pixel(lat, lon) {
      const p = map.project([lon, lat]);
      const r = el.mapEl.getBoundingClientRect();
      return { x: r.left + p.x, y: r.top + p.y };
    },
    map: () => map,
    /** The GeoJSON last given to one of the map's sources (zones, homes, draft...). */
    mapData: (id) => clone(lastData[id] || null),
  };
  window.sadesimConsole = Object.defineProperties(window.sadesimConsole || {}, Object.getOwnPropertyDescriptors(hooksApi));
}

export function setInfo(info) {
  S.info = info;
  if (!el.queueRow) return;
  el.queueRow.hidden = !(info && info.backend === 'cluster');
}

/** The page became visible: create the map the first time (it needs its size). */
export function showPlan() {
  if (!map) createMap();
  else map.resize();
  if (!S.validated) scheduleValidate.flush();
}

export function hidePlan() {
  if (S.mode) setMode(null);
}

function selectTab(id) {
  S.tab = id;
  for (const b of el.tabs.querySelectorAll('button')) b.classList.toggle('active', b.dataset.tab === id);
  for (const s of el.bodies.children) s.hidden = s.dataset.tab !== id;
  if (id === 'yaml') refreshYaml();
}

function renderForms() {
  for (const s of el.bodies.children) {
    const t = s.dataset.tab;
    const scroll = s.scrollTop;
    fill(s, t === 'general' ? generalTab() : t === 'zones' ? zonesTab() : t === 'fleet' ? fleetTab()
      : t === 'environment' ? environmentTab() : t === 'pilot' ? pilotTab() : yamlTab());
    s.scrollTop = scroll;
  }
  showErrors();
}

// ---------------------------------------------------------------- tabs

function btn(label, onclick, cls = 'small', attrs = {}) {
  return h(`button.${cls.split(' ').join('.')}`, Object.assign({ type: 'button', onclick }, attrs), label);
}

/** An optional object switched on and off by a checkbox (wind, GNSS, pilot...). */
function optional(path, label, make, body) {
  const present = getPath(S.doc, path) !== undefined;
  const box = h('input', { type: 'checkbox', checked: present, id: `opt-${path.replace(/\W/g, '-')}` });
  box.addEventListener('change', () => {
    setPath(S.doc, path, box.checked ? make() : undefined);
    changed(path, { structure: true });
  });
  return h('div.optional', { 'data-field': path }, h('div.row.check', box, h('label', { for: box.id }, label)), present ? body() : null);
}

function generalTab() {
  const p = 'spec';
  const sp = spec();
  const clockMode = sp.clock && sp.clock.mode;
  const world = sp.world || {};
  const openAreas = world.openAreas || [];
  return h('div',
    F.text('metadata.name', 'Name', { keepEmpty: true, help: 'DNS label, at most 40 characters' }),
    F.text(`${p}.duration`, 'Duration', { placeholder: '3m', help: 'Simulated time: 90s, 15m, 1h30m' }),
    F.group(`${p}.clock`, 'Clock',
      F.select(`${p}.clock.mode`, 'Mode', [['', '(default: realtime)'], 'realtime', 'scaled', 'asFastAsPossible'], {
        onChange: (v) => {
          if (v !== 'scaled' && sp.clock) delete sp.clock.factor;
          if (v === 'scaled' && sp.clock && sp.clock.factor === undefined) sp.clock.factor = 4;
          if (v === '' && sp.clock && Object.keys(sp.clock).length === 0) delete sp.clock;
          changed(`${p}.clock`, { structure: true });
        },
      }),
      clockMode === 'scaled' ? F.num(`${p}.clock.factor`, 'Factor', { help: 'simulated seconds per wall second' }) : null),
    F.num(`${p}.seed`, 'Seed', { placeholder: '0' }),
    F.num(`${p}.physicsRateHz`, 'Physics rate (Hz)', { placeholder: '1000' }),
    F.group(`${p}.origin`, 'Origin',
      F.num(`${p}.origin.latitudeDeg`, 'Latitude (°)'),
      F.num(`${p}.origin.longitudeDeg`, 'Longitude (°)'),
      F.num(`${p}.origin.altitudeMslM`, 'Ground altitude (m MSL)'),
      h('div.actions', btn('Pick on the map', () => setMode({ kind: 'origin' })))),
    F.group(`${p}.world`, 'World',
      F.select(`${p}.world.source`, 'Source', [['', '(default: procedural)'], 'procedural', 'osm'], { onChange: () => changed(`${p}.world.source`, { structure: true }) }),
      F.num(`${p}.world.extentM`, 'Half-width (m)', { placeholder: '3000' }),
      world.source === 'osm' ? F.text(`${p}.world.osm.file`, 'OSM extract') : null,
      world.source !== 'osm' ? F.group(`${p}.world.city`, 'Procedural city',
        F.num(`${p}.world.city.blockSizeM`, 'Block size (m)', { placeholder: '120' }),
        F.num(`${p}.world.city.streetWidthM`, 'Street width (m)', { placeholder: '25' }),
        F.num(`${p}.world.city.medianBuildingHeightM`, 'Median height (m)', { placeholder: '30' }),
        F.num(`${p}.world.city.maxBuildingHeightM`, 'Tallest (m)', { placeholder: '300' }),
        F.num(`${p}.world.city.builtFraction`, 'Built fraction', { placeholder: '0.5' })) : null,
      world.source !== 'osm' ? h('div.sublist', { 'data-field': `${p}.world.openAreas` },
        h('div.sublist-title', 'Open areas (kept free of buildings)'),
        openAreas.map((a, j) => discRow(`${p}.world.openAreas[${j}]`, () => { openAreas.splice(j, 1); if (!openAreas.length) delete world.openAreas; changed(`${p}.world.openAreas`, { structure: true }); })),
        h('div.actions', btn('Add an open area on the map', () => setMode({ kind: 'openArea' })))) : null),
    F.group(`${p}.sharding`, 'Sharding',
      F.num(`${p}.sharding.dronesPerShard`, 'Drones per shard', { placeholder: '100' }),
      F.num(`${p}.sharding.syncWindowSteps`, 'Sync window (steps)', { placeholder: '10' })),
    F.group(`${p}.recording`, 'Recording',
      F.check(`${p}.recording.mcap`, 'MCAP recording', { defaultOn: true, explicitFalse: true }),
      F.check(`${p}.recording.ulog`, 'ULog per drone', { defaultOn: true, explicitFalse: true })),
    F.check(`${p}.rendering.enabled`, 'Live 3D view (rendering)', { explicitFalse: true }),
    F.text(`${p}.archive.url`, 'Archive URL', { placeholder: 'file://runs' }),
    F.text(`${p}.queue`, 'Kueue queue', { placeholder: '(Kubernetes only)' }));
}

/** A disc (open area, home area): centre, radius, name, and a delete button. */
function discRow(path, onDelete) {
  return h('div.subitem', { 'data-field': path },
    h('div.grid3',
      F.num(`${path}.center.latitudeDeg`, 'Lat (°)'),
      F.num(`${path}.center.longitudeDeg`, 'Lon (°)'),
      F.num(`${path}.radiusM`, 'Radius (m)')),
    h('div.grid-name', F.text(`${path}.name`, 'Name'), btn('Delete', onDelete, 'small danger')));
}

function zonesTab() {
  const zones = spec().zones || [];
  return h('div', { 'data-field': 'spec.zones' },
    h('div.actions', btn('Draw a zone on the map', () => startZone(-1), 'small primary')),
    zones.length ? null : h('p.muted', 'No zones. Draw one: click its corners on the map, then Finish (or double-click).'),
    zones.map((z, i) => zoneCard(z, i)));
}

function zoneCard(z, i) {
  const p = `spec.zones[${i}]`;
  const n = Array.isArray(z.polygon) ? z.polygon.length : 0;
  return h(`div.item${S.selectedZone === i ? '.selected' : ''}`, { 'data-field': p, id: `zone-${i}`, dataset: { index: i } },
    h('div.item-head', { onclick: (e) => { if (e.target.tagName !== 'BUTTON') selectZone(i, true); } },
      h('span.swatch.zone-swatch'),
      h('strong', { id: `zone-title-${i}` }, z.name || `zone ${i + 1}`),
      h('span.spacer'),
      btn('Redraw', () => startZone(i)),
      btn('Delete', () => { spec().zones.splice(i, 1); if (!spec().zones.length) delete spec().zones; S.selectedZone = -1; changed('spec.zones', { structure: true }); }, 'small danger')),
    F.text(`${p}.name`, 'Name', { keepEmpty: true }),
    h('div.polygon-info', { 'data-field': `${p}.polygon` }, `${n} vertices`,
      n ? h('span.muted', ` · first ${fmtPos(z.polygon[0])}`) : null),
    F.group(`${p}.floor`, 'Floor',
      h('div.grid2',
        F.num(`${p}.floor.heightM`, 'Height (m)', { placeholder: '0 = ground' }),
        F.select(`${p}.floor.reference`, 'Reference', [['', '–'], 'agl', 'msl']))),
    F.group(`${p}.ceiling`, 'Ceiling',
      h('div.grid2',
        F.num(`${p}.ceiling.heightM`, 'Height (m)'),
        F.select(`${p}.ceiling.reference`, 'Reference', ['agl', 'msl']))),
    h('div.grid2',
      F.text(`${p}.activeFrom`, 'Active from', { placeholder: 'start' }),
      F.text(`${p}.activeUntil`, 'Active until', { placeholder: 'end' })),
    F.group(`${p}.policy`, 'Policy',
      F.list(`${p}.policy.authorizedOperators`, 'Authorized operators', { placeholder: 'chicago-dps, ...', keepEmpty: false }),
      h('div.grid2',
        F.num(`${p}.policy.capacity`, 'Capacity', { placeholder: 'unlimited' }),
        F.text(`${p}.policy.leaseDuration`, 'Lease', { placeholder: '10m' })),
      h('div.grid2',
        F.num(`${p}.policy.minAltitudeAglM`, 'Min altitude (m AGL)'),
        F.num(`${p}.policy.maxAltitudeAglM`, 'Max altitude (m AGL)'))));
}

function fmtPos(p) {
  return isPos(p) ? `${p.latitudeDeg.toFixed(5)}, ${p.longitudeDeg.toFixed(5)}` : '?';
}

function fleetTab() {
  const fleet = spec().fleet || [];
  return h('div', { 'data-field': 'spec.fleet' },
    h('div.actions', btn('Add a group on the map', () => setMode({ kind: 'group' }), 'small primary')),
    fleet.length ? null : h('p.muted', 'No fleet groups. Add one: then click its home on the map.'),
    fleet.map((g, i) => groupCard(g, i)));
}

function homesKind(g) {
  const hm = g.homes || {};
  return hm.explicit ? 'explicit' : hm.areas ? 'areas' : hm.randomInArea ? 'randomInArea' : '';
}

function groupCard(g, i) {
  const p = `spec.fleet[${i}]`;
  const colour = GROUP_COLOURS[i % GROUP_COLOURS.length];
  const kind = homesKind(g);
  const homes = g.homes || {};
  const kindSel = h('select', { 'data-homes-kind': i },
    h('option', { value: 'randomInArea' }, 'random in one disc'),
    h('option', { value: 'areas' }, 'spread over discs (parks)'),
    h('option', { value: 'explicit' }, 'explicit positions'));
  kindSel.value = kind || 'randomInArea';
  kindSel.addEventListener('change', () => {
    const anchor = groupAnchor(g) || S.doc.spec.origin;
    const c = anchor ? { latitudeDeg: anchor.latitudeDeg, longitudeDeg: anchor.longitudeDeg } : { latitudeDeg: 0, longitudeDeg: 0 };
    if (kindSel.value === 'randomInArea') g.homes = { randomInArea: { center: c, radiusM: 50 } };
    else if (kindSel.value === 'areas') g.homes = { areas: [{ center: c, radiusM: 50 }] };
    else { g.homes = { explicit: [c] }; g.count = 1; }
    changed(`${p}.homes`, { structure: true });
  });
  let homesBody;
  if (kind === 'explicit') {
    homesBody = h('div.sublist', { 'data-field': `${p}.homes.explicit` },
      homes.explicit.map((q, j) => h('div.subitem.inline', { 'data-field': `${p}.homes.explicit[${j}]` },
        h('span.muted', `#${j}`),
        F.num(`${p}.homes.explicit[${j}].latitudeDeg`, 'Lat'),
        F.num(`${p}.homes.explicit[${j}].longitudeDeg`, 'Lon'),
        btn('×', () => { homes.explicit.splice(j, 1); g.count = homes.explicit.length || 1; changed(`${p}.homes`, { structure: true }); }, 'small danger', { title: 'Delete this home' }))),
      h('div.actions', btn('Add homes on the map', () => setMode({ kind: 'home', group: i }))),
      h('div.help', 'One position per drone: the count follows the list.'));
  } else if (kind === 'areas') {
    homesBody = h('div.sublist', { 'data-field': `${p}.homes.areas` },
      homes.areas.map((a, j) => discRow(`${p}.homes.areas[${j}]`, () => { homes.areas.splice(j, 1); changed(`${p}.homes`, { structure: true }); })),
      h('div.actions', btn('Add a disc on the map', () => setMode({ kind: 'area', group: i }))));
  } else if (kind === 'randomInArea') {
    homesBody = h('div',
      h('div.grid3',
        F.num(`${p}.homes.randomInArea.center.latitudeDeg`, 'Lat (°)'),
        F.num(`${p}.homes.randomInArea.center.longitudeDeg`, 'Lon (°)'),
        F.num(`${p}.homes.randomInArea.radiusM`, 'Radius (m)')),
      F.text(`${p}.homes.randomInArea.name`, 'Name'),
      h('div.actions', btn('Move on the map', () => setMode({ kind: 'home', group: i }))));
  }
  const mission = g.mission;
  const items = (mission && mission.items) || [];
  const addSel = h('select.add-item', h('option', { value: '' }, 'add an item…'), MISSION_KINDS.map((k) => h('option', { value: k }, k)));
  addSel.addEventListener('change', () => {
    if (!addSel.value) return;
    const last = [...items].reverse().find((it) => kindOf(it) === 'waypoint');
    const at = last ? last.waypoint : groupAnchor(g);
    items.push(newMissionItem(addSel.value, at));
    changed(`${p}.mission.items`, { structure: true });
  });
  const cred = g.credential || {};
  return h(`div.item${S.selectedGroup === i ? '.selected' : ''}`, { 'data-field': p, id: `group-${i}`, dataset: { index: i } },
    h('div.item-head', { onclick: (e) => { if (e.target.tagName !== 'BUTTON') selectGroup(i, true); } },
      h('span.swatch', { style: { background: colour } }),
      h('strong', { id: `group-title-${i}` }, g.name || `group ${i + 1}`),
      h('span.spacer'),
      btn('Delete', () => { spec().fleet.splice(i, 1); S.selectedGroup = -1; changed('spec.fleet', { structure: true }); }, 'small danger')),
    h('div.grid2',
      F.text(`${p}.name`, 'Name', { keepEmpty: true }),
      F.num(`${p}.count`, 'Count')),
    h('div.grid2',
      F.select(`${p}.airframe`, 'Airframe', AIRFRAMES),
      F.text(`${p}.operator`, 'Operator', { keepEmpty: true })),
    h('div.grid2',
      F.select(`${p}.role`, 'Role', [['', '(default: other)'], ...ROLES]),
      F.select(`${p}.geofence`, 'Geofence', [['', 'none (pilot keeps out)'], 'hold', 'returnToLaunch'])),
    cred.secretKeyRef
      ? F.group(`${p}.credential`, 'Credential (Secret)', h('div.grid2', F.text(`${p}.credential.secretKeyRef.name`, 'Secret'), F.text(`${p}.credential.secretKeyRef.key`, 'Key')))
      : F.text(`${p}.credential.value`, 'Credential', { placeholder: 'token for the airspace authority' }),
    F.group(`${p}.altitude`, 'Altitude limits',
      h('div.grid2',
        F.num(`${p}.altitude.maxAglM`, 'Max (m AGL)'),
        F.num(`${p}.altitude.minAglM`, 'Min cruising (m AGL)'))),
    F.group(`${p}.homes`, 'Homes', h('div.row', h('label', 'Placement'), kindSel), homesBody),
    optional(`${p}.mission`, 'Scripted mission (the built-in pilot flies it)', () => ({ items: [{ takeoff: { altitudeAglM: 30 } }, { loiter: { holdS: 10 } }, { returnToLaunch: {} }] }), () =>
      F.group(`${p}.mission`, 'Mission',
        F.num(`${p}.mission.speedMps`, 'Speed (m/s)', { placeholder: '5' }),
        h('ol.mission-items', { 'data-field': `${p}.mission.items` },
          items.map((it, j) => missionItem(p, items, it, j))),
        h('div.actions', btn('Add waypoints on the map', () => setMode({ kind: 'waypoint', group: i })), addSel))),
    (g.cameras && g.cameras.length) ? h('p.muted', `${g.cameras.length} onboard camera(s): kept as imported.`) : null);
}

function missionItem(p, items, it, j) {
  const ip = `${p}.mission.items[${j}]`;
  const k = kindOf(it);
  let body = null;
  if (k === 'takeoff') body = F.num(`${ip}.takeoff.altitudeAglM`, 'Altitude (m AGL)');
  else if (k === 'waypoint') {
    body = h('div',
      h('div.grid2', F.num(`${ip}.waypoint.latitudeDeg`, 'Lat (°)'), F.num(`${ip}.waypoint.longitudeDeg`, 'Lon (°)')),
      h('div.grid2', F.num(`${ip}.waypoint.altitudeAglM`, 'Altitude (m AGL)'), F.num(`${ip}.waypoint.holdS`, 'Hold (s)')));
  } else if (k === 'loiter') body = F.num(`${ip}.loiter.holdS`, 'Hold (s)');
  else if (k === 'randomWaypoints') {
    body = h('div',
      h('div.grid3', F.num(`${ip}.randomWaypoints.count`, 'Count'), F.num(`${ip}.randomWaypoints.minAltitudeAglM`, 'Min (m)'), F.num(`${ip}.randomWaypoints.maxAltitudeAglM`, 'Max (m)')),
      F.num(`${ip}.randomWaypoints.holdS`, 'Hold (s)'));
  }
  const move = (d) => {
    const t = j + d;
    if (t < 0 || t >= items.length) return;
    [items[j], items[t]] = [items[t], items[j]];
    changed(`${p}.mission.items`, { structure: true });
  };
  return h('li.mitem', { 'data-field': ip },
    h('div.mitem-head', h('span.kind', k || '?'), h('span.spacer'),
      btn('↑', () => move(-1), 'small secondary', { title: 'Move up' }),
      btn('↓', () => move(1), 'small secondary', { title: 'Move down' }),
      btn('×', () => { items.splice(j, 1); changed(`${p}.mission.items`, { structure: true }); }, 'small danger', { title: 'Delete' })),
    body);
}

function environmentTab() {
  const p = 'spec.environment';
  const env = spec().environment || {};
  const gnss = env.gnss || {};
  const dropouts = gnss.dropouts || [];
  const ensureEnv = () => spec().environment || (spec().environment = {});
  const optEnv = (key, label, make, body) => {
    const present = env[key] !== undefined;
    const box = h('input', { type: 'checkbox', checked: present, id: `opt-env-${key}` });
    box.addEventListener('change', () => {
      if (box.checked) ensureEnv()[key] = make();
      else if (spec().environment) {
        delete spec().environment[key];
        if (!Object.keys(spec().environment).length) delete spec().environment;
      }
      changed(`${p}.${key}`, { structure: true });
    });
    return h('div.optional', { 'data-field': `${p}.${key}` }, h('div.row.check', box, h('label', { for: box.id }, label)), present ? body() : null);
  };
  return h('div',
    optEnv('wind', 'Wind', () => ({ speedMps: 5, directionFromDeg: 270 }), () => F.group(`${p}.wind`, 'Wind',
      h('div.grid2', F.num(`${p}.wind.speedMps`, 'Speed (m/s)'), F.num(`${p}.wind.directionFromDeg`, 'From (° true)')),
      h('div.grid2', F.num(`${p}.wind.referenceHeightM`, 'Measured at (m)', { placeholder: '10' }),
        F.select(`${p}.wind.turbulence`, 'Turbulence', [['', '(default: none)'], 'none', 'light', 'moderate', 'severe'])),
      F.select(`${p}.wind.urban.model`, 'Around buildings', [['', '(default: diagnostic)'], 'diagnostic', 'none', 'openfoam']))),
    optEnv('gnss', 'GNSS receivers', () => ({ rateHz: 5 }), () => F.group(`${p}.gnss`, 'GNSS',
      F.num(`${p}.gnss.rateHz`, 'Fix rate (Hz)', { placeholder: '5' }),
      optional(`${p}.gnss.constellation`, 'Ranging receiver: real satellites, blocked by buildings (urban GNSS)', () => ({}), () => h('div',
        F.num(`${p}.gnss.constellation.elevationMaskDeg`, 'Elevation mask (°)', { placeholder: '10' }),
        F.text(`${p}.gnss.constellation.epoch`, 'Epoch (UTC)', { placeholder: '2020-12-01T12:00:00Z' }),
        F.text(`${p}.gnss.constellation.file`, 'Orbit file (TLE)', { placeholder: '(nominal GPS + Galileo)' }))),
      gnss.constellation ? null : h('div.grid3',
        F.num(`${p}.gnss.horizontalSigmaM`, 'σ horiz. (m)', { placeholder: '0.5' }),
        F.num(`${p}.gnss.verticalSigmaM`, 'σ vert. (m)', { placeholder: '0.8' }),
        F.num(`${p}.gnss.biasWalkMPerSqrtS`, 'Bias walk', { placeholder: '0.01' })),
      F.group(`${p}.gnss.bias`, 'Constant bias (m, ENU)', h('div.grid3',
        F.num(`${p}.gnss.bias.eastM`, 'East'), F.num(`${p}.gnss.bias.northM`, 'North'), F.num(`${p}.gnss.bias.upM`, 'Up'))),
      h('div.sublist', { 'data-field': `${p}.gnss.dropouts` },
        h('div.sublist-title', 'Dropouts'),
        dropouts.map((d, j) => h('div.subitem', { 'data-field': `${p}.gnss.dropouts[${j}]` },
          h('div.grid3',
            F.text(`${p}.gnss.dropouts[${j}].start`, 'Start', { keepEmpty: true }),
            F.text(`${p}.gnss.dropouts[${j}].duration`, 'Duration', { keepEmpty: true }),
            F.list(`${p}.gnss.dropouts[${j}].groups`, 'Groups', { placeholder: 'all' })),
          btn('Delete', () => { dropouts.splice(j, 1); if (!dropouts.length) delete gnss.dropouts; changed(`${p}.gnss.dropouts`, { structure: true }); }, 'small danger'))),
        h('div.actions', btn('Add a dropout', () => { (gnss.dropouts || (gnss.dropouts = [])).push({ start: '30s', duration: '10s' }); changed(`${p}.gnss.dropouts`, { structure: true }); }))))));
}

function pilotTab() {
  const p = 'spec.pilot';
  const criteria = spec().criteria || [];
  const env = (spec().pilot && spec().pilot.env) || [];
  const addSel = h('select#add-criterion', h('option', { value: '' }, 'add a criterion…'), CRITERION_KINDS.map((k) => h('option', { value: k }, k)));
  addSel.addEventListener('change', () => {
    if (!addSel.value) return;
    (spec().criteria || (spec().criteria = [])).push(newCriterion(addSel.value, S.doc));
    changed('spec.criteria', { structure: true });
  });
  return h('div',
    h('h3', 'Pilot'),
    optional(p, 'A pilot program (flies the groups without a mission, over MAVLink)', () => ({ command: ['python3', 'pilot.py'] }), () => F.group(p, null,
      F.lines(`${p}.command`, 'Command', { help: 'program and arguments, one a line; started from the scenario file\'s folder' }),
      F.text(`${p}.image`, 'Image', { placeholder: '(Kubernetes)' }),
      F.lines(`${p}.containerCommand`, 'Container command', { rows: 2, help: 'on Kubernetes, when it differs from the command' }),
      F.select(`${p}.onExit`, 'When it exits', [['', '(default: endRun)'], 'endRun', 'continue']),
      h('div.sublist', { 'data-field': `${p}.env` },
        h('div.sublist-title', 'Environment'),
        env.map((e, j) => h('div.subitem.inline', { 'data-field': `${p}.env[${j}]` },
          F.text(`${p}.env[${j}].name`, 'Name', { keepEmpty: true }),
          F.text(`${p}.env[${j}].value`, 'Value', { keepEmpty: true }),
          btn('×', () => { env.splice(j, 1); if (!env.length) delete spec().pilot.env; changed(`${p}.env`, { structure: true }); }, 'small danger'))),
        h('div.actions', btn('Add a variable', () => { const pl = spec().pilot; (pl.env || (pl.env = [])).push({ name: 'NAME', value: '' }); changed(`${p}.env`, { structure: true }); }))))),
    h('h3', 'Criteria'),
    h('div', { 'data-field': 'spec.criteria' },
      criteria.length ? null : h('p.muted', 'No criteria: the run passes whatever happens.'),
      criteria.map((c, j) => criterionCard(c, j)),
      h('div.actions', addSel)));
}

function criterionCard(c, j) {
  const cp = `spec.criteria[${j}]`;
  const k = kindOf(c);
  let body = null;
  if (k === 'minSeparation') body = F.num(`${cp}.minSeparation.distanceM`, 'Distance (m)');
  else if (k === 'reachZone') {
    body = h('div', F.list(`${cp}.reachZone.groups`, 'Groups', { keepEmpty: true }), h('div.grid2', F.text(`${cp}.reachZone.zone`, 'Zone', { keepEmpty: true }), F.text(`${cp}.reachZone.within`, 'Within', { keepEmpty: true })));
  } else if (k === 'zoneVerdicts') {
    body = h('div', F.list(`${cp}.zoneVerdicts.groups`, 'Groups', { keepEmpty: true }), h('div.grid2', F.text(`${cp}.zoneVerdicts.zone`, 'Zone', { keepEmpty: true }), F.select(`${cp}.zoneVerdicts.expect`, 'Expect', ['granted', 'denied'])));
  } else if (k === 'estimatedPositionError') {
    body = h('div', F.num(`${cp}.estimatedPositionError.maxHorizontalM`, 'Max horizontal (m)'), F.list(`${cp}.estimatedPositionError.groups`, 'Groups', { placeholder: 'all' }));
  }
  return h('div.item.criterion', { 'data-field': cp },
    h('div.item-head', h('strong', k || '?'), h('span.spacer'),
      btn('Delete', () => { spec().criteria.splice(j, 1); if (!spec().criteria.length) delete spec().criteria; changed('spec.criteria', { structure: true }); }, 'small danger')),
    body);
}

function yamlTab() {
  return h('div.yaml-tab',
    h('div.actions', btn('Download', () => exportYaml(true), 'small'), h('span.muted', S.original !== null ? ' imported: exported exactly as the file was until you change it; after a change, written from the fields (its comments are lost)' : '')),
    el.yamlPre = h('pre#yaml-text', S.yaml === null ? 'exporting…' : S.yaml));
}

// ---------------------------------------------------------------- validation and errors

let vseq = 0;
const scheduleValidate = debounce(async () => {
  const seq = ++vseq;
  document.body.dataset.validating = '1';
  try {
    const r = await post('/api/scenario/validate', { document: S.doc });
    if (seq !== vseq) return;
    S.errors = (r.body && r.body.errors) || [];
    S.plan = (r.body && r.body.plan) || null;
    S.validated = true;
  } catch (e) {
    if (seq !== vseq) return;
    S.errors = e.errors || [{ field: '', message: `validation failed: ${e.message}` }];
    S.plan = null;
  } finally {
    if (seq === vseq) { delete document.body.dataset.validating; hooks.validations++; }
  }
  showErrors();
  updateMap();
}, 300);

/** The element an error's path belongs to: the control with that exact `data-field`, else
 * the nearest enclosing object's (a group, a list item), never `spec` itself. */
function fieldFor(path) {
  if (!path) return null;
  let parts = parsePath(path);
  while (parts.length > 1) {
    const found = el.bodies.querySelector(`[data-field="${CSS.escape(joinPath(parts))}"]`);
    if (found) return found;
    parts = parts.slice(0, -1);
  }
  return null;
}

function showErrors() {
  if (!el.bodies) return;
  for (const e of el.panel.querySelectorAll('.field-error')) e.remove();
  for (const e of el.panel.querySelectorAll('.has-error')) e.classList.remove('has-error');
  const byEl = new Map();
  const loose = [];
  for (const err of S.errors) {
    const f = fieldFor(err.field);
    if (!f) { loose.push(err); continue; }
    if (!byEl.has(f)) byEl.set(f, []);
    byEl.get(f).push(f.dataset.field === err.field ? err.message : `${err.field.slice(f.dataset.field.length).replace(/^\./, '')}: ${err.message}`);
  }
  const perTab = {};
  for (const [f, msgs] of byEl) {
    f.classList.add('has-error');
    f.after(h('div.field-error', { role: 'alert', dataset: { for: f.dataset.field } }, msgs.join('\n')));
    const tab = f.closest('.tab-body');
    if (tab) perTab[tab.dataset.tab] = (perTab[tab.dataset.tab] || 0) + msgs.length;
  }
  for (const b of el.tabs.querySelectorAll('button')) {
    const n = perTab[b.dataset.tab] || 0;
    b.querySelector('.tab-badge').textContent = n ? String(n) : '';
    b.classList.toggle('has-errors', n > 0);
  }
  fill(el.topErrors, loose.map((e) => h('li.field-error-top', e.field ? h('code', e.field) : null, e.field ? ': ' : '', e.message)));
  const n = S.errors.length;
  const pl = S.plan;
  fill(el.status,
    n ? h('span.bad', `${n} problem${n > 1 ? 's' : ''}`) : S.validated ? h('span.ok', 'valid') : h('span.muted', 'validating…'),
    pl ? h('span.muted', ` · ${pl.drones} drone${pl.drones === 1 ? '' : 's'}, ${fmtS(pl.durationS)}${typeof pl.shards === 'number' ? `, ${pl.shards} shard${pl.shards === 1 ? '' : 's'}` : ''}`) : null,
    S.original !== null ? h('span.muted', ' · imported') : null);
  el.status.dataset.problems = String(n);
}

function fmtS(s) {
  if (typeof s !== 'number') return '';
  if (s >= 60) return `${Math.floor(s / 60)} min${s % 60 ? ` ${Math.round(s % 60)} s` : ''}`;
  return `${s} s`;
}

function errorPaths() {
  return S.errors.map((e) => e.field || '');
}

// ---------------------------------------------------------------- import, export, launch

async function importText(text, name) {
  flash(null);
  try {
    const r = await post('/api/scenario/parse', text);
    S.doc = r.body.document;
    S.original = text;
    S.errors = r.body.errors || [];
    S.validated = true;
    S.selectedZone = -1;
    S.selectedGroup = -1;
    S.fitPending = true;
    S.yaml = null;
    store();
    renderForms();
    updateMap();
    scheduleWorld();
    scheduleValidate();
    flash(`loaded ${name || 'the scenario'}`, 'ok');
    return true;
  } catch (e) {
    flash(`not loaded ${name || 'the scenario'}: ${e.message}`, 'error');
    return false;
  }
}

function newScenario() {
  S.doc = defaultDocument();
  S.original = null;
  S.selectedZone = -1;
  S.selectedGroup = -1;
  S.fitPending = true;
  changed(null, { structure: true });
}

async function exportYaml(download) {
  try {
    const text = await call('POST', '/api/scenario/yaml', { document: S.doc, original: S.original }, { text: true });
    S.yaml = text;
    if (el.yamlPre) el.yamlPre.textContent = text;
    if (download) {
      const name = `${(S.doc.metadata && S.doc.metadata.name) || 'scenario'}.yaml`;
      if (el.exportLink.href) URL.revokeObjectURL(el.exportLink.href);
      el.exportLink.href = URL.createObjectURL(new Blob([text], { type: 'text/yaml' }));
      el.exportLink.download = name;
      el.exportLink.click();
    }
    return text;
  } catch (e) {
    flash(`export failed: ${e.message}`, 'error');
    return null;
  }
}

const refreshYaml = debounce(() => exportYaml(false), 300);

async function launch() {
  el.refusal.hidden = true;
  flash(null);
  const body = { document: S.doc };
  if (S.info && S.info.backend === 'cluster' && namespace()) body.namespace = namespace();
  if (S.info && S.info.backend === 'cluster' && el.queue.value.trim()) body.queue = el.queue.value.trim();
  el.launch.disabled = true;
  try {
    const r = await post('/api/runs', body);
    const run = r.body && r.body.run;
    flash(`launched ${run ? run.name : ''}`, 'ok');
    if (run) location.hash = `#/runs/${encodeURIComponent(run.id)}`;
  } catch (e) {
    if (e instanceof ApiError && e.status === 422 && e.errors) {
      S.errors = e.errors;
      showErrors();
      updateMap();
      flash(`not launched: ${e.errors.length} problem${e.errors.length > 1 ? 's' : ''}`, 'error');
    } else if (e instanceof ApiError && (e.status === 401 || e.status === 403)) {
      fill(el.refusal, h('strong', e.status === 401 ? 'Not logged in: ' : 'Refused by the Kubernetes API server: '), e.message);
      el.refusal.hidden = false;
    } else {
      flash(`launch failed: ${e.message}`, 'error');
    }
  } finally {
    el.launch.disabled = false;
  }
}

function flash(text, kind) {
  if (!el.flash) return;
  el.flash.hidden = !text;
  el.flash.className = `flash ${kind || ''}`;
  el.flash.textContent = text || '';
}

// ---------------------------------------------------------------- the map

const EMPTY = { type: 'FeatureCollection', features: [] };

function createMap() {
  const o = spec().origin || { latitudeDeg: 41.8796, longitudeDeg: -87.6237 };
  map = new maplibregl.Map({
    container: el.mapEl,
    style: {
      version: 8,
      sources: {},
      layers: [{ id: 'background', type: 'background', paint: { 'background-color': '#eceae4' } }],
    },
    center: [o.longitudeDeg || 0, o.latitudeDeg || 0],
    zoom: 14,
    attributionControl: false,
    dragRotate: true,
    maxPitch: 60,
    fadeDuration: 0,
  });
  map.addControl(new maplibregl.NavigationControl({ visualizePitch: true }), 'top-right');
  map.addControl(new maplibregl.ScaleControl({ unit: 'metric' }), 'bottom-left');
  map.on('load', () => {
    // The city's sources are the big ones (tens of thousands of footprints): tiles built to
    // zoom 15 only, a thin buffer, drawn without antialiasing (an outline pass per polygon).
    const src = (id) => map.addSource(id, /buildings|parks/.test(id) ? { type: 'geojson', data: EMPTY, maxzoom: 15, buffer: 16, tolerance: 0.5 } : { type: 'geojson', data: EMPTY });
    for (const id of ['world-square', 'parks', 'buildings', 'open-areas', 'zones', 'home-discs', 'missions', 'waypoints', 'homes', 'draft']) src(id);
    map.addLayer({ id: 'world-square', type: 'line', source: 'world-square', paint: { 'line-color': '#888', 'line-width': 1.5, 'line-dasharray': [4, 3] } });
    map.addLayer({ id: 'parks', type: 'fill', source: 'parks', paint: { 'fill-color': '#b7dca8', 'fill-antialias': false } });
    map.addLayer({ id: 'open-areas', type: 'fill', source: 'open-areas', paint: { 'fill-color': '#9fd38d', 'fill-opacity': 0.35, 'fill-outline-color': '#4d8b3c' } });
    map.addLayer({
      id: 'buildings', type: 'fill', source: 'buildings',
      paint: {
        'fill-color': ['interpolate', ['linear'], ['coalesce', ['get', 'heightM'], 10], 0, '#d6d3cc', 30, '#b3afa6', 100, '#8a8579', 300, '#5d584e'],
        'fill-antialias': false,
      },
    });
    map.addLayer({
      id: 'zones-fill', type: 'fill', source: 'zones',
      paint: { 'fill-color': ['case', ['get', 'error'], '#ff3b3b', '#ff4fa3'], 'fill-opacity': ['case', ['get', 'selected'], 0.45, 0.28] },
    });
    map.addLayer({
      id: 'zones-line', type: 'line', source: 'zones',
      paint: {
        'line-color': ['case', ['get', 'error'], '#d00000', ['get', 'selected'], '#9c0058', '#e0308a'],
        'line-width': ['case', ['get', 'selected'], 3.5, 2],
      },
    });
    map.addLayer({
      id: 'home-discs', type: 'fill', source: 'home-discs',
      paint: { 'fill-color': ['get', 'color'], 'fill-opacity': ['case', ['get', 'selected'], 0.3, 0.15] },
    });
    map.addLayer({
      id: 'home-discs-line', type: 'line', source: 'home-discs',
      paint: { 'line-color': ['case', ['get', 'error'], '#d00000', ['get', 'color']], 'line-width': ['case', ['get', 'error'], 3, 1.5] },
    });
    map.addLayer({ id: 'missions', type: 'line', source: 'missions', paint: { 'line-color': ['get', 'color'], 'line-width': 2.5, 'line-opacity': 0.85 } });
    map.addLayer({
      id: 'waypoints', type: 'circle', source: 'waypoints',
      paint: { 'circle-radius': 4.5, 'circle-color': '#fff', 'circle-stroke-color': ['case', ['get', 'error'], '#d00000', ['get', 'color']], 'circle-stroke-width': ['case', ['get', 'error'], 3, 2] },
    });
    map.addLayer({
      id: 'homes', type: 'circle', source: 'homes',
      paint: { 'circle-radius': 6, 'circle-color': ['get', 'color'], 'circle-stroke-color': ['case', ['get', 'error'], '#d00000', '#fff'], 'circle-stroke-width': ['case', ['get', 'error'], 3, 1.5] },
    });
    map.addLayer({ id: 'draft-line', type: 'line', source: 'draft', filter: ['==', ['geometry-type'], 'LineString'], paint: { 'line-color': '#e0308a', 'line-width': 2, 'line-dasharray': [2, 2] } });
    map.addLayer({ id: 'draft-points', type: 'circle', source: 'draft', filter: ['==', ['geometry-type'], 'Point'], paint: { 'circle-radius': 5, 'circle-color': '#fff', 'circle-stroke-color': '#e0308a', 'circle-stroke-width': 2.5 } });
    mapReady = true;
    updateMap();
    scheduleWorld.flush();
  });
  map.on('click', onMapClick);
  map.on('dblclick', (e) => {
    if (S.mode && S.mode.kind === 'zone') { e.preventDefault(); finishZone(); }
  });
  for (const layer of ['zones-fill', 'homes', 'home-discs']) {
    map.on('mouseenter', layer, () => { if (!S.mode) map.getCanvas().style.cursor = 'pointer'; });
    map.on('mouseleave', layer, () => { if (!S.mode) map.getCanvas().style.cursor = ''; });
  }
}

const lastData = {};
function setSource(id, data) {
  lastData[id] = data;
  const s = map && mapReady && map.getSource(id);
  if (s) s.setData(data);
}

function errorAt(prefix) {
  return errorPaths().some((f) => f === prefix || f.startsWith(`${prefix}.`) || f.startsWith(`${prefix}[`));
}

/** Redraws the scenario's layers from the document (cheap: a few GeoJSON sources). */
function updateMap() {
  if (!map || !mapReady) return;
  const sp = spec();
  const zones = [];
  (sp.zones || []).forEach((z, i) => {
    const ring = (z.polygon || []).filter(isPos).map((p) => [p.longitudeDeg, p.latitudeDeg]);
    if (ring.length < 3) return;
    ring.push(ring[0]);
    zones.push({ type: 'Feature', properties: { index: i, selected: i === S.selectedZone, error: errorAt(`spec.zones[${i}]`) }, geometry: { type: 'Polygon', coordinates: [ring] } });
  });
  setSource('zones', { type: 'FeatureCollection', features: zones });

  const discs = [], homes = [], lines = [], wps = [];
  (sp.fleet || []).forEach((g, i) => {
    const color = GROUP_COLOURS[i % GROUP_COLOURS.length];
    const selected = i === S.selectedGroup;
    const homeErr = errorAt(`spec.fleet[${i}].homes`) || errorAt(`spec.fleet[${i}].count`);
    const { points, discs: ds } = groupHomes(g);
    ds.forEach((d) => discs.push({ type: 'Feature', properties: { index: i, color, selected, error: homeErr }, geometry: { type: 'Polygon', coordinates: [discRing(d.center, Math.max(1, Number(d.radiusM) || 1))] } }));
    ds.forEach((d) => homes.push({ type: 'Feature', properties: { index: i, color, error: homeErr }, geometry: { type: 'Point', coordinates: [d.center.longitudeDeg, d.center.latitudeDeg] } }));
    points.forEach((q) => homes.push({ type: 'Feature', properties: { index: i, color, error: homeErr }, geometry: { type: 'Point', coordinates: [q.longitudeDeg, q.latitudeDeg] } }));
    const items = (g.mission && g.mission.items) || [];
    const anchor = groupAnchor(g);
    const line = anchor ? [[anchor.longitudeDeg, anchor.latitudeDeg]] : [];
    items.forEach((it, j) => {
      if (kindOf(it) === 'waypoint' && isPos(it.waypoint)) {
        const c = [it.waypoint.longitudeDeg, it.waypoint.latitudeDeg];
        line.push(c);
        wps.push({ type: 'Feature', properties: { index: i, item: j, color, error: errorAt(`spec.fleet[${i}].mission.items[${j}]`) }, geometry: { type: 'Point', coordinates: c } });
      }
      if (kindOf(it) === 'returnToLaunch' && anchor) line.push([anchor.longitudeDeg, anchor.latitudeDeg]);
      if (kindOf(it) === 'randomWaypoints' && it.randomWaypoints.area && isPos(it.randomWaypoints.area.center)) {
        discs.push({ type: 'Feature', properties: { index: i, color, selected: false, error: false }, geometry: { type: 'Polygon', coordinates: [discRing(it.randomWaypoints.area.center, Math.max(1, Number(it.randomWaypoints.area.radiusM) || 1))] } });
      }
    });
    if (line.length > 1) lines.push({ type: 'Feature', properties: { index: i, color }, geometry: { type: 'LineString', coordinates: line } });
  });
  setSource('home-discs', { type: 'FeatureCollection', features: discs });
  setSource('homes', { type: 'FeatureCollection', features: homes });
  setSource('missions', { type: 'FeatureCollection', features: lines });
  setSource('waypoints', { type: 'FeatureCollection', features: wps });

  const open = ((sp.world && sp.world.openAreas) || []).filter((a) => a && isPos(a.center))
    .map((a) => ({ type: 'Feature', properties: {}, geometry: { type: 'Polygon', coordinates: [discRing(a.center, Math.max(1, Number(a.radiusM) || 1))] } }));
  setSource('open-areas', { type: 'FeatureCollection', features: open });
  const o = sp.origin;
  const extent = Number(sp.world && sp.world.extentM) || 3000;
  setSource('world-square', isPos(o) ? { type: 'FeatureCollection', features: [{ type: 'Feature', properties: {}, geometry: { type: 'LineString', coordinates: worldSquare(o, extent) } }] } : EMPTY);
  updateDraft();
  updateLabels();
  if (S.fitPending) { S.fitPending = false; fitScenario(); }
}

function updateDraft() {
  const pts = S.draft.map((p) => [p.longitudeDeg, p.latitudeDeg]);
  const features = pts.map((c, i) => ({ type: 'Feature', properties: { i }, geometry: { type: 'Point', coordinates: c } }));
  if (pts.length > 1) features.push({ type: 'Feature', properties: {}, geometry: { type: 'LineString', coordinates: pts.length > 2 ? [...pts, pts[0]] : pts } });
  setSource('draft', { type: 'FeatureCollection', features });
}

/** Names as HTML markers (the map has no fonts: nothing is fetched). */
function updateLabels() {
  for (const m of labelMarkers) m.remove();
  labelMarkers = [];
  const sp = spec();
  const add = (p, text, cls) => {
    if (!isPos(p)) return;
    const m = new maplibregl.Marker({ element: h(`div.map-label.${cls}`, text), anchor: 'bottom', offset: [0, -8] })
      .setLngLat([p.longitudeDeg, p.latitudeDeg]).addTo(map);
    labelMarkers.push(m);
  };
  (sp.zones || []).forEach((z, i) => add(centroid(z.polygon || []), z.name || `zone ${i + 1}`, 'zone-label'));
  (sp.fleet || []).forEach((g, i) => {
    const a = groupAnchor(g);
    add(a, `${g.name || `group ${i + 1}`} ×${g.count ?? '?'}`, 'group-label');
  });
  if (isPos(sp.origin)) {
    if (!originMarker) {
      originMarker = new maplibregl.Marker({ element: h('div.origin-marker', { title: 'origin' }, h('span', '✚')), anchor: 'center' });
      originMarker.setLngLat([sp.origin.longitudeDeg, sp.origin.latitudeDeg]).addTo(map);
    } else {
      originMarker.setLngLat([sp.origin.longitudeDeg, sp.origin.latitudeDeg]);
    }
  }
}

/** Frames the scenario: its zones, homes and waypoints, or the origin. */
function fitScenario() {
  const sp = spec();
  const b = new maplibregl.LngLatBounds();
  const addP = (p) => { if (isPos(p)) b.extend([p.longitudeDeg, p.latitudeDeg]); };
  (sp.zones || []).forEach((z) => (z.polygon || []).forEach(addP));
  (sp.fleet || []).forEach((g) => {
    const { points, discs } = groupHomes(g);
    points.forEach(addP);
    discs.forEach((d) => discRing(d.center, Number(d.radiusM) || 1).forEach(([lo, la]) => b.extend([lo, la])));
    ((g.mission && g.mission.items) || []).forEach((it) => { if (it.waypoint) addP(it.waypoint); });
  });
  addP(sp.origin);
  if (b.isEmpty()) return;
  map.fitBounds(b, { padding: 50, maxZoom: 16.5, duration: 0 });
}

// ---------------------------------------------------------------- world (buildings, parks)

let wseq = 0;
const scheduleWorld = debounce(async () => {
  if (!map || !mapReady) return;
  const sp = spec();
  const key = JSON.stringify([sp.origin, sp.world, (sp.fleet || []).map((g) => g.homes)]);
  if (key === S.worldKey) return;
  S.worldKey = key;
  const seq = ++wseq;
  el.spinner.hidden = false;
  try {
    const r = await post('/api/world', { document: S.doc });
    if (seq !== wseq) return;
    S.world = r.body;
    setSource('buildings', r.body.buildings || EMPTY);
    setSource('parks', r.body.parks || EMPTY);
    el.worldNote.hidden = true;
  } catch (e) {
    if (seq !== wseq) return;
    S.world = null;
    el.worldNote.hidden = false;
    el.worldNote.textContent = e.errors ? `no city: ${e.errors.map((x) => `${x.field}: ${x.message}`).join('; ')}` : `no city: ${e.message}`;
  } finally {
    if (seq === wseq) { el.spinner.hidden = true; hooks.worldLoads++; }
  }
}, 600);

// ---------------------------------------------------------------- map modes

const HINTS = {
  origin: 'Click the map where the origin goes.',
  zone: 'Click the zone\'s corners; double-click or Finish to close it. Esc cancels.',
  group: 'Click the new group\'s home.',
  home: 'Click a home for the group.',
  area: 'Click the centre of a home disc.',
  openArea: 'Click the centre of an open area.',
  waypoint: 'Click to add waypoints; Esc when done.',
};

function setMode(mode) {
  S.mode = mode;
  if (!mode || mode.kind !== 'zone') S.draft = [];
  if (map) {
    if (mode && mode.kind === 'zone') map.doubleClickZoom.disable();
    else map.doubleClickZoom.enable();
    map.getCanvas().style.cursor = mode ? 'crosshair' : '';
  }
  el.hint.hidden = !mode;
  el.hint.textContent = mode ? HINTS[mode.kind] + (mode.kind === 'zone' ? ` (${S.draft.length} vertices)` : '') : '';
  el.finishZone.hidden = !(mode && mode.kind === 'zone');
  el.cancelMode.hidden = !mode;
  el.mapWrap.classList.toggle('picking', !!mode);
  updateDraft();
}

function startZone(target) {
  setMode({ kind: 'zone', target });
}

function finishZone() {
  if (!S.mode || S.mode.kind !== 'zone') return;
  // The two clicks of a double-click add the same corner twice: keep one.
  const pts = [];
  for (const p of S.draft) {
    const prev = pts[pts.length - 1];
    if (prev && map) {
      const a = map.project([prev.longitudeDeg, prev.latitudeDeg]), b = map.project([p.longitudeDeg, p.latitudeDeg]);
      if (Math.hypot(a.x - b.x, a.y - b.y) < 5) continue;
    }
    pts.push(p);
  }
  if (pts.length < 3) {
    el.hint.textContent = `A zone needs at least 3 corners (${pts.length} so far).`;
    return;
  }
  const target = S.mode.target;
  const sp = spec();
  if (target >= 0 && sp.zones && sp.zones[target]) {
    sp.zones[target].polygon = pts;
    S.selectedZone = target;
  } else {
    const zones = sp.zones || (sp.zones = []);
    const names = new Set(zones.map((z) => z.name));
    let k = zones.length + 1;
    while (names.has(`zone-${k}`)) k++;
    zones.push({ name: `zone-${k}`, polygon: pts, ceiling: { heightM: 120, reference: 'agl' }, policy: {} });
    S.selectedZone = zones.length - 1;
  }
  setMode(null);
  selectTab('zones');
  changed('spec.zones', { structure: true });
  scrollToItem(`zone-${S.selectedZone}`);
}

function onMapClick(e) {
  const m = S.mode;
  const p = pos(e.lngLat);
  const sp = spec();
  if (!m) {
    const f = map.queryRenderedFeatures(e.point, { layers: ['homes', 'home-discs', 'waypoints', 'zones-fill'] });
    if (!f.length) return;
    const top = f[0];
    if (top.layer.id === 'zones-fill') selectZone(top.properties.index, true);
    else selectGroup(top.properties.index, true);
    return;
  }
  if (m.kind === 'origin') {
    sp.origin = Object.assign({ altitudeMslM: 0 }, sp.origin || {}, p);
    setMode(null);
    selectTab('general');
    changed('spec.origin', { structure: true });
  } else if (m.kind === 'zone') {
    S.draft.push(p);
    el.hint.textContent = `${HINTS.zone} (${S.draft.length} vertices)`;
    updateDraft();
  } else if (m.kind === 'group') {
    const fleet = sp.fleet || (sp.fleet = []);
    const names = new Set(fleet.map((g) => g.name));
    let k = fleet.length + 1;
    while (names.has(`group-${k}`)) k++;
    fleet.push({
      name: `group-${k}`, count: 1, airframe: 'x500', operator: 'me',
      homes: { randomInArea: { center: p, radiusM: 30 } },
      altitude: { maxAglM: 60 },
      mission: { items: [{ takeoff: { altitudeAglM: 30 } }, { loiter: { holdS: 10 } }, { returnToLaunch: {} }] },
    });
    S.selectedGroup = fleet.length - 1;
    setMode(null);
    selectTab('fleet');
    changed('spec.fleet', { structure: true });
    scrollToItem(`group-${S.selectedGroup}`);
  } else if (m.kind === 'home') {
    const g = sp.fleet[m.group];
    if (!g) return setMode(null);
    if (g.homes && g.homes.explicit) {
      g.homes.explicit.push(p);
      g.count = g.homes.explicit.length;
    } else {
      g.homes = { randomInArea: Object.assign({ radiusM: 30 }, (g.homes && g.homes.randomInArea) || {}, { center: p }) };
      setMode(null);
    }
    changed(`spec.fleet[${m.group}].homes`, { structure: true });
  } else if (m.kind === 'area') {
    const g = sp.fleet[m.group];
    if (!g) return setMode(null);
    (g.homes.areas || (g.homes.areas = [])).push({ center: p, radiusM: 50 });
    setMode(null);
    changed(`spec.fleet[${m.group}].homes`, { structure: true });
  } else if (m.kind === 'openArea') {
    const w = sp.world || (sp.world = {});
    (w.openAreas || (w.openAreas = [])).push({ center: p, radiusM: 100 });
    setMode(null);
    changed('spec.world.openAreas', { structure: true });
  } else if (m.kind === 'waypoint') {
    const g = sp.fleet[m.group];
    if (!g) return setMode(null);
    const mission = g.mission || (g.mission = { items: [{ takeoff: { altitudeAglM: 30 } }, { returnToLaunch: {} }] });
    const items = mission.items || (mission.items = []);
    const prev = [...items].reverse().find((it) => kindOf(it) === 'waypoint' || kindOf(it) === 'takeoff');
    const alt = prev ? (prev.waypoint ? prev.waypoint.altitudeAglM : prev.takeoff.altitudeAglM) : 30;
    const wp = { waypoint: Object.assign(p, { altitudeAglM: alt }) };
    let at = items.length;
    while (at > 0 && ['returnToLaunch', 'land', 'loiter'].includes(kindOf(items[at - 1]))) at--;
    items.splice(at, 0, wp);
    changed(`spec.fleet[${m.group}].mission.items`, { structure: true });
  }
}

function scrollToItem(id) {
  const t = document.getElementById(id);
  if (t) t.scrollIntoView({ block: 'nearest' });
}

function selectZone(i, scroll) {
  S.selectedZone = i;
  S.selectedGroup = -1;
  selectTab('zones');
  for (const c of el.bodies.querySelectorAll('.item')) c.classList.toggle('selected', c.id === `zone-${i}`);
  updateMap();
  if (scroll) scrollToItem(`zone-${i}`);
}

function selectGroup(i, scroll) {
  S.selectedGroup = i;
  S.selectedZone = -1;
  selectTab('fleet');
  for (const c of el.bodies.querySelectorAll('.item')) c.classList.toggle('selected', c.id === `group-${i}`);
  updateMap();
  if (scroll) scrollToItem(`group-${i}`);
}
