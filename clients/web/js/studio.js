// The editing half of the studio (never loaded on a /?view page): sketch pad with live contour
// preview, "Make it" (CreateObject with progress and cancel, then AddToScene), the touch tools
// (press with the simulated hand, or drag the network tool), live parameters and the library.

import { Code } from './rpc.js';
import { SketchPad } from './sketchpad.js';
import { ParamsPanel } from './params.js';
import { Library } from './library.js';

const $ = (sel) => document.querySelector(sel);

/** What to change, by status code, after the daemon's own words. */
function advice(err) {
  switch (err.code) {
    case Code.INVALID_ARGUMENT:
      return 'Change the sketch: draw one closed outline without crossings (or fix the value named above).';
    case Code.RESOURCE_EXHAUSTED:
      return 'Make it lighter: raise Resolution (coarser mesh) or lower Thickness, or draw a smaller shape.';
    case Code.DEADLINE_EXCEEDED:
      return 'It took too long: raise Resolution for a coarser mesh.';
    case Code.FAILED_PRECONDITION:
      // A daemon playing a recording back (rheod --replay) says why and what to do itself.
      if (/^rheod is playing back /.test(err.message)) return '';
      return 'The daemon is not ready for this right now.';
    case Code.UNAVAILABLE:
      return 'The daemon is not reachable; the studio reconnects by itself.';
    default:
      return '';
  }
}

function describe(err) {
  const hint = advice(err);
  return `${err.codeName || 'Error'}: ${err.message}${hint ? `\n${hint}` : ''}`;
}

const newRequestId = () =>
  crypto.randomUUID ? crypto.randomUUID() : `${Date.now()}-${Math.random().toString(16).slice(2)}`;

export class Studio {
  constructor({ rpc, view, report }) {
    this.rpc = rpc;
    this.view = view;
    this.report = report;
    this.padAlert = $('#pad-alert');
    this.job = null; // the running CreateObject: {handle, jobId}
    this.device = null; // DeviceStatus
    this.mode = null; // "press" | "drag" | null
    this.initPad();
    this.initMake();
    this.params = new ParamsPanel($('#params'), rpc, report);
    this.library = new Library($('#library'), rpc, { add: (o) => this.addToScene(o), report });
    this.initControls();
    this.initViewInput();
  }

  // ------------------------------------------------------------------ connection

  async onConnected() {
    this.sceneRevision = undefined;
    await Promise.allSettled([this.library.refresh(), this.params.refreshScene(), this.loadDevice()]);
  }

  /** Every status poll (1.5 s): a multi-rate object's figures (lag, step time) move as it runs. */
  onStatus() {
    if (this.params.anyMultiRate && !this.multiRateBusy) {
      this.multiRateBusy = true;
      this.params
        .refreshMultiRate()
        .catch(() => {})
        .finally(() => (this.multiRateBusy = false));
    }
  }

  onFrame(frame) {
    // The scene changed (an object added or removed anywhere): refresh the instance list.
    const rev = frame.topologyRevision;
    if (rev !== undefined && rev !== this.sceneRevision) {
      this.sceneRevision = rev;
      this.params.refreshScene().catch(() => {});
    }
  }

  // ------------------------------------------------------------------ sketch pad

  initPad() {
    const pad = new SketchPad($('#pad'));
    this.pad = pad;
    this.previewSeq = 0;
    pad.addEventListener('change', () => this.schedulePreview());
    $('#undo').addEventListener('click', () => pad.undo());
    $('#clear').addEventListener('click', () => pad.clear());
    $('#bg-opacity').addEventListener('input', (e) => pad.setBackgroundOpacity(Number(e.target.value)));
    $('#bg-file').addEventListener('change', (e) => this.loadBackground(e.target.files[0]));
    $('#bg-clear').addEventListener('click', () => pad.clearBackground());
    $('#picture-file').addEventListener('change', async (e) => {
      const f = e.target.files[0];
      if (!f) return;
      try {
        await pad.setPicture(f);
        $('#pad-info').textContent = `Sketch: picture ${f.name} (${pad.canvas.width} × ${pad.canvas.height} px). Undo returns to drawing.`;
      } catch (err) {
        this.setPadAlert(`That picture cannot be opened here: ${err.message}`);
      }
      e.target.value = '';
    });
    // Drag and drop: a photo to trace over.
    const wrap = $('#pad-wrap');
    wrap.addEventListener('dragover', (e) => {
      e.preventDefault();
      wrap.classList.add('dragover');
    });
    wrap.addEventListener('dragleave', () => wrap.classList.remove('dragover'));
    wrap.addEventListener('drop', (e) => {
      e.preventDefault();
      wrap.classList.remove('dragover');
      const f = [...(e.dataTransfer?.files || [])].find((x) => /^image\//.test(x.type));
      if (f) this.loadBackground(f);
    });
  }

  async loadBackground(file) {
    if (!file) return;
    try {
      await this.pad.setBackground(file);
      $('#pad-info').textContent = `Background: ${file.name} (stored with the object, not traced)`;
    } catch (err) {
      this.setPadAlert(`That photo cannot be opened here: ${err.message}`);
    }
    $('#bg-file').value = '';
  }

  setPadAlert(text) {
    this.padAlert.classList.remove('ok');
    this.padAlert.textContent = text;
  }

  schedulePreview() {
    clearTimeout(this.previewTimer);
    this.previewTimer = setTimeout(() => this.preview(), 250);
  }

  /** ExtractContour after each stroke: the contour over the strokes, or the refusal in words. */
  async preview() {
    const seq = ++this.previewSeq;
    if (this.pad.isEmpty()) {
      this.pad.setContour(null);
      this.setPadAlert('');
      $('#pad-info').textContent = '';
      return;
    }
    try {
      const report = await this.rpc.call('rheo.v1.ObjectService/ExtractContour', {
        sketch: this.pad.sketch({ withBackground: false }),
        options: {},
      });
      if (seq !== this.previewSeq) return;
      const pts = (report.contour?.points || []).map((p) => [p.x || 0, p.y || 0]);
      this.pad.setContour(pts);
      this.setPadAlert('');
      const notes = [...(report.repairs || []), ...(report.warnings || [])];
      $('#pad-info').textContent = `Contour: ${pts.length} points` + (notes.length ? ` · ${notes.join('; ')}` : '');
    } catch (err) {
      if (seq !== this.previewSeq) return;
      this.pad.setContour(null);
      $('#pad-info').textContent = '';
      this.setPadAlert(describe(err));
    }
  }

  // ------------------------------------------------------------------ make it

  initMake() {
    const th = $('#thickness');
    const res = $('#resolution');
    const show = () => {
      $('#thickness-out').textContent = `${Number(th.value).toFixed(2)} ×`;
      $('#resolution-out').textContent = `${Number(res.value)} mm`;
    };
    th.addEventListener('input', show);
    res.addEventListener('input', show);
    show();
    $('#create').addEventListener('click', () => this.create());
    $('#cancel').addEventListener('click', () => this.cancel());
  }

  setBusy(busy) {
    $('#create').disabled = busy;
    $('#cancel').disabled = !busy;
    $('#progress').hidden = !busy && !this.keepProgress;
  }

  showProgress(stage, fraction) {
    $('#progress').hidden = false;
    $('#progress-bar').value = fraction;
    $('#progress-stage').textContent = `${stage} · ${Math.round(fraction * 100)} %`;
  }

  /** CreateObject (a stream of CreateObjectProgress), then AddToScene with the stored object. */
  async create() {
    if (this.job) return;
    const request = {
      name: $('#obj-name').value.trim(),
      sketch: this.pad.sketch(),
      contourOptions: {},
      meshOptions: {
        thickness: Number($('#thickness').value),
        resolution: Number($('#resolution').value) / 1000,
      },
      addToScene: false,
      requestId: newRequestId(),
    };
    this.setPadAlert('');
    this.keepProgress = false;
    this.setBusy(true);
    this.showProgress('queued', 0);
    let object = null;
    const job = { jobId: '', handle: null };
    this.job = job;
    job.handle = this.rpc.stream('rheo.v1.ObjectService/CreateObject', request, (p) => {
      if (p.jobId) job.jobId = p.jobId;
      this.showProgress(p.stage || '…', p.fraction || 0);
      if (p.contour?.contour?.points) this.pad.setContour(p.contour.contour.points.map((q) => [q.x || 0, q.y || 0]));
      if (p.object && p.object.id) object = p.object;
    });
    try {
      await job.handle.done;
      if (!object) throw Object.assign(new Error('the daemon ended the job without an object'), { code: Code.UNKNOWN });
      this.showProgress('stored', 1);
      const placed = await this.addToScene(object);
      if (placed) {
        this.padAlert.classList.add('ok');
        this.padAlert.textContent = `Created “${object.name}”: ${object.mesh?.tetrahedronCount || 0} tetrahedra, in the scene as #${placed.instanceId}.`;
      }
      this.library.refresh().catch(() => {});
    } catch (err) {
      this.setPadAlert(err.code === Code.CANCELLED ? 'Cancelled: nothing was stored.' : describe(err));
    } finally {
      this.job = null;
      this.setBusy(false);
    }
  }

  async cancel() {
    const job = this.job;
    if (!job) return;
    $('#cancel').disabled = true;
    if (job.jobId) {
      try {
        await this.rpc.call('rheo.v1.ObjectService/CancelJob', { jobId: job.jobId });
      } catch (err) {
        console.warn('CancelJob', err);
      }
    }
    job.handle.cancel();
  }

  /** AddToScene; returns the SceneObject, or null after showing why not. */
  async addToScene(object) {
    try {
      const placed = await this.rpc.call('rheo.v1.SceneService/AddToScene', { objectId: object.id });
      await this.params.refreshScene(placed.instanceId);
      return placed;
    } catch (err) {
      this.setPadAlert(`Stored “${object.name}”, but it was not added to the scene.\n${describe(err)}`);
      return null;
    }
  }

  // ------------------------------------------------------------------ run controls

  initControls() {
    const control = async (command) => {
      try {
        await this.rpc.call('rheo.v1.SceneService/Control', { command });
      } catch (err) {
        this.report(describe(err));
      }
    };
    $('#pause').addEventListener('click', () => control('RUN_COMMAND_PAUSE'));
    $('#resume').addEventListener('click', () => control('RUN_COMMAND_RESUME'));
    $('#reset').addEventListener('click', () => control('RUN_COMMAND_RESET'));
    $('#step').addEventListener('click', () => control('RUN_COMMAND_STEP'));
    $('#remove').addEventListener('click', async () => {
      const id = this.params.instanceId;
      if (!id) {
        this.report('Choose an object to remove (not the scene).');
        return;
      }
      try {
        await this.rpc.call('rheo.v1.SceneService/RemoveFromScene', { instanceId: id });
        await this.params.refreshScene();
      } catch (err) {
        this.report(describe(err));
      }
    });
    $('#lib-refresh').addEventListener('click', () => this.library.refresh().catch((e) => this.report(e.message)));
  }

  // ------------------------------------------------------------------ touch: device tools

  async loadDevice() {
    const info = $('#device-info');
    const actions = $('#device-actions');
    actions.replaceChildren();
    try {
      this.device = await this.rpc.call('rheo.v1.DeviceService/GetDeviceStatus', {});
    } catch (err) {
      this.device = null;
      info.textContent = err.code === Code.FAILED_PRECONDITION ? 'No haptic device attached (--device none).' : `Device: ${err.message}`;
      return;
    }
    const d = this.device;
    if (d.kind === 'DEVICE_KIND_NONE') {
      this.showNoDevice();
      return;
    }
    info.textContent = `${d.model || d.name || d.kind}${d.connected ? '' : ' (not connected)'}`;
    const button = (label, onClick) => {
      const b = document.createElement('button');
      b.type = 'button';
      b.textContent = label;
      b.addEventListener('click', onClick);
      actions.appendChild(b);
      return b;
    };
    if (d.kind === 'DEVICE_KIND_SIM_SPIDAR_G') {
      this.pressButton = button('Press here', () => this.setMode(this.mode === 'press' ? null : 'press'));
      button('Let go', () => this.hand({ release: true }));
    } else if (d.kind === 'DEVICE_KIND_NETWORK') {
      this.dragButton = button('Drag tool', () => (this.mode === 'drag' ? this.stopDrag() : this.startDrag()));
    }
  }

  /**
   * The playback bar's news: whether rheod plays a recording back (it then has no device, and the
   * tool in the view is the recorded one, which "--device none" would misdescribe).
   */
  setReplaying(on) {
    if (this.replaying === on) return;
    this.replaying = on;
    if (this.device?.kind === 'DEVICE_KIND_NONE') this.showNoDevice();
  }

  showNoDevice() {
    $('#device-info').textContent = this.replaying
      ? 'Playing a recording back (rheod --replay): the tool in the view is the recorded one; nothing here can touch.'
      : 'No haptic device attached (rheod --device none): watch only.';
  }

  setMode(mode) {
    this.mode = mode;
    this.pressButton?.classList.toggle('active', mode === 'press');
    this.dragButton?.classList.toggle('active', mode === 'drag');
    $('.viewport').classList.toggle('picking', !!mode);
    $('#view-hint').textContent =
      mode === 'press'
        ? 'Click an object to press the simulated hand into it'
        : mode === 'drag'
          ? 'Drag in the view to move the tool (Shift: along depth); orbit with the right button'
          : '';
  }

  async hand(action) {
    try {
      return await this.rpc.call('rheo.v1.DeviceService/SimulatedHand', action);
    } catch (err) {
      this.report(describe(err));
      return null;
    }
  }

  initViewInput() {
    const canvas = this.view.canvas;
    canvas.addEventListener('pointerdown', (e) => {
      if (this.mode === 'press' && e.button === 0) {
        const hit = this.view.pick(e.clientX, e.clientY);
        if (!hit) return;
        e.stopImmediatePropagation();
        this.hand({
          press: { depthM: 0.008, seconds: 1, instanceId: hit.instanceId, at: { x: hit.point.x, y: hit.point.y, z: hit.point.z } },
        });
      } else if (this.mode === 'drag' && e.button === 0) {
        e.stopImmediatePropagation();
        canvas.setPointerCapture(e.pointerId);
        this.dragging = { id: e.pointerId };
        this.dragTo(e);
      }
    }, { capture: true });
    canvas.addEventListener('pointermove', (e) => {
      if (this.dragging && e.pointerId === this.dragging.id) {
        e.stopImmediatePropagation();
        this.dragTo(e);
      }
    }, { capture: true });
    const up = (e) => {
      if (this.dragging && e.pointerId === this.dragging.id) this.dragging = null;
    };
    canvas.addEventListener('pointerup', up, { capture: true });
    canvas.addEventListener('pointercancel', up, { capture: true });
  }

  // The network tool: lease, ToolStream of poses in the device frame (scene minus tool_origin).
  async startDrag() {
    try {
      this.lease = await this.rpc.call('rheo.v1.DeviceService/AcquireLease', { clientName: 'studio', durationS: 10 });
    } catch (err) {
      this.report(describe(err));
      return;
    }
    const status = await this.rpc.call('rheo.v1.DeviceService/GetDeviceStatus', {}).catch(() => this.device);
    const o = status?.toolOrigin || {};
    this.toolOrigin = { x: o.x || 0, y: o.y || 0, z: o.z || 0 };
    const tool = this.view.tool;
    this.toolTarget = tool.group.visible ? tool.grip.position.clone() : null;
    this.toolStream = this.rpc.bidi('rheo.v1.DeviceService/ToolStream', (fb) => (this.feedback = fb));
    this.toolStream.done.catch((err) => {
      if (this.mode === 'drag') {
        this.report(describe(err));
        this.stopDrag();
      }
    });
    this.renewTimer = setInterval(async () => {
      try {
        this.lease = await this.rpc.call('rheo.v1.DeviceService/RenewLease', { leaseId: this.lease.leaseId, durationS: 10 });
      } catch (err) {
        this.report(describe(err));
        this.stopDrag();
      }
    }, 3000);
    // Keep the pose fresh (the daemon treats a silent tool as disconnected after 0.2 s).
    this.poseTimer = setInterval(() => this.sendPose(), 50);
    this.setMode('drag');
  }

  dragTo(e) {
    const through = this.toolTarget || this.view.tool.grip.position;
    const p = this.view.pointOnViewPlane(e.clientX, e.clientY, through);
    if (!p) return;
    this.toolTarget = p;
    this.sendPose();
  }

  sendPose() {
    if (!this.toolStream || !this.toolTarget) return;
    const p = this.toolTarget;
    const o = this.toolOrigin;
    this.toolStream.write({
      leaseId: this.lease.leaseId,
      pose: { position: { x: p.x - o.x, y: p.y - o.y, z: p.z - o.z }, orientation: { w: 1, x: 0, y: 0, z: 0 } },
      buttons: 0,
    });
  }

  async stopDrag() {
    clearInterval(this.renewTimer);
    clearInterval(this.poseTimer);
    this.setMode(null);
    if (this.toolStream) this.toolStream.end();
    this.toolStream = null;
    const lease = this.lease;
    this.lease = null;
    if (lease) await this.rpc.call('rheo.v1.DeviceService/ReleaseLease', { leaseId: lease.leaseId }).catch(() => {});
  }
}
