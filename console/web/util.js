// Small helpers shared by the console's pages: DOM building, formatting, paths.

/** h('div.card#main', {onclick, dataset, ...}, children...) -> an element. */
export function h(tag, attrs, ...children) {
  const m = /^([a-z0-9]+)((?:[.#][-\w]+)*)$/i.exec(tag);
  const el = document.createElement(m ? m[1] : tag);
  if (m && m[2]) {
    for (const part of m[2].match(/[.#][-\w]+/g)) {
      if (part[0] === '.') el.classList.add(part.slice(1));
      else el.id = part.slice(1);
    }
  }
  if (attrs && (typeof attrs !== 'object' || attrs instanceof Node || Array.isArray(attrs))) {
    children.unshift(attrs);
    attrs = null;
  }
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k.startsWith('on') && typeof v === 'function') el.addEventListener(k.slice(2), v);
    else if (k === 'dataset') Object.assign(el.dataset, v);
    else if (k === 'style' && typeof v === 'object') Object.assign(el.style, v);
    else if (k === 'value') el.value = v;
    else if (k === 'checked') el.checked = !!v;
    else if (k === 'class') el.className = v;
    else el.setAttribute(k, v === true ? '' : v);
  }
  append(el, children);
  return el;
}

function append(el, children) {
  for (const c of children) {
    if (c === null || c === undefined || c === false) continue;
    if (Array.isArray(c)) append(el, c);
    else el.append(c instanceof Node ? c : String(c));
  }
}

/** Replaces the children of `el`. */
export function fill(el, ...children) {
  el.replaceChildren();
  append(el, children);
  return el;
}

/** "spec.fleet[0].count" -> ["spec", "fleet", 0, "count"]. */
export function parsePath(path) {
  const out = [];
  for (const part of path.split('.')) {
    const m = /^([^[]*)((?:\[\d+\])*)$/.exec(part);
    if (!m) { out.push(part); continue; }
    if (m[1]) out.push(m[1]);
    for (const idx of m[2].match(/\d+/g) || []) out.push(Number(idx));
  }
  return out;
}

/** ["spec", "fleet", 0] -> "spec.fleet[0]". */
export function joinPath(parts) {
  let s = '';
  for (const p of parts) s += typeof p === 'number' ? `[${p}]` : (s ? '.' : '') + p;
  return s;
}

export function getPath(obj, path) {
  let o = obj;
  for (const k of parsePath(path)) {
    if (o === null || o === undefined) return undefined;
    o = o[k];
  }
  return o;
}

/** Sets `path` in `obj`, creating objects on the way; `undefined` deletes the key. */
export function setPath(obj, path, value) {
  const keys = parsePath(path);
  let o = obj;
  for (let i = 0; i < keys.length - 1; i++) {
    if (o[keys[i]] === undefined || o[keys[i]] === null || typeof o[keys[i]] !== 'object') {
      if (value === undefined) return;
      o[keys[i]] = typeof keys[i + 1] === 'number' ? [] : {};
    }
    o = o[keys[i]];
  }
  const last = keys[keys.length - 1];
  if (value === undefined) {
    if (Array.isArray(o)) o.splice(last, 1);
    else delete o[last];
  } else {
    o[last] = value;
  }
}

export function clone(v) {
  return v === undefined ? undefined : JSON.parse(JSON.stringify(v));
}

export function debounce(fn, ms) {
  let t = null;
  const d = (...args) => {
    clearTimeout(t);
    t = setTimeout(() => { t = null; fn(...args); }, ms);
  };
  d.flush = (...args) => { clearTimeout(t); t = null; fn(...args); };
  d.pending = () => t !== null;
  return d;
}

export function fmtDuration(s) {
  if (s === null || s === undefined || !isFinite(s)) return '–';
  s = Math.round(s);
  const hh = Math.floor(s / 3600), mm = Math.floor((s % 3600) / 60), ss = s % 60;
  if (hh) return `${hh}h${String(mm).padStart(2, '0')}m`;
  if (mm) return `${mm}m${String(ss).padStart(2, '0')}s`;
  return `${ss}s`;
}

export function fmtAge(iso) {
  if (!iso) return '–';
  const t = Date.parse(iso);
  if (!isFinite(t)) return iso;
  const s = Math.max(0, (Date.now() - t) / 1000);
  if (s < 60) return `${Math.floor(s)}s`;
  if (s < 3600) return `${Math.floor(s / 60)}m`;
  if (s < 86400) return `${Math.floor(s / 3600)}h${String(Math.floor((s % 3600) / 60)).padStart(2, '0')}m`;
  return `${Math.floor(s / 86400)}d`;
}

export function fmtDate(iso) {
  if (!iso) return '–';
  const d = new Date(iso);
  if (isNaN(d)) return iso;
  return d.toISOString().replace('T', ' ').replace(/\.\d+Z$/, 'Z').replace(/:\d\dZ$/, 'Z');
}

export function fmtBytes(n) {
  if (n === null || n === undefined) return '';
  if (n < 1024) return `${n} B`;
  const u = ['kB', 'MB', 'GB', 'TB'];
  let i = -1;
  do { n /= 1024; i++; } while (n >= 1024 && i < u.length - 1);
  return `${n.toFixed(n < 10 ? 1 : 0)} ${u[i]}`;
}

/** A verdict as a coloured badge. */
export function verdictBadge(v) {
  if (!v) return h('span.badge.muted', '–');
  return h(`span.badge.${v === 'passed' ? 'ok' : v === 'failed' ? 'bad' : 'muted'}`, v);
}

export function phaseBadge(p) {
  const cls = p === 'Succeeded' ? 'ok' : p === 'Failed' ? 'bad' : /Running|Starting|Generating|Archiving/.test(p || '') ? 'live' : 'muted';
  return h(`span.badge.${cls}`, p || '–');
}

export const FINISHED = new Set(['Succeeded', 'Failed', 'Aborted', 'Stopped', 'Cancelled', 'Canceled', 'Error', 'Deleted']);

export function isFinished(run) {
  return !!run && (FINISHED.has(run.phase) || (!!run.archiveId && !/Archiving/.test(run.phase || '')));
}

export function progressBar(p) {
  const v = p === null || p === undefined ? null : Math.max(0, Math.min(1, p));
  return h('div.progress', { title: v === null ? 'unknown' : `${Math.round(v * 100)} %`, dataset: { value: v === null ? '' : String(v) } },
    h('div.progress-fill', { style: { width: v === null ? '0%' : `${(v * 100).toFixed(1)}%` } }),
    h('span.progress-text', v === null ? '–' : `${Math.round(v * 100)} %`));
}

/** Group colours, the same order as the live view's. */
export const GROUP_COLOURS = ['#1f77b4', '#ff7f0e', '#2ca02c', '#9467bd', '#8c564b', '#17becf', '#bcbd22', '#7f7f7f', '#e377c2', '#d62728'];
