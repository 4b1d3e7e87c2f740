// Playback of a session recording (rheod --replay FILE): a bar above the view with the file, a
// Play / Pause button, Step, the position as a slider, the time and the speed, a note that the
// scene follows the recording, and "REPLAY" in the status line, so that nobody takes the
// recording's scene for a live one. The bar is in the document only while the daemon plays a
// recording back: GetPlayback is asked once at every (re)connection and, while it answers, every
// 250 ms; FAILED_PRECONDITION (this rheod plays nothing back) takes the bar away and stops the
// polling. ControlPlayback acts for every client at once, so the bar draws what the daemon
// answers, never what was clicked. A page that may not control it (a viewer's token, /?view)
// gets the position and the time only: the buttons, the slider and the selector are not put into
// its document (the daemon checks the role on every call anyway).

import { Code } from './rpc.js';

const S = 'rheo.v1.RecordingService';
const POLL_MS = 250;
/** The speeds offered; another one set elsewhere (rheoctl record playback --speed) is added. */
export const SPEEDS = [0.25, 0.5, 1, 2, 4];
// A seek's answer may still show the frame before it (the playback thread takes the seek after
// the reply): the slider keeps the asked-for position until a poll shows it, or this long.
const SEEK_HOLD_MS = 1500;

/** The daemon's words, with what to do where the status code says more. */
export function describeError(err) {
  let hint = '';
  if (err.code === Code.PERMISSION_DENIED)
    hint = 'Controlling the playback needs an operator or admin token; this one may watch only.';
  else if (err.code === Code.UNAVAILABLE) hint = 'The daemon is not reachable; the studio reconnects by itself.';
  return `${err.codeName || 'Error'}: ${err.message}${hint ? `\n${hint}` : ''}`;
}

/** Seconds as "12.3 / 45.6 s". */
export function timeText(position, duration) {
  const f = (s) => Math.max(0, Number(s) || 0).toFixed(1);
  return `${f(position)} / ${f(duration)} s`;
}

/** 0.25 -> "0.25×", 4 -> "4×". */
export const speedText = (v) => `${Number(v)}×`;

/** The file's name without its directory (the path on the daemon's machine is the tooltip). */
export const baseName = (path) => String(path || '').split(/[\\/]/).pop() || '(unnamed)';

export class Playback {
  /**
   * @param {HTMLElement} root  the bar (#playback, from the page's template), not yet in the document
   * @param {import('./rpc.js').Rpc} rpc
   * @param {{canControl: boolean, indicator: HTMLElement|null, before: HTMLElement}} options
   *   canControl: the buttons, slider and selector (operators and admins on the studio page);
   *   indicator: the status line's element; before: the bar is put into the page before it;
   *   onChange(playing): told when the bar comes (true) and goes (false)
   */
  constructor(root, rpc, { canControl = false, indicator = null, before = null, onChange = () => {} } = {}) {
    this.root = root;
    this.onChange = onChange;
    this.rpc = rpc;
    this.canControl = canControl;
    this.indicator = indicator;
    this.before = before;
    this.state = null; // the last Playback the daemon answered; null: not playing back
    this.timer = null; // the 250 ms poll, only while shown
    this.polling = false;
    this.version = 0; // counts controls sent: a poll asked before one must not draw over its answer
    this.scrub = null; // the slider's value while it is dragged
    this.hold = null; // {value, at, until}: a seek asked for and not yet shown
    this.checking = null;
    this.file = root.querySelector('#pb-file');
    this.time = root.querySelector('#pb-time');
    this.stateEl = root.querySelector('#pb-state');
    this.alert = root.querySelector('#pb-alert');
    const slider = root.querySelector('#pb-position');
    if (!canControl) {
      // Watching only: the position as a bar that cannot be moved, no buttons, no selector.
      root.querySelector('#pb-controls')?.remove();
      root.querySelector('#pb-speed-field')?.remove();
      // What is refused concerns those who may edit; a watcher needs to know it is not live.
      root.querySelector('.pb-note').textContent = 'The 3D view shows the recording, not a live scene.';
      const progress = document.createElement('progress');
      progress.id = 'pb-progress';
      progress.className = 'pb-position';
      progress.setAttribute('aria-label', 'Playback position');
      progress.max = 1;
      progress.value = 0;
      slider.replaceWith(progress);
      this.progress = progress;
    } else {
      this.toggle = root.querySelector('#pb-toggle');
      this.step = root.querySelector('#pb-step');
      this.slider = slider;
      this.speed = root.querySelector('#pb-speed');
      for (const v of SPEEDS) this.speed.append(new Option(speedText(v), String(v)));
      this.toggle.addEventListener('click', () => this.state && this.control({ paused: !this.state.paused }));
      this.step.addEventListener('click', () => this.control({ step: true }));
      // Dragged: the time follows the thumb, and a thumb held still is not moved by the polls
      // under the pointer; let go (or a key): one seek.
      slider.addEventListener('pointerdown', () => (this.scrub = Number(slider.value)));
      slider.addEventListener('input', () => {
        this.scrub = Number(slider.value);
        this.render();
      });
      slider.addEventListener('change', () => this.seek(Number(slider.value)));
      // Let go where it was (no change, no seek): the polls move it again.
      const release = () => setTimeout(() => (this.scrub = null), 0);
      slider.addEventListener('pointerup', release);
      slider.addEventListener('pointercancel', release);
      this.speed.addEventListener('change', () => this.control({ speed: Number(this.speed.value) }));
    }
  }

  get shown() {
    return this.root.isConnected;
  }

  /**
   * GetPlayback once (at every connection): shows the bar and polls while the daemon plays back,
   * takes it away when it says it plays nothing. Resolves with the Playback or null.
   */
  check() {
    if (this.checking) return this.checking;
    this.checking = (async () => {
      try {
        const p = await this.rpc.call(`${S}/GetPlayback`, {});
        this.take(p);
        return p;
      } catch (err) {
        // FAILED_PRECONDITION: a live daemon; UNIMPLEMENTED: one older than playback. Anything
        // else (the connection dropped) leaves the bar as it is: the next connection asks again.
        if (err.code === Code.FAILED_PRECONDITION || err.code === Code.UNIMPLEMENTED) this.hide();
        return null;
      } finally {
        this.checking = null;
      }
    })();
    return this.checking;
  }

  /** Every 250 ms while shown: GetPlayback, unless one is still on its way. */
  async poll() {
    if (!this.rpc.connected || this.polling || this.checking) return;
    this.polling = true;
    const version = this.version;
    try {
      const p = await this.rpc.call(`${S}/GetPlayback`, {});
      if (version === this.version) this.take(p);
    } catch (err) {
      if (err.code === Code.FAILED_PRECONDITION) this.hide(); // restarted without --replay
    } finally {
      this.polling = false;
    }
  }

  show() {
    if (this.shown) return;
    this.before.before(this.root);
    document.body.classList.add('replaying');
    this.timer = setInterval(() => this.poll(), POLL_MS);
    this.onChange(true);
  }

  hide() {
    clearInterval(this.timer);
    this.timer = null;
    this.state = null;
    const was = this.shown;
    this.root.remove();
    document.body.classList.remove('replaying');
    this.renderIndicator();
    if (was) this.onChange(false);
  }

  take(p) {
    this.state = p;
    const h = this.hold;
    // The seek is shown once the position is at it, or past it by what playing added since.
    if (h) {
      const ran = p.paused ? 0 : ((performance.now() - h.at) / 1000) * (p.speed || 1);
      const pos = Number(p.positionS || 0);
      if (performance.now() > h.until || (pos >= h.value - 0.1 && pos <= h.value + ran + 0.3)) this.hold = null;
    }
    this.show();
    this.render();
  }

  setAlert(text) {
    if (this.alert.textContent !== text) this.alert.textContent = text;
  }

  // ------------------------------------------------------------------ control

  /** ControlPlayback with `request` (speed, seekS, paused, step); resolves with its answer or null. */
  async control(request) {
    if (!this.canControl) return null;
    this.version += 1;
    try {
      const p = await this.rpc.call(`${S}/ControlPlayback`, request);
      this.version += 1; // a poll asked meanwhile may predate it
      this.setAlert('');
      this.take(p);
      return p;
    } catch (err) {
      this.setAlert(describeError(err));
      this.render(); // e.g. the selector back to the speed the daemon kept
      return null;
    }
  }

  seek(value) {
    this.scrub = null;
    this.hold = { value, at: performance.now(), until: performance.now() + SEEK_HOLD_MS };
    this.render();
    return this.control({ seekS: value });
  }

  // ------------------------------------------------------------------ drawing

  renderIndicator() {
    if (!this.indicator) return;
    const p = this.state;
    const text = p ? `REPLAY${p.ended ? ' · ended' : p.paused ? ' · paused' : ''}` : '';
    if (this.indicator.textContent !== text) this.indicator.textContent = text;
    this.indicator.title = p ? `playing back ${p.file} (rheod --replay): the scene is the recording's, not a live one` : '';
  }

  render() {
    this.renderIndicator();
    const p = this.state;
    if (!p) return;
    const duration = Number(p.durationS || 0);
    const shown = this.scrub ?? this.hold?.value ?? Number(p.positionS || 0);
    const name = baseName(p.file);
    if (this.file.textContent !== name) this.file.textContent = name;
    this.file.title = p.file;
    const time = timeText(shown, duration);
    if (this.time.textContent !== time) this.time.textContent = time;
    const speed = Number(p.speed || 1);
    let state = p.ended ? 'ended' : p.paused ? 'paused' : 'playing';
    if (!this.canControl && speed !== 1) state += ` at ${speedText(speed)}`;
    if (this.stateEl.textContent !== state) this.stateEl.textContent = state;
    this.stateEl.className = `pb-state ${p.ended ? 'ended' : p.paused ? 'paused' : 'playing'}`;
    this.stateEl.title = `tick ${p.tick}; ${p.frames} frames in the file, ${p.framesShown} shown since rheod started`;
    if (this.progress) {
      this.progress.max = duration || 1;
      this.progress.value = Math.min(shown, duration);
      return;
    }
    const label = p.paused ? 'Play' : 'Pause';
    if (this.toggle.dataset.label !== label) {
      this.toggle.dataset.label = label;
      this.toggle.innerHTML = `<span class="pb-icon" aria-hidden="true">${p.paused ? '▶' : '❚❚'}</span>${label}`;
      this.toggle.title = p.paused ? (p.ended ? 'Play it again from the start' : 'Play on from here') : 'Pause the playback';
    }
    this.step.disabled = !p.paused || p.ended;
    this.step.title = p.ended ? 'at the last frame' : p.paused ? 'show the next recorded frame' : 'pause first';
    if (this.slider.max !== String(duration)) this.slider.max = String(duration);
    if (this.scrub === null) this.slider.value = String(shown);
    const value = String(speed);
    if (![...this.speed.options].some((o) => o.value === value)) this.speed.append(new Option(speedText(speed), value));
    if (this.speed.value !== value) this.speed.value = value;
  }
}
