// sadesim console: one page, hash routes. #/plan edits a scenario on a map, #/runs follows
// the runs, #/archive reads the archived ones. Nothing is fetched from the internet.

import { h, fill } from './util.js';
import { get, token, setToken, onUnauthorized, namespace, setNamespace } from './api.js';
import { mountPlan, showPlan, hidePlan, setInfo } from './plan.js';
import { runsPage, runPage } from './runs.js';
import { archivePage, archiveEntryPage } from './archive.js';

const state = { info: null, cleanup: null, planMounted: false };
const app = document.getElementById('app');
const planView = h('div.view.plan-view', { hidden: true });
const otherView = h('div.view.other-view', { hidden: true });
app.append(planView, otherView);

// ---------------------------------------------------------------- nav and token

const tokenInput = h('input#token', { type: 'password', placeholder: 'Kubernetes token', autocomplete: 'off', size: 18 });
const tokenBox = h('form.token-box', { hidden: true, onsubmit: (e) => { e.preventDefault(); setToken(tokenInput.value.trim()); tokenInput.value = ''; showTokenState(); route(); } },
  h('span.token-state'), tokenInput, h('button.small', { type: 'submit' }, 'Log in'),
  h('button.small.secondary#logout', { type: 'button', onclick: () => { setToken(''); showTokenState(); } }, 'Log out'));
const loginBanner = h('div.login-banner', { hidden: true, role: 'alert' }, 'Log in with your token: the cluster refused this request without it (401).');
const backendBadge = h('span.backend');
// The namespace the page works in (cluster): any may be typed, the offered ones are listed.
const namespaceList = h('datalist#namespaces');
const namespaceInput = h('input#namespace', {
  type: 'text', list: 'namespaces', placeholder: 'namespace', size: 14, spellcheck: 'false', title: 'the namespace runs are listed in and launched into',
  onchange: () => { setNamespace(namespaceInput.value.trim()); route(); },
});
const namespaceBox = h('label.namespace-box', { hidden: true }, 'namespace ', namespaceInput, namespaceList);

document.getElementById('nav').append(
  h('a.brand', { href: '#/plan' }, 'sadesim ', h('span', 'console')),
  h('a.nav-link', { href: '#/plan', dataset: { route: 'plan' } }, 'Plan'),
  h('a.nav-link', { href: '#/runs', dataset: { route: 'runs' } }, 'Runs'),
  h('a.nav-link', { href: '#/archive', dataset: { route: 'archive' } }, 'Archive'),
  h('span.spacer'),
  backendBadge,
  namespaceBox,
  tokenBox);
document.getElementById('banner').append(loginBanner);

function showTokenState() {
  const has = !!token();
  tokenBox.querySelector('.token-state').textContent = has ? 'token set' : '';
  tokenInput.hidden = has;
  tokenBox.querySelector('button[type=submit]').hidden = has;
  tokenBox.querySelector('#logout').hidden = !has;
  if (has) loginBanner.hidden = true;
}

onUnauthorized(() => {
  loginBanner.hidden = false;
  if (state.info && state.info.needsToken) { tokenBox.hidden = false; setToken(''); showTokenState(); tokenInput.focus(); }
});

async function loadInfo() {
  try {
    state.info = await get('/api/info');
  } catch (e) {
    state.info = { backend: 'unknown', needsToken: e.status === 401, namespaces: null };
  }
  const i = state.info;
  fill(backendBadge, `${i.backend}${i.version ? ` · ${i.version}` : ''}`);
  backendBadge.title = i.archive ? `archive: ${i.archive}` : '';
  tokenBox.hidden = !i.needsToken;
  const offered = i.namespaces || [];
  namespaceBox.hidden = i.backend !== 'cluster';
  fill(namespaceList, offered.map((n) => h('option', { value: n })));
  if (i.backend === 'cluster' && !namespace() && offered.length) setNamespace(offered[0]);
  namespaceInput.value = namespace();
  showTokenState();
  setInfo(i);
}

// ---------------------------------------------------------------- routes

function route() {
  const hash = location.hash || '#/plan';
  const m = /^#\/(plan|runs|archive)(?:\/(.+))?$/.exec(hash);
  if (!m) { location.replace('#/plan'); return; }
  const [, page, rest] = m;
  const id = rest ? decodeURIComponent(rest) : null;
  for (const a of document.querySelectorAll('.nav-link')) a.classList.toggle('active', a.dataset.route === page);
  if (state.cleanup) { state.cleanup(); state.cleanup = null; }
  document.body.dataset.route = page + (id ? '/item' : '');
  if (page === 'plan') {
    otherView.hidden = true;
    planView.hidden = false;
    if (!state.planMounted) { mountPlan(planView, state.info); state.planMounted = true; }
    showPlan();
    document.title = 'Plan · sadesim console';
    return;
  }
  if (state.planMounted) hidePlan();
  planView.hidden = true;
  otherView.hidden = false;
  otherView.scrollTop = 0;
  if (page === 'runs') {
    state.cleanup = id ? runPage(otherView, id) : runsPage(otherView);
    document.title = `${id ? 'Run' : 'Runs'} · sadesim console`;
  } else {
    state.cleanup = id ? archiveEntryPage(otherView, id) : archivePage(otherView);
    document.title = `Archive · sadesim console`;
  }
}

window.addEventListener('hashchange', route);
await loadInfo();
route();
window.sadesimConsole = Object.assign(window.sadesimConsole || {}, { ready: true, info: () => state.info });
