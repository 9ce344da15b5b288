// Form controls bound to paths of the scenario document. Every control carries
// `data-field="<path>"`, the path the validator uses, so its errors land next to it.

import { h, getPath, setPath } from './util.js';

let ctx = null;
let uid = 0;

/** `bind(editor)`: `editor.doc()` gives the document, `editor.changed(path)` is called after
 * every edit. */
export function bind(editor) { ctx = editor; }

function row(label, control, help) {
  const id = control.id || (control.id = `f${++uid}`);
  return h('div.row', h('label', { for: id }, label), control, help ? h('div.help', help) : null);
}

function commit(path, value) {
  setPath(ctx.doc(), path, value);
  ctx.changed(path);
}

/** A number input; empty removes the key (optional fields), text that is no number is kept
 * as text so that the validator names the problem. */
export function num(path, label, opts = {}) {
  const v = getPath(ctx.doc(), path);
  const el = h('input', {
    type: 'text', inputmode: 'decimal', 'data-field': path, placeholder: opts.placeholder || '',
    value: v === undefined || v === null ? '' : String(v), autocomplete: 'off', spellcheck: 'false',
  });
  el.addEventListener('input', () => {
    const s = el.value.trim();
    if (s === '') commit(path, undefined);
    else if (/^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/.test(s)) commit(path, Number(s));
    else commit(path, s);
  });
  return row(label, el, opts.help);
}

/** A text input; empty removes the key unless `keepEmpty`. */
export function text(path, label, opts = {}) {
  const v = getPath(ctx.doc(), path);
  const el = h('input', { type: 'text', 'data-field': path, placeholder: opts.placeholder || '', value: v === undefined || v === null ? '' : String(v), autocomplete: 'off', spellcheck: 'false' });
  el.addEventListener('input', () => commit(path, el.value === '' && !opts.keepEmpty ? undefined : el.value));
  if (opts.onChange) el.addEventListener('change', opts.onChange);
  return row(label, el, opts.help);
}

/** A select; the option '' removes the key. `options`: [value, label] pairs or values. */
export function select(path, label, options, opts = {}) {
  const v = getPath(ctx.doc(), path);
  const el = h('select', { 'data-field': path });
  const values = [];
  for (const o of options) {
    const [val, lab] = Array.isArray(o) ? o : [o, o];
    values.push(val);
    el.append(h('option', { value: val }, lab));
  }
  const cur = v === undefined || v === null ? '' : String(v);
  if (!values.includes(cur)) el.append(h('option', { value: cur }, cur));
  el.value = cur;
  el.addEventListener('change', () => {
    commit(path, el.value === '' ? undefined : el.value);
    if (opts.onChange) opts.onChange(el.value);
  });
  return row(label, el, opts.help);
}

/** A checkbox for an optional boolean: unchecked writes `false` when `explicitFalse`, else
 * removes the key. */
export function check(path, label, opts = {}) {
  const v = getPath(ctx.doc(), path);
  const el = h('input', { type: 'checkbox', 'data-field': path, checked: v === undefined ? !!opts.defaultOn : !!v });
  el.addEventListener('change', () => {
    commit(path, el.checked ? true : (opts.explicitFalse ? false : undefined));
    if (opts.onChange) opts.onChange(el.checked);
  });
  return h('div.row.check', el, h('label', { for: el.id || (el.id = `f${++uid}`) }, label), opts.help ? h('div.help', opts.help) : null);
}

/** A list of strings, comma separated (operators, group names). */
export function list(path, label, opts = {}) {
  const v = getPath(ctx.doc(), path);
  const el = h('input', { type: 'text', 'data-field': path, placeholder: opts.placeholder || 'a, b, c', value: Array.isArray(v) ? v.join(', ') : '', autocomplete: 'off', spellcheck: 'false' });
  el.addEventListener('input', () => {
    const items = el.value.split(',').map((s) => s.trim()).filter((s) => s !== '');
    commit(path, items.length || opts.keepEmpty ? items : undefined);
  });
  return row(label, el, opts.help);
}

/** A list of strings, one a line (a command and its arguments). */
export function lines(path, label, opts = {}) {
  const v = getPath(ctx.doc(), path);
  const n = Array.isArray(v) ? v.length : 0;
  const el = h('textarea', { 'data-field': path, rows: Math.min(10, Math.max(opts.rows || 3, n)), placeholder: opts.placeholder || '', spellcheck: 'false' });
  el.value = Array.isArray(v) ? v.join('\n') : '';
  el.addEventListener('input', () => {
    const items = el.value.split('\n').filter((s, i, a) => s !== '' || i < a.length - 1);
    commit(path, items.length || opts.keepEmpty ? items : undefined);
  });
  return row(label, el, opts.help);
}

/** A group of controls about one object (`floor`, `altitude`): the object's own errors
 * (a rule across its fields) go after the group. */
export function group(path, title, ...children) {
  return h('fieldset.group', { 'data-field': path }, title ? h('legend', title) : null, ...children);
}
