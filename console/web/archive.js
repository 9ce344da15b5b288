// The archive pages: #/archive (every archived run) and #/archive/<id> (one: summary,
// files, report, replay, events, and a check of the files against the manifest).

import { h, fill, fmtDate, fmtDuration, fmtBytes, verdictBadge } from './util.js';
import { get, post, call, archiveFileUrl, scoped } from './api.js';

function entryHref(id) { return `#/archive/${encodeURIComponent(id)}`; }

export function archivePage(container) {
  const body = h('tbody');
  const status = h('p.muted', 'loading…');
  const table = h('table.data.archive-table', { hidden: true },
    h('thead', h('tr', ['Scenario', 'Namespace', 'Date', 'Verdict', 'Drones', 'Duration', 'Complete'].map((c) => h('th', c)))), body);
  fill(container, h('div.page', h('div.page-head', h('h1', 'Archive'), h('span.spacer'), h('button.secondary.small', { type: 'button', onclick: () => load() }, 'Refresh')), status, table));
  let alive = true;
  const load = async () => {
    try {
      const r = await get(scoped('/api/archive'));
      if (!alive) return;
      const runs = (r && r.runs) || [];
      runs.sort((a, b) => String(b.date).localeCompare(String(a.date)));
      status.hidden = runs.length > 0;
      status.textContent = 'The archive is empty.';
      table.hidden = runs.length === 0;
      fill(body, runs.map((a) => h('tr', { dataset: { id: a.id, scenario: a.scenario }, onclick: (e) => { if (e.target.tagName !== 'A') location.hash = entryHref(a.id); } },
        h('td', h('a', { href: entryHref(a.id) }, a.scenario)),
        h('td', a.namespace || '–'),
        h('td', fmtDate(a.date)),
        h('td.verdict', verdictBadge(a.verdict)),
        h('td.num', a.drones ?? '–'),
        h('td.num', fmtDuration(a.durationS)),
        h('td', a.complete ? h('span.badge.ok', 'yes') : h('span.badge.bad', 'no')))));
    } catch (e) {
      if (!alive) return;
      status.hidden = false;
      status.textContent = `cannot read the archive: ${e.message}`;
    }
  };
  load();
  return () => { alive = false; };
}

const HIGHLIGHT = /(\.mcap|\.ulg)$/i;

export function archiveEntryPage(container, id) {
  const root = h('div.page', h('div.page-head', h('a.back', { href: '#/archive' }, '← archive')), h('p.muted', 'loading…'));
  fill(container, root);
  let alive = true;
  (async () => {
    let e;
    try {
      e = await get(`/api/archive/${encodeURIComponent(id)}`);
    } catch (err) {
      if (alive) fill(root, h('div.page-head', h('a.back', { href: '#/archive' }, '← archive')), h('div.flash.error', `cannot read this archive entry: ${err.message}`));
      return;
    }
    if (!alive) return;
    const verifyOut = h('div.verify-result', { 'aria-live': 'polite' });
    const verifyBtn = h('button#verify', { type: 'button' }, 'Verify');
    verifyBtn.addEventListener('click', async () => {
      verifyBtn.disabled = true;
      fill(verifyOut, h('span.muted', 'checking…'));
      try {
        const r = (await post(`/api/archive/${encodeURIComponent(id)}/verify`, {})).body;
        verifyOut.dataset.ok = String(!!r.ok);
        fill(verifyOut, r.ok
          ? h('span.badge.ok', `ok: ${r.checked} files match the manifest`)
          : [h('span.badge.bad', `${(r.problems || []).length} problem(s), ${r.checked} files checked`), h('ul.problems', (r.problems || []).map((p) => h('li', p)))]);
      } catch (err) {
        verifyOut.dataset.ok = 'false';
        fill(verifyOut, h('span.badge.bad', `verify failed: ${err.message}`));
      } finally {
        verifyBtn.disabled = false;
      }
    });
    const files = (e.files || []).slice().sort((a, b) => a.path.localeCompare(b.path));
    const hasReport = files.some((f) => f.path === 'report.html');
    const events = h('div.events.archive-events', h('p.muted', 'loading events…'));
    fill(root,
      h('div.page-head', h('a.back', { href: '#/archive' }, '← archive')),
      h('div.run-head',
        h('h1', e.scenario, e.namespace ? h('span.muted.ns', ` ${e.namespace}`) : null),
        h('div.run-facts',
          h('span.fact', fmtDate(e.date)),
          h('span.fact.verdict', 'verdict ', verdictBadge(e.verdict)),
          h('span.fact', `${e.drones ?? '?'} drones`),
          h('span.fact', fmtDuration(e.durationS)),
          h('span.fact', e.complete ? h('span.badge.ok', 'complete') : h('span.badge.bad', 'incomplete')))),
      h('div.run-links',
        hasReport ? h('a.button#open-report', { href: archiveFileUrl(id, 'report.html'), target: '_blank', rel: 'noopener' }, 'Open report') : null,
        h('a.button#open-replay', { href: `/replay/${encodeURIComponent(id)}/`, target: '_blank', rel: 'noopener' }, '3D replay'),
        verifyBtn, verifyOut),
      e.summary ? summaryCard(e.summary) : null,
      h('section.card', h('h2', `Files (${files.length})`),
        h('table.data.files', h('tbody', files.map((f) => h(`tr${HIGHLIGHT.test(f.path) ? '.highlight' : ''}`,
          h('td', h('a', { href: archiveFileUrl(id, f.path), download: f.path.split('/').pop() }, f.path),
            HIGHLIGHT.test(f.path) ? h('span.badge.live.small', f.path.endsWith('.mcap') ? 'MCAP' : 'ULog') : null),
          h('td.num', fmtBytes(f.size))))))),
      h('section.card', h('h2', 'Events (first 200)'), events));
    if (files.some((f) => f.path === 'events.jsonl')) {
      try {
        const text = await call('GET', archiveFileUrl(id, 'events.jsonl'), undefined, { text: true });
        if (!alive) return;
        const lines = text.split('\n').filter((l) => l.trim()).slice(0, 200);
        fill(events, h('table.data.events-table', h('thead', h('tr', ['t (s)', 'event', 'drone', 'details'].map((c) => h('th', c)))),
          h('tbody', lines.map((l) => {
            let ev;
            try { ev = JSON.parse(l); } catch { return h('tr', h('td', { colspan: 4 }, l)); }
            const { timeS, event, drone, ...rest } = ev;
            return h('tr', h('td.num', typeof timeS === 'number' ? timeS.toFixed(2) : ''), h('td', event), h('td', drone ?? ''),
              h('td.small', Object.entries(rest).map(([k, v]) => `${k}=${typeof v === 'object' ? JSON.stringify(v) : v}`).join(' ')));
          }))));
      } catch (err) {
        fill(events, h('p.muted', `cannot read events.jsonl: ${err.message}`));
      }
    } else {
      fill(events, h('p.muted', 'no events.jsonl in this entry'));
    }
  })();
  return () => { alive = false; };
}

function summaryCard(s) {
  const facts = [
    ['End', s.endReason], ['Simulated', fmtDuration(s.simTimeS)], ['Wall', fmtDuration(s.wallTimeS)],
    ['Real-time ×', typeof s.realTimeFactor === 'number' ? s.realTimeFactor.toFixed(1) : null],
    ['Drones', s.drones], ['Shards', s.shards], ['Airborne at end', s.airborne], ['Crashed', s.crashed], ['Events', s.events],
  ].filter(([, v]) => v !== undefined && v !== null);
  const crit = (s.verdict && s.verdict.criteria) || [];
  return h('section.card.summary', h('h2', 'Summary'),
    h('dl.facts', facts.map(([k, v]) => [h('dt', k), h('dd', String(v))])),
    crit.length ? h('ul.criteria', crit.map((c) => h(`li.criterion.${c.passed ? 'passed' : 'failed'}`,
      h(`span.badge.${c.passed ? 'ok' : 'bad'}`, c.passed ? 'passed' : 'failed'), ' ', h('strong', c.criterion), ' ', h('span.small', c.summary || ''),
      (c.failures || []).length ? h('ul.small', c.failures.slice(0, 20).map((f) => h('li', f))) : null))) : null);
}
