// Rheo studio: wires the sketch pad, the make-it panel, the 3D view, the live parameters, the
// library, the recordings, the playback bar (rheod --replay) and the status line to one Rpc
// connection. `/?view` is a watch-only page: only the 3D view and the status line (and, while
// rheod plays a recording back, the playback bar without its controls) are put into the document.

import { Rpc, rpcUrl, Code } from './rpc.js';
import { View3D } from './view3d.js';

const asked = { view: new URLSearchParams(location.search).has('view') };
let viewOnly = asked.view;
const $ = (sel) => document.querySelector(sel);

// The access token: from the URL fragment (#token=..., never the query, so it reaches no server
// log), else the one this browser used here before. The fragment is then removed from the
// address bar.
const TOKEN_KEY = 'rheo.token';
function takeToken() {
  const m = location.hash.match(/(?:^#|&)token=([^&]+)/);
  if (m) {
    const t = decodeURIComponent(m[1]);
    localStorage.setItem(TOKEN_KEY, t);
    history.replaceState(null, '', location.pathname + location.search);
    return t;
  }
  return localStorage.getItem(TOKEN_KEY) || '';
}
const rpc = new Rpc(rpcUrl(), takeToken());
let studio = null; // the editing panels, in studio mode (below)
let recordings = null; // the recordings panel (or the status line's indicator alone), once signed in
let playback = null; // the playback bar (rheod --replay), once signed in; in the page only while one plays
const view = new View3D($('#view'), $('#view-overlay'));

// ---------------------------------------------------------------------------------------------
// Frames and statistics

const stats = { frames: 0, dropped: 0, times: [], lastFrame: null, latencies: [] };

// Milliseconds from the loop publishing a frame (its stamp) to this page receiving it, over the
// last 600 frames (the daemon's and this machine's clocks are one when both run here).
function latency() {
  const v = [...stats.latencies].sort((a, b) => a - b);
  const at = (q) => (v.length ? v[Math.min(v.length - 1, Math.round(q * (v.length - 1)))] : 0);
  return { p50: at(0.5), p99: at(0.99), count: v.length };
}

function onFrame(frame) {
  stats.frames += 1;
  const published = Date.parse(frame.stamp?.published || '');
  if (Number.isFinite(published) && published > 0) {
    stats.latencies.push(Date.now() - published);
    if (stats.latencies.length > 600) stats.latencies.shift();
  }
  stats.dropped += Number(frame.droppedFrames || 0);
  const now = performance.now();
  stats.times.push(now);
  while (stats.times.length && stats.times[0] < now - 1000) stats.times.shift();
  stats.lastFrame = frame;
  view.applyFrame(frame);
  // Objects the daemon stopped after repeated restores are named in the status line.
  const stopped = (frame.objects || []).filter((o) => o.unstable).map((o) => `#${o.instanceId}`);
  const note = stopped.length ? `stopped (unstable): ${stopped.join(' ')}` : frame.paused ? 'paused' : '';
  const el = $('#st-note');
  if (el.textContent !== note) el.textContent = note;
  if (studio) studio.onFrame(frame);
}

function fps() {
  const now = performance.now();
  return stats.times.filter((t) => t >= now - 1000).length;
}

/** What tests and curious people can read: `window.rheo.stats()`. */
window.rheo = {
  rpc,
  view,
  viewOnly,
  stats: () => ({
    connected: rpc.connected,
    frames: stats.frames,
    fps: fps(),
    objects: view.objectCount(),
    dropped: stats.dropped,
    latencyMs: latency(),
  }),
  lastFrame: () => stats.lastFrame,
};

let frameRequest = { rateHz: 30, positions: true, quantized: true };
let frames = null;
function watchFrames() {
  if (frames) frames.close();
  frames = rpc.subscribe('rheo.v1.FrameService/WatchFrames', frameRequest, onFrame, (err) => {
    // A gateway without quantized positions refuses the field: fall back to plain floats.
    if (err && err.code === Code.INVALID_ARGUMENT && frameRequest.quantized) {
      frameRequest = { rateHz: 30, positions: true };
      watchFrames();
      return;
    }
    // The stream ended on its own (e.g. the daemon restarted the scene): watch again.
    setTimeout(() => rpc.connected && watchFrames(), 500);
  });
}

// ---------------------------------------------------------------------------------------------
// Status line and connection banner

function setConn(state) {
  const pill = $('#st-conn');
  pill.className = `pill ${state}`;
  pill.textContent = state === 'open' ? 'connected' : state === 'reconnecting' ? 'reconnecting…' : 'connecting…';
  $('#banner').hidden = state !== 'reconnecting';
}

rpc.addEventListener('state', (e) => setConn(e.detail.state));
rpc.addEventListener('open', () => {
  view.reset(); // the new subscription sends every topology again
  loadScene();
  if (studio) studio.onConnected();
  if (recordings) recordings.refresh().catch(() => {});
  if (playback) playback.check(); // a restarted daemon may play back now, or no longer
});

async function loadScene() {
  try {
    const scene = await rpc.call('rheo.v1.SceneService/GetScene', {});
    view.setFloor(scene.floorHeight || 0);
  } catch (e) {
    console.warn('GetScene', e);
  }
}

let lastStatus = null;
async function pollStatus() {
  if (!rpc.connected) return;
  try {
    const s = await rpc.call('rheo.v1.DaemonService/GetStatus', {});
    // The daemon's own clock (its uptime), not this page's: on a busy machine the replies arrive
    // unevenly, and timing them here showed the 1 kHz loop as 19 Hz, then as 1762 Hz.
    const ticks = Number(s.loop?.ticks || 0);
    const t = Number(s.uptimeS || 0);
    let rate = s.loop?.rateHz || 0;
    if (lastStatus && t > lastStatus.t) rate = (ticks - lastStatus.ticks) / (t - lastStatus.t);
    lastStatus = { t, ticks };
    $('#st-loop').textContent = `loop ${Math.round(rate)} Hz`;
    $('#st-late').textContent = `late ${Number(s.loop?.lateTicks || 0)}`;
    $('#st-viewers').textContent = `viewers ${s.frameClients ?? '—'}`;
    if (studio) studio.onStatus(s);
  } catch (e) {
    console.warn('GetStatus', e);
  }
}

setInterval(() => {
  $('#st-fps').textContent = `${fps()} fps`;
  $('#st-dropped').textContent = `dropped ${stats.dropped}`;
}, 250);
setInterval(pollStatus, 1500);

// ---------------------------------------------------------------------------------------------
// Studio mode: the editing panels exist only here.

// Who this page is: a viewer's token gets the watch-only page (the daemon refuses its edits
// whatever a page does); no valid token gets the sign-in form.
async function whoAmI() {
  await rpc.ready();
  try {
    return await rpc.call('rheo.v1.AuthService/WhoAmI', {});
  } catch (e) {
    return { error: e };
  }
}

// The sign-in form exists only on a page that needs it (a watch-only page has no inputs).
function showSignIn(reason) {
  const form = document.createElement('form');
  form.id = 'sign-in';
  form.className = 'sign-in';
  form.setAttribute('aria-label', 'Sign in');
  form.innerHTML = `
    <h2>This daemon needs an access token</h2>
    <p id="sign-in-reason"></p>
    <p>Ask the daemon's admin for one (<code>rheoctl token create --role operator</code> makes a
      token that may draw and touch; <code>--role viewer</code> one that may only watch), or open
      the address they gave you, which ends in <code>#token=…</code>.</p>
    <label>Token <input id="sign-in-token" type="password" autocomplete="off" spellcheck="false"
      aria-label="Access token"></label>
    <button type="submit">Use this token</button>`;
  form.querySelector('#sign-in-reason').textContent = reason;
  form.addEventListener('submit', (ev) => {
    ev.preventDefault();
    const t = form.querySelector('#sign-in-token').value.trim();
    if (!t) return;
    localStorage.setItem(TOKEN_KEY, t);
    location.reload();
  });
  document.body.append(form);
}

const identity = await whoAmI();
const roleName = { ROLE_VIEWER: 'viewer', ROLE_OPERATOR: 'operator', ROLE_ADMIN: 'admin' };
if (identity.error) {
  viewOnly = true;
  showSignIn(
    identity.error.code === Code.UNAUTHENTICATED
      ? identity.error.message
      : `The daemon did not say who this token is: ${identity.error.message}`,
  );
} else if (identity.role === 'ROLE_VIEWER') {
  viewOnly = true;
}
$('#who').textContent = identity.error ? 'not signed in' : `${identity.tokenName} (${roleName[identity.role] || '?'})`;

const template = $('#studio-panels');
const recTemplate = $('#recordings-panel');
// The recordings panel: in the studio, with its controls; on a viewer's page at the studio's
// address, the list and the downloads only; a /?view page (asked for by its address) and the
// sign-in page keep only the status line's "● REC" indicator, or nothing without a token.
const recPanel = identity.error || asked.view ? null : recTemplate.content.cloneNode(true).firstElementChild;
recTemplate.remove();
if (viewOnly) {
  template.remove();
  $('#mode').textContent = identity.error ? 'sign in' : 'viewer';
  document.title = identity.error ? 'Rheo: sign in' : 'Rheo viewer';
  if (recPanel) {
    const aside = document.createElement('aside');
    aside.className = 'col right';
    aside.setAttribute('aria-label', 'Recordings');
    aside.append(recPanel);
    const layout = $('#layout');
    layout.classList.add('viewer');
    layout.append(aside);
  }
} else {
  const panels = template.content.cloneNode(true);
  template.remove();
  const layout = $('#layout');
  layout.classList.add('studio');
  const [left, right] = panels.querySelectorAll('aside');
  right.querySelector('#recordings-slot').replaceWith(recPanel);
  layout.prepend(left);
  layout.append(right);
  const { Studio } = await import('./studio.js');
  studio = new Studio({ rpc, view, report: (m) => showAppAlert(m) });
}
if (!identity.error) {
  const { Recordings } = await import('./recordings.js');
  const canRecord = !viewOnly && (identity.role === 'ROLE_OPERATOR' || identity.role === 'ROLE_ADMIN');
  recordings = new Recordings(recPanel, rpc, { canRecord, indicator: $('#st-rec') });
  window.rheo.recordings = recordings;
}
// The playback bar: on every signed-in page while rheod plays a recording back (/?view too, so
// no watcher takes it for a live scene); its controls only where the studio's are, for operators
// and admins.
const pbTemplate = $('#playback-bar');
if (!identity.error) {
  const { Playback } = await import('./playback.js');
  const canControl = !viewOnly && (identity.role === 'ROLE_OPERATOR' || identity.role === 'ROLE_ADMIN');
  const bar = pbTemplate.content.cloneNode(true).firstElementChild;
  playback = new Playback(bar, rpc, {
    canControl,
    indicator: $('#st-replay'),
    before: $('#layout'),
    onChange: (playing) => studio?.setReplaying(playing),
  });
  window.rheo.playback = playback;
}
pbTemplate.remove();
// Published once the document has its final controls (templates gone or placed): whoever waits on
// window.rheo.identity (the browser tests) then sees the page as its user will. Set before, a
// viewer's page was once read with the studio's inputs still in it.
window.rheo.viewOnly = viewOnly;
window.rheo.identity = identity.error ? null : { name: identity.tokenName, role: roleName[identity.role] || 'none' };

function showAppAlert(msg) {
  const el = $('#app-alert');
  if (!el) return;
  el.textContent = msg;
  clearTimeout(showAppAlert.timer);
  showAppAlert.timer = setTimeout(() => (el.textContent = ''), 12000);
}

setConn(rpc.state);
watchFrames();
if (rpc.connected) {
  loadScene();
  if (studio) studio.onConnected();
  if (recordings) recordings.refresh().catch(() => {});
  if (playback) playback.check();
}
