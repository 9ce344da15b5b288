// The runs pages: #/runs (every run, live from the watch stream) and #/runs/<id> (one run:
// conditions, events, criteria, the live view, cameras, stop, and its evidence once archived).

import { h, fill, fmtAge, fmtDuration, phaseBadge, verdictBadge, progressBar, isFinished } from './util.js';
import { get, post, watch, archiveFileUrl, scoped } from './api.js';

function runHref(id) { return `#/runs/${encodeURIComponent(id)}`; }

function connBadge() {
  return h('span.conn.muted', 'connecting…');
}

function setConn(badge, state, detail) {
  badge.className = `conn ${state === 'open' ? 'ok' : 'muted'}`;
  badge.textContent = state === 'open' ? 'live' : state === 'retrying' ? `reconnecting (${detail || 'error'})` : state;
}

export function runsPage(container) {
  const conn = connBadge();
  const body = h('tbody');
  const empty = h('p.muted', { hidden: true }, 'No runs yet. Launch one from the ', h('a', { href: '#/plan' }, 'plan'), '.');
  const table = h('table.runs-table.data',
    h('thead', h('tr', ['Name', 'Namespace', 'Phase', 'Progress', 'Real-time ×', 'Queue', 'Verdict', 'Age', 'Drones'].map((c) => h('th', c)))),
    body);
  fill(container, h('div.page',
    h('div.page-head', h('h1', 'Runs'), h('span.spacer'), conn),
    table, empty));
  let runs = [];
  const render = () => {
    empty.hidden = runs.length > 0;
    table.hidden = runs.length === 0;
    fill(body, runs.map((r) => h('tr', { dataset: { id: r.id, name: r.name, phase: r.phase || '' }, onclick: (e) => { if (e.target.tagName !== 'A') location.hash = runHref(r.id); } },
      h('td', h('a', { href: runHref(r.id) }, r.name)),
      h('td', r.namespace || '–'),
      h('td.phase', phaseBadge(r.phase), r.message ? h('div.small.muted', r.message) : null),
      h('td', progressBar(r.progress)),
      h('td.num', r.realTimeFactor === null || r.realTimeFactor === undefined ? '–' : `${r.realTimeFactor.toFixed(1)}`),
      h('td.num', r.queuePosition === null || r.queuePosition === undefined ? '–' : String(r.queuePosition)),
      h('td.verdict', verdictBadge(r.verdict)),
      h('td', { title: r.startedAt || '' }, fmtAge(r.startedAt)),
      h('td.num', r.drones ?? '–'))));
  };
  render();
  const stop = watch(scoped('/api/runs/watch'), (name, data) => {
    if (name === 'runs' && data && Array.isArray(data.runs)) { runs = data.runs; render(); }
  }, (s, d) => setConn(conn, s, d));
  const ageTimer = setInterval(render, 10000);
  return () => { stop(); clearInterval(ageTimer); };
}

export function runPage(container, id) {
  const conn = connBadge();
  const head = h('div.run-head');
  const links = h('div.run-links');
  const condBody = h('tbody');
  const critList = h('ul.criteria');
  const events = h('div.events', { role: 'log' });
  const viewBox = h('div.view-box', { hidden: true });
  const camBox = h('div.cameras', { hidden: true });
  const errBox = h('div.flash.error', { hidden: true });
  const stopBtn = h('button#stop-run.danger', { type: 'button' }, 'Stop');
  fill(container, h('div.page',
    h('div.page-head', h('a.back', { href: '#/runs' }, '← runs'), h('span.spacer'), conn),
    head, errBox, links,
    h('div.run-grid',
      h('section.card', h('h2', 'Criteria'), critList),
      h('section.card', h('h2', 'Conditions'), h('table.data.conditions', h('thead', h('tr', ['Type', 'Status', 'Reason', 'Message'].map((c) => h('th', c)))), condBody))),
    viewBox, camBox,
    h('section.card', h('h2', 'Events ', h('span.muted.small', 'newest last')), events)));

  let detail = null;
  let viewUrl = null;
  let camKey = '';
  let eventCount = 0;
  let eventSig = '';
  stopBtn.addEventListener('click', async () => {
    stopBtn.disabled = true;
    try { await post(`/api/runs/${encodeURIComponent(id)}/stop`, {}); } catch (e) { errBox.hidden = false; errBox.textContent = `stop failed: ${e.message}`; stopBtn.disabled = false; }
  });

  const render = () => {
    const r = detail.run;
    const finished = isFinished(r);
    fill(head,
      h('h1', r.name, r.namespace ? h('span.muted.ns', ` ${r.namespace}`) : null),
      h('div.run-facts',
        h('span.fact', phaseBadge(r.phase)),
        h('span.fact', progressBar(r.progress)),
        h('span.fact', `sim ${fmtDuration(r.simTimeS)} / ${fmtDuration(r.durationS)}`),
        r.realTimeFactor !== null && r.realTimeFactor !== undefined ? h('span.fact', `× ${r.realTimeFactor.toFixed(1)} real time`) : null,
        r.queuePosition !== null && r.queuePosition !== undefined ? h('span.fact', `queue position ${r.queuePosition}`) : null,
        h('span.fact', `${r.drones} drones`),
        h('span.fact.verdict', 'verdict ', verdictBadge(r.verdict)),
        finished ? null : stopBtn),
      r.message ? h('p.run-message', r.message) : null);
    if (r.archiveId) {
      const a = r.archiveId;
      fill(links,
        h('a.button#open-report', { href: archiveFileUrl(a, 'report.html'), target: '_blank', rel: 'noopener' }, 'Report'),
        h('a.button#open-replay', { href: `/replay/${encodeURIComponent(a)}/`, target: '_blank', rel: 'noopener' }, '3D replay'),
        h('a.button#open-archive', { href: `#/archive/${encodeURIComponent(a)}` }, 'Archive entry'));
    } else {
      fill(links);
    }
    fill(condBody, (detail.conditions || []).map((c) => h('tr',
      h('td', c.type), h('td', h(`span.badge.${c.status === 'True' ? 'ok' : c.status === 'False' ? 'muted' : 'muted'}`, c.status)), h('td', c.reason || ''), h('td', c.message || ''))));
    fill(critList, (detail.criteria || []).length ? detail.criteria.map((c) => h(`li.criterion.${c.state}`, { dataset: { state: c.state } },
      h(`span.badge.${c.state === 'passed' ? 'ok' : c.state === 'failed' ? 'bad' : 'muted'}`, c.state),
      ' ', h('strong', c.name), c.detail ? h('div.small.muted', c.detail) : null)) : h('li.muted', 'no criteria'));
    const evs = detail.events || [];
    // The backend sends the newest events (a sliding window): redraw when the newest changed.
    const last = evs[evs.length - 1];
    const sig = `${evs.length}|${last ? `${last.timeS}|${last.kind}|${last.drone}|${last.text}` : ''}`;
    if (sig !== eventSig) {
      eventSig = sig;
      const atBottom = events.scrollHeight - events.scrollTop - events.clientHeight < 30;
      fill(events, h('table.data.events-table', h('tbody', evs.map((e) => h(`tr.ev-${e.kind}`,
        h('td.num', typeof e.timeS === 'number' ? e.timeS.toFixed(2) : ''), h('td', e.kind), h('td', e.drone ?? ''), h('td', e.text || ''))))));
      if (atBottom || eventCount === 0) events.scrollTop = events.scrollHeight;
      eventCount = evs.length;
    }
    if (detail.viewUrl !== viewUrl) {
      viewUrl = detail.viewUrl;
      viewBox.hidden = !viewUrl;
      fill(viewBox, viewUrl ? [h('div.card-head', h('h2', 'Live 3D view'), h('a', { href: viewUrl, target: '_blank', rel: 'noopener' }, 'open in a tab')), h('iframe.live-view', { src: viewUrl, title: 'live 3D view' })] : []);
    }
    const cams = detail.cameras || [];
    const key = cams.map((c) => c.url).join('|');
    if (key !== camKey) {
      camKey = key;
      camBox.hidden = !cams.length;
      fill(camBox, cams.length ? [h('h2', 'Onboard cameras'), h('div.camera-grid', cams.map((c) => h('figure', h('img', { src: c.url, alt: `${c.drone} ${c.camera}` }), h('figcaption', `${c.drone} · ${c.camera}`))))] : []);
    }
  };

  const stop = watch(`/api/runs/${encodeURIComponent(id)}/watch`, (name, data) => {
    if (name === 'run' && data && data.run) { detail = data; errBox.hidden = true; render(); }
  }, (s, d) => {
    setConn(conn, s, d);
    if (s === 'retrying' && !detail) { errBox.hidden = false; errBox.textContent = `cannot follow this run: ${d}`; }
  });
  return stop;
}

/** For scripts: the run's detail once (no stream). */
export function fetchRun(id) { return get(`/api/runs/${encodeURIComponent(id)}`); }
