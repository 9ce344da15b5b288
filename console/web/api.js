// The console's access to its backend: JSON calls with the user's token, and the
// Server-Sent Events watches read through fetch() (EventSource cannot send a header).

const TOKEN_KEY = 'sadesim-console-token';
const listeners = { unauthorized: [] };

export function token() {
  try { return sessionStorage.getItem(TOKEN_KEY) || ''; } catch { return ''; }
}

/** The token also rides in the `sadesim_token` cookie (this site only), for what the browser
 * fetches by itself: links to the report, the replay, archive files, camera images. */
function setCookie(t) {
  const secure = location.protocol === 'https:' ? '; Secure' : '';
  document.cookie = t
    ? `sadesim_token=${encodeURIComponent(t)}; Path=/; SameSite=Strict${secure}`
    : `sadesim_token=; Path=/; Max-Age=0; SameSite=Strict${secure}`;
}

export function setToken(t) {
  try {
    if (t) sessionStorage.setItem(TOKEN_KEY, t);
    else sessionStorage.removeItem(TOKEN_KEY);
  } catch { /* storage refused: the token lasts for this page only */ }
  setCookie(t);
}

if (token()) setCookie(token());

const NAMESPACE_KEY = 'sadesim-console-namespace';

/** The namespace the page works in (cluster backend): runs are listed, archived and
 * launched there. Empty: the console's offered namespaces. */
export function namespace() {
  try { return sessionStorage.getItem(NAMESPACE_KEY) || ''; } catch { return ''; }
}

export function setNamespace(n) {
  try {
    if (n) sessionStorage.setItem(NAMESPACE_KEY, n);
    else sessionStorage.removeItem(NAMESPACE_KEY);
  } catch { /* storage refused: the namespace lasts for this page only */ }
}

/** `path` limited to the page's namespace, when one is chosen. */
export function scoped(path) {
  const n = namespace();
  return n ? `${path}${path.includes('?') ? '&' : '?'}namespace=${encodeURIComponent(n)}` : path;
}

export function onUnauthorized(fn) { listeners.unauthorized.push(fn); }

function headers(extra) {
  const hd = Object.assign({}, extra || {});
  const t = token();
  if (t) hd.Authorization = `Bearer ${t}`;
  return hd;
}

/** An API failure: `status`, the backend's `error` text, its validation `errors`. */
export class ApiError extends Error {
  constructor(status, body, text) {
    const msg = (body && body.error) || (body && body.errors && body.errors.map((e) => `${e.field}: ${e.message}`).join('; ')) || text || `HTTP ${status}`;
    super(msg);
    this.status = status;
    this.body = body;
    this.errors = (body && body.errors) || null;
  }
}

/** fetch() of an API path with the token; JSON bodies are sent as JSON, strings as text. */
export async function call(method, path, body, opts = {}) {
  const init = { method, headers: headers(opts.headers) };
  if (body !== undefined) {
    if (typeof body === 'string') {
      init.body = body;
      init.headers['Content-Type'] = 'text/plain; charset=utf-8';
    } else {
      init.body = JSON.stringify(body);
      init.headers['Content-Type'] = 'application/json';
    }
  }
  if (opts.signal) init.signal = opts.signal;
  const res = await fetch(path, init);
  if (res.status === 401) listeners.unauthorized.forEach((fn) => fn());
  const ctype = res.headers.get('content-type') || '';
  if (opts.raw) {
    if (!res.ok) {
      const text = await res.text();
      let parsed = null;
      try { parsed = JSON.parse(text); } catch { /* not JSON */ }
      throw new ApiError(res.status, parsed, text);
    }
    return res;
  }
  const text = await res.text();
  let parsed = null;
  if (ctype.includes('json') || /^\s*[[{]/.test(text)) {
    try { parsed = JSON.parse(text); } catch { parsed = null; }
  }
  if (!res.ok) throw new ApiError(res.status, parsed, text);
  return opts.text ? text : { status: res.status, body: parsed, text };
}

export const get = (path, opts) => call('GET', path, undefined, opts).then((r) => r.body);
export const post = (path, body, opts) => call('POST', path, body, opts);

/**
 * Follows a Server-Sent Events stream: `onEvent(name, data)` for every event whose data is
 * JSON, `onState('open'|'retrying'|'closed', detail)`. Reconnects after an error or the end
 * of the stream with a backoff (1 s, doubling, at most 15 s). Returns a stop function.
 */
export function watch(path, onEvent, onState = () => {}) {
  const ctl = new AbortController();
  let stopped = false;
  let delay = 1000;
  (async () => {
    while (!stopped) {
      try {
        const res = await fetch(path, { headers: headers({ Accept: 'text/event-stream' }), signal: ctl.signal, cache: 'no-store' });
        if (res.status === 401) listeners.unauthorized.forEach((fn) => fn());
        if (!res.ok) {
          let msg = `HTTP ${res.status}`;
          try { msg = JSON.parse(await res.text()).error || msg; } catch { /* keep */ }
          throw Object.assign(new Error(msg), { status: res.status });
        }
        onState('open');
        delay = 1000;
        const reader = res.body.getReader();
        const decoder = new TextDecoder();
        let buf = '';
        let ev = { name: 'message', data: [] };
        for (;;) {
          const { value, done } = await reader.read();
          if (done) break;
          buf += decoder.decode(value, { stream: true });
          let nl;
          while ((nl = buf.search(/\r\n|\n|\r/)) >= 0) {
            const line = buf.slice(0, nl);
            buf = buf.slice(nl + (buf[nl] === '\r' && buf[nl + 1] === '\n' ? 2 : 1));
            if (line === '') {
              if (ev.data.length) {
                const raw = ev.data.join('\n');
                let data = raw;
                try { data = JSON.parse(raw); } catch { /* plain text data */ }
                if (!stopped) onEvent(ev.name, data);
              }
              ev = { name: 'message', data: [] };
            } else if (line[0] !== ':') {
              const c = line.indexOf(':');
              const field = c < 0 ? line : line.slice(0, c);
              let val = c < 0 ? '' : line.slice(c + 1);
              if (val[0] === ' ') val = val.slice(1);
              if (field === 'event') ev.name = val;
              else if (field === 'data') ev.data.push(val);
            }
          }
        }
        if (stopped) break;
        onState('retrying', 'the stream ended');
      } catch (e) {
        if (stopped) break;
        onState('retrying', e.message || String(e));
      }
      await new Promise((r) => setTimeout(r, delay));
      delay = Math.min(delay * 2, 15000);
    }
    onState('closed');
  })();
  return () => { stopped = true; ctl.abort(); };
}

/** The URL of an archive file (links carry the token in the cookie). */
export function archiveFileUrl(id, path) {
  return `/api/archive/${encodeURIComponent(id)}/files/${path.split('/').map(encodeURIComponent).join('/')}`;
}
