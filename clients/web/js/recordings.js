// Session recordings (rheo.v1.RecordingService): the Record / Stop button with a name and a
// frames-per-second field, the live state of the running recording (elapsed time, size, ticks
// dropped), and the list of recordings with Download (ExportRecording streamed into a Blob,
// saved as <name>.mcap) and Delete. A viewer's page gets the list and the downloads only (the
// controls are not put into its document); the daemon checks the role on every call anyway.
// Without a panel (a /?view page) it only keeps the status line's "● REC" indicator.

import { Code, fromBase64 } from './rpc.js';

const S = 'rheo.v1.RecordingService';
const POLL_RECORDING_MS = 1000; // while a recording runs: its duration, size and drops
const POLL_IDLE_MS = 5000; // otherwise: recordings started or deleted by other clients

/** The daemon's words, with what to do where the status code says more. */
export function describeError(err) {
  let hint = '';
  if (err.code === Code.PERMISSION_DENIED)
    hint = 'Recording needs an operator or admin token; this one may watch and download only.';
  else if (err.code === Code.UNAVAILABLE) hint = 'The daemon is not reachable; the studio reconnects by itself.';
  else if (err.code === Code.RESOURCE_EXHAUSTED && /free/.test(err.message))
    hint = 'Delete recordings you no longer need, or free space on the daemon’s disk.';
  return `${err.codeName || 'Error'}: ${err.message}${hint ? `\n${hint}` : ''}`;
}

const STATES = {
  RECORDING_STATE_RECORDING: 'RECORDING',
  RECORDING_STATE_COMPLETE: 'COMPLETE',
  RECORDING_STATE_FAILED: 'FAILED',
  RECORDING_STATE_TRUNCATED: 'TRUNCATED',
};
export const stateName = (r) => STATES[r.state] || 'UNKNOWN';

/** 1536 -> "1.5 KiB". */
export function sizeText(bytes) {
  const b = Number(bytes || 0);
  if (b < 1024) return `${b} B`;
  const units = ['KiB', 'MiB', 'GiB', 'TiB'];
  let v = b / 1024;
  let i = 0;
  while (v >= 1024 && i < units.length - 1) {
    v /= 1024;
    i++;
  }
  return `${v < 10 ? v.toFixed(1) : Math.round(v)} ${units[i]}`;
}

/** Seconds as "2.1 s", "3 min 05 s", "1 h 02 min". */
export function durationText(s) {
  s = Math.max(0, Number(s) || 0);
  if (s < 60) return `${s.toFixed(1)} s`;
  const m = Math.floor(s / 60);
  if (m < 60) return `${m} min ${String(Math.floor(s % 60)).padStart(2, '0')} s`;
  return `${Math.floor(m / 60)} h ${String(m % 60).padStart(2, '0')} min`;
}

/** Seconds as a clock: "00:12", "12:05", "1:02:03". */
export function clockText(s) {
  s = Math.max(0, Math.floor(Number(s) || 0));
  const hh = Math.floor(s / 3600);
  const mm = String(Math.floor((s % 3600) / 60)).padStart(2, '0');
  const ss = String(s % 60).padStart(2, '0');
  return hh ? `${hh}:${mm}:${ss}` : `${mm}:${ss}`;
}

function dateText(ts) {
  const t = Date.parse(ts || '');
  if (!Number.isFinite(t) || t <= 0) return '—';
  return new Date(t).toLocaleString(undefined, { dateStyle: 'medium', timeStyle: 'medium' });
}

/** A recording's name as a file name: "press test #3" -> "press_test_3.mcap". */
export function fileName(r) {
  const base = (r.name || r.id || 'recording').replace(/[^\w.-]+/g, '_').replace(/^[._]+|_+$/g, '');
  return `${base || r.id || 'recording'}.mcap`;
}

const plural = (n, one, many = `${one}s`) => `${n} ${n === 1 ? one : many}`;

function el(tag, className, text) {
  const e = document.createElement(tag);
  if (className) e.className = className;
  if (text !== undefined) e.textContent = text;
  return e;
}

export class Recordings {
  /**
   * @param {HTMLElement|null} root  the panel (#recordings), or null for the indicator alone
   * @param {import('./rpc.js').Rpc} rpc
   * @param {{canRecord: boolean, indicator: HTMLElement|null}} options  canRecord: the Record /
   *   Stop and Delete controls (operators and admins); indicator: the status line's element
   */
  constructor(root, rpc, { canRecord = false, indicator = null } = {}) {
    this.root = root;
    this.rpc = rpc;
    this.canRecord = canRecord && !!root;
    this.indicator = indicator;
    this.recordings = []; // as ListRecordings answered, oldest first
    this.running = null; // the Recording being written, if any
    this.listedAt = 0; // performance.now() of that answer (the elapsed time counts on from it)
    this.busy = false; // a Start or Stop in flight
    this.downloads = new Map(); // id -> fraction done
    this.entries = new Map(); // id -> {sig, node}: the list's elements as drawn
    this.refreshing = null;
    this.lastPoll = 0;
    if (root) {
      this.list = root.querySelector('#rec-list');
      this.live = root.querySelector('#rec-live');
      this.alert = root.querySelector('#rec-alert');
      const controls = root.querySelector('#rec-controls');
      if (!this.canRecord) {
        controls?.remove(); // a viewer's document has no controls it may not use
        root.querySelector('h2').textContent = 'Recordings';
        root.querySelector('h3.sub')?.remove();
      } else {
        this.toggle = root.querySelector('#rec-toggle');
        this.nameInput = root.querySelector('#rec-name');
        this.fpsInput = root.querySelector('#rec-fps');
        this.toggle.addEventListener('click', () => (this.running ? this.stop() : this.start()));
        this.nameInput.addEventListener('keydown', (e) => {
          if (e.key === 'Enter' && !this.running) this.start();
        });
      }
    }
    this.render();
    setInterval(() => this.tick(), 250);
  }

  /** Every 250 ms: the elapsed time; a ListRecordings when one is due. */
  tick() {
    // While recording, the running entry's clock too (only that entry is drawn again).
    if (this.running) this.render();
    else this.renderLive();
    if (!this.rpc.connected || this.refreshing) return;
    const due = this.running ? POLL_RECORDING_MS : POLL_IDLE_MS;
    if (performance.now() - this.lastPoll >= due) this.refresh().catch(() => {});
  }

  /** ListRecordings, then the list and the live state drawn again. */
  refresh() {
    if (this.refreshing) return this.refreshing;
    this.lastPoll = performance.now();
    this.refreshing = (async () => {
      try {
        const resp = await this.rpc.call(`${S}/ListRecordings`, {});
        this.take(resp.recordings || []);
      } finally {
        this.refreshing = null;
        this.lastPoll = performance.now();
      }
      return this.recordings;
    })();
    return this.refreshing;
  }

  take(recordings) {
    const wasRunning = this.running;
    this.recordings = recordings;
    this.running = recordings.find((r) => r.state === 'RECORDING_STATE_RECORDING') || null;
    this.listedAt = performance.now();
    // The one we watched ended without a Stop from this page: say how, if not cleanly.
    if (wasRunning && (!this.running || this.running.id !== wasRunning.id) && !this.busy) {
      const now = recordings.find((r) => r.id === wasRunning.id);
      if (now && now.state === 'RECORDING_STATE_FAILED')
        this.setAlert(`Recording “${now.name}” failed and was ended: ${now.error || 'no reason given'}`);
    }
    this.render();
  }

  setAlert(text, ok = false) {
    if (!this.alert) return;
    this.alert.classList.toggle('ok', ok);
    this.alert.textContent = text;
  }

  // ------------------------------------------------------------------ start / stop

  /** StartRecording with the fields' name and frames per second (or `request` as given). */
  async start(request) {
    if (!this.canRecord || this.busy) return null;
    if (!request) {
      const fpsText = this.fpsInput.value.trim();
      const fps = fpsText === '' ? 60 : Number(fpsText);
      if (!Number.isFinite(fps) || fps < 0) {
        this.setAlert('Frames per second: a number, 0 (no frames) or 1 to 1000.');
        return null;
      }
      request = { name: this.nameInput.value.trim(), framesHz: fps };
    }
    this.busy = true;
    this.setAlert('');
    this.renderLive();
    try {
      const r = await this.rpc.call(`${S}/StartRecording`, request);
      this.running = r;
      this.listedAt = performance.now();
      if (this.nameInput) this.nameInput.value = '';
      return r; // the live state below the button says what runs
    } catch (err) {
      this.setAlert(describeError(err));
      return null;
    } finally {
      this.busy = false;
      await this.refresh().catch(() => this.render());
    }
  }

  async stop() {
    if (!this.canRecord || this.busy) return null;
    this.busy = true;
    this.renderLive();
    try {
      const r = await this.rpc.call(`${S}/StopRecording`, {});
      const state = stateName(r);
      if (state === 'COMPLETE')
        this.setAlert(`Stopped “${r.name}”: ${durationText(r.durationS)}, ${sizeText(r.bytes)}.`, true);
      else this.setAlert(`Stopped “${r.name}”: ${state}${r.error ? `: ${r.error}` : ''}`);
      return r;
    } catch (err) {
      this.setAlert(describeError(err));
      return null;
    } finally {
      this.busy = false;
      await this.refresh().catch(() => this.render());
    }
  }

  // ------------------------------------------------------------------ download / delete

  /** ExportRecording streamed into a Blob (the chunks decoded as they come), saved as <name>.mcap. */
  async download(r) {
    if (this.downloads.has(r.id)) return;
    const total = Number(r.bytes || 0);
    const parts = [];
    let got = 0;
    this.downloads.set(r.id, 0);
    const show = () => {
      // The entry's link as drawn now (a poll may have drawn the entry again meanwhile).
      const link = this.entries.get(r.id)?.node.querySelector('a.download');
      if (!link) return;
      link.classList.add('busy');
      link.textContent = total ? `Downloading… ${Math.floor((100 * got) / total)} %` : 'Downloading…';
    };
    show();
    try {
      const h = this.rpc.stream(`${S}/ExportRecording`, { id: r.id }, (chunk) => {
        const bytes = fromBase64(chunk.data || '');
        parts.push(bytes);
        got += bytes.length;
        show();
      });
      await h.done;
      const blob = new Blob(parts, { type: 'application/octet-stream' });
      const a = document.createElement('a');
      a.href = URL.createObjectURL(blob);
      a.download = fileName(r);
      document.body.appendChild(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(a.href), 30000);
    } catch (err) {
      this.setAlert(`Download “${r.name}”: ${describeError(err)}`);
    } finally {
      this.downloads.delete(r.id);
      this.entries.delete(r.id); // its link's text was changed in place: draw it again
      this.render();
    }
  }

  async remove(r) {
    if (!this.canRecord) return;
    const what = `${durationText(r.durationS)}, ${sizeText(r.bytes)}`;
    if (!window.confirm(`Delete the recording “${r.name}” (${what})? Its file is removed from the daemon; this cannot be undone.`))
      return;
    try {
      await this.rpc.call(`${S}/DeleteRecording`, { id: r.id });
      this.setAlert(`Deleted “${r.name}”.`, true);
    } catch (err) {
      this.setAlert(`Delete “${r.name}”: ${describeError(err)}`);
    }
    await this.refresh().catch(() => this.render());
  }

  // ------------------------------------------------------------------ drawing

  /** Seconds the running recording has been going, counted on locally since the last listing. */
  elapsed() {
    if (!this.running) return 0;
    return Number(this.running.durationS || 0) + (performance.now() - this.listedAt) / 1000;
  }

  renderLive() {
    const r = this.running;
    if (this.indicator) {
      const text = r ? `● REC ${clockText(this.elapsed())}` : '';
      if (this.indicator.textContent !== text) this.indicator.textContent = text;
      this.indicator.title = r ? `recording “${r.name}” (${r.id})` : '';
    }
    if (this.toggle) {
      const label = r ? 'Stop' : 'Record';
      if (this.toggle.dataset.label !== label) {
        this.toggle.dataset.label = label;
        this.toggle.innerHTML = `<span class="rec-dot" aria-hidden="true"></span>${label}`;
        this.toggle.classList.toggle('recording', !!r);
        this.toggle.title = r ? 'Stop the recording (writes its summary and footer)' : 'Start recording the session';
      }
      this.toggle.disabled = this.busy;
      this.nameInput.disabled = !!r || this.busy;
      this.fpsInput.disabled = !!r || this.busy;
    }
    if (!this.live) return;
    let text;
    if (this.busy && !r) text = 'Starting…';
    else if (this.busy) text = 'Stopping…';
    else if (r) {
      const drops = Number(r.droppedTicks || 0);
      text =
        `● Recording “${r.name}” · ${clockText(this.elapsed())} · ${sizeText(r.bytes)} · ` +
        `${r.framesHz ? `${r.framesHz} frames/s` : 'no frames'} · ${drops ? plural(drops, 'tick') + ' dropped' : 'no ticks dropped'}`;
    } else text = 'Not recording.';
    if (this.live.textContent !== text) this.live.textContent = text;
    this.live.classList.toggle('on', !!r);
  }

  render() {
    this.renderLive();
    if (!this.list) return;
    const running = this.running;
    const done = this.recordings.filter((r) => !running || r.id !== running.id);
    if (!running && !done.length) {
      this.entries.clear();
      if (!this.list.querySelector('.rec-empty'))
        this.list.replaceChildren(
          el('p', 'rec-empty muted small', this.canRecord ? 'No recordings yet. Press Record to record the session.' : 'No recordings yet.'),
        );
      return;
    }
    // Newest first, the running one on top. An entry whose text would not change keeps its
    // element (a link being clicked, a hover), and the list is only touched when one changed:
    // a poll answers the same recordings over and over.
    const next = new Map();
    const nodes = [...(running ? [running] : []), ...done.reverse()].map((r) => {
      const sig = this.entrySig(r);
      const old = this.entries.get(r.id);
      const node = old && old.sig === sig ? old.node : this.entry(r);
      next.set(r.id, { sig, node });
      return node;
    });
    this.entries = next;
    const now = [...this.list.children];
    const sameOrder = now.length === nodes.length && now.every((n, i) => n.dataset.id === nodes[i].dataset.id);
    if (!sameOrder) this.list.replaceChildren(...nodes);
    else now.forEach((n, i) => n !== nodes[i] && n.replaceWith(nodes[i])); // the others stay put
  }

  /** What an entry shows (not message_counts, whose order the daemon's JSON does not keep). */
  entrySig(r) {
    const state = stateName(r);
    return JSON.stringify([
      r.id, r.name, state, r.started, state === 'RECORDING' ? clockText(this.elapsed()) : r.durationS, r.bytes,
      r.framesHz, r.droppedTicks, r.droppedEvents, r.error, this.downloads.has(r.id),
    ]);
  }

  entry(r) {
    const state = stateName(r);
    const item = el('article', `rec-item ${state.toLowerCase()}`);
    item.dataset.id = r.id;
    item.setAttribute('aria-label', `Recording ${r.name}`);
    const head = el('div', 'rec-head');
    const name = el('span', 'rec-name', r.name || r.id);
    name.title = `${r.id}\n${r.file || ''}`;
    const badge = el('span', `rec-state ${state.toLowerCase()}`, state);
    head.append(name, badge);
    const when = state === 'RECORDING' ? clockText(this.elapsed()) : durationText(r.durationS);
    const meta = el(
      'div',
      'muted small',
      `${dateText(r.started)} · ${when} · ${sizeText(r.bytes)} · ${r.framesHz ? `${r.framesHz} frames/s` : 'no frames'}`,
    );
    const drops = Number(r.droppedTicks || 0);
    const events = Number(r.droppedEvents || 0);
    const dropText =
      (drops ? `${plural(drops, 'tick')} dropped (missing from /tool)` : 'no ticks dropped') +
      (events ? ` · ${plural(events, 'event')} dropped` : '');
    const dropLine = el('div', `small ${drops || events ? 'rec-warn' : 'muted'}`, dropText);
    item.append(head, meta, dropLine);
    if (state === 'FAILED' || state === 'TRUNCATED') {
      const why =
        state === 'FAILED'
          ? `Failed: ${r.error || 'no reason given'}. The file holds what was written before.`
          : `Truncated: rheod ended without stopping it${r.error ? ` (${r.error})` : ''}. Every complete chunk is in the file.`;
      item.append(el('div', 'rec-error small', why));
    }
    const actions = el('div', 'lib-actions');
    if (state !== 'RECORDING') {
      const a = el('a', 'download', this.downloads.has(r.id) ? 'Downloading…' : 'Download .mcap');
      a.href = '#';
      a.setAttribute('aria-label', `Download ${r.name} as MCAP`);
      a.addEventListener('click', (e) => {
        e.preventDefault();
        this.download(r);
      });
      actions.append(a);
      if (this.canRecord) {
        const del = el('button', 'danger', 'Delete');
        del.type = 'button';
        del.setAttribute('aria-label', `Delete recording ${r.name}`);
        del.addEventListener('click', () => this.remove(r));
        actions.append(del);
      }
    } else {
      actions.append(el('span', 'muted small', 'download once stopped'));
    }
    item.append(actions);
    return item;
  }
}
